//! AAF diffuse indirect light (src/filters/aaf_indirect, src/render/indirect, kernels/render/
//! indirect.cl, kernels/filters/aaf_indirect.cl): the filter's kernels against the Rust
//! reference, the separable passes against the 2-D filter at constant β, constant images,
//! β and n by hand and the sampling pass's n against Rust's, spp bookkeeping, and no NaN/Inf
//! where z_min is 0 or no sample met a reflector.

mod common;

use common::aaf::{aaf_indirect_filtered, floor_scene_with, indirect_frame, indirect_renderer};
use common::*;
use noisefree::filters::aaf_indirect::{AafIndirectSettings, reference};
use noisefree::imaging::RgbImage;
use noisefree::layout::IndirectPixel;
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::render::indirect::bandlimit::{
    DIFFUSE_BANDLIMIT, SEED_FOOTPRINTS, beta, sample_count,
};
use noisefree::render::shadows::bandlimit::adaptive_plan;
use noisefree::render::{Renderer, Tile};

/// Small counts, so the tests stay quick on PoCL.
fn small() -> AafIndirectSettings {
    AafIndirectSettings {
        sparse_spp: 4,
        max_spp: 25,
        ..Default::default()
    }
}

/// Receivers on the plane z = 0 at pixel spacing `d`, L from `l` (grey), albedo 1, z_min
/// from `z`, z_max = 2 z_min.
fn plane_pixels(
    w: u32,
    h: u32,
    d: f32,
    l: &dyn Fn(u32, u32) -> f32,
    z: &dyn Fn(u32, u32) -> f32,
) -> Vec<IndirectPixel> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            IndirectPixel {
                irradiance: [4.0 * l(x, y); 3],
                samples: 4.0,
                albedo: [4.0; 3],
                weight: 4.0,
                position: [x as f32 * d, y as f32 * d, 0.0],
                z_min: z(x, y),
                normal: [0.0, 0.0, 1.0],
                z_max: 2.0 * z(x, y),
                pixel_size: d,
                target: 4.0,
                object: 0.0,
                reflectors: 4.0,
                bandlimit: DIFFUSE_BANDLIMIT,
                lobe: 0.0,
                pad: [0.0; 2],
            }
        })
        .collect()
}

fn max_abs(a: &RgbImage, b: &RgbImage) -> f32 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

#[test]
fn kernels_match_the_reference_on_a_rendered_frame() {
    let s = small();
    let r = indirect_renderer(&bundled_scene("cornell_diffuse"), 48, 48, 1, s.sampling());
    let frame = r.frame();
    let device = aaf_indirect_filtered(&frame, &s);
    let cpu = reference(&frame, &s).unwrap();
    let diff = max_rel_diff(&device, &cpu);
    eprintln!("kernel against reference: {diff:e}");
    // Measured 2.6e-7 (exp of two libraries); bound 1e-6.
    assert!(diff < 1e-6, "{diff}");
    assert_finite(&device, "cornell_diffuse");
}

#[test]
fn separable_passes_equal_the_2d_filter_at_constant_beta() {
    let mut rng = TestRng(5);
    let (w, h, d) = (40u32, 30u32, 1.0 / 64.0);
    let noise: Vec<f32> = (0..w * h).map(|_| rng.range(0.05, 1.0)).collect();
    // z_min = 0.1: β = max(0.2 / 2.8, 1 / 64) = 0.0714, 4.6 pixels.
    let px = plane_pixels(w, h, d, &|x, y| noise[(y * w + x) as usize], &|_, _| 0.1);
    let s = AafIndirectSettings {
        normal_angle: 180.0,
        depth_tolerance: f32::INFINITY,
        beta_tolerance: f32::INFINITY,
        ..small()
    };
    let b = beta(0.1, d, DIFFUSE_BANDLIMIT, s.footprints) as f64;
    let r = s.radius as i64;
    let (wi, hi) = (w as i64, h as i64);
    let want: Vec<f64> = (0..wi * hi)
        .map(|i| {
            let (x, y) = (i % wi, i / wi);
            let (mut sum, mut sw) = (0f64, 0f64);
            for ny in (y - r).max(0)..=(y + r).min(hi - 1) {
                for nx in (x - r).max(0)..=(x + r).min(wi - 1) {
                    let (dx, dy) = ((nx - x) as f64 * d as f64, (ny - y) as f64 * d as f64);
                    let wgt = (-(dx * dx + dy * dy) / (2.0 * b * b)).exp();
                    sum += wgt * noise[(ny * wi + nx) as usize] as f64;
                    sw += wgt;
                }
            }
            sum / sw
        })
        .collect();
    let frame = indirect_frame(w, h, &px);
    let worst = |img: &RgbImage| {
        img.pixels
            .iter()
            .zip(&want)
            .map(|(p, v)| (p[1] as f64 - v).abs() / v)
            .fold(0.0, f64::max)
    };
    let (device, cpu) = (
        worst(&aaf_indirect_filtered(&frame, &s)),
        worst(&reference(&frame, &s).unwrap()),
    );
    eprintln!("separable against 2-D at constant beta: device {device:e}, reference {cpu:e}");
    // Eq. 3.6's exactness, to float32 rounding: measured 5.6e-7 (device and reference);
    // bound 1e-6.
    assert!(device <= 1e-6 && cpu <= 1e-6, "{device} {cpu}");
}

