//! The sheared soft-shadow filter (src/filters/sheared, kernels/filters/sheared.cl; Yan et al.
//! 2015; digest §4 T6, T7, T9): the factored steps against eq. 9's brute force, η = 0 against
//! the separable axis-aligned filter, one occluder plane against a 4096-sample reference
//! (which settles eq. 5's form and sign), each device step against its Rust reference, and the
//! hard cases (grazing receivers, walls along the light, no occluder, sizes that do not fit).

mod common;

use common::aaf::floor_scene;
use common::*;
use glam::Vec3;
use noisefree::filters::Configured;
use noisefree::filters::sheared::reference::{
    ETA, FILTERED, Guide, KIND, SIGMA, brute_force, compose, factored, g_floats, own_mean,
    p_floats, prepare, step_1a, step_1b, step_2a, step_2b,
};
use noisefree::filters::sheared::shear::eta_printed;
use noisefree::filters::sheared::{Sheared, ShearedKernel, ShearedSettings};
use noisefree::layout::outputs::BufferId;
use noisefree::layout::{Float4, LightFieldPixel, ShadowPixel, ShadowTerms, ShearedParams};
use noisefree::render::Renderer;
use noisefree::scene::Scene;

/// A synthetic light field (one argument per quantity the tests vary): a w × h receiver plane z = 0 of pixels d apart (x1 = x, x2 = y),
/// a light of radius `radius` at height `height` above the origin, l × l samples per pixel
/// with jitter from `jitter(pixel)`, visibility from `f(receiver point, light point)`, and
/// slopes s_min = s_max = `slope`.
struct Synthetic {
    p: ShearedParams,
    shadow: Vec<ShadowPixel>,
    field: Vec<LightFieldPixel>,
}

#[allow(clippy::too_many_arguments)]
fn synthetic(
    w: u32,
    h: u32,
    d: f32,
    side: u32,
    bins: u32,
    slope: f32,
    mut jitter: impl FnMut(usize) -> [f32; 2],
    mut f: impl FnMut([f32; 2], [f32; 2]) -> f32,
) -> Synthetic {
    let (radius, height) = (1.0f32, 10.0f32);
    // The synthetic light fields and their references are those of a Gaussian light of
    // sigma_y = R/2 (the seed's), whatever the filter's default light_sigma.
    let settings = ShearedSettings {
        side,
        bins,
        light_sigma: 0.5,
        ..Default::default()
    };
    let mut p = settings.params([0.0, 0.0, height, radius], [0.0; 3], w, h);
    p.axis1 = Float4::from_vec3(Vec3::X, 0.0);
    p.axis2 = Float4::from_vec3(Vec3::Y, 0.0);
    let mut shadow = Vec::new();
    let mut field = Vec::new();
    for i in 0..(w * h) as usize {
        let x = [(i as u32 % w) as f32 * d, (i as u32 / w) as f32 * d];
        shadow.push(ShadowPixel {
            weight: 1.0,
            samples: 1.0,
            slope_min: slope,
            slope_max: slope,
            slope_source: 1.0,
            pixel_size: d,
            position: [x[0], x[1], 0.0],
            normal: [0.0, 0.0, 1.0],
            ..Default::default()
        });
        let j = jitter(i);
        let mut lf = LightFieldPixel {
            jitter: j,
            dir1: [1.0, 0.0],
            dir2: [0.0, 1.0],
            scale: [d, d],
            count: (side * side) as f32,
            ..Default::default()
        };
        for b in 0..side {
            for a in 0..side {
                let y = [
                    radius * (2.0 * (a as f32 + j[0]) / side as f32 - 1.0),
                    radius * (2.0 * (b as f32 + j[1]) / side as f32 - 1.0),
                ];
                lf.samples[(b * side + a) as usize] = f(x, y);
            }
        }
        field.push(lf);
    }
    Synthetic { p, shadow, field }
}

fn constant_guide(n: usize, sigma_x: f32, eta: f32) -> Vec<Guide> {
    vec![[sigma_x, eta, FILTERED, 0.0]; n]
}

