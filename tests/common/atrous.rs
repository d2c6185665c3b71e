//! Helpers of the à-trous tests (tests/atrous.rs, tests/atrous_variants.rs), included by path
//! from each: the kernel and the reference on host buffers, rendered and synthetic buffers.
#![allow(dead_code)]

use glam::Vec3;
use noisefree::filters::Auto;
use noisefree::filters::atrous::{AtrousKernel, AtrousSettings, reference};
use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::layout::{FilterVector, SKY_DEPTH};
use noisefree::render::Renderer;
use noisefree::scene::{CameraBasis, Scene};

use crate::common::*;

/// The kernel of `s.variant` (auto: packed on PoCL, a CPU).
pub fn device(b: &Buffers, cam: &CameraBasis, s: &AtrousSettings) -> RgbImage {
    let mut f = AtrousKernel::new(gpu(), s, cam, b.width, b.height).unwrap();
    f.filter(&b.frame()).unwrap().image
}

/// The plain Rust reference on host buffers.
pub fn host(b: &Buffers, cam: &CameraBasis, s: &AtrousSettings) -> RgbImage {
    reference(&b.frame(), cam, s).unwrap()
}

/// Settings with every sigma set to `sigma`.
pub fn all_sigmas(sigma: f32, demodulate: bool) -> AtrousSettings {
    AtrousSettings {
        sigma_color: Auto::Set(sigma),
        sigma_normal: Auto::Set(sigma),
        sigma_position: Auto::Set(sigma),
        demodulate,
        ..Default::default()
    }
}

/// The defaults, or with `demodulate = false` the settings tuned for the beauty.
pub fn settings(demodulate: bool) -> AtrousSettings {
    if demodulate {
        AtrousSettings::default()
    } else {
        AtrousSettings::for_beauty()
    }
}

/// Renders `scene` and returns its buffers and camera.
pub fn render(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> (Buffers, CameraBasis) {
    let mut o = options(scene, w, h, seed);
    o.outputs = OutputSet::of(&[Output::Features]);
    let mut r = Renderer::new(gpu(), scene, &o).unwrap_or_else(|e| panic!("{e:#}"));
    while r.samples_done() < spp {
        r.render_samples((spp - r.samples_done()).min(256)).unwrap();
    }
    let frame = r.frame();
    assert_eq!(frame.info().scene.camera, r.arrays.camera());
    (Buffers::of_frame(&frame), r.arrays.camera())
}

/// An arbitrary, oblique camera for synthetic buffers.
pub fn test_camera() -> CameraBasis {
    let forward = Vec3::new(0.3, -0.2, -1.0).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    CameraBasis {
        origin: Vec3::new(0.5, 2.0, 7.0),
        forward,
        right,
        up: right.cross(forward),
        tan_half_fov: 0.4,
        lens_radius: 0.0,
        focal_distance: 1.0,
    }
}

/// Synthetic buffers: `f(x, y)` gives each pixel's FilterVector; no variance output (the
/// filter reads none), unlike [`Buffers::from_fn`].
pub fn synthetic(w: u32, h: u32, f: impl Fn(u32, u32) -> FilterVector) -> Buffers {
    Buffers {
        variances: None,
        directions: None,
        ..Buffers::from_fn(w, h, 100.0, f)
    }
}

/// Random features: noisy light, a few depth layers, random normals and albedos, some sky.
pub fn random_buffers(w: u32, h: u32, seed: u64) -> Buffers {
    let mut rng = TestRng(seed);
    let fvs: Vec<FilterVector> = (0..w * h)
        .map(|_| {
            if rng.uniform() < 0.1 {
                return FilterVector {
                    direct: [rng.range(0.0, 3.0); 3],
                    indirect: [0.0; 3],
                    depth: SKY_DEPTH,
                    ..Default::default()
                };
            }
            let layer = (rng.uniform() * 3.0).floor();
            let n = if rng.uniform() < 0.5 {
                rng.unit_vector()
            } else {
                Vec3::Z
            };
            FilterVector {
                direct: std::array::from_fn(|_| rng.range(0.0, 1.0)),
                indirect: std::array::from_fn(|_| rng.range(0.0, 0.5)),
                depth: 2.0 + 3.0 * layer + rng.range(0.0, 0.05),
                normal: n.to_array(),
                albedo: std::array::from_fn(|_| rng.range(0.0, 1.0)),
                albedo2: [0.5; 3],
            }
        })
        .collect();
    synthetic(w, h, |x, y| fvs[(y * w + x) as usize])
}

pub fn fv(light: [f32; 3], depth: f32, normal: [f32; 3], albedo: [f32; 3]) -> FilterVector {
    FilterVector {
        direct: light,
        indirect: [0.0; 3],
        depth,
        normal,
        albedo,
        albedo2: albedo,
    }
}

/// The largest relative difference between the kernel of `s.variant` and the reference.
pub fn check_against_reference(
    b: &Buffers,
    cam: &CameraBasis,
    s: &AtrousSettings,
    what: &str,
) -> f32 {
    let want = host(b, cam, s);
    assert_finite(&want, what);
    let got = device(b, cam, s);
    assert_finite(&got, what);
    let d = max_rel_diff(&got, &want);
    // Measured on PoCL (2026-11-24): at most 5.9e-7 over every case of
    // tests/atrous_variants.rs for the scalar kernel, 5.8e-7 for the packed one (float16 exp
    // and division). The bound, 1e-5, leaves ~17 x for devices whose exp differs by the few
    // ulp OpenCL allows.
    assert!(
        d <= 1e-5,
        "{what} {s:?}: max relative difference {d:e} between kernel and reference"
    );
    d
}
