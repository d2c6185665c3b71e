//! The edge-avoiding à-trous filter (Dammertz et al. 2010) as `variant = "auto"` runs it (the
//! packed kernel on PoCL; each kernel against the plain Rust reference: tests/atrous_variants.rs):
//! the behaviour the equations promise (constant images, sky, edges, the limits of the sigmas,
//! no NaN, tiny images), the error on the bundled Cornell diffuse scene and its independence of
//! the scene's scale.

mod common;

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use common::*;
use glam::Vec3;
use noisefree::filters::Auto;
use noisefree::filters::atrous::{AtrousKernel, AtrousSettings, B3, pixel_direction};
use noisefree::imaging::RgbImage;
use noisefree::layout::SKY_DEPTH;
use noisefree::metrics::mse_luv;
use noisefree::scene::CameraBasis;

#[path = "common/atrous.rs"]
mod atrous_common;
use atrous_common::*;

#[test]
fn constant_image_stays_constant() {
    // Constant light and albedo; depth, normals and sky vary: every weighted mean of equal
    // values is that value, whatever the weights.
    let b = synthetic(37, 23, |x, y| {
        if (x * 3 + y) % 11 == 0 {
            fv([0.3, 0.2, 0.1], SKY_DEPTH, [0.0; 3], [0.0; 3])
        } else {
            let n = if x < 20 {
                [0.0, 0.0, 1.0]
            } else {
                [0.6, 0.0, 0.8]
            };
            fv(
                [0.3, 0.2, 0.1],
                1.0 + (x as f32) * 0.1 + if y > 10 { 5.0 } else { 0.0 },
                n,
                [0.5, 0.7, 0.9],
            )
        }
    });
    for demodulate in [true, false] {
        for sigma in [1e-6, 1.0, 1e6] {
            let s = all_sigmas(sigma, demodulate);
            for (what, out) in [
                ("kernel", device(&b, &test_camera(), &s)),
                ("reference", host(&b, &test_camera(), &s)),
            ] {
                for p in &out.pixels {
                    for (c, want) in p.iter().zip([0.3, 0.2, 0.1]) {
                        assert!(
                            (c - want).abs() <= 1e-5 * want,
                            "{what} demodulate {demodulate} sigma {sigma}: {c} vs {want}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn no_nan_with_degenerate_features_all_sky_and_extreme_sigmas() {
    let (rendered, cam) = render(&cornell_with_spheres(), 40, 30, 2, 5);
    let cases: Vec<(&str, Buffers, CameraBasis)> = vec![
        ("rendered", rendered, cam),
        // Zero-variance features: every pixel has the same depth, normal and albedo.
        (
            "identical features",
            synthetic(19, 11, |x, y| {
                fv(
                    [(x * y % 5) as f32 * 0.2; 3],
                    3.0,
                    [0.0, 1.0, 0.0],
                    [0.5; 3],
                )
            }),
            test_camera(),
        ),
        (
            "all sky",
            synthetic(16, 9, |x, _| {
                fv([x as f32 * 0.1; 3], SKY_DEPTH, [0.0; 3], [0.0; 3])
            }),
            test_camera(),
        ),
        // Depth 0, normals 0, black albedo, black and very bright light.
        (
            "degenerate",
            synthetic(12, 12, |x, y| {
                let light = if (x + y) % 2 == 0 { 0.0 } else { 1e6 };
                fv([light; 3], 0.0, [0.0; 3], [0.0; 3])
            }),
            test_camera(),
        ),
    ];
    for (what, b, cam) in &cases {
        for demodulate in [true, false] {
            for sigma in [1e-6f32, 1e-3, 1.0, 1e3, 1e6] {
                let s = all_sigmas(sigma, demodulate);
                let got = device(b, cam, &s);
                assert_finite(
                    &got,
                    &format!("{what} sigma {sigma} demodulate {demodulate}"),
                );
                let want = host(b, cam, &s);
                assert_finite(&want, &format!("reference {what} sigma {sigma}"));
            }
        }
    }
    // All sky: nothing is filtered, every pixel keeps its input bit for bit.
    let (_, b, cam) = &cases[2];
    let out = device(b, cam, &AtrousSettings::default());
    assert_eq!(out.pixels, b.beauty().pixels);
}

/// The plain à-trous B3-spline blur (no edge weights), out-of-image taps skipped.
fn b3_blur(img: &RgbImage, iterations: u32) -> RgbImage {
    let (w, h) = (img.width as i32, img.height as i32);
    let mut c = img.pixels.clone();
    for i in 0..iterations {
        let step = 1 << i;
        c = (0..w * h)
            .map(|p| {
                let (x, y) = (p % w, p / w);
                let (mut sum, mut wsum) = ([0f64; 3], 0f64);
                for ky in 0..5 {
                    for kx in 0..5 {
                        let (nx, ny) = (x + (kx - 2) * step, y + (ky - 2) * step);
                        if nx < 0 || ny < 0 || nx >= w || ny >= h {
                            continue;
                        }
                        let wq = (B3[kx as usize] * B3[ky as usize]) as f64;
                        let q = c[(ny * w + nx) as usize];
                        for k in 0..3 {
                            sum[k] += wq * q[k] as f64;
                        }
                        wsum += wq;
                    }
                }
                sum.map(|v| (v / wsum) as f32)
            })
            .collect();
    }
    RgbImage {
        width: img.width,
        height: img.height,
        pixels: c,
    }
}

#[test]
fn huge_sigmas_give_the_b3_blur_and_tiny_sigmas_the_input() {
    let (b, cam) = render(&cornell_with_spheres(), 48, 40, 4, 9);
    // The box is closed: no sky, so with every weight 1 the filter is the plain blur.
    assert!(b.filter_vectors.iter().all(|f| f.depth < SKY_DEPTH));
    let huge = all_sigmas(1e6, false);
    let blur = b3_blur(&b.beauty(), 5);
    let got = device(&b, &cam, &huge);
    let d = max_rel_diff(&got, &blur);
    // Measured 3.5e-7; bound 1e-5 (~30 x, for other devices' rounding).
    assert!(d < 1e-5, "sigma 1e6 vs the B3 blur: {d:e}");

    for demodulate in [true, false] {
        let got = device(&b, &cam, &all_sigmas(1e-6, demodulate));
        let d = max_rel_diff(&got, &b.beauty());
        // Measured 1.1e-7 demodulated (a division and a multiplication by the albedo: ~2
        // ulp), 6.7e-8 for the beauty; bound 1e-6.
        assert!(
            d < 1e-6,
            "sigma 1e-6 (demodulate {demodulate}) vs the input: {d:e}"
        );
    }
}

#[test]
fn sky_passes_through_and_is_never_a_neighbour() {
    let make = |sky_light: f32| {
        synthetic(24, 16, move |x, y| {
            if (x / 3 + y / 2) % 4 == 0 {
                fv([sky_light, 0.5, 0.25], SKY_DEPTH, [0.0; 3], [0.0; 3])
            } else {
                fv(
                    [((x * 7 + y * 3) % 5) as f32 * 0.1; 3],
                    4.0,
                    [0.0, 0.0, 1.0],
                    [0.6; 3],
                )
            }
        })
    };
    let (a, b) = (make(0.123_456_7), make(1000.0));
    for demodulate in [true, false] {
        let s = AtrousSettings {
            // No colour edge-stopping: only the sky rule keeps them apart.
            sigma_color: Auto::Set(1e6),
            demodulate,
            ..Default::default()
        };
        let (oa, ob) = (
            device(&a, &test_camera(), &s),
            device(&b, &test_camera(), &s),
        );
        for (i, f) in a.filter_vectors.iter().enumerate() {
            if f.depth >= SKY_DEPTH {
                assert_eq!(oa.pixels[i], a.beauty().pixels[i], "sky changed");
                assert_eq!(ob.pixels[i], b.beauty().pixels[i], "sky changed");
            } else {
                assert_eq!(oa.pixels[i], ob.pixels[i], "the sky leaked into a surface");
            }
        }
        // The surfaces were filtered: with σ_colour off and one depth and normal they are
        // blurred flat. Measured: the variance of the surface pixels drops from 0.0203 to
        // 5.8e-5 demodulated, 4.0e-5 for the beauty (0.29 %, 0.19 %); bound 1 %.
        let surfaces: Vec<usize> = (0..a.filter_vectors.len())
            .filter(|&i| a.filter_vectors[i].depth < SKY_DEPTH)
            .collect();
        let variance = |img: &RgbImage| {
            let n = surfaces.len() as f64;
            let m = surfaces
                .iter()
                .map(|&i| img.pixels[i][0] as f64)
                .sum::<f64>()
                / n;
            surfaces
                .iter()
                .map(|&i| (img.pixels[i][0] as f64 - m).powi(2))
                .sum::<f64>()
                / n
        };
        let (before, after) = (variance(&a.beauty()), variance(&oa));
        assert!(
            after < 0.01 * before,
            "demodulate {demodulate}: surface variance {before} -> {after}"
        );
    }
}

#[test]
fn depth_and_normal_edges_are_kept() {
    // Left and right halves differ in light (0.2 vs 0.8, with a noise pattern) and in one
    // guide; colour edge-stopping is off, so only that guide can keep the halves apart.
    let noise = |x: u32, y: u32| ((x * 7 + y * 13) % 5) as f32 * 0.02;
    let light = move |x: u32, y: u32| [if x < 16 { 0.2 } else { 0.8 } + noise(x, y); 3];
    let cam = CameraBasis {
        origin: Vec3::ZERO,
        forward: -Vec3::Z,
        right: Vec3::X,
        up: Vec3::Y,
        tan_half_fov: 0.5,
        lens_radius: 0.0,
        focal_distance: 1.0,
    };
    let cases: Vec<(&str, Buffers)> = vec![
        (
            "depth",
            synthetic(32, 16, |x, y| {
                let depth = if x < 16 { 2.0 } else { 9.0 };
                fv(light(x, y), depth, [0.0, 0.0, 1.0], [0.5; 3])
            }),
        ),
        (
            "normal",
            synthetic(32, 16, |x, y| {
                let n = if x < 16 {
                    [0.0, 0.0, 1.0]
                } else {
                    [1.0, 0.0, 0.0]
                };
                fv(light(x, y), 3.0, n, [0.5; 3])
            }),
        ),
    ];
    for (what, b) in cases {
        let s = AtrousSettings {
            sigma_color: Auto::Set(1e6),
            ..Default::default()
        };
        let out = device(&b, &cam, &s);
        for y in 0..16 {
            for x in 0..32u32 {
                let want = if x < 16 { 0.24 } else { 0.84 };
                let got = out.pixels[(y * 32 + x) as usize][0];
                // Measured: at most 0.0028 from the half's mean (depth), 0.0015 (normal);
                // bound 0.01, a sixtieth of the step between the halves.
                assert!(
                    (got - want).abs() < 0.01,
                    "{what} edge bled at ({x},{y}): {got} vs {want}"
                );
            }
        }
    }
}

#[test]
fn reconstructed_positions_lie_on_the_rendered_walls() {
    // The test box's walls are the planes z = -1 (back, normal +z), y = 0 (floor, +y),
    // x = -1 (left, +x) and x = 1 (right, -x). Pixels that see only one wall must reconstruct
    // onto it from their depth and the camera, to a small fraction of a pixel footprint (the
    // mean depth is over jittered samples, the reconstruction uses the pixel centre).
    let scene = scene_from_toml(&cornell("max_depth = 1", ""));
    let (b, cam) = render(&scene, 40, 30, 64, 3);
    // A pinhole camera: the renderer's basis is the scene camera's.
    assert_eq!(cam, CameraBasis::new(&scene.camera));
    let p = AtrousSettings::default().params(&cam, b.width, b.height, 0);
    let walls: [([f32; 3], usize, f32); 4] = [
        ([0.0, 0.0, 1.0], 2, -1.0),
        ([0.0, 1.0, 0.0], 1, 0.0),
        ([1.0, 0.0, 0.0], 0, -1.0),
        ([-1.0, 0.0, 0.0], 0, 1.0),
    ];
    let mut seen = [0; 4];
    for (i, f) in b.filter_vectors.iter().enumerate() {
        for (k, (n, axis, plane)) in walls.iter().enumerate() {
            let dot: f32 = (0..3).map(|c| n[c] * f.normal[c]).sum();
            if dot < 0.9999 {
                continue;
            }
            let d = pixel_direction(&p, i as u32 % b.width, i as u32 / b.width);
            let coord = cam.origin[*axis] + f.depth * d[*axis];
            let footprint = f.depth * 2.0 * cam.tan_half_fov / b.height as f32;
            // Measured: at most 0.098 footprints (a pixel's mean depth averages jittered
            // samples, the reconstruction uses the pixel centre): the bound has no slack.
            assert!(
                (coord - plane).abs() < 0.1 * footprint,
                "pixel {i} on wall {k}: {coord} instead of {plane} (footprint {footprint})"
            );
            seen[k] += 1;
        }
    }
    // Seen: [324, 120, 270, 270].
    assert!(seen.iter().all(|&n| n >= 100), "wall pixels seen: {seen:?}");
}

#[test]
fn settings_are_validated() {
    let ok = AtrousSettings::default();
    assert!(ok.validate().is_ok());
    for bad in [
        AtrousSettings {
            iterations: 16,
            ..ok.clone()
        },
        AtrousSettings {
            sigma_color: Auto::Set(0.0),
            ..ok.clone()
        },
        AtrousSettings {
            sigma_normal: Auto::Set(f32::NAN),
            ..ok.clone()
        },
        AtrousSettings {
            sigma_position: Auto::Set(f32::INFINITY),
            ..ok.clone()
        },
        AtrousSettings {
            sigma_position: Auto::Set(-1.0),
            ..ok.clone()
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?} was accepted");
        assert!(AtrousKernel::new(gpu(), &bad, &test_camera(), 4, 4).is_err());
    }
    let b = random_buffers(4, 4, 1);
    let mut f = AtrousKernel::new(gpu(), &ok, &test_camera(), 5, 4).unwrap();
    assert!(
        f.filter(&b.frame()).is_err(),
        "a size mismatch was accepted"
    );
}

// ---- Bundled scenes (thesis Fig. 7.1) at 128 x 128, 8 spp, against 1024 spp. ----
//
// The defaults were tuned (the `sweep` below) on scenes/cornell_diffuse.toml at 128 x 128,
// 8 spp, seed 7 against a 1024-spp reference at seed 100. The quality bounds are checked on
// scenes/cornell_plane.toml (textures, glass, a mirror and the airplane mesh: none of it in
// the tuning scene) at seed 3, so they say how the defaults do on a scene they were not
// fitted to; the tuning scene is kept at another seed (11) for the numbers the defaults'
// doc quotes, and for the scale experiment.

const SIZE: u32 = 128;

/// Samples per pixel of a bundled scene's reference: 1024, but 512 for cornell_plane, whose
/// airplane mesh makes it twice as slow on PoCL (its reference noise then adds about 1 / 64
/// of the 8-spp noise to every MSE against it, about 1 %: the bounds below hold it).
fn truth_spp(name: &str) -> u32 {
    if name == "cornell_plane" { 512 } else { 1024 }
}

/// The reference of a bundled scene at `scale`, rendered once per binary (the lock is held
/// while rendering, so two tests never render the same reference).
fn truth(name: &str, scale: f32) -> Arc<RgbImage> {
    static TRUTHS: Mutex<BTreeMap<String, Arc<RgbImage>>> = Mutex::new(BTreeMap::new());
    let mut truths = TRUTHS.lock().unwrap_or_else(|e| e.into_inner());
    truths
        .entry(format!("{name} x{scale}"))
        .or_insert_with(|| {
            let scene = bundled_scene(name).scaled(scale);
            Arc::new(reference_image(&scene, SIZE, SIZE, truth_spp(name), 100))
        })
        .clone()
}

/// (filtered MSE, unfiltered MSE, kernel time) of 8 spp of a bundled scene at `scale` with
/// `seed` against its own reference.
fn filtered_error(
    name: &str,
    scale: f32,
    seed: u32,
    s: &AtrousSettings,
) -> (f64, f64, std::time::Duration) {
    let scene = bundled_scene(name).scaled(scale);
    let (noisy, cam) = render(&scene, SIZE, SIZE, 8, seed);
    let mut f = AtrousKernel::new(gpu(), s, &cam, SIZE, SIZE).unwrap();
    let out = f.filter(&noisy.frame()).unwrap();
    let truth = truth(name, scale);
    (
        mse_luv(&out.image, &truth).unwrap(),
        mse_luv(&noisy.beauty(), &truth).unwrap(),
        out.kernel_time
            .expect("a device filter reports its kernel time"),
    )
}

#[test]
fn filtering_lowers_the_error_on_a_scene_it_was_not_tuned_on() {
    // Measured (PoCL, reference at 512 spp): MSE-LUV 31.54 filtered / 68.92 unfiltered =
    // 0.458 demodulated, 49.01 / 68.92 = 0.711 filtering the beauty. Bounds: 1.25 x the
    // measured ratio (0.57, 0.89); 1.5 x would allow 1.07 for the beauty, i.e. no
    // improvement at all. Demodulating must also beat filtering the beauty (textures!).
    let mut errors = Vec::new();
    for (demodulate, bound) in [(true, 0.57), (false, 0.89)] {
        let (e, unfiltered, t) = filtered_error("cornell_plane", 1.0, 3, &settings(demodulate));
        eprintln!(
            "cornell_plane seed 3, demodulate {demodulate}: filtered MSE {e:.5}, unfiltered \
             {unfiltered:.5} (ratio {:.4}), kernel time {t:?}",
            e / unfiltered
        );
        assert!(t > std::time::Duration::ZERO);
        assert!(
            e < bound * unfiltered,
            "demodulate {demodulate}: filtered MSE {e} vs unfiltered {unfiltered}"
        );
        errors.push(e);
    }
    assert!(
        errors[0] < errors[1],
        "demodulated {} vs beauty {}",
        errors[0],
        errors[1]
    );
}

#[test]
fn filtering_lowers_the_error_on_cornell_diffuse() {
    // The tuning scene at a seed the sweep did not use (11, not 7). Measured (PoCL): MSE-LUV
    // 4.887 / 30.98 = 0.158 demodulated, 13.21 / 30.98 = 0.426 for the beauty (at the tuning
    // seed 7 the defaults' doc quotes 5.19 / 30.9 = 0.168 and 13.0 / 30.9 = 0.421). Bounds:
    // 1.25 x the measured ratio (0.20, 0.53), as above. Demodulating must also beat
    // filtering the beauty, as the doc claims.
    let mut errors = Vec::new();
    for (demodulate, bound) in [(true, 0.20), (false, 0.53)] {
        let (e, unfiltered, _) = filtered_error("cornell_diffuse", 1.0, 11, &settings(demodulate));
        eprintln!(
            "cornell_diffuse seed 11, demodulate {demodulate}: filtered MSE {e:.5}, \
             unfiltered {unfiltered:.5} (ratio {:.4})",
            e / unfiltered
        );
        assert!(
            e < bound * unfiltered,
            "demodulate {demodulate}: filtered MSE {e} vs unfiltered {unfiltered}"
        );
        errors.push(e);
    }
    assert!(
        errors[0] < errors[1],
        "demodulated {} vs beauty {}",
        errors[0],
        errors[1]
    );
}

#[test]
fn scaling_the_scene_keeps_the_filtered_error() {
    // The filter alone: the same buffers with every depth and the camera scaled by 1000
    // filter to the same image (σ_position is in pixel footprints). The test box is closed:
    // a pixel partly covered by sky has a mean depth between its surface's and SKY_DEPTH,
    // which does not scale with the scene.
    let (a, cam) = render(&cornell_with_spheres(), 64, 48, 8, 4);
    assert!(a.filter_vectors.iter().all(|f| f.depth < 100.0));
    let mut big = a.clone();
    for f in &mut big.filter_vectors {
        f.depth *= 1000.0;
    }
    let big_cam = CameraBasis {
        origin: cam.origin * 1000.0,
        ..cam
    };
    for demodulate in [true, false] {
        let s = settings(demodulate);
        let d = max_rel_diff(&device(&a, &cam, &s), &device(&big, &big_cam, &s));
        // Measured 9.5e-7; bound 1e-5.
        assert!(
            d < 1e-5,
            "demodulate {demodulate}: scaled buffers differ by {d:e}"
        );
    }
    // Rendered: Scene::scaled(1000), each scale against its own 1024-spp reference. (The
    // renderer's images of the two scales are not the same: at scale 1000 it is about 0.8 %
    // darker, so the error against the scale-1 reference says more about the renderer.)
    for demodulate in [true, false] {
        let s = settings(demodulate);
        let (e1, u1, _) = filtered_error("cornell_diffuse", 1.0, 7, &s);
        let (e1000, u1000, _) = filtered_error("cornell_diffuse", 1000.0, 7, &s);
        eprintln!(
            "demodulate {demodulate}: filtered MSE {e1:.5} at scale 1, {e1000:.5} at scale \
             1000 (unfiltered {u1:.5}, {u1000:.5})"
        );
        // Measured: 5.18528 vs 5.18527 demodulated, 13.03464 vs 13.03465 for the beauty
        // (2e-6 apart, relative). Bound 1e-3, 500 x that: room for another device's rounding
        // and for the renderer, whose two scales differ slightly, but not for a filter that
        // depends on the scene's scale (the old bound, 10 %, would have let one through).
        assert!(
            (e1000 - e1).abs() < 1e-3 * e1,
            "demodulate {demodulate}: scaling the scene changed the filtered MSE from {e1} \
             to {e1000}"
        );
    }
}

/// Prints the error for a grid of sigmas (how the defaults were chosen):
/// `cargo test --release --test atrous -- --ignored sweep --nocapture`.
#[test]
#[ignore]
fn sweep() {
    let scene = bundled_scene("cornell_diffuse");
    let (noisy, cam) = render(&scene, SIZE, SIZE, 8, 7);
    let frame = noisy.frame();
    let truth = truth("cornell_diffuse", 1.0);
    eprintln!(
        "unfiltered MSE {:.5}",
        mse_luv(&noisy.beauty(), &truth).unwrap()
    );
    // (demodulate, sigma_color, sigma_normal, sigma_position values)
    type Grid = Vec<(bool, Vec<f32>, Vec<f32>, Vec<f32>)>;
    let grid: Grid = vec![
        (
            true,
            vec![0.25, 0.35, 0.5, 0.6, 0.7, 1.0, 2.0],
            vec![0.1, 0.3, 0.5, 1.0],
            vec![2.0, 4.0, 5.0, 6.0, 8.0, 16.0],
        ),
        (
            false,
            vec![0.05, 0.1, 0.15, 0.25],
            vec![0.3, 1.0],
            vec![2.0, 4.0, 6.0, 8.0, 16.0],
        ),
    ];

    for (demodulate, cs, ns, ps) in grid {
        for &sigma_color in &cs {
            for &sigma_normal in &ns {
                for &sigma_position in &ps {
                    let s = AtrousSettings {
                        sigma_color: Auto::Set(sigma_color),
                        sigma_normal: Auto::Set(sigma_normal),
                        sigma_position: Auto::Set(sigma_position),
                        demodulate,
                        ..Default::default()
                    };
                    let mut f = AtrousKernel::new(gpu(), &s, &cam, SIZE, SIZE).unwrap();
                    let out = f.filter(&frame).unwrap();
                    let e = mse_luv(&out.image, &truth).unwrap();
                    eprintln!(
                        "demodulate {demodulate} colour {sigma_color} normal {sigma_normal} \
                         position {sigma_position}: {e:.5}"
                    );
                }
            }
        }
    }
}

/// Kernel time at 512 x 512, 5 passes (init + passes + finish), from profiling events:
/// `cargo test --release --test atrous -- --ignored timing --nocapture`.
#[test]
#[ignore]
fn timing() {
    let (b, cam) = render(&bundled_scene("cornell_diffuse"), 512, 512, 1, 1);
    let frame = b.frame();
    let gpu = gpu();
    for demodulate in [true, false] {
        let mut f = AtrousKernel::new(gpu.clone(), &settings(demodulate), &cam, 512, 512).unwrap();
        let times: Vec<_> = (0..7).map(|_| f.filter(&frame).unwrap().time()).collect();
        let (lo, med, hi) = noisefree::filters::time_summary(&times).unwrap();
        eprintln!(
            "{} 512x512 demodulate {demodulate}: min {lo:?} median {med:?} max {hi:?}",
            gpu.summary.name
        );
    }
}
