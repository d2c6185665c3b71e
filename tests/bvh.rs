//! The flattened BVH and the skip-index traversal (Alg. 4, with nearest-hit fixes), and the
//! eight-wide BVH's front-to-back walk, find the same nearest hit as a brute-force search over
//! every primitive: on the device (PoCL) and in the Rust reference, for random triangle soups
//! and for the bundled scenes' meshes, including axis-parallel rays, rays through box planes,
//! rays leaving surfaces and coincident triangles (ties).

mod common;

use common::{TestRng, bundled_scenes, device_intersect};
use glam::{Vec2, Vec3};
use noisefree::arrays::trace::{
    Hit, Prim, brute_force_closest, intersect_closest, occluded, occluder_range,
};
use noisefree::arrays::trace_wide;
use noisefree::bvh::BvhLayout;
use noisefree::geometry::offset_ray_origin;
use noisefree::render::{FrameSettings, SceneArrays};
use noisefree::scene::{
    Camera, Material, MaterialKind, RenderSettings, Scene, Setting, SphereObject, Triangle,
};
use rayon::prelude::*;

fn scene_of(triangles: Vec<Triangle>, spheres: Vec<SphereObject>) -> Scene {
    Scene {
        path: "soup".into(),
        render: RenderSettings {
            width: 8,
            height: 8,
            spp: 1,
            max_depth: 3,
            seed: 0,
            russian_roulette: true,
            next_event_estimation: true,
            setting: Setting::Indoor,
            clamp: 0.0,
        },
        camera: Camera {
            origin: Vec3::new(0.0, 0.0, 10.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_degrees: 40.0,
            lens_radius: 0.0,
            focal_distance: None,
            autofocus: false,
        },
        textures: vec![],
        materials: vec![Material {
            name: "m".into(),
            kind: MaterialKind::Diffuse {
                color: Vec3::ONE,
                texture: None,
            },
            emission: Vec3::ZERO,
        }],
        spheres,
        triangles,
        environment: None,
        filter: Default::default(),
        warnings: vec![],
    }
}

fn soup(rng: &mut TestRng, n: usize, extent: f32, size: f32) -> Vec<Triangle> {
    (0..n)
        .map(|_| {
            let c = Vec3::new(
                rng.range(-extent, extent),
                rng.range(-extent, extent),
                rng.range(-extent, extent),
            );
            let p = [
                c,
                c + rng.unit_vector() * size,
                c + rng.unit_vector() * size,
            ];
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            Triangle {
                p,
                n: [n; 3],
                uv: [Vec2::ZERO; 3],
                material: 0,
                object: 0,
            }
        })
        .collect()
}

/// 10,000+ rays of the three kinds the issue names.
fn rays(
    rng: &mut TestRng,
    arrays: &SceneArrays,
    lo: Vec3,
    hi: Vec3,
    count: usize,
) -> Vec<(Vec3, Vec3, f32)> {
    let mut out = Vec::with_capacity(count);
    let pad = (hi - lo) * 0.2;
    let random_point = |rng: &mut TestRng| {
        Vec3::new(
            rng.range(lo.x - pad.x, hi.x + pad.x),
            rng.range(lo.y - pad.y, hi.y + pad.y),
            rng.range(lo.z - pad.z, hi.z + pad.z),
        )
    };
    let axes = [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    while out.len() < count {
        match out.len() % 4 {
            0 => out.push((random_point(rng), rng.unit_vector(), f32::INFINITY)),
            1 => {
                // Axis-parallel, with the origin often exactly on a node's box plane.
                let mut o = random_point(rng);
                let node = &arrays.nodes[rng.next_u32() as usize % arrays.nodes.len()];
                let k = rng.next_u32() as usize % 3;
                o[k] = if rng.uniform() < 0.5 {
                    node.bounds_min[k]
                } else {
                    node.bounds_max[k]
                };
                let mut d = axes[rng.next_u32() as usize % 6];
                if d[k] != 0.0 {
                    d = axes[(k * 2 + 2) % 6]; // move within the plane
                }
                out.push((o, d, f32::INFINITY));
            }
            2 => {
                // Leaving a surface, as secondary rays do (origin offset as in the kernel).
                let t = &arrays.tri_geom[rng.next_u32() as usize % arrays.tri_geom.len()];
                let (a, b) = (rng.uniform(), rng.uniform());
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                let p = t.v0.xyz() + a * (t.v1.xyz() - t.v0.xyz()) + b * (t.v2.xyz() - t.v0.xyz());
                let ng = (t.v1.xyz() - t.v0.xyz())
                    .cross(t.v2.xyz() - t.v0.xyz())
                    .normalize();
                let mut d = rng.unit_vector();
                let n = if d.dot(ng) >= 0.0 { ng } else { -ng };
                if d.dot(n) < 1e-3 {
                    d = (d + n).normalize();
                }
                out.push((
                    offset_ray_origin(p, n, arrays.params.scene_size),
                    d,
                    f32::INFINITY,
                ));
            }
            _ => {
                // Finite segments, as shadow rays are.
                let o = random_point(rng);
                let e = random_point(rng);
                let d = (e - o).normalize();
                out.push((o, d, (e - o).length()));
            }
        }
    }
    out
}

fn prim_code(p: Option<Prim>) -> i32 {
    match p {
        None => -1,
        Some(Prim::Triangle(k)) => k as i32,
        Some(Prim::Sphere(i)) => -2 - i as i32,
    }
}

/// Compares the BVH traversals (device and Rust, both trees) with brute force; returns
/// mismatches.
fn check(arrays: &SceneArrays, rays: &[(Vec3, Vec3, f32)]) -> Vec<String> {
    // Brute force once per ray (the conference room: 360k triangles a ray).
    let truths: Vec<Option<Hit>> = rays
        .par_iter()
        .map(|&(o, d, t_max)| brute_force_closest(arrays, o, d, t_max))
        .collect();
    let mut bad = check_rust(arrays, rays, &truths);
    let skip = device_intersect(arrays, rays, BvhLayout::Skip);
    let wide = device_intersect(arrays, rays, BvhLayout::Wide);
    bad.extend(check_device(rays, &skip, &truths, BvhLayout::Skip));
    bad.extend(check_device(rays, &wide, &truths, BvhLayout::Wide));
    // On the device the two walks give the same bits: the wide walk's four-lane triangle test
    // runs the scalar test's float operations in order, and ties go to the same triangle.
    bad.extend(
        skip.iter()
            .zip(&wide)
            .enumerate()
            .filter(|(_, (a, b))| a.0.to_bits() != b.0.to_bits() || a.1 != b.1 || a.2 != b.2)
            .map(|(i, (a, b))| format!("ray {i}: device skip-index walk {a:?} != wide walk {b:?}")),
    );
    bad
}

/// The Rust walks of both trees run the same float operations as brute force: exact, ties
/// included (the triangle first in leaf order).
fn check_rust(
    arrays: &SceneArrays,
    rays: &[(Vec3, Vec3, f32)],
    truths: &[Option<Hit>],
) -> Vec<String> {
    rays.par_iter()
        .zip(truths.par_iter())
        .enumerate()
        .filter_map(|(i, (&(o, d, t_max), &truth))| {
            let cpu = intersect_closest(arrays, o, d, t_max);
            if cpu != truth {
                return Some(format!(
                    "ray {i}: Rust BVH {cpu:?} != brute force {truth:?}"
                ));
            }
            let wide = trace_wide::intersect_closest(arrays, o, d, t_max);
            if wide != truth {
                return Some(format!(
                    "ray {i}: Rust wide BVH {wide:?} != brute force {truth:?}"
                ));
            }
            if occluded(arrays, o, d, t_max) != truth.is_some()
                || trace_wide::occluded(arrays, o, d, t_max) != truth.is_some()
            {
                return Some(format!("ray {i}: Rust any-hit disagrees with brute force"));
            }
            let (skip_range, wide_range) = (
                occluder_range(arrays, o, d, t_max),
                trace_wide::occluder_range(arrays, o, d, t_max),
            );
            if skip_range != wide_range {
                return Some(format!(
                    "ray {i}: occluder range {skip_range:?} (skip) != {wide_range:?} (wide)"
                ));
            }
            None
        })
        .collect()
}

/// The device's answers (`device`, from walking the `bvh` tree) against brute force.
fn check_device(
    rays: &[(Vec3, Vec3, f32)],
    device: &[(f32, i32, bool)],
    truths: &[Option<Hit>],
    bvh: BvhLayout,
) -> Vec<String> {
    rays.par_iter()
        .zip(device.par_iter().zip(truths.par_iter()))
        .enumerate()
        .filter_map(|(i, (&(o, d, _), (&(dt, dp, d_occ), &truth)))| {
            let (tt, tp) = (truth.map_or(-1.0, |h| h.t), prim_code(truth.map(|h| h.prim)));
            let same_t = (dt - tt).abs() <= 1e-5 * tt.abs().max(1.0);
            // The device may round differently in the last bits; a different primitive is only
            // acceptable at the same distance (a shared edge or coincident surfaces).
            if (dp == -1) != (tp == -1) || (dp != tp && !same_t) || (tp != -1 && !same_t) {
                return Some(format!("{bvh:?} ray {i} o={o} d={d}: device (t={dt}, prim={dp}) vs brute force (t={tt}, prim={tp})"));
            }
            if d_occ != truth.is_some() {
                return Some(format!("{bvh:?} ray {i}: device any-hit {d_occ} vs brute force {}", truth.is_some()));
            }
            None
        })
        .collect()
}

#[test]
fn random_triangle_soups_match_brute_force() {
    let mut rng = TestRng(42);
    for (n, size) in [(1usize, 2.0f32), (7, 1.0), (2000, 0.8), (20_000, 0.3)] {
        let tris = soup(&mut rng, n, 5.0, size);
        let spheres = vec![SphereObject {
            center: Vec3::new(0.5, -0.2, 0.1),
            radius: 1.3,
            material: 0,
        }];
        let scene = scene_of(tris, spheres);
        let arrays = SceneArrays::build(&scene, &FrameSettings::from_scene(&scene)).unwrap();
        let rays = rays(
            &mut rng,
            &arrays,
            Vec3::splat(-5.0),
            Vec3::splat(5.0),
            10_000,
        );
        let bad = check(&arrays, &rays);
        assert!(
            bad.is_empty(),
            "{n} triangles: {} mismatches, first: {:?}",
            bad.len(),
            &bad[..bad.len().min(5)]
        );
    }
}

#[test]
fn bundled_scene_meshes_match_brute_force() {
    let mut rng = TestRng(7);
    let mut checked = 0;
    for path in bundled_scenes() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if name.contains("_dof") {
            continue; // DOF variants share their geometry
        }
        let scene = noisefree::scene::load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        if scene.triangles.is_empty() {
            continue;
        }
        let arrays = SceneArrays::build(&scene, &FrameSettings::from_scene(&scene)).unwrap();
        let (lo, hi) = noisefree::arrays::scene_bounds(&scene);
        let rays = rays(&mut rng, &arrays, lo, hi, 10_000);
        let bad = check(&arrays, &rays);
        assert!(
            bad.is_empty(),
            "{name}: {} mismatches of 10000, first: {:?}",
            bad.len(),
            &bad[..bad.len().min(5)]
        );
        checked += 1;
    }
    // conference, cornell_diffuse, cornell_glossy, cornell_plane and outside.
    assert!(
        checked >= 5,
        "only {checked} bundled scenes with meshes were found under scenes/"
    );
}

/// Coincident triangles, nine copies of each, so that a leaf (at most four triangles) cannot
/// hold all copies: a ray meets the same distance in several leaves, which the wide walk
/// visits in another order than the skip-index walk. Both must return the copy first in leaf
/// order, on the device too (the copies' distances are the same float there as well).
#[test]
fn coincident_triangles_resolve_to_the_first_in_leaf_order() {
    let mut rng = TestRng(99);
    let base = soup(&mut rng, 300, 4.0, 1.5);
    let tris: Vec<Triangle> = base
        .iter()
        .flat_map(|t| std::iter::repeat_n(*t, 9))
        .collect();
    let scene = scene_of(tris, vec![]);
    let arrays = SceneArrays::build(&scene, &FrameSettings::from_scene(&scene)).unwrap();
    let rays = rays(
        &mut rng,
        &arrays,
        Vec3::splat(-4.0),
        Vec3::splat(4.0),
        8_000,
    );
    let bad = check(&arrays, &rays);
    assert!(
        bad.is_empty(),
        "{} mismatches, first: {:?}",
        bad.len(),
        &bad[..bad.len().min(5)]
    );
    let mut ties = 0;
    for bvh in [BvhLayout::Skip, BvhLayout::Wide] {
        let device = device_intersect(&arrays, &rays, bvh);
        for (i, (&(o, d, t_max), &(_, dp, _))) in rays.iter().zip(&device).enumerate() {
            let truth = brute_force_closest(&arrays, o, d, t_max);
            assert_eq!(dp, prim_code(truth.map(|h| h.prim)), "{bvh:?} ray {i}");
            ties += truth.is_some() as usize;
        }
    }
    assert!(ties > 1000, "only {ties} rays hit a copy");
}

/// Two copies of one triangle in two leaves whose boxes differ: the second copy's box reaches
/// out towards the ray, so the wide walk, which takes the nearer box first, meets the second
/// copy first. It must still answer with the first copy, as the skip-index walk (and brute
/// force) do: without its tie rule the wide walk returns the second.
#[test]
fn a_tie_across_leaves_entered_out_of_order_goes_to_the_first_copy() {
    use noisefree::layout::{BvhNode, LEAF_COUNT_SHIFT};
    let tri = Triangle {
        p: [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
        n: [Vec3::Z; 3],
        uv: [Vec2::ZERO; 3],
        material: 0,
        object: 0,
    };
    let scene = scene_of(vec![tri, tri], vec![]);
    let mut arrays = SceneArrays::build(&scene, &FrameSettings::from_scene(&scene)).unwrap();
    let leaf = |first: u32, near_z: f32, skip: u32| BvhNode {
        bounds_min: [-1.1, -1.1, -0.1],
        bounds_max: [1.1, 1.1, near_z],
        skip,
        leaf: first | 1 << LEAF_COUNT_SHIFT,
    };
    arrays.nodes = vec![
        BvhNode {
            bounds_min: [-1.1, -1.1, -0.1],
            bounds_max: [1.1, 1.1, 5.0],
            skip: 3,
            leaf: 0,
        },
        leaf(0, 0.1, 2),
        leaf(1, 5.0, 3),
    ];
    arrays.params.node_count = 3;
    arrays.wide_bvh = noisefree::bvh::wide::collapse(&arrays.nodes, &arrays.tri_geom);
    let rays = vec![(Vec3::new(0.1, 0.0, 10.0), Vec3::NEG_Z, f32::INFINITY); 4];
    assert!(
        check(&arrays, &rays).is_empty(),
        "{:?}",
        check(&arrays, &rays)
    );
    for bvh in [BvhLayout::Skip, BvhLayout::Wide] {
        let device = device_intersect(&arrays, &rays, bvh);
        assert_eq!(device[0].1, 0, "{bvh:?}: {:?}", device[0]);
    }
}
