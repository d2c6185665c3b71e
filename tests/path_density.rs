//! The path-density outlier filter (DeCoro 2009 ch. 5; src/filters/path_density/): the kernels
//! against the plain Rust reference on PoCL, the ring scan against brute-force kNN, the
//! stability cases (every sample rejected, one sample, non-finite samples, a constant image,
//! a firefly, a dense highlight, two colour modes, a coloured grid). On rendered scenes:
//! tests/path_density_scenes.rs.

mod common;

use common::*;
use noisefree::filters::path_density::{
    ColorSpace, DensityMode, FilmSamples, PathDensityKernel, PathDensityParams,
    PathDensitySettings, reference,
};
use noisefree::filters::trimmed::trimmed_mean;
use noisefree::imaging::RgbImage;
use noisefree::layout::SampleVector;
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::render::{Frame, FrameInfo, HostBuffer, SceneInfo, VarianceForm};

fn params(k: u32) -> PathDensityParams {
    PathDensitySettings {
        k,
        ..Default::default()
    }
    .params()
}

/// A frame holding only these samples (pixel-major, `spp` per pixel); non-finite colours
/// allowed (a samples file refuses them, a live buffer could hold them).
fn frame_of(s: &FilmSamples) -> Frame {
    let vectors: Vec<SampleVector> =
        s.xy.iter()
            .zip(&s.rgb)
            .map(|(xy, c)| SampleVector {
                position: *xy,
                color: *c,
                ..Default::default()
            })
            .collect();
    Frame::on_host(
        FrameInfo {
            width: s.width,
            height: s.height,
            spp: s.spp,
            sample_capacity: s.spp,
            shadow_lights: Vec::new(),
            scene: SceneInfo::unknown(),
        },
        OutputSet::of(&[Output::Samples]),
        VarianceForm::Variances,
        vec![(BufferId::SampleVectors, HostBuffer::from_slice(&vectors))],
    )
    .unwrap()
}

/// A small counter-based hash in [0, 1) for synthetic samples.
fn hash01(i: u32, d: u32) -> f32 {
    let mut h = i.wrapping_mul(0x9E37_79B9) ^ d.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^= h >> 16;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Samples jittered inside their pixels with colours from `colour(pixel x, y, sample, i)`.
fn samples(
    w: u32,
    h: u32,
    spp: u32,
    colour: impl Fn(u32, u32, u32, u32) -> [f32; 3],
) -> FilmSamples {
    let (mut xy, mut rgb) = (Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            for s in 0..spp {
                let i = (y * w + x) * spp + s;
                xy.push([x as f32 + hash01(i, 0), y as f32 + hash01(i, 1)]);
                rgb.push(colour(x, y, s, i));
            }
        }
    }
    FilmSamples {
        width: w,
        height: h,
        spp,
        xy,
        rgb,
    }
}

/// Noisy grey with a few fireflies: every stage of the filter sees work.
fn noisy(w: u32, h: u32, spp: u32) -> FilmSamples {
    samples(w, h, spp, |_, _, _, i| {
        let v = 0.2 + 0.3 * hash01(i, 2);
        if hash01(i, 3) < 0.01 {
            [40.0 * v, 30.0 * v, 20.0 * v]
        } else {
            [v, 0.9 * v, 0.8 * v]
        }
    })
}

fn run_device(s: &FilmSamples, p: PathDensityParams) -> (RgbImage, reference::Densities) {
    let mut k = PathDensityKernel::new(gpu(), p).unwrap();
    let out = k.run(&frame_of(s)).unwrap();
    (out.image, k.densities().unwrap())
}

fn max_rel(a: f32, b: f32) -> f32 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}

