//! The roofline study's parts (src/bench/roofline/): the micro-kernels against their Rust
//! references, and the work models' tap counts against a brute-force walk of the kernels'
//! loops. Timings are never asserted.

mod common;

use noisefree::bench::roofline::models;
use noisefree::bench::roofline::peaks::{self, Op};
use noisefree::layout::{FilterVector, SKY_DEPTH};

#[test]
fn fma_chains_match_the_reference_bit_for_bit() {
    let gpu = common::gpu();
    for lanes in [1, 16] {
        let (n, iterations) = (300, 257);
        let (got, _) = peaks::chains(&gpu, Op::Fma, lanes, n, iterations).unwrap();
        assert_eq!(
            got,
            peaks::reference_chains(Op::Fma, lanes, n, iterations),
            "{lanes}"
        );
    }
}

#[test]
fn exp_chains_match_the_reference() {
    let gpu = common::gpu();
    for lanes in [1, 16] {
        let (n, iterations) = (300, 257);
        let (got, _) = peaks::chains(&gpu, Op::Exp, lanes, n, iterations).unwrap();
        let want = peaks::reference_chains(Op::Exp, lanes, n, iterations);
        // OpenCL's exp may differ from Rust's by a few ulp; the chain x -> exp(-x) damps
        // errors (|derivative| 0.57 at its fixed point), so they do not grow with the
        // iterations. Measured on PoCL 3.1: 0 (the same bits); the bound, about 8 ulp, is for
        // devices whose exp is not correctly rounded (OpenCL allows 3 ulp per call).
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| ((a - b) / b).abs())
            .fold(0f32, f32::max);
        eprintln!("exp chains of {lanes}: worst relative difference {worst:e}");
        assert!(
            worst < 1e-6,
            "{lanes} lanes: worst relative difference {worst}"
        );
        // The fixed point: every chain at the omega constant 0.5671433.
        let omega = (8 * lanes) as f32 * 0.567_143_3;
        assert!((want[0] - omega).abs() < 1e-5 * omega, "{}", want[0]);
    }
}

#[test]
fn triad_matches_the_reference_bit_for_bit() {
    let gpu = common::gpu();
    let triad = peaks::Triad::new(&gpu, 5000).unwrap();
    triad.run().unwrap();
    let got: Vec<[f32; 4]> = triad.result().unwrap().iter().map(|v| v.0).collect();
    let want: Vec<[f32; 4]> = peaks::reference_triad(5000).iter().map(|v| v.0).collect();
    assert_eq!(got, want);
}

/// A w x h frame whose pixels in `sky` columns are sky.
fn frame(w: u32, h: u32, sky: impl Fn(u32, u32) -> bool) -> Vec<FilterVector> {
    (0..w * h)
        .map(|i| FilterVector {
            depth: if sky(i % w, i / w) { SKY_DEPTH } else { 1.0 },
            ..Default::default()
        })
        .collect()
}

/// The data-driven filter's loops (kernels/filters/ddf.cl), walked one tap at a time.
fn ddf_taps_brute(fv: &[FilterVector], w: i64, h: i64, half: i64, step: i64, sky: bool) -> u64 {
    let mut taps = 0;
    for y in 0..h {
        for x in 0..w {
            if sky && fv[(y * w + x) as usize].depth >= SKY_DEPTH {
                continue;
            }
            let mut dy = -half;
            while dy <= half {
                let mut dx = -half;
                while dx <= half {
                    if (0..h).contains(&(y + dy)) && (0..w).contains(&(x + dx)) {
                        taps += 1;
                    }
                    dx += step;
                }
                dy += step;
            }
            if half % step != 0 {
                taps += 1;
            }
        }
    }
    taps
}

#[test]
fn ddf_tap_counts_match_the_kernel_loops() {
    let (w, h) = (37u32, 23u32);
    let fv = frame(w, h, |x, y| x < 5 && y > 10);
    for (half, step, sky) in [
        (10, 1, true),
        (10, 1, false),
        (10, 2, true),
        (5, 2, true),
        (1, 1, true),
    ] {
        let got = models::ddf_work(&fv, w, h, half, step, sky, 0.0);
        let want = ddf_taps_brute(&fv, w as i64, h as i64, half as i64, step as i64, sky);
        assert_eq!(got.taps, want, "half {half} step {step} sky {sky}");
        assert_eq!(got.exps, 2.0 * want as f64);
    }
    // Sky pixels copied: 5 x 12 of them, 80 bytes each; the others 144.
    let work = models::ddf_work(&fv, w, h, 10, 1, true, 0.0);
    assert_eq!(work.bytes, 60.0 * 80.0 + (w * h - 60) as f64 * 144.0);
}

