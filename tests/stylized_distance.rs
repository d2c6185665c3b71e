//! Stylized shadows, the distance and blur steps (src/filters/stylized/distance.rs, blur.rs;
//! digest shared/notes/seed-decoro.md §1.7): the L8 analytics of a straight edge and of the
//! medial axis, the error against the number of contour samples, the 45° rule, a lit object
//! in front of a shadow, the blur of a constant and the two-pass variance, and the stability
//! cases (scale ×1e-3 / ×1e3 of a synthetic frame, no contour, all shadow).

mod common;
#[path = "common/stylized.rs"]
mod stylized_common;

use common::*;
use glam::Vec3;
use noisefree::filters::stylized::{Controls, StylizedSettings, blur, distance, reference};
use noisefree::layout::Float4;
use stylized_common::*;

#[test]
fn straight_edge_follows_the_l8_analytics() {
    // The digest's check (§1.2 item 4, §1.7 item 3): ℓ = 100, r = 10 gives 13.37.
    let want = distance::straight_edge(100.0, 10.0);
    assert!((want - 13.37).abs() < 0.005, "{want}");
    let contour = line_contour(100.0, 0.05);
    let s = distance::Sampling::new((contour.len() / 2) as u32, 1 << 16, 1, 0.7);
    let mut worst_rel = 0f64;
    for r in [1.0f32, 2.0, 5.0, 10.0] {
        let (d, _) = distance::at(Vec3::new(r, 0.0, 0.0), Vec3::Z, true, 0.0, &contour, &s, 0);
        let want = distance::straight_edge(100.0, r as f64);
        worst_rel = worst_rel.max((d as f64 - want).abs() / want);
        // D ≥ the Euclidean distance (power-mean inequality), and its sign follows V.
        assert!(d >= r, "{d} < {r}");
        let (neg, _) = distance::at(Vec3::new(r, 0.0, 0.0), Vec3::Z, false, 0.0, &contour, &s, 0);
        assert_eq!(neg, -d);
        eprintln!("r = {r}: D = {d}, analytic {want:.4}");
    }
    // Measured 6.1e-5 (the line's ends, which the r ≪ ℓ formula ignores, the 0.05 step and
    // float32); bound 2e-4.
    assert!(worst_rel < 2e-4, "{worst_rel}");
    // Far from a small contour D tends to the distance R (every point is at about R).
    let small = line_contour(0.1, 0.01);
    let s = distance::Sampling::new((small.len() / 2) as u32, 64, 1, 0.7);
    let (d, _) = distance::at(
        Vec3::new(100.0, 0.0, 0.0),
        Vec3::Z,
        true,
        0.0,
        &small,
        &s,
        0,
    );
    assert!((d - 100.0).abs() < 1e-3, "{d}");
}

#[test]
fn scene_scale_changes_nothing_but_the_units() {
    // ×1e-3 and ×1e3 of a base spacing of 0.01: D scales with the scene, S with i and s
    // scaled does not change (digest §1.7 item 6). At ×1e-3 the nearest contour point is
    // 5e-6 away and eq. 3.2 as written overflows float32 (d^-8 = 2.6e42).
    let settings = |scale: f32| StylizedSettings {
        inflation: [0.02 * scale, 0.0, 0.0],
        softness: [0.03 * scale, 0.0, 0.0],
        brightness: [0.1, 0.0, 0.0],
        abstraction: [2.0, 0.0, 0.0],
        contour_samples: 32,
        ..Default::default()
    };
    let none = |_: u32, _: u32| false;
    let base = plane_frame(48, 40, 0.01, &notched_disc, &none);
    let (img0, st0) = device(&base, &settings(1.0));
    let mut worst_d = 0f32;
    let mut worst_s = 0f32;
    for scale in [1e-3f32, 1e3] {
        let f = plane_frame(48, 40, 0.01 * scale, &notched_disc, &none);
        let s = settings(scale);
        let (img, st) = device(&f, &s);
        let cpu = reference(&f, &s).unwrap();
        assert_finite(&img, "scaled");
        let scaled: Vec<f32> = st0.distance.iter().map(|d| d * scale).collect();
        worst_d = worst_d.max(worst(&st.distance, &scaled, 0.0));
        worst_s = worst_s.max(worst(&st.matte, &st0.matte, 1e-3));
        worst_s = worst_s.max(worst(&cpu.matte, &st0.matte, 1e-3));
        assert!(max_rel_diff(&img, &img0) < 1e-4);
    }
    eprintln!("scaled D within {worst_d:e}, S within {worst_s:e}");
    // Measured: D within 6.1e-6 (relative; the scaled positions round differently), S within
    // 3.0e-6: bounds 2e-5 and 1e-5.
    assert!(worst_d < 2e-5, "{worst_d}");
    assert!(worst_s < 1e-5, "{worst_s}");
    let tiny: Vec<f32> = (0..20).map(|k| 5e-6 + k as f32 * 1e-5).collect();
    assert!(!distance::naive(&tiny).is_finite() || distance::naive(&tiny) == 0.0);
}