#[test]
fn constant_images_pass_through_and_z_min_zero_stays_finite() {
    let s = small();
    let r = indirect_renderer(&bundled_scene("cornell_diffuse"), 40, 40, 1, s.sampling());
    let frame = r.frame();
    let mut px: Vec<IndirectPixel> = frame
        .host_slice::<IndirectPixel>(BufferId::IndirectPixels)
        .unwrap()
        .to_vec();
    // The rendered geometry, z's and kinds, every L = 0.37 and albedo 1, F = 0.
    for p in &mut px {
        p.irradiance = [0.37 * p.weight; 3];
        p.albedo = [p.weight; 3];
    }
    let out = aaf_indirect_filtered(&indirect_frame(40, 40, &px), &s);
    let mut worst = 0f32;
    for (p, o) in px.iter().zip(&out.pixels) {
        let want = if p.weight > 0.0 { 0.37 } else { 0.0 };
        worst = worst.max((o[0] - want).abs());
    }
    eprintln!("constant 0.37: off by {worst:e} at most");
    // Measured 1.5e-7 (the normalised mean's rounding); bound 3e-7.
    assert!(worst <= 3e-7, "{worst}");
    // z_min = 0 (a contact) everywhere, and a third of the receivers with no reflector.
    for (i, p) in px.iter_mut().enumerate() {
        p.z_min = 0.0;
        if i % 3 == 0 {
            p.reflectors = 0.0;
            p.z_max = 0.0;
        }
    }
    let out = aaf_indirect_filtered(&indirect_frame(40, 40, &px), &s);
    assert_finite(&out, "z_min = 0");
    let diff = max_abs(&out, &reference(&indirect_frame(40, 40, &px), &s).unwrap());
    eprintln!("z_min = 0: kernel against reference {diff:e}");
    // Measured 8.9e-8 (exp of two libraries, values about 0.37); bound 3e-7.
    assert!(diff <= 3e-7, "{diff}");
}

#[test]
fn beta_and_n_by_hand() {
    // Eq. 4.4 at z_min = 0.7 m, d = 0.004 m: 2 · 0.7 / 2.8 = 0.5 m; the floor 0.0267 m.
    assert!((beta(0.7, 0.004, 2.8, SEED_FOOTPRINTS) - 0.5).abs() < 1e-6);
    // At z_min = 0.01 m the floor wins: 0.004 / 0.15.
    assert!((beta(0.01, 0.004, 2.8, SEED_FOOTPRINTS) - 0.026_666_67).abs() < 1e-7);
    // Eq. 4.6 at z_min = 0.7, z_max = 1.4, d = 0.004: 0.4 (0.9·2.8·0.004/0.7 + 0.3)² 2.8²
    // (1 + 0.9·2)² = 0.4 · 0.3144² · 7.84 · 7.84 = 2.4303.
    let n = sample_count(0.7, 1.4, 0.004, 2.8);
    assert!((n - 2.430_3).abs() < 1e-3, "{n}");
    // Units: scaling every length by 1000 keeps n and scales β.
    let n_k = sample_count(700.0, 1400.0, 4.0, 2.8);
    assert!((n_k / n - 1.0).abs() < 1e-5, "{n_k} {n}");
    assert!((beta(700.0, 4.0, 2.8, SEED_FOOTPRINTS) / 500.0 - 1.0).abs() < 1e-6);
    // z_min = 0: n is +inf (clamped to max_spp by the plan), never NaN.
    assert_eq!(sample_count(0.0, 0.0, 0.004, 2.8), f32::INFINITY);
    assert_eq!(adaptive_plan(f32::INFINITY, 16, 100), (100.0, 9));
}

