//! AAF soft shadows against the ground truth: the filter beats Monte Carlo at equal light
//! samples on Grids (Wang 2013 Fig. 3.6's claim, in small), the hard cases give finite images
//! that are what they must be, and (ignored, run by hand) the measurement that chose the
//! rejection thresholds.

mod common;

use common::aaf::{OVERHEAD, aaf_filtered, floor_scene, shadow_renderer};
use common::*;
use noisefree::filters::aaf_shadows::AafShadowSettings;
use noisefree::imaging::RgbImage;
use noisefree::layout::ShadowPixel;
use noisefree::layout::outputs::BufferId;
use noisefree::metrics::mse_rgb;
use noisefree::render::Frame;
use noisefree::scene::Scene;

/// The beauty of `spp` path samples (direct light only in these scenes: Monte Carlo with one
/// shadow ray per sample).
fn monte_carlo(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> RgbImage {
    let film = render_film(scene, &options(scene, w, h, seed), spp, spp.min(256));
    RgbImage::beauty(w, h, &film)
}

/// The shadow output for `s` over `spp` path samples (which estimate the rest of the image),
/// and the average light samples spent.
fn aaf_frame(scene: &Scene, w: u32, h: u32, spp: u32, s: &AafShadowSettings) -> (Frame, f64) {
    let r = shadow_renderer(scene, w, h, spp, 9, s.sampling());
    let avg = r.shadow_stats().unwrap().1.average_spp;
    (r.frame(), avg)
}

fn filtered(frame: &Frame, s: &AafShadowSettings) -> RgbImage {
    aaf_filtered(frame, s)
}

fn rms(a: &RgbImage, b: &RgbImage) -> f64 {
    mse_rgb(a, b).unwrap().sqrt()
}

/// The pixels whose 3 × 3 neighbourhood is all one receiving object: where the filter
/// works alone (a pixel on an edge between objects keeps part of the path tracer's noise).
fn interior(frame: &Frame) -> Vec<bool> {
    let px: &[ShadowPixel] = frame.host_slice(BufferId::ShadowPixels).unwrap();
    let (w, h) = (frame.width() as i64, frame.height() as i64);
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let o = px[i as usize].object;
            (-1..=1).all(|dy| {
                (-1..=1).all(|dx| {
                    let (nx, ny) = ((x + dx).clamp(0, w - 1), (y + dy).clamp(0, h - 1));
                    let q = &px[(ny * w + nx) as usize];
                    q.weight > 0.0 && q.object == o
                })
            })
        })
        .collect()
}

#[test]
fn aaf_beats_monte_carlo_at_equal_light_samples_on_grids() {
    let scene = bundled_scene("grids");
    let (w, h) = (96, 72);
    let truth = monte_carlo(&scene, w, h, 1024, 1);
    let s = AafShadowSettings::default();
    // 16 path samples per pixel for the rest of the image and the replaced term.
    let (frame, avg) = aaf_frame(&scene, w, h, 16, &s);
    let inside = interior(&frame);
    let all = vec![true; inside.len()];
    let aaf = filtered(&frame, &s);
    // The same light samples unfiltered (r · h_n of the adaptive render).
    let unfiltered_settings = AafShadowSettings {
        radius: 0,
        ..s.clone()
    };
    let unfiltered = filtered(&frame, &unfiltered_settings);
    // Monte Carlo at the same light samples per pixel, and at twice as many.
    let n = avg.round() as u32;
    let mc = monte_carlo(&scene, w, h, n, 2);
    let mc2 = monte_carlo(&scene, w, h, 2 * n, 2);
    let rows: Vec<[f64; 4]> = [&inside, &all]
        .iter()
        .map(|m| [&aaf, &unfiltered, &mc, &mc2].map(|img| masked_rms(img, &truth, m)))
        .collect();
    for (what, r) in ["interior", "all"].iter().zip(&rows) {
        eprintln!(
            "{what} pixels, RMS at {avg:.1} spp: AAF {:.5}, unfiltered {:.5}, MC {:.5} ({n} \
             spp), MC {:.5} ({} spp)",
            r[0],
            r[1],
            r[2],
            r[3],
            2 * n
        );
    }
    let ([a, u, m, m2], [a_all, _, m_all, _]) = (rows[0], rows[1]);
    // Measured on the interior (59% of the pixels), RMS 0.01017: 0.49 of the unfiltered RMS,
    // 0.50 of MC's at the same spp (37) and 0.70 of MC's at twice the samples; on every pixel,
    // 0.86 of MC's at the same spp (edges between objects keep 16 path samples of noise).
    // Bounds 0.6, 0.6, 0.85 and 0.95.
    assert!(a < 0.6 * u, "{a} {u}");
    assert!(a < 0.6 * m, "{a} {m}");
    assert!(a < 0.85 * m2, "{a} {m2}");
    assert!(a_all < 0.95 * m_all, "{a_all} {m_all}");
    let share = inside.iter().filter(|&&b| b).count() as f64 / inside.len() as f64;
    eprintln!("interior: {:.0}% of the pixels", 100.0 * share);
    assert!(share > 0.5, "{share}");
}