#[test]
fn no_contour_gives_one_or_b_never_nan() {
    let s = StylizedSettings {
        inflation: [0.1, 0.0, 0.0],
        softness: [0.0, 0.0, 0.0],
        brightness: [0.25, 0.0, 0.0],
        abstraction: [3.0, 0.0, 0.0],
        ..Default::default()
    };
    let none = |_: u32, _: u32| false;
    for (lit, want) in [(true, 1.0f32), (false, 0.25)] {
        let f = plane_frame(16, 12, 0.1, &move |_, _| lit, &none);
        let (img, st) = device(&f, &s);
        assert_eq!(st.contour_points, 0);
        assert!(st.matte.iter().all(|&v| v == want), "lit {lit}");
        assert_finite(&img, "no contour");
        let cpu = reference(&f, &s).unwrap();
        assert!(cpu.matte.iter().all(|&v| v == want));
    }
}

#[test]
fn the_normal_rule_keeps_a_wall_out_of_the_floor_shadow() {
    // Columns 24.. are a wall (normal +x), lit; the floor (columns < 24) has the notched disc.
    // With a large inflation the floor's shadow grows, but the wall, whose normal is 90° from
    // every contour point's, keeps S = 1 (D = +∞), and the blur does not mix the two.
    let s = StylizedSettings {
        inflation: [0.5, 0.0, 0.0],
        abstraction: [3.0, 0.0, 0.0],
        ..Default::default()
    };
    let wall = |x: u32, _: u32| x >= 24;
    let lit = move |x: u32, y: u32| x >= 24 || notched_disc(x, y);
    let f = plane_frame(48, 40, 0.01, &lit, &wall);
    let (_, st) = device(&f, &s);
    for y in 0..40 {
        for x in 0..48 {
            let k = (y * 48 + x) as usize;
            if x >= 24 {
                assert_eq!(st.distance[k], f32::INFINITY);
                assert_eq!(st.matte[k], 1.0, "wall pixel ({x}, {y})");
            }
        }
    }
    // The floor's shadow did grow: more shadowed pixels than V has.
    let hard = (0..48 * 40).filter(|&k| !lit(k % 48, k / 48)).count();
    let styled = st.matte.iter().filter(|&&v| v < 0.5).count();
    assert!(styled > hard, "{styled} <= {hard}");
}

#[test]
fn blur_of_a_constant_is_the_constant_and_alpha_zero_is_a_no_op() {
    let none = |_: u32, _: u32| false;
    let f = plane_frame(32, 24, 0.1, &|_, _| true, &none);
    let px = pixels(&f);
    let occ = vec![0.0f32; px.len()];
    let c = Controls {
        abstraction: [4.0, 0.0, 0.0],
        ..Default::default()
    };
    let stencil = blur::stencil(0, 64);
    for value in [0.37f32, -2.5, 1e4] {
        let input = vec![value; px.len()];
        let out = blur::pass(px, &c, &occ, &stencil, &input, 32, 24, 0.7, 4.0);
        let w = out
            .iter()
            .map(|v| (v - value).abs() / value.abs())
            .fold(0f32, f32::max);
        // A mean of 64 equal floats: within a few ulp (measured 5.6e-7).
        assert!(w < 1e-6, "{w}");
    }
    let input: Vec<f32> = (0..px.len()).map(|k| k as f32 * 0.01).collect();
    let zero = Controls::default();
    assert_eq!(
        blur::pass(px, &zero, &occ, &stencil, &input, 32, 24, 0.7, 4.0),
        input
    );
}

#[test]
fn two_passes_of_alpha_over_root_two_have_the_variance_of_one_pass_of_alpha() {
    // §3.3.3: "two 2-d convolutions of √(1/2) the width" equal one of the full width. The two
    // stencils' second moments (per axis, unit σ) add: 2 · (α/√2)² · m = α² · m, with m the
    // truncated Gaussian's per-axis variance, 1 − 4.5 e^-4.5 / (1 − e^-4.5) = 0.9494.
    let m = 1.0 - 4.5 * (-4.5f64).exp() / (1.0 - (-4.5f64).exp());
    for pass in 0..2u32 {
        let st = blur::stencil(pass * 64, 64);
        let (mut sx, mut sy, mut mx, mut my) = (0f64, 0f64, 0f64, 0f64);
        for o in &st {
            let (x, y) = (o.0[0] as f64, o.0[1] as f64);
            mx += x / 64.0;
            my += y / 64.0;
            sx += x * x / 64.0;
            sy += y * y / 64.0;
            assert!(x * x + y * y <= 9.0 + 1e-5);
        }
        eprintln!("pass {pass}: mean ({mx:.3}, {my:.3}), variance ({sx:.3}, {sy:.3}), want {m:.4}");
        // Measured within 0.045 of m and means within 0.04 of 0 (64 Halton points); bounds
        // 0.08 and 0.05.

        assert!((sx - m).abs() < 0.08 && (sy - m).abs() < 0.08);
        assert!(mx.abs() < 0.05 && my.abs() < 0.05);
    }
}