#[test]
fn ring_scan_is_exact_knn() {
    // The ring scan with its early stop finds the same k nearest as a scan of every sample of
    // the image (or of the frame group), for the seed's k and at the borders. Same float
    // operations in the same order: equal bits.
    let s = noisy(9, 7, 6);
    for (k, frame_spp) in [
        (1, u32::MAX),
        (10, u32::MAX),
        (50, u32::MAX),
        (10, 2),
        (50, 1),
    ] {
        let p = PathDensityParams {
            frame_spp,
            ..params(k)
        }
        .for_spp(s.spp);
        let d = reference::densities(&s, &p);
        for i in 0..s.len() {
            assert_eq!(
                d.sigma[i].to_bits(),
                reference::brute_force_sigma(&s, &p, i).to_bits(),
                "k {k}, frame_spp {frame_spp}, sample {i}"
            );
        }
    }
}

#[test]
fn epsilon_approximate_sigma_is_within_one_plus_epsilon_of_the_exact() {
    // Every held j-th distance is ≥ the true j-th (a subset's) and < (1 + ε) times it, so the
    // sums are too: σ_exact ≤ σ_ε ≤ (1 + ε) σ_exact (float sums are monotone; the upper bound
    // gets 1e-6 relative for the rounding of (1 + ε) · sum against the sum of the products).
    let s = noisy(12, 10, 6);
    for (k, eps) in [(10, 0.5f32), (50, 0.5), (50, 2.0)] {
        let exact = reference::densities(&s, &params(k).for_spp(s.spp));
        let p = PathDensityParams {
            epsilon: eps,
            ..params(k)
        }
        .for_spp(s.spp);
        let approx = reference::densities(&s, &p);
        let mut differ = 0;
        for (a, e) in approx.sigma.iter().zip(&exact.sigma) {
            assert!(a >= e, "k {k} eps {eps}: {a} < {e}");
            assert!(
                *a <= (1.0 + eps) * e * (1.0 + 1e-6),
                "k {k} eps {eps}: {a} vs {e}"
            );
            differ += (a != e) as usize;
        }
        eprintln!("k {k} eps {eps}: {differ} of {} sigmas differ", s.len());
        assert!(
            differ > 0,
            "k {k} eps {eps}: the earlier stop changed nothing"
        );
        let (_, d) = run_device(&s, p);
        assert_eq!(d, approx, "k {k} eps {eps}: kernel against reference");
    }
}

#[test]
fn kernels_match_the_reference() {
    // A rendered frame (Cornell glossy: mirror and metal fireflies) and a synthetic one, in
    // both modes and for the seed's three k, and the RGB distance (PD_RGB).
    let scene = bundled_scene("cornell_glossy");
    let mut o = options(&scene, 24, 20, 3);
    o.outputs = OutputSet::of(&[Output::Samples]);
    o.sample_capacity = 8;
    let frame = render_frame(&scene, &o, 8);
    let set = noisefree::stats::samples::SampleSet::from_frame(&frame, Default::default()).unwrap();
    let rendered = FilmSamples::from_set(&set);
    for (s, name) in [
        (&rendered, "cornell_glossy"),
        (&noisy(16, 12, 5), "synthetic"),
    ] {
        for (k, mode, color_space) in [
            (10, DensityMode::Accumulated, ColorSpace::Cielab),
            (50, DensityMode::Accumulated, ColorSpace::Cielab),
            (200, DensityMode::Accumulated, ColorSpace::Cielab),
            (10, DensityMode::PerFrame, ColorSpace::Cielab),
            (10, DensityMode::Accumulated, ColorSpace::Rgb),
        ] {
            let settings = PathDensitySettings {
                k,
                mode,
                frame_spp: 2,
                color_space,
                ..Default::default()
            };
            let p = settings.params().for_spp(s.spp);
            let (ref_image, ref_d) = reference::filter(s, &p);
            let (image, d) = run_device(s, settings.params());
            let (mut sigma_err, mut weight_err, mut image_err) = (0.0f32, 0.0f32, 0.0f32);
            for i in 0..s.len() {
                sigma_err = sigma_err.max(max_rel(d.sigma[i], ref_d.sigma[i]));
                weight_err = weight_err.max((d.weight[i] - ref_d.weight[i]).abs());
            }
            for (a, b) in image.pixels.iter().zip(&ref_image.pixels) {
                for c in 0..3 {
                    image_err = image_err.max(max_rel(a[c], b[c]));
                }
            }
            eprintln!(
                "{name} k {k} {mode:?} {color_space:?}: sigma {sigma_err:e}, weight \
                 {weight_err:e}, image {image_err:e}"
            );
            // The same float operations in the same order: measured bit-identical on PoCL
            // (σ, weights and image all 0 difference), so the bound is 0. Only cbrt could
            // differ on another device (OpenCL allows it 2 ulps); such a device would need a
            // tolerance here.
            assert_eq!(sigma_err, 0.0, "{name} k {k} {mode:?}: sigma");
            assert_eq!(weight_err, 0.0, "{name} k {k} {mode:?}: weight");
            assert_eq!(image_err, 0.0, "{name} k {k} {mode:?}: image");
        }
    }
}