#[test]
fn empty_shadows_and_total_shadow_give_what_they_must() {
    let s = AafShadowSettings::default();
    // No occluder: every receiver's visibility is exactly 1, the output is r̄ (no noise left):
    // equal to the truth up to the split of r from the cone's cosines.
    let scene = floor_scene(OVERHEAD, "");
    let (frame, _) = aaf_frame(&scene, 32, 24, 16, &s);
    let out = filtered(&frame, &s);
    assert_finite(&out, "no shadow");
    let truth = monte_carlo(&scene, 32, 24, 4096, 3);
    let (mean, want) = (mean_rgb(&out.pixels), mean_rgb(&truth.pixels));
    eprintln!("no shadow: mean {mean:?} against {want:?}");
    // Measured 0.006% apart; bound 0.5% (the truth's own noise at 4096 spp is ~0.1%).
    assert!((mean[0] / want[0] - 1.0).abs() < 5e-3);
    // A roof over everything the camera sees: all in shadow, the output is black.
    let scene = floor_scene(
        OVERHEAD,
        r#"
[[mesh]]
generator = "quad"
material = "floor"
scale = 20
translate = [0, 2, 0]
"#,
    );
    let mut scene = scene;
    scene.camera.origin = glam::Vec3::new(0.0, 1.0, 2.0);
    let (frame, _) = aaf_frame(&scene, 32, 24, 4, &s);
    let out = filtered(&frame, &s);
    assert!(
        out.pixels.iter().all(|p| *p == [0.0; 3]),
        "light under a roof"
    );
}

/// Runs by hand: `cargo test --release --test aaf_quality -- --ignored --nocapture`. The
/// rejection thresholds against the ground truth on Grids and on curved receivers; the
/// defaults of [`AafShadowSettings`] come from this table.
#[test]
#[ignore]
fn measure_rejection_thresholds() {
    let spheres = floor_scene(
        OVERHEAD,
        r#"
[[sphere]]
center = [-0.6, 0.5, 0.2]
radius = 0.5
material = "floor"

[[sphere]]
center = [0.5, 0.35, -0.3]
radius = 0.35
material = "floor"

[[mesh]]
generator = "grid"
material = "floor"
scale = 1.5
rotate = [0, 25, 0]
translate = [0, 1.6, 0]
"#,
    );
    let (w, h) = (320, 240);
    for (name, scene) in [("grids", bundled_scene("grids")), ("spheres", spheres)] {
        let truth = monte_carlo(&scene, w, h, 1024, 1);
        let base = AafShadowSettings::default();
        let (frame, avg) = aaf_frame(&scene, w, h, 16, &base);
        let mc = rms(&monte_carlo(&scene, w, h, avg.round() as u32, 2), &truth);
        eprintln!("{name}: {avg:.1} spp; Monte Carlo at that: RMS {mc:.5}");
        let mut rows = Vec::new();
        for normal_angle in [10.0f32, 20.0, 45.0, 180.0] {
            for depth_tolerance in [0.5f32, 1.0, 2.0, 3.0, f32::INFINITY] {
                for beta_tolerance in [0.25f32, 0.5, 1.0, f32::INFINITY] {
                    let s = AafShadowSettings {
                        normal_angle,
                        depth_tolerance,
                        beta_tolerance,
                        ..base.clone()
                    };
                    let e = rms(&filtered(&frame, &s), &truth);
                    rows.push((e, normal_angle, depth_tolerance, beta_tolerance));
                }
            }
        }
        rows.sort_by(|a, b| a.0.total_cmp(&b.0));
        for r in rows.iter().take(6).chain(rows.last()) {
            eprintln!(
                "{name}: RMS {:.5}  normal {} depth {} beta {}",
                r.0, r.1, r.2, r.3
            );
        }
        let default = rows
            .iter()
            .find(|r| {
                (r.1, r.2, r.3) == (base.normal_angle, base.depth_tolerance, base.beta_tolerance)
            })
            .unwrap();
        eprintln!("{name}: the defaults: RMS {:.5}", default.0);
        // The defaults are within 3% of the best setting measured on either scene.
        assert!(default.0 < 1.03 * rows[0].0, "{name}");
    }
}