#[test]
fn the_sampling_pass_follows_eq_4_6_in_whole_strata() {
    let s = small();
    let r = indirect_renderer(&bundled_scene("cornell_diffuse"), 40, 40, 1, s.sampling());
    let (sampling, stats) = r.indirect_stats().expect("the indirect output");
    assert_eq!(sampling, s.sampling());
    let frame = r.frame();
    let px: &[IndirectPixel] = frame.host_slice(BufferId::IndirectPixels).unwrap();
    let (mut total, mut adapted, mut worst) = (0f64, 0u32, 0f32);
    for p in px {
        total += p.samples as f64;
        if p.weight == 0.0 {
            assert_eq!(p.samples, 0.0);
            continue;
        }
        if p.reflectors == 0.0 {
            assert_eq!(p.samples, s.sparse_spp as f32);
            continue;
        }
        let n = sample_count(p.z_min, p.z_max, p.pixel_size, DIFFUSE_BANDLIMIT);
        let (target, k) = adaptive_plan(n, s.sparse_spp, s.max_spp);
        worst = worst.max((p.target - target).abs() / target);
        assert_eq!(p.samples, (s.sparse_spp + k * k) as f32, "{p:?}");
        assert!(
            p.z_min > 0.0 && p.z_max >= p.z_min && p.z_min.is_finite(),
            "{p:?}"
        );
        adapted += (k > 0) as u32;
    }
    eprintln!(
        "target n against Rust: {worst:e}; {adapted} pixels adapted; average {:.3} spp",
        stats.average_spp
    );
    // The device's eq. 4.6 against Rust's: the same operations in the same order (FP_CONTRACT
    // OFF), measured equal.
    assert_eq!(worst, 0.0);
    assert!(adapted > 0);
    // Σn / N².
    assert!((stats.average_spp - total / px.len() as f64).abs() < 1e-9);
    assert!(stats.average_spp > s.sparse_spp as f64 * 0.5);
}

#[test]
fn open_sky_no_reflector_stays_finite() {
    // A lit floor with nothing around it: every indirect ray leaves to the sky, so no pixel
    // has a reflector (z undefined) and the indirect light is exactly 0. Depth 3 so that the
    // pass traces its first bounce (at depth 1 it traces nothing and this would test
    // nothing); the light is far and tiny (a sphere light is a reflector too: a cosine
    // sample meets it with probability ~1e-8 here, against ~1 % for the overhead light).
    let floor = |light: &str| floor_scene_with(3, common::aaf::GREY_DIFFUSE, light);
    let s = small();
    // The pass does trace here: with the overhead light some bounce rays meet it.
    let near = floor(&format!(
        "{}\nemission = [20, 20, 20]",
        common::aaf::OVERHEAD
    ));
    let r = indirect_renderer(&near, 32, 24, 1, s.sampling());
    let near_frame = r.frame();
    let px: &[IndirectPixel] = near_frame.host_slice(BufferId::IndirectPixels).unwrap();
    assert!(px.iter().any(|p| p.reflectors > 0.0));
    let scene = floor("center = [0, 100, 0]\nradius = 0.01\nemission = [2e6, 2e6, 2e6]");
    let r = indirect_renderer(&scene, 32, 24, 1, s.sampling());
    let frame = r.frame();
    let px: &[IndirectPixel] = frame.host_slice(BufferId::IndirectPixels).unwrap();
    assert!(px.iter().any(|p| p.weight > 0.0));
    assert!(
        px.iter()
            .all(|p| p.reflectors == 0.0 && p.irradiance == [0.0; 3])
    );
    let out = aaf_indirect_filtered(&frame, &s);
    assert_finite(&out, "open sky");
    let diff = max_rel_diff(&out, &reference(&frame, &s).unwrap());
    assert!(diff < 1e-6, "{diff}");
}

#[test]
fn the_indirect_output_refuses_a_tile() {
    let scene = bundled_scene("cornell_diffuse");
    let mut o = options(&scene, 32, 32, 5);
    o.outputs = OutputSet::of(&[Output::Indirect]);
    o.tile = Some(Tile {
        x: 0,
        y: 0,
        width: 16,
        height: 32,
    });
    let e = match Renderer::new(gpu(), &scene, &o) {
        Ok(_) => panic!("a tile with the indirect output was accepted"),
        Err(e) => format!("{e:#}"),
    };
    assert!(e.contains("needs the whole image, not a tile"), "{e}");
}