#[test]
fn a_constant_image_is_unchanged_and_a_firefly_is_removed() {
    // Constant colour, 8 spp; the channels have few mantissa bits so that the sums of equal
    // values are exact and the mean is the colour bit for bit (0.3 summed 8 times is not): every
    // σ is a mean of image distances below 2 pixels, every weight 1, every pixel the colour,
    // the borders (one-sided neighbourhoods) included.
    let c = [0.25f32, 0.5, 0.75];
    let flat = samples(12, 10, 8, |_, _, _, _| c);
    let (image, d) = run_device(&flat, params(10));
    assert!(d.weight.iter().all(|&w| w == 1.0));
    assert!(
        image.pixels.iter().all(|p| *p == c),
        "constant image changed"
    );
    // One firefly (1000x, L* ≈ 1000 against 56) in the middle: it alone is rejected, and the
    // image is the constant again; the plain mean of its pixel is 125x too bright.
    let fire = samples(12, 10, 8, |x, y, s, _| {
        if (x, y, s) == (6, 5, 3) {
            c.map(|v| 1000.0 * v)
        } else {
            c
        }
    });
    for k in [10, 50, 200] {
        let (image, d) = run_device(&fire, params(k));
        let firefly = (5 * 12 + 6) * 8 + 3;
        assert_eq!(d.weight[firefly], 0.0, "k {k}: sigma {}", d.sigma[firefly]);
        assert!(d.sigma[firefly] >= 3.0);
        let others = d.weight.iter().enumerate().filter(|(i, _)| *i != firefly);
        if k <= 50 {
            assert!(others.clone().all(|(_, &w)| w == 1.0), "k {k}");
            assert!(image.pixels.iter().all(|p| *p == c), "k {k}: firefly kept");
        } else {
            // k = 200 at 8 spp reaches ~3 pixels out (6 at the corners): the image term alone
            // takes σ past 2 and the border samples are down-weighted, all alike, so each
            // pixel is a weighted mean of equal colours: c up to rounding (measured 2 ulps,
            // 1.6e-7 relative, in the blue channel).
            let reduced = others.filter(|(_, w)| **w < 1.0).count();
            eprintln!(
                "k 200: {reduced} of {} samples down-weighted",
                d.weight.len()
            );
            for p in &image.pixels {
                for ch in 0..3 {
                    assert!((p[ch] - c[ch]).abs() <= 2.4e-7 * c[ch], "k {k}: {p:?}");
                }
            }
        }
    }
    let plain = reference::reconstruct(&fire, &vec![1.0; fire.len()], u32::MAX);
    assert!(plain.pixels[5 * 12 + 6][0] > 100.0 * c[0]);
}