#[test]
fn distance_error_falls_with_more_contour_samples() {
    // The Fig. 3.10 trend: the stratified estimate of D against the exact one (every point)
    // on the grids' shadow, RMS relative error at N and 4N samples.
    let exact = StylizedSettings {
        contour_samples: 1 << 16,
        ..Default::default()
    };
    let frame = grids_frame(&exact);
    let want = reference(&frame, &exact).unwrap().distance;
    let rms = |n: u32| {
        let s = StylizedSettings {
            contour_samples: n,
            ..Default::default()
        };
        let got = reference(&frame, &s).unwrap().distance;
        let (mut sum, mut count) = (0f64, 0);
        for (a, b) in got.iter().zip(&want) {
            if a.is_finite() && b.is_finite() {
                sum += ((a - b) / b) as f64 * ((a - b) / b) as f64;
                count += 1;
            }
        }
        (sum / count as f64).sqrt()
    };
    let (e16, e64, e256) = (rms(16), rms(64), rms(256));
    eprintln!("RMS relative error of D: N=16 {e16:.4}, 64 {e64:.4}, 256 {e256:.4}");
    // Measured 3.47, 1.61, 0.64 (478 contour points): about halved per 4× samples, 1/√N;
    // bound: each 4× at least 1.6× smaller.
    assert!(e64 * 1.6 < e16 && e256 * 1.6 < e64);
}

#[test]
fn a_lit_object_in_front_of_a_shadow_keeps_its_s() {
    // Digest §1.7 item 5: the floor (z = 0, spacing 0.01) is shadowed left of column 30 and
    // lit right of it; a lit bar floats 0.2 above it over rows 18-22, crossing the shadow.
    // The pairs across the bar's silhouette differ in V but are 0.2 apart along the normal
    // (20 footprints): no contour points there, so the only contour is the floor's line; the
    // bar, 0.2 or more from it, stays lit under an inflation of 0.1, and the blur does not
    // take the floor's D across the silhouette: its S = 1 everywhere.
    let (w, h) = (48, 40);
    let bar = |y: u32| (18..=22).contains(&y);
    let none = |_: u32, _: u32| false;
    let mut px = plane_pixels(w, h, 0.01, &move |x, y| x >= 30 || bar(y), &none);
    for (i, p) in px.iter_mut().enumerate() {
        if bar(i as u32 / w) {
            p.position[2] = 0.2;
        }
    }
    let f = shadow_frame(w, h, px);
    let s = StylizedSettings {
        inflation: [0.1, 0.0, 0.0],
        abstraction: [2.0, 0.0, 0.0],
        ..Default::default()
    };
    let (_, st) = device(&f, &s);
    // The floor's line at column 29|30 on the 35 rows the bar does not cover.
    assert_eq!(st.contour_points, 35);
    for y in 18..=22u32 {
        for x in 0..w {
            assert_eq!(st.matte[(y * w + x) as usize], 1.0, "bar pixel ({x}, {y})");
        }
    }
    // Without the gap test the silhouette pairs become contour points floating at z = 0.1:
    // 2 rows of 30 more, and the floor shadow beside the bar would be measured from them.
    let loose = StylizedSettings {
        surface_gap: 1e9,
        ..s.clone()
    };
    let (_, st) = device(&f, &loose);
    assert_eq!(st.contour_points, 35 + 60);
}

#[test]
fn l8_distance_has_no_cusp_on_the_medial_axis() {
    // Digest §1.7 item 3: between two parallel contour lines (x = 0 and x = 2, length 100)
    // the Euclidean distance min(x, 2 − x) has a kink at x = 1 (second difference / h² =
    // −2/h); the L8-averaged D is smooth there.
    let mut contour = line_contour(100.0, 0.05);
    contour.extend(
        line_contour(100.0, 0.05)
            .chunks_exact(2)
            .flat_map(|p| [Float4([2.0, p[0].0[1], 0.0, 1.0]), p[1]]),
    );
    let s = distance::Sampling::new((contour.len() / 2) as u32, 1 << 16, 1, 0.7);
    let d = |x: f32| distance::at(Vec3::new(x, 0.0, 0.0), Vec3::Z, true, 0.0, &contour, &s, 0).0;
    // A smooth D has second differences that converge as h shrinks; a kink's grow as 1/h.
    let second = |h: f32| (d(1.0 - h) - 2.0 * d(1.0) + d(1.0 + h)) / (h * h);
    let (a, b, c) = (second(0.2), second(0.1), second(0.05));
    let slope = (d(1.05) - d(0.95)) / 0.1;
    eprintln!("second differences at h = 0.2, 0.1, 0.05: {a}, {b}, {c}; slope {slope}");
    // Measured: slope 1.2e-6 (symmetric); second differences -9.74, -11.57, -12.23: they
    // converge (ratios 1.19, 1.06, shrinking), where the Euclidean distance's double (ratio
    // 2) each time h halves; bounds: |slope| < 1e-4, ratios below 1.25 and 1.1.
    assert!(slope.abs() < 1e-4, "{slope}");
    assert!(b / a < 1.25 && c / b < 1.1 && c / b < b / a, "{a} {b} {c}");
}