fn max_abs(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

fn rms(a: &[f32], b: &[f32]) -> f64 {
    let s: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
    (s / a.len() as f64).sqrt()
}

#[test]
fn factored_steps_approach_the_4d_brute_force_as_bins_grow() {
    // T6: random light fields (uniform values, random jitter), constant σ_x and η.
    for (side, eta) in [(2u32, 0.5f32), (3, 1.5), (4, -0.8)] {
        let mut errors = Vec::new();
        for bins in [5u32, 9, 17, 33] {
            let mut rng = Lcg(7 + side as u64);
            let mut vals = Lcg(99);
            let s = synthetic(
                24,
                20,
                0.1,
                side,
                bins,
                1.0,
                |_| [rng.uniform(), rng.uniform()],
                |_, _| vals.uniform(),
            );
            let guide = constant_guide(s.shadow.len(), 0.3, eta);
            let brute = brute_force(&s.p, &s.shadow, &s.field, &guide);
            let fact = factored(&s.p, &s.shadow, &s.field, &guide);
            errors.push(max_abs(&brute, &fact));
        }
        eprintln!(
            "l = {side}, eta = {eta}: max |factored - brute force| at 5/9/17/33 bins: {errors:?}"
        );
        // Falls with the bins (the quantisation of y1 = η Δx1 and of y2' to bin centres):
        // measured 0.025/0.019/0.011/0.0061 (l = 2), 0.027/0.014/0.0085/0.0030 (l = 3),
        // 0.012/0.013/0.0077/0.0037 (l = 4; 5 bins are too coarse to rank); values in [0, 1].
        for k in 2..errors.len() {
            assert!(errors[k] < errors[k - 1], "{errors:?}");
        }
        assert!(errors[3] * 2.0 < errors[0], "{errors:?}");
        assert!(errors[3] < 0.008, "{errors:?}");
    }
}

#[test]
fn no_shear_reproduces_the_separable_axis_aligned_filter() {
    // T7: η = 0, every pixel with the same jitter whose grid points sit on bin centres (l = 2,
    // R = 1, 17 bins over [-2, 2]: centres 0.25 apart): the factored filter is then exactly
    // the separable Gaussian mean of the per-pixel Gaussian-light visibilities.
    let mut vals = Lcg(3);
    let s = synthetic(
        20,
        16,
        0.1,
        2,
        17,
        1.0,
        |_| [0.25, 0.5],
        |_, _| (vals.uniform() > 0.5) as u32 as f32,
    );
    let sigma = 0.25;
    let guide = constant_guide(s.shadow.len(), sigma, 0.0);
    let fact = factored(&s.p, &s.shadow, &s.field, &guide);
    let g = |t: f32, sd: f32| (-(t * t) / (2.0 * sd * sd)).exp();
    let hn: Vec<f32> = s
        .field
        .iter()
        .map(|lf| {
            let (mut v, mut w) = (0f32, 0f32);
            for b in 0..2 {
                for a in 0..2 {
                    let y1 = 2.0 * (a as f32 + lf.jitter[0]) / 2.0 - 1.0;
                    let y2 = 2.0 * (b as f32 + lf.jitter[1]) / 2.0 - 1.0;
                    let wy = g(y1, 0.5) * g(y2, 0.5);
                    v += wy * lf.samples[b * 2 + a];
                    w += wy;
                }
            }
            v / w
        })
        .collect();
    let (w, h) = (20i32, 16i32);
    let r = (2.0 * sigma / 0.1f32).ceil() as i32;
    let mut worst = 0f32;
    for y in 0..h {
        for x in 0..w {
            let (mut v, mut wt) = (0f32, 0f32);
            for qy in (y - r).max(0)..=(y + r).min(h - 1) {
                for qx in (x - r).max(0)..=(x + r).min(w - 1) {
                    let k = g((qx - x) as f32 * 0.1, sigma) * g((qy - y) as f32 * 0.1, sigma);
                    v += k * hn[(qy * w + qx) as usize];
                    wt += k;
                }
            }
            worst = worst.max((v / wt - fact[(y * w + x) as usize]).abs());
        }
    }
    eprintln!("eta = 0: max |factored - separable| = {worst:e}");
    // Float rounding only (measured 2.4e-7).
    assert!(worst < 2e-6, "{worst}");
}

/// The checkerboard occluder plane halfway to the light (s = 1), squares 2 wide.
fn checker(x: [f32; 2], y: [f32; 2]) -> f32 {
    let t = 0.5;
    let u = [x[0] + t * (y[0] - x[0]), x[1] + t * (y[1] - x[1])];
    let cell = (u[0] / 2.0).floor() as i64 + (u[1] / 2.0).floor() as i64;
    (cell.rem_euclid(2) == 0) as u32 as f32
}

#[test]
fn one_occluder_plane_decides_the_shear() {
    // T9: one occluder plane (s_min = s_max = 1) at 9 spp against the Gaussian light's
    // visibility integrated with 64 x 64 = 4096 samples per pixel.
    let (w, h, d) = (64u32, 48u32, 0.1f32);
    let mut rng = Lcg(11);
    let s = synthetic(
        w,
        h,
        d,
        3,
        17,
        1.0,
        |_| [rng.uniform(), rng.uniform()],
        checker,
    );
    let g = |t: f32| (-(t * t) / (2.0 * 0.25)).exp();
    let reference: Vec<f32> = s
        .shadow
        .iter()
        .map(|px| {
            let x = [px.position[0], px.position[1]];
            let (mut v, mut wt) = (0f64, 0f64);
            for b in 0..64 {
                for a in 0..64 {
                    let y = [(a as f32 + 0.5) / 32.0 - 1.0, (b as f32 + 0.5) / 32.0 - 1.0];
                    let k = (g(y[0]) * g(y[1])) as f64;
                    v += k * checker(x, y) as f64;
                    wt += k;
                }
            }
            (v / wt) as f32
        })
        .collect();
    let guide = prepare(&s.p, &s.shadow, &s.field);
    let own: Vec<f32> = s.field.iter().map(|lf| own_mean(&s.p, lf)).collect();
    let mut errors = Vec::new();
    for (name, eta) in [
        ("corrected, +", guide[0][ETA]),
        ("corrected, -", -guide[0][ETA]),
        ("printed", eta_printed(1.0, 1.0)),
        ("none (axis-aligned)", 0.0),
    ] {
        let gd = constant_guide(s.shadow.len(), guide[0][SIGMA], eta);
        let out = factored(&s.p, &s.shadow, &s.field, &gd);
        errors.push((name, eta, rms(&out, &reference)));
    }
    let unfiltered = rms(&own, &reference);
    eprintln!(
        "sigma_x = {}, unfiltered RMS {unfiltered:.4}; {errors:?}",
        guide[0][SIGMA]
    );
    assert!(
        (guide[0][ETA] - 1.0).abs() < 1e-6,
        "eta = 1/s for one plane"
    );
    let best = errors[0].2;
    // The corrected form with + is the only reading that beats the unfiltered samples, by
    // 3.3x; the others are worse than no filter (measured RMS: + 0.0409; - 0.1878, printed
    // 0.1647, none 0.1433; unfiltered 0.1344).
    for e in &errors[1..] {
        assert!(best * 3.0 < e.2, "{errors:?}");
    }
    assert!(best * 3.0 < unfiltered, "{best} vs {unfiltered}");
    assert!(best < 0.045, "{best}");
    // What is left is mostly the bins' quantisation of y2' (centres sigma_y / 2 apart at 17
    // bins): with 33 bins the + form's RMS falls further.
    let mut rng = Lcg(11);
    let fine = synthetic(
        w,
        h,
        d,
        3,
        33,
        1.0,
        |_| [rng.uniform(), rng.uniform()],
        checker,
    );
    let gd = constant_guide(fine.shadow.len(), guide[0][SIGMA], guide[0][ETA]);
    let out = factored(&fine.p, &fine.shadow, &fine.field, &gd);
    let at33 = rms(&out, &reference);
    eprintln!("corrected, + at 33 bins: RMS {at33:.4}");
    // Nor is it noise: eq. 4 gives sigma_x = inf for one plane, capped at 8 px (0.8). The
    // neighbours' squares, shifted by eta (x - x'), cover the light unevenly (densest at its
    // centre), so a wide w_x weights the light's centre up: the penumbra sharpens. Narrower
    // sigma_x does better (measured 0.0165 at 0.2, 0.0189 at 0.4), within the 9-spp noise of
    // such a window; the seed's cap is kept and the bias reported (issue 16).
    let mut narrow = Vec::new();
    for sx in [0.2f32, 0.4] {
        let gd = constant_guide(s.shadow.len(), sx, guide[0][ETA]);
        let out = factored(&s.p, &s.shadow, &s.field, &gd);
        narrow.push(rms(&out, &reference));
    }
    eprintln!("corrected, + at sigma_x 0.2, 0.4: RMS {narrow:?}");
    assert!(narrow[0] < 0.02 && narrow[1] < best, "{narrow:?}");
    assert!(at33 < best, "{at33} vs {best}");
}

fn sheared_settings() -> ShearedSettings {
    ShearedSettings::default()
}

fn render(scene: &Scene, w: u32, h: u32, spp: u32, s: &ShearedSettings) -> Renderer {
    common::sheared::sheared_renderer(scene, w, h, spp, 5, s)
}

fn close(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    let mut worst = 0f32;
    let mut far = 0usize;
    for (x, y) in a.iter().zip(b) {
        let e = (x - y).abs() / x.abs().max(y.abs()).max(1.0);
        worst = worst.max(e);
        far += (e > 1e-5) as usize;
    }
    eprintln!("{what}: worst relative difference {worst:e}, {far} above 1e-5");
    // exp/length of two libraries: measured at most 2.3e-7 relative; bound 1e-5 (as the AAF
    // tests), none above.
    assert_eq!(far, 0, "{what}");
}

#[test]
fn every_device_step_matches_its_rust_reference() {
    let scene = bundled_scene("grids");
    let (w, h) = (64, 48);
    let s = sheared_settings();
    let r = render(&scene, w, h, 2, &s);
    let frame = r.frame();
    let info = &frame.info().scene;
    let light = info.sphere_lights[0];
    let mut k = ShearedKernel::new(gpu(), &s, &[(0, light)], info.scene_centre, w, h).unwrap();
    let image = k.filter(&frame).unwrap().image;
    let dev = k.intermediates().unwrap().unwrap();
    let p = s.params(light, info.scene_centre, w, h);
    let shadow: &[ShadowPixel] = frame.host_slice(BufferId::ShadowPixels).unwrap();
    let field: &[LightFieldPixel] = frame.host_slice(BufferId::LightFieldPixels).unwrap();
    let guide = prepare(&p, shadow, field);
    let flat = |g: &[Guide]| g.iter().flatten().copied().collect::<Vec<f32>>();
    close(&flat(&guide), &flat(&dev.guide), "prepare");
    let filtered = guide.iter().filter(|g| g[KIND] == FILTERED).count();
    assert!(
        filtered * 4 > guide.len(),
        "Grids has penumbrae in view: {filtered}"
    );
    assert_eq!(dev.p1a.len(), guide.len() * p_floats(s.bins));
    assert_eq!(dev.g1b.len(), guide.len() * g_floats(s.bins));
    close(&step_1a(&p, field, &dev.guide), &dev.p1a, "1a");
    close(
        &step_1b(&p, shadow, field, &dev.guide, &dev.p1a),
        &dev.g1b,
        "1b",
    );
    close(&step_2a(&p, &dev.guide, &dev.g1b), &dev.q2a, "2a");
    let vis = step_2b(&p, shadow, field, &dev.guide, &dev.q2a);
    close(&vis, &dev.visibility, "2b");
    assert!(
        vis.iter()
            .all(|v| v.is_finite() && (0.0..=1.0 + 1e-6).contains(v))
    );
    // Compose: the replaced light out, the path samples' r times the sheared visibility in.
    let terms: &[ShadowTerms] = frame.host_slice(BufferId::ShadowTerms).unwrap();
    let reference = compose(&frame.beauty().unwrap(), terms, &dev.guide, &dev.visibility);
    close(
        &reference
            .pixels
            .iter()
            .flatten()
            .copied()
            .collect::<Vec<_>>(),
        &image.pixels.iter().flatten().copied().collect::<Vec<_>>(),
        "compose",
    );
}

fn filtered(scene: &Scene, w: u32, h: u32, s: &ShearedSettings) -> noisefree::imaging::RgbImage {
    let r = render(scene, w, h, 2, s);
    let frame = r.frame();
    Configured::typed::<Sheared>(s.clone(), &frame.info().scene)
        .unwrap()
        .prepare(frame.info(), &gpu())
        .unwrap()
        .run(&frame)
        .unwrap()
        .image
}

#[test]
fn hard_cases_stay_finite() {
    // No occluder anywhere (an empty light field); the light straight above the scene centre
    // (along the floor's normal); a wall standing along the light direction, seen at a grazing
    // angle (its light axes have no screen image: radius 0).
    let wall = r#"
[[mesh]]
generator = "quad"
material = "floor"
scale = 2
translate = [0, 1, -1]
rotate = [90, 0, 0]
"#;
    for (name, scene) in [
        ("empty", floor_scene("center = [0, 3, 0]\nradius = 0.3", "")),
        (
            "wall",
            floor_scene("center = [0, 3, 0]\nradius = 0.3", wall),
        ),
        (
            "grazing",
            floor_scene("center = [2.5, 0.5, -2.5]\nradius = 0.4", wall),
        ),
    ] {
        let img = filtered(&scene, 40, 30, &sheared_settings());
        assert_finite(&img, name);
    }
}

#[test]
fn sizes_that_do_not_fit_are_refused_with_a_clear_message() {
    let s = sheared_settings();
    // O(N^2 l^2): report the bytes per pixel.
    let per_pixel = s.memory_bytes(1, 1);
    eprintln!(
        "sheared filter memory: {per_pixel} B per pixel ({:.0} MiB at 1024 x 1024)",
        s.memory_bytes(1024, 1024) as f64 / (1 << 20) as f64
    );
    assert_eq!(per_pixel, 288 + 4 * (136 + 2 * 34) + 36);
    // A light field per filtered light; the steps' buffers are shared by the lights.
    let two = ShearedSettings {
        light_count: 2,
        ..s.clone()
    };
    assert_eq!(two.memory_bytes(1, 1), per_pixel + 288);
    assert_eq!(two.memory_bytes(4, 3), 12 * (per_pixel + 288));
    let e = ShearedKernel::new(
        gpu(),
        &s,
        &[(0, [0.0, 3.0, 0.0, 0.3])],
        [0.0; 3],
        200_000,
        200_000,
    )
    .err()
    .expect("refused");
    let msg = format!("{e:#}");
    eprintln!("{msg}");
    assert!(
        msg.contains("sheared") && msg.contains("lower the resolution"),
        "{msg}"
    );
}