#[test]
fn atrous_tap_counts_match_the_kernel_loops() {
    let (w, h) = (41u32, 29u32);
    let fv = frame(w, h, |x, y| (x + 2 * y) % 7 == 0);
    let (wi, hi) = (w as i64, h as i64);
    let surface = |x: i64, y: i64| fv[(y * wi + x) as usize].depth < SKY_DEPTH;
    let mut want = 0u64;
    for i in 0..5 {
        let step = 1i64 << i;
        for y in 0..hi {
            for x in 0..wi {
                if !surface(x, y) {
                    continue;
                }
                for ky in 0..5 {
                    for kx in 0..5 {
                        let (nx, ny) = (x + (kx - 2) * step, y + (ky - 2) * step);
                        if (0..wi).contains(&nx) && (0..hi).contains(&ny) && surface(nx, ny) {
                            want += 1;
                        }
                    }
                }
            }
        }
    }
    let got = models::atrous_work(&fv, w, h, 5);
    assert_eq!(got.taps, want);
    assert_eq!(got.exps, want as f64);
}

/// bmfr's models: the non-local means' (pixel, offset) pairs (the frame's window for every
/// pixel of a class, the halves' smaller one twice) and the selection's window positions,
/// against a walk of every window over an image that is no multiple of anything.
#[test]
fn bmfr_counts_match_a_walk_of_the_windows() {
    let (w, h) = (37i64, 23i64);
    let classes: Vec<f32> = (0..w * h)
        .map(|i| [0.0, 1.0, 2.0][(i * 7 % 5 % 3) as usize])
        .collect();
    let shape = models::BmfrShape {
        features: 10,
        block: 16,
        grids: 4,
        nlm_radius: 5,
        estimate_radius: 3,
        select_radius: 4,
        nlm_patch: 2,
    };
    let window = |x: i64, y: i64, r: i64| -> u64 {
        let mut k = 0;
        for dy in -r..=r {
            for dx in -r..=r {
                if (0..w).contains(&(x + dx)) && (0..h).contains(&(y + dy)) {
                    k += 1;
                }
            }
        }
        k
    };
    let (mut nlm, mut select) = (0u64, 0u64);
    for y in 0..h {
        for x in 0..w {
            select += window(x, y, 4);
            if classes[(y * w + x) as usize] != 0.0 {
                nlm += window(x, y, 5) + 2 * window(x, y, 3);
            }
        }
    }
    let got = models::bmfr_nlm_work(&classes, w as u32, h as u32, &shape);
    assert_eq!(got.taps, nlm);
    assert_eq!(got.exps, nlm as f64);
    assert_eq!(
        models::bmfr_select_work(w as u32, h as u32, &shape).taps,
        select
    );
}

/// Stylized shadows' distance step: pass 1 over the matte's pixels (a unit normal), pass 2
/// over those whose D came out finite, each over min(points, contour_samples) samples, the
/// draw's flops only when the samples are a subset of the contour.
#[test]
fn stylized_distance_counts_the_matte_and_the_summed_pixels() {
    use noisefree::layout::ShadowPixel;
    let matte = ShadowPixel {
        normal: [0.0, 0.0, 1.0],
        ..Default::default()
    };
    // Two pixels of the matte (one with a contour point on its side, one without: D = -inf)
    // and two outside it (D = +inf).
    let pixels = [matte, ShadowPixel::default(), matte, ShadowPixel::default()];
    let distance = [0.5, f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY];
    for (points, samples, draw) in [(100, 100, 0.0), (3000, 1024, models::ST_DRAW_FLOPS)] {
        let got = models::stylized_distance_work(&pixels, &distance, points, 1024);
        assert_eq!(got.taps, 3 * samples, "{points} points");
        let want = (2 * samples) as f64 * (models::ST_PASS1_SAMPLE_FLOPS + draw)
            + samples as f64 * models::ST_PASS2_SAMPLE_FLOPS
            + models::ST_PIXEL_FLOPS;
        assert_eq!(got.flops, want, "{points} points");
        assert_eq!(got.exps, 0.0);
    }
}
