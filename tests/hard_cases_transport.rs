//! Hard cases of geometry and light transport stay numerically stable: closed meshes do not
//! leak, any scene scale renders the same image, glass at and past the critical angle, extreme
//! metal exponents, tiny and very bright lights, Russian roulette extremes, cameras inside glass
//! and autofocus into the void. No NaN or Inf reaches any buffer.

mod common;

use common::*;
use glam::{Vec2, Vec3};
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::layout::{FilterVector, Float4, MATERIAL_GLASS, Material, WelfordSums};
use noisefree::render::SceneArrays;
use noisefree::render::cpu::pathtrace::{Surface, scatter};
use noisefree::render::cpu::rng::rng_sample_key;
use noisefree::scene::Scene;

/// Renders with every output on and checks every buffer is finite; returns the film.
fn render_checked(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> Vec<FilterVector> {
    let mut o = options(scene, w, h, seed);
    o.outputs = OutputSet::of(&[Output::Variance, Output::Position, Output::Samples]);
    o.sample_capacity = spp;
    let frame = render_frame(scene, &o, spp);
    assert_eq!(frame.outputs(), o.outputs.closed());
    let film = frame.filter_vectors().unwrap();
    assert!(
        film.iter().flat_map(lanes).all(f32::is_finite),
        "non-finite FilterVector"
    );
    // Every lane of every buffer (depth shifts, Welford state, positions too).
    for b in frame.outputs().buffers() {
        let floats = frame.host(b.id).unwrap().floats();
        if let Some(i) = floats.iter().position(|v| !v.is_finite()) {
            panic!("{}: float {i} is {}", b.name, floats[i]);
        }
    }
    let sums: &[WelfordSums] = frame.host_slice(BufferId::WelfordSums).unwrap();
    for g in sums {
        let v = noisefree::stats::feature_variance_sums(g);
        assert!(
            v.iter().all(|x| x.is_finite() && *x >= 0.0),
            "variance {g:?}"
        );
    }
    let samples: &[noisefree::layout::SampleVector] =
        frame.host_slice(BufferId::SampleVectors).unwrap();
    assert_eq!(samples.len(), (w * h * spp) as usize);
    for s in samples {
        let all = s
            .position
            .iter()
            .chain(&s.random)
            .chain(&s.world1)
            .chain(&s.normal1)
            .chain(&s.world2)
            .chain(&s.normal2)
            .chain(&s.texture1)
            .chain(&s.color);
        assert!(
            all.copied().all(f32::is_finite),
            "non-finite sample vector {s:?}"
        );
    }
    film.to_vec()
}

/// A black, closed box around the camera under a bright environment: a ray that slips between
/// two triangles (through a shared edge or vertex) would show the environment.
#[test]
fn a_closed_mesh_seen_from_inside_never_shows_the_environment() {
    for (origin, target) in [
        ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
        ([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]),
        ([0.25, -0.1, 0.3], [1.0, 0.0, 1.0]),
    ] {
        let text = format!(
            r#"
[render]
max_depth = 1
russian_roulette = false

[camera]
origin = {origin:?}
target = {target:?}
fov = 150

[[material]]
name = "black"
type = "diffuse"
color = [0, 0, 0]

[[light]]
type = "infinite"
color = [1000, 1000, 1000]

[[mesh]]
generator = "box"
material = "black"
scale = 2
"#
        );
        let scene = scene_from_toml(&text);
        // Pixels whose centres look exactly along the box's edges and through its corners.
        for (w, seed) in [(64u32, 1u32), (65, 2), (101, 3)] {
            let film = render_checked(&scene, w, w, 4, seed);
            let leaks = film
                .iter()
                .filter(|f| f.direct.iter().chain(&f.indirect).any(|v| *v != 0.0))
                .count();
            assert_eq!(
                leaks, 0,
                "{leaks} pixels saw the environment through the closed box (camera at {origin:?})"
            );
        }
    }
}

/// Scaling geometry, camera and lights together (emission unchanged) leaves the image
/// unchanged up to rounding: secondary-ray offsets and shadow-ray ends are scale-invariant.
/// Rounding does send an occasional path another way, so a few pixels differ by more: the
/// image means agree to 2e-4 and 95 % of the pixels to 1e-3, not every pixel.
#[test]
fn cornell_scenes_render_the_same_at_any_scale() {
    let glass = "[[material]]\nname = \"glass\"\ntype = \"glass\"\n\n[[sphere]]\ncenter = [0.3, 0.35, 0.1]\nradius = 0.35\nmaterial = \"glass\"\n\n[[sphere]]\ncenter = [-0.4, 0.3, -0.3]\nradius = 0.3\nmaterial = \"white\"\n";
    let base = scene_from_toml(&cornell("max_depth = 3", glass));
    let bundled = bundled_scene("cornell_diffuse");
    for scene in [base, bundled] {
        let reference = beauty(&render_checked(&scene, 32, 32, 64, 9));
        let m0 = mean_rgb(&reference);
        for factor in [1e-3f32, 1e3] {
            let img = beauty(&render_checked(&scene.scaled(factor), 32, 32, 64, 9));
            let m = mean_rgb(&img);
            // Measured (PoCL): the channel means differ by at most 4.2e-5 relative (scale
            // 1e-3; 1.6e-6 at 1e3). Bound 2e-4, about 5 x.
            for c in 0..3 {
                assert!(
                    (m[c] - m0[c]).abs() < 2e-4 * m0[c],
                    "scale {factor}: channel {c} mean {} vs {}",
                    m[c],
                    m0[c]
                );
            }
            // Same random numbers: most pixels follow the same paths. Measured: the median
            // pixel differs by 2.8e-5 relative, and 21 of 1024 pixels (2.1 %) by more than
            // 1e-3 (up to 13 %: paths that rounding sent another way), at scale 1e-3; at
            // most 1 pixel at 1e3. Bound: 95 % of the pixels within 1e-3 (2.4 x the measured
            // share of outliers).
            let same = img
                .iter()
                .zip(&reference)
                .filter(|(a, b)| (0..3).all(|c| (a[c] - b[c]).abs() <= 1e-3 * b[c].abs().max(1e-2)))
                .count();
            assert!(
                same as f64 >= 0.95 * img.len() as f64,
                "scale {factor}: only {same} of {} pixels agree",
                img.len()
            );
        }
    }
}

fn glass_arrays(ior_out: f32, ior_in: f32) -> SceneArrays {
    let mut a = SceneArrays::default();
    a.materials.push(Material {
        kind: MATERIAL_GLASS,
        color: Float4::new(1.0, 0.5, 0.25, 0.0),
        color2: Float4::new(0.25, 0.5, 1.0, 0.0),
        ior_outside: ior_out,
        ior_inside: ior_in,
        texture: -1,
        ..Default::default()
    });
    a
}

fn surface(entering: bool) -> Surface {
    // The normal always faces the incoming ray (as surface_at makes it).
    Surface {
        p: Vec3::ZERO,
        ng: Vec3::Y,
        ns: Vec3::Y,
        uv: Vec2::ZERO,
        material: 0,
        entering,
    }
}

/// Eq. 4.10: leaving glass (n = 1.5) past the critical angle every sample reflects, with the
/// reflection colour; just below it some refract; all directions stay unit and finite.
#[test]
fn glass_total_internal_reflection_and_grazing_incidence() {
    let a = glass_arrays(1.0, 1.5);
    let critical = (1.0f32 / 1.5).asin();
    let dir_at = |theta: f32| Vec3::new(theta.sin(), -theta.cos(), 0.0);
    for (theta, tir) in [
        (critical + 1e-3, true),
        (critical + 0.3, true),
        (critical - 0.05, false),
    ] {
        let d = dir_at(theta);
        let mut refracted = 0;
        for i in 0..2000u32 {
            let sc = scatter(
                &a,
                &surface(false),
                d,
                Vec3::ONE,
                rng_sample_key(1, i, 0),
                0,
            );
            assert!(sc.direction.is_finite() && (sc.direction.length() - 1.0).abs() < 1e-4);
            if sc.direction.y < 0.0 {
                refracted += 1;
                assert_eq!(sc.weight, Vec3::new(0.25, 0.5, 1.0));
            } else {
                assert_eq!(sc.weight, Vec3::new(1.0, 0.5, 0.25));
            }
        }
        if tir {
            assert_eq!(
                refracted, 0,
                "past the critical angle ({theta} rad) nothing may refract"
            );
        } else {
            // Measured 1644 of 2000 (Fresnel reflects ~18 % this close to the critical
            // angle); bound 1400.
            assert!(
                refracted > 1400,
                "below the critical angle most samples refract ({refracted})"
            );
        }
    }
    // Grazing incidence from outside: finite, unit directions, Fresnel reflection near 1.
    let d = dir_at(std::f32::consts::FRAC_PI_2 - 1e-6);
    let mut reflected = 0;
    for i in 0..1000u32 {
        let sc = scatter(&a, &surface(true), d, Vec3::ONE, rng_sample_key(2, i, 0), 0);
        assert!(sc.direction.is_finite() && (sc.direction.length() - 1.0).abs() < 1e-4);
        reflected += (sc.direction.y > 0.0) as u32;
    }
    assert!(
        reflected > 990,
        "at grazing incidence glass reflects almost everything ({reflected})"
    );
}

/// Equal indices of refraction: no interface, so no reflection at any angle and no bending.
#[test]
fn glass_with_equal_indices_is_invisible() {
    let a = glass_arrays(1.33, 1.33);
    for theta in [0.0f32, 0.5, 1.2, std::f32::consts::FRAC_PI_2 - 1e-4] {
        let d = Vec3::new(theta.sin(), -theta.cos(), 0.0);
        for i in 0..200u32 {
            let sc = scatter(&a, &surface(true), d, Vec3::ONE, rng_sample_key(3, i, 0), 0);
            assert!(
                (sc.direction - d).length() < 1e-5,
                "bent at {theta}: {:?}",
                sc.direction
            );
        }
    }
    // A white glass sphere of equal indices in a white furnace: exactly the environment.
    let text = "[render]\nmax_depth = 8\n\n[camera]\norigin = [0, 0, 4]\ntarget = [0, 0, 0]\nfov = 40\n\n[[material]]\nname = \"g\"\ntype = \"glass\"\nior_outside = 1.33\nior_inside = 1.33\n\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"g\"\n\n[[light]]\ntype = \"infinite\"\ncolor = [1, 1, 1]\n";
    let img = beauty(&render_checked(&scene_from_toml(text), 24, 24, 16, 1));
    for p in &img {
        for c in p {
            assert!((c - 1.0).abs() < 1e-5, "no darkening expected, got {c}");
        }
    }
}

/// The white furnace with a camera inside a glass sphere, glass of extreme index, metal of
/// exponent 1 and 1e5, and Russian roulette from depth 0 and 64: finite, and never brighter
/// than the environment on average (nor much darker than it where nothing is absorbed).
#[test]
fn furnace_extremes_stay_finite_and_energy_conserving() {
    let furnace = |material: &str, max_depth: u32, camera: &str| {
        format!(
            "[render]\nmax_depth = {max_depth}\n\n[camera]\n{camera}\nfov = 40\n\n[[material]]\nname = \"m\"\n{material}\n\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n\n[[light]]\ntype = \"infinite\"\ncolor = [1, 1, 1]\n"
        )
    };
    let outside = "origin = [0, 0, 4]\ntarget = [0, 0, 0]";
    let inside = "origin = [0.1, 0.2, 0.3]\ntarget = [0, 0, -1]";
    // Measured means (PoCL): 0.9326 (metal, exponent 1: the lobe below the horizon is lost),
    // 1.0 (exponent 1e5), 0.9990, 1.0000 and 1.0000 (glass), 0.9987 (diffuse with roulette
    // from depth 0). The lower bounds allow 1.5 x the loss of the exponent-1 metal and 0.01
    // elsewhere (about 8 x the largest deficit measured, 0.0013, which is roulette noise);
    // the upper bound, 1.01, the same above 1.
    let cases = [
        (
            "type = \"metal\"\ncolor = [1, 1, 1]\nexponent = 1",
            4,
            outside,
            0.9,
        ),
        (
            "type = \"metal\"\ncolor = [1, 1, 1]\nexponent = 100000",
            4,
            outside,
            0.99,
        ),
        ("type = \"glass\"\nior_inside = 1.5", 0, outside, 0.99),
        ("type = \"glass\"\nior_inside = 1.5", 64, outside, 0.99),
        ("type = \"glass\"\nior_inside = 3.0", 4, inside, 0.99),
        ("type = \"diffuse\"\ncolor = [1, 1, 1]", 0, outside, 0.99),
    ];
    for (material, depth, camera, at_least) in cases {
        let scene = scene_from_toml(&furnace(material, depth, camera));
        let img = beauty(&render_checked(&scene, 24, 24, 128, 5));
        let m = mean_rgb(&img);
        for mc in m {
            assert!(
                mc <= 1.01 && mc >= at_least,
                "{material} (max_depth {depth}): mean {mc}"
            );
        }
    }
}

/// A tiny, very bright sphere light (the same power as a normal one) stays finite in every
/// buffer; the optional per-sample clamp, off by default, bounds every sample.
#[test]
fn tiny_bright_lights_and_the_clamp() {
    // Out of the camera's view (it looks down -z from z = 3.4), so the comparison is about
    // the light it sheds, not about hitting a sub-pixel sphere with camera rays.
    let light = |radius: f32, emission: f32| {
        format!(
            "[[light]]\ntype = \"sphere\"\ncenter = [0, 1.6, 3.0]\nradius = {radius}\nemission = [{emission}, {emission}, {emission}]\n"
        )
    };
    let reference = scene_from_toml(&cornell("max_depth = 3", &light(0.1, 25.0)));
    let tiny_text = cornell("max_depth = 3", &light(1e-4, 25.0 * 1e6));
    let tiny = scene_from_toml(&tiny_text);
    let a = beauty(&render_checked(&reference, 24, 24, 64, 3));
    let b = beauty(&render_checked(&tiny, 24, 24, 64, 3));
    // Same power: the image means agree within noise (the small light's image is noisier).
    // Measured: 0.4055 vs 0.4058 in green, 0.08 % apart (0.06 % in red and blue). Bound 1 %
    // in every channel, for the tiny light's fireflies (up to 6 here) on another device.
    let (ma, mb) = (mean_rgb(&a), mean_rgb(&b));
    for c in 0..3 {
        assert!((ma[c] - mb[c]).abs() < 0.01 * ma[c], "{ma:?} vs {mb:?}");
    }
    // With the clamp, no pixel mean can exceed it.
    let clamped =
        scene_from_toml(&tiny_text.replace("max_depth = 3", "max_depth = 3\nclamp = 2.0"));
    let c = beauty(&render_checked(&clamped, 24, 24, 64, 3));
    assert!(
        c.iter().flatten().all(|v| *v <= 2.0 + 1e-5),
        "clamp exceeded"
    );
    assert!(
        !b.iter().flatten().all(|v| *v <= 2.0),
        "the unclamped image should have fireflies above 2"
    );
}

#[test]
fn autofocus_into_the_void_falls_back() {
    let text = "[camera]\norigin = [0, 0, 4]\ntarget = [0, 0, 0]\nup = [0, 1, 0]\nfov = 30\nlens_radius = 0.1\nautofocus = true\n\n[[material]]\nname = \"m\"\ntype = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n\n[[sphere]]\ncenter = [3, 0, 0]\nradius = 0.5\nmaterial = \"m\"\n\n[[light]]\ntype = \"infinite\"\ncolor = [1, 1, 1]\n";
    let scene = scene_from_toml(text);
    let arrays = SceneArrays::build(
        &scene,
        &noisefree::render::FrameSettings::from_scene(&scene),
    )
    .unwrap();
    assert!(
        arrays.focus_note.contains("hit nothing"),
        "{}",
        arrays.focus_note
    );
    assert!(arrays.params.focal_distance > 0.0 && arrays.params.focal_distance.is_finite());
    render_checked(&scene, 16, 16, 4, 1);
}

/// Every bundled scene: no NaN or Inf in any buffer, with every statistic and the sample
/// vectors gathered.
#[test]
fn every_bundled_scene_renders_finite_buffers() {
    for p in bundled_scenes() {
        let scene = noisefree::scene::load_scene(&p).unwrap();
        render_checked(&scene, 32, 24, 4, 2);
    }
}