#[test]
fn every_sample_rejected_falls_back_to_the_plain_mean_and_one_sample_is_kept() {
    // keep = reject = 0: every sample with σ > 0 is rejected. Each pixel is then the plain
    // mean of its samples, finite, exactly the reference's.
    let s = noisy(8, 6, 4);
    let p = PathDensityParams {
        keep: 0.0,
        reject: 0.0,
        ..params(10)
    };
    let (image, d) = run_device(&s, p);
    assert!(d.weight.iter().all(|&w| w == 0.0));
    let plain = reference::reconstruct(&s, &vec![1.0; s.len()], u32::MAX);
    for (a, b) in image.pixels.iter().zip(&plain.pixels) {
        assert!(a.iter().all(|v| v.is_finite()));
        for c in 0..3 {
            assert!(max_rel(a[c], b[c]) <= 1.2e-7, "{a:?} {b:?}");
        }
    }
    // The colour weight read as a product (ΔE · 20 instead of ΔE / 20, digest §3.2 item 1)
    // rejects almost everything in noise: measured 100 % of the samples of this image (grey
    // noise of ΔE ≈ 5-15 between neighbours); the divisor rejects 0.52 % (fireflies).
    let product = PathDensityParams {
        color_weight: 1.0 / 20.0,
        ..params(10)
    };
    let (_, d) = run_device(&s, product);
    eprintln!("product reading: rejected {:?}", d.fractions());
    assert!(d.fractions().0 > 0.95);
    let (_, d) = run_device(&s, params(10));
    eprintln!("divisor reading: rejected {:?}", d.fractions());
    assert!(d.fractions().0 < 0.01);
    // One sample in the whole image: no neighbour, σ = 0, kept; the pixel is the sample.
    let one = samples(1, 1, 1, |_, _, _, _| [5.0, 1.0, 0.5]);
    let (image, d) = run_device(&one, params(10));
    assert_eq!((d.sigma[0], d.weight[0]), (0.0, 1.0));
    assert_eq!(image.pixels[0], [5.0, 1.0, 0.5]);
    // k larger than the samples there are: σ over those there are, as brute force says.
    let few = noisy(2, 2, 3);
    let (_, d) = run_device(&few, params(200));
    let p = params(200).for_spp(3);
    for i in 0..few.len() {
        assert!(max_rel(d.sigma[i], reference::brute_force_sigma(&few, &p, i)) <= 1e-6);
    }
}

#[test]
fn non_finite_and_extreme_samples_stay_finite() {
    // NaN and ∞ samples are never neighbours and weigh 0; a pixel of only such samples is
    // black; 0, negative and 1e6 radiance give finite Lab.
    let s = samples(6, 5, 4, |x, y, s, _| match (x, y, s) {
        (1, 1, 0) => [f32::NAN, 0.5, 0.5],
        (1, 1, 1) => [f32::INFINITY, 0.5, 0.5],
        (2, 2, _) => [f32::NAN; 3],
        (3, 3, 0) => [1e6, 1e6, 1e6],
        (3, 3, 1) => [-0.2, 0.0, 0.0],
        (3, 3, 2) => [0.0; 3],
        _ => [0.5, 0.5, 0.5],
    });
    for c in [
        [1e6f32, 1e6, 1e6],
        [-0.2, 0.0, 0.0],
        [0.0; 3],
        [1e30, 0.0, 0.0],
    ] {
        assert!(reference::lab(c).is_some(), "{c:?}");
    }
    // Z = 1.089 · f32::MAX overflows to ∞: such a sample is left out like a NaN.
    assert!(reference::lab([f32::MAX; 3]).is_none(), "overflows to ∞");
    let (image, d) = run_device(&s, params(10));
    assert!(image.pixels.iter().flatten().all(|v| v.is_finite()));
    assert_eq!(image.pixels[2 * 6 + 2], [0.0; 3]);
    assert_eq!(d.weight[(6 + 1) * 4], 0.0);
    assert_eq!(
        image.pixels[6 + 1],
        [0.5; 3],
        "the NaN and ∞ samples left out"
    );
    let (ref_image, _) = reference::filter(&s, &params(10).for_spp(4));
    assert_eq!(image, ref_image);
}

#[test]
fn dense_highlights_and_two_colour_modes_survive_where_a_trimmed_mean_fails() {
    // A 4 x 4 block of bright samples (a highlight, 50x the background) at 16 spp is dense:
    // every sample is kept, in the block and out.
    let hl = samples(12, 12, 16, |x, y, _, _| {
        if (4..8).contains(&x) && (4..8).contains(&y) {
            [50.0, 45.0, 40.0]
        } else {
            [0.5, 0.45, 0.4]
        }
    });
    let (image, d) = run_device(&hl, params(10));
    assert!(d.weight.iter().all(|&w| w == 1.0));
    assert_eq!(image.pixels[5 * 12 + 5], [50.0, 45.0, 40.0]);
    // The seed's Fig. 5.5: a large yellow light and a small, brighter blue one seen in
    // reflections: 80% yellow and 20% bright blue samples everywhere. Both are dense, both
    // are kept and the mean colour is the plain mean's; the 10%-trimmed mean drops blue
    // samples (by luminance, the blue ones are... the dimmest here) and shifts the colour.
    let (yellow, blue) = ([1.0f32, 0.9, 0.1], [0.2f32, 0.3, 4.0]);
    let two = samples(
        10,
        10,
        10,
        |_, _, s, _| if s % 5 == 0 { blue } else { yellow },
    );
    let (image, d) = run_device(&two, params(10));
    assert!(d.weight.iter().all(|&w| w == 1.0));
    let mean: [f32; 3] = std::array::from_fn(|c| 0.8 * yellow[c] + 0.2 * blue[c]);
    for p in &image.pixels {
        for c in 0..3 {
            assert!((p[c] - mean[c]).abs() <= 1e-6 * mean[c].max(1.0), "{p:?}");
        }
    }
    let pixel: Vec<[f32; 3]> = two.rgb[..10].to_vec();
    let trimmed = trimmed_mean(&pixel, 0.1);
    assert!(
        (trimmed[2] - mean[2]).abs() > 0.1 * mean[2],
        "the trimmed mean keeps the blue: {trimmed:?}"
    );
}

#[test]
fn a_coloured_grid_keeps_its_black_lines() {
    // The seed's Fig. 5.9: coloured cells between black lines one pixel wide. In CIELAB the
    // line's samples have each other (and their pixel's) as neighbours and the cells' samples
    // theirs, so nothing is rejected and every pixel keeps its colour: the lines neither grow
    // nor shrink. (With noisy cells an RGB metric grows them: tests/path_density_scenes.rs.)
    let cell = |x: u32, y: u32| -> [f32; 3] {
        if x.is_multiple_of(6) || y.is_multiple_of(6) {
            [0.0; 3]
        } else {
            match (x / 6 + y / 6) % 3 {
                0 => [0.8, 0.1, 0.1],
                1 => [0.1, 0.6, 0.1],
                _ => [0.1, 0.1, 0.9],
            }
        }
    };
    let grid = samples(25, 19, 8, |x, y, _, _| cell(x, y));
    let (image, d) = run_device(&grid, params(10));
    assert!(d.weight.iter().all(|&w| w == 1.0), "{:?}", d.fractions());
    for y in 0..19 {
        for x in 0..25 {
            let (p, c) = (image.pixels[(y * 25 + x) as usize], cell(x, y));
            for ch in 0..3 {
                // 8 equal values summed: exact for 0, within an ulp or two for the others.
                assert!(
                    (p[ch] - c[ch]).abs() <= 2.4e-7 * c[ch],
                    "({x}, {y}): {p:?} {c:?}"
                );
            }
        }
    }
}

/// One prepared kernel filters frame after frame (the viewer's use): its buffers, kept from
/// run to run and reused for fewer samples, give the bytes and densities of a fresh kernel's.
#[test]
fn a_kernel_reused_across_frames_gives_a_fresh_kernels_bytes() {
    let p = params(10);
    let mut k = PathDensityKernel::new(gpu(), p).unwrap();
    for (w, h, spp) in [(12, 9, 8), (12, 9, 3), (12, 9, 8), (7, 5, 6)] {
        let s = noisy(w, h, spp);
        let out = k.run(&frame_of(&s)).unwrap();
        let (image, densities) = run_device(&s, p);
        assert_eq!(out.image.pixels, image.pixels, "{w}x{h}, {spp} spp");
        let d = k.densities().unwrap();
        assert_eq!(d.sigma.len(), (w * h * spp) as usize);
        assert_eq!((d.sigma, d.weight), (densities.sigma, densities.weight));
    }
}
