//! Random Parameter Filtering (thesis ch. 5) on synthetic sample sets: mutual information,
//! the weights, the behaviour the equations promise (constant images, no NaN, determinism,
//! degenerate neighbourhoods), denoising with a clean edge, the scale experiment of Table 5.4,
//! and the `samples.bin` file format. No device needed.

mod common;

use std::io::Cursor;

use common::{assert_finite, tempdir};
use noisefree::filters::Auto;
use noisefree::filters::rpf::mi::{entropy, mutual_information};
use noisefree::filters::rpf::samples::{self, HEADER_BYTES, MAGIC, to_floats};
use noisefree::filters::rpf::weights::{Dependencies, weights};
use noisefree::filters::rpf::{self, RangeColors, RpfSettings, SampleSet, analyze_pixel, filter};
use noisefree::imaging::RgbImage;
use noisefree::layout::SampleVector;
use noisefree::render::SceneInfo;
use noisefree::scene::Setting;
use noisefree::stats::RenderRecord;

/// A small counter-based generator for the synthetic scenes.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x1234_5678)
    }
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }
}

const ALBEDO_LEFT: [f32; 3] = [0.2, 0.3, 0.25];
const ALBEDO_RIGHT: [f32; 3] = [0.8, 0.7, 0.75];

/// A textured plane seen head-on, lit so that a sample's colour is albedo · L with L = 3 when
/// the first-bounce direction is within ~35° of the normal and 0 otherwise (mean 1): the noise
/// depends on the random parameters only. The albedo ("texture") has a clean vertical edge in
/// the middle of the image, on a pixel boundary. World units are `pixel_size` per pixel times
/// `scale`. Returns the samples and the clean image (albedo · 1).
fn textured_plane(
    w: u32,
    h: u32,
    spp: u32,
    seed: u64,
    pixel_size: f32,
    scale: f32,
) -> (SampleSet, RgbImage) {
    let mut samples = Vec::with_capacity((w * h * spp) as usize);
    let mut rng = Rng::new(seed);
    let mut clean = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let albedo = if x < w / 2 { ALBEDO_LEFT } else { ALBEDO_RIGHT };
            clean.push(albedo);
            for _ in 0..spp {
                let (jx, jy) = (rng.next(), rng.next());
                let (u, v) = (rng.next(), rng.next());
                let (r1, r2) = (rng.next(), rng.next());
                let phi = 2.0 * std::f32::consts::PI * r1;
                let cos_t = (1.0 - r2).sqrt();
                let sin_t = r2.sqrt();
                let dir = [phi.cos() * sin_t, phi.sin() * sin_t, cos_t];
                let light = if r2 < 1.0 / 3.0 { 3.0 } else { 0.0 };
                let px = (x as f32 + jx) * pixel_size;
                let py = (y as f32 + jy) * pixel_size;
                let world1 = [px * scale, py * scale, 10.0 * pixel_size * scale];
                let hit2 = 4.0 * pixel_size * (1.0 + r1);
                let world2 = std::array::from_fn(|k| world1[k] + dir[k] * hit2 * scale);
                samples.push(SampleVector {
                    position: [x as f32 + jx, y as f32 + jy],
                    random: [u, v, 0.0, dir[0], dir[1], dir[2]],
                    world1,
                    normal1: [0.0, 0.0, 1.0],
                    world2,
                    normal2: [-dir[0], -dir[1], -dir[2]],
                    texture1: albedo,
                    color: albedo.map(|a| a * light),
                });
            }
        }
    }
    let set = SampleSet::new(w, h, spp, samples).unwrap();
    let clean = RgbImage {
        width: w,
        height: h,
        pixels: clean,
    };
    (set, clean)
}

/// The box-filtered input (what the renderer would show unfiltered).
fn unfiltered(set: &SampleSet) -> RgbImage {
    let spp = set.spp as usize;
    RgbImage {
        width: set.width,
        height: set.height,
        pixels: set
            .samples
            .chunks(spp)
            .map(|c| {
                std::array::from_fn(|k| c.iter().map(|s| s.color[k] as f64).sum::<f64>() as f32)
                    .map(|v: f32| v / spp as f32)
            })
            .collect(),
    }
}

fn mse(a: &RgbImage, b: &RgbImage) -> f64 {
    noisefree::metrics::mse_rgb(a, b).unwrap()
}

fn fast(boxes: &[u32]) -> RpfSettings {
    RpfSettings {
        box_sizes: boxes.to_vec(),
        ..Default::default()
    }
}

fn uniforms(n: usize, seed: u64) -> Vec<f32> {
    let mut r = Rng::new(seed);
    (0..n).map(|_| r.next()).collect()
}

// ---------------------------------------------------------------------------------------------
// Mutual information (eq. 5.3, Alg. 7)
// ---------------------------------------------------------------------------------------------

#[test]
fn mutual_information_of_independent_uniform_variables_is_close_to_zero() {
    let x = uniforms(20_000, 1);
    let y = uniforms(20_000, 2);
    let mi = mutual_information(&x, &y, 5);
    // Histogram bias ≈ (B − 1)² / (2 n ln 2) ≈ 0.0006 bits; measured 0.00055. Bound 0.002.
    assert!(mi < 0.002, "μ = {mi} bits");
    assert!(mi >= 0.0);
    // Against a dependent pair, for scale (measured 1.77 bits of the 2.32 possible).
    let z: Vec<f32> = x.iter().zip(&y).map(|(a, b)| a + 0.1 * b).collect();
    assert!(mutual_information(&x, &z, 5) > 1.5);
}

#[test]
fn mutual_information_of_a_variable_with_itself_is_its_entropy() {
    let x = uniforms(20_000, 3);
    let h = entropy(&x, 5);
    // Measured 0.0002 below log2 5 (the bias is about (B − 1) / (2 n ln 2) = 0.00014);
    // bound 0.002.
    assert!((h - 5f64.log2()).abs() < 0.002, "H = {h}");
    assert!((mutual_information(&x, &x, 5) - h).abs() < 1e-12);
    // A skewed variable too, and other bucket counts.
    let skewed: Vec<f32> = x.iter().map(|v| v * v * v).collect();
    for b in [2, 5, 8, 16] {
        let h = entropy(&skewed, b);
        assert!(h > 0.0 && h < (b as f64).log2());
        assert!((mutual_information(&skewed, &skewed, b) - h).abs() < 1e-12);
    }
}

#[test]
fn mutual_information_with_one_populated_bucket_is_zero() {
    let x = uniforms(100, 4);
    let c = vec![0.5f32; 100];
    assert_eq!(entropy(&c, 5), 0.0);
    assert_eq!(mutual_information(&x, &c, 5), 0.0);
    assert_eq!(mutual_information(&c, &c, 5), 0.0);
    assert_eq!(mutual_information(&[], &[], 5), 0.0);
}

// ---------------------------------------------------------------------------------------------
// α and β (eqs. 5.8-5.14)
// ---------------------------------------------------------------------------------------------

fn check_weights_in_unit_interval(w: &rpf::Weights, what: &str) {
    let all = w
        .alpha
        .iter()
        .chain(&w.beta)
        .chain(&w.w_r_ck)
        .chain(&w.w_c_fk)
        .chain(&w.w_r_fk)
        .chain(std::iter::once(&w.w_r_c));
    for v in all {
        assert!((0.0..=1.0).contains(v), "{what}: {w:?}");
    }
    let sum_beta: f32 = w.beta.iter().sum();
    assert!(sum_beta <= 1.0 + 1e-5, "{what}: Σβ = {sum_beta}");
}

#[test]
fn alpha_and_beta_are_always_in_unit_interval() {
    let mut r = Rng::new(5);
    let magnitudes = [0.0, 1e-300, 1e-12, 0.01, 1.0, 2.3, 1e6, 1e300];
    for case in 0..2000 {
        let mut pick = || {
            let m = magnitudes[(r.next() * magnitudes.len() as f32) as usize % magnitudes.len()];
            if case % 3 == 0 {
                m
            } else {
                m * r.next() as f64
            }
        };
        let mut d = Dependencies::default();
        d.color_random
            .iter_mut()
            .flatten()
            .for_each(|v| *v = pick());
        d.color_position
            .iter_mut()
            .flatten()
            .for_each(|v| *v = pick());
        d.color_feature
            .iter_mut()
            .flatten()
            .for_each(|v| *v = pick());
        d.feature_random
            .iter_mut()
            .flatten()
            .for_each(|v| *v = pick());
        d.feature_position
            .iter_mut()
            .flatten()
            .for_each(|v| *v = pick());
        for t in [0, 1, 3, 10, 100] {
            check_weights_in_unit_interval(&weights(&d, t), &format!("case {case}, t {t}"));
        }
    }
    // All zero: α = 1, β = 0.
    let w = weights(&Dependencies::default(), 0);
    assert_eq!(w.alpha, [1.0; 3]);
    assert_eq!(w.beta, [0.0; 15]);
    // Colour driven by the random parameters only: α = 0 from t = 0 on.
    let mut d = Dependencies {
        color_random: [[1.0; 6]; 3],
        ..Default::default()
    };
    assert!(weights(&d, 0).alpha.iter().all(|&a| a < 1e-9));
    // Non-finite or negative estimates count as 0.
    d.color_position = [[f64::NAN, -1.0]; 3];
    check_weights_in_unit_interval(&weights(&d, 2), "NaN input");

    // And on real neighbourhoods, every pixel, every iteration.
    let (set, _) = textured_plane(12, 10, 4, 6, 0.01, 1.0);
    let s = fast(&[9, 5, 3]);
    for it in 0..3 {
        for y in 0..10 {
            for x in 0..12 {
                let info = analyze_pixel(&set, &s, it, x, y).unwrap();
                check_weights_in_unit_interval(&info.weights, &format!("pixel {x},{y}"));
                assert!(info.neighbours >= 4);
            }
        }
    }
}

#[test]
fn noise_from_the_random_parameters_lowers_alpha() {
    // The colour of the textured plane depends on the bounce direction, not on the position:
    // W^r_c is large and α small in the flat interior.
    let (set, _) = textured_plane(24, 24, 8, 7, 0.01, 1.0);
    let s = RpfSettings::default();
    let interior = analyze_pixel(&set, &s, 0, 6, 12).unwrap();
    // Measured: W^r_c 0.9948, α 0.0052 in every channel; bounds 0.95 and 0.05.
    assert!(interior.weights.w_r_c > 0.95, "{:?}", interior.weights);
    assert!(
        interior.weights.alpha.iter().all(|&a| a < 0.05),
        "{:?}",
        interior.weights
    );
    // Next to the texture edge, Alg. 6 rejects the other side (a jump of 0.6 > the 0.1 floor
    // of a constant feature): far fewer neighbours than the same pixel without the edge.
    let mut plain = set.clone();
    plain
        .samples
        .iter_mut()
        .for_each(|s| s.texture1 = ALBEDO_LEFT);
    for x in [11, 12] {
        let edge = analyze_pixel(&set, &s, 0, x, 12).unwrap().neighbours;
        let no_edge = analyze_pixel(&plain, &s, 0, x, 12).unwrap().neighbours;
        // Measured: 1595 of 2977 (0.54) at x = 11, 1541 of 2911 (0.53) at x = 12; bound 2/3.
        assert!(edge < no_edge * 2 / 3, "pixel {x}: {edge} vs {no_edge}");
    }
}

// ---------------------------------------------------------------------------------------------
// Behaviour of the filter
// ---------------------------------------------------------------------------------------------

#[test]
fn constant_images_stay_constant() {
    let (mut set, _) = textured_plane(16, 12, 4, 8, 0.01, 1.0);
    let c = [0.25f32, 0.5, 1.5];
    set.samples.iter_mut().for_each(|s| s.color = c);
    for range_colors in [RangeColors::Current, RangeColors::Original] {
        let s = RpfSettings {
            range_colors,
            ..fast(&[17, 7])
        };
        let out = filter(&set, &s).unwrap();
        assert!(out.pixels.iter().all(|p| *p == c), "{:?}", out.pixels[0]);
    }
}

#[test]
fn never_produces_nan() {
    let settings = fast(&[9, 5]);
    let mut cases: Vec<(String, SampleSet)> = Vec::new();
    // Everything zero.
    cases.push((
        "all zero".into(),
        SampleSet::new(5, 4, 3, vec![SampleVector::default(); 60]).unwrap(),
    ));
    // Huge and tiny colours, fireflies.
    let (mut set, _) = textured_plane(8, 6, 4, 9, 0.01, 1.0);
    for (i, s) in set.samples.iter_mut().enumerate() {
        s.color = match i % 7 {
            0 => [3.0e38, 1.0e-38, 0.0],
            1 => [1.0e6, 1.0e6, 1.0e6],
            2 => [-3.0e38, 0.0, 1.0],
            _ => s.color,
        };
    }
    cases.push(("extreme colours".into(), set));
    // Sky: world1 at 1e9, normals 0, no second hit.
    let (mut set, _) = textured_plane(8, 6, 4, 10, 0.01, 1.0);
    for (i, s) in set.samples.iter_mut().enumerate() {
        if (i / 4) % 8 >= 4 {
            let d = [s.random[3], s.random[4], s.random[5]];
            s.world1 = d.map(|v| v * 1.0e9);
            s.normal1 = [0.0; 3];
            s.world2 = [0.0; 3];
            s.normal2 = [0.0; 3];
            s.texture1 = [0.0; 3];
            s.color = [0.5, 0.7, 1.0];
        }
    }
    cases.push(("sky".into(), set));
    // Tiny images and one sample per pixel.
    for (w, h, spp) in [(1, 1, 1), (1, 1, 8), (1, 7, 2), (7, 1, 1), (2, 2, 1)] {
        let (set, _) = textured_plane(w, h, spp, 11, 0.01, 1.0);
        cases.push((format!("{w}x{h} at {spp} spp"), set));
    }
    for (what, set) in &cases {
        for s in [settings.clone(), RpfSettings::default()] {
            let out = filter(set, &s).unwrap();
            assert_eq!(out.pixels.len(), set.pixels());
            assert_finite(&out, what);
        }
    }
}

#[test]
fn rpf_is_deterministic_for_a_seed_with_any_number_of_threads() {
    let (set, _) = textured_plane(20, 14, 4, 12, 0.01, 1.0);
    let s = RpfSettings {
        seed: 42,
        ..fast(&[15, 7])
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| filter(&set, &s).unwrap())
    };
    let bits =
        |img: &RgbImage| -> Vec<u32> { img.pixels.iter().flatten().map(|v| v.to_bits()).collect() };
    let one = bits(&run(1));
    assert_eq!(one, bits(&run(2)));
    assert_eq!(one, bits(&run(3)));
    assert_eq!(one, bits(&run(2)));
    let other = filter(
        &set,
        &RpfSettings {
            seed: 43,
            ..s.clone()
        },
    )
    .unwrap();
    assert_ne!(
        one,
        bits(&other),
        "the seed should change the neighbourhoods"
    );
}

#[test]
fn a_neighbourhood_of_constant_features_gives_finite_output() {
    // Every element but the colour the same for every sample: zero standard deviation in the
    // normalisation and one populated bucket in every histogram but the colour's.
    let (w, h, spp) = (9, 7, 4);
    let mut rng = Rng::new(13);
    let base = SampleVector {
        position: [3.5, 3.5],
        random: [0.5, 0.5, 0.0, 0.0, 0.0, 1.0],
        world1: [1.0, 2.0, 3.0],
        normal1: [0.0, 0.0, 1.0],
        world2: [0.0; 3],
        normal2: [0.0; 3],
        texture1: [0.5; 3],
        color: [0.0; 3],
    };
    let noisy: Vec<SampleVector> = (0..w * h * spp)
        .map(|_| SampleVector {
            color: [rng.next(), rng.next(), 4.0 * rng.next()],
            ..base
        })
        .collect();
    let set = SampleSet::new(w, h, spp, noisy.clone()).unwrap();
    for s in [fast(&[9, 5]), RpfSettings::default()] {
        let out = filter(&set, &s).unwrap();
        assert_finite(&out, "constant features, noisy colour");
        for p in &out.pixels {
            assert!(
                p[0] >= 0.0 && p[0] <= 1.0 && p[2] >= 0.0 && p[2] <= 4.0,
                "{p:?}"
            );
        }
        let info = analyze_pixel(&set, &s, 0, 4, 3).unwrap();
        assert!(info.weights.alpha.iter().all(|a| a.is_finite()));
    }
    // Everything constant, colour included: the colour comes back.
    let flat: Vec<SampleVector> = (0..w * h * spp)
        .map(|_| SampleVector {
            color: [0.3, 0.6, 0.9],
            ..base
        })
        .collect();
    let set = SampleSet::new(w, h, spp, flat).unwrap();
    let out = filter(&set, &fast(&[9, 5])).unwrap();
    assert!(out.pixels.iter().all(|p| *p == [0.3, 0.6, 0.9]));
    let info = analyze_pixel(&set, &fast(&[9]), 0, 4, 3).unwrap();
    assert_eq!(info.weights.alpha, [1.0; 3]);
    assert_eq!(info.weights.beta, [0.0; 15]);
}

#[test]
fn rpf_lowers_the_error_on_a_noisy_image_with_a_clean_edge() {
    let (set, clean) = textured_plane(24, 24, 8, 14, 0.01, 1.0);
    let noisy = unfiltered(&set);
    let out = rpf::filter_with_progress(&set, &RpfSettings::default(), &|_| {}).unwrap();
    let filtered = &out.image;
    let (before, after) = (mse(&noisy, &clean), mse(filtered, &clean));
    eprintln!(
        "MSE noisy {before:.5}, RPF {after:.5}; iterations {:?}",
        out.iterations
    );
    // Measured: 0.07316 -> 0.00256 (0.035); bound 0.05 (1.4 x).
    assert!(after < 0.05 * before, "MSE {before} -> {after}");
    // The edge stays: the two columns beside it keep their own albedo.
    let column_error = |img: &RgbImage, x: u32| {
        (0..24)
            .map(|y| {
                let i = (y * 24 + x) as usize;
                (0..3)
                    .map(|k| (img.pixels[i][k] - clean.pixels[i][k]).powi(2) as f64)
                    .sum::<f64>()
            })
            .sum::<f64>()
            / 72.0
    };
    for x in [11, 12] {
        let (b, a) = (column_error(&noisy, x), column_error(filtered, x));
        // Measured: 0.0211 -> 0.00047 (0.022) at x = 11, 0.0904 -> 0.0046 (0.051) at
        // x = 12; bound 0.1.
        assert!(a < 0.1 * b, "column {x}: {b} -> {a}");
    }
    // A blur that ignores the features would smear it: the edge columns' mean stays apart.
    let mean_col = |x: u32| {
        (0..24)
            .map(|y| filtered.pixels[(y * 24 + x) as usize][0])
            .sum::<f32>()
            / 24.0
    };
    // Measured: 0.2170 (+0.017) and 0.8711 (+0.071). Both sides come out brighter than
    // the input: the unfiltered right half averages 0.821 and columns 12-14 filter to 0.871
    // all alike, so most of the 0.071 is a bias of the filter (RPF's weighted means do not
    // keep the mean of their input; on the rendered Cornell box it is +2 to +5 %, see
    // tests/rpf_rendered.rs), not edge bleeding, which would pull column 12 down towards the
    // left half. Bounds 0.03 and 0.1 (1.5 x, 1.4 x); the columns must also stay 0.6 apart.
    assert!(
        (mean_col(11) - ALBEDO_LEFT[0]).abs() < 0.03,
        "{}",
        mean_col(11)
    );
    assert!(
        (mean_col(12) - ALBEDO_RIGHT[0]).abs() < 0.1,
        "{}",
        mean_col(12)
    );
    assert!(mean_col(12) - mean_col(11) > 0.6 - 0.1);
}

#[test]
fn scaling_the_scene_changes_the_error_by_less_than_ten_percent() {
    // Table 5.4: the same image with every world position multiplied by 1000.
    let (set, clean) = textured_plane(24, 24, 8, 15, 0.01, 1.0);
    let (scaled, clean2) = textured_plane(24, 24, 8, 15, 0.01, 1000.0);
    assert_eq!(clean, clean2);
    assert_eq!(unfiltered(&set), unfiltered(&scaled));
    let s = RpfSettings::default();
    let a = mse(&filter(&set, &s).unwrap(), &clean);
    let b = mse(&filter(&scaled, &s).unwrap(), &clean);
    eprintln!("MSE unscaled {a:.6}, scaled x1000 {b:.6}");
    // Measured: 0.001684 vs 0.001759, 4.5 % apart; the bound is the thesis's 10 % (Table
    // 5.4). Where the 4.5 % comes from is not established (rounding at the thresholds of
    // Alg. 6's acceptance test is a candidate); tests/rpf_rendered.rs measures 0.03 % on a
    // rendered scene.
    assert!((a - b).abs() < 0.1 * a, "MSE {a} vs {b}");
}

#[test]
fn outdoor_sigma_filters_less() {
    // σ²_8 only scales the colour and feature terms by (1 − W^r_c)² / (2σ²) (eq. 5.16), so it
    // matters where the colour noise is not explained by the random parameters: on the
    // textured plane as it is (W^r_c near 1) indoor and outdoor moved the image by 0.072295
    // and 0.072287 (0.01 % apart). Here the light of each sample is drawn independently of
    // its random parameters (same mean, same texture edge).
    let (mut set, clean) = textured_plane(16, 16, 8, 16, 0.01, 1.0);
    let mut rng = Rng::new(99);
    for s in &mut set.samples {
        let light = if rng.next() < 1.0 / 3.0 { 3.0 } else { 0.0 };
        s.color = s.texture1.map(|a| a * light);
    }
    let noisy = unfiltered(&set);
    let indoor = filter(&set, &RpfSettings::for_setting(Setting::Indoor)).unwrap();
    let outdoor = filter(&set, &RpfSettings::for_setting(Setting::Outdoor)).unwrap();
    assert_finite(&outdoor, "outdoor");
    // How far each moved the image from the unfiltered input, and their errors.
    let (moved_in, moved_out) = (mse(&indoor, &noisy), mse(&outdoor, &noisy));
    let (e_noisy, e_in, e_out) = (
        mse(&noisy, &clean),
        mse(&indoor, &clean),
        mse(&outdoor, &clean),
    );
    eprintln!(
        "moved indoor {moved_in:.6}, outdoor {moved_out:.6}; MSE unfiltered {e_noisy:.6}, \
         indoor {e_in:.6}, outdoor {e_out:.6}"
    );
    // Measured: moved 0.032802 indoor, 0.020177 outdoor (ratio 0.615); bound 0.8 (1.3 x).
    assert!(
        moved_out < 0.8 * moved_in,
        "outdoor moved the image by {moved_out}, indoor by {moved_in}"
    );
    // Filtering less on a noisy image leaves more error, but still less than none. Measured:
    // MSE 0.0819 unfiltered, 0.0491 indoor (0.60 of it), 0.0584 outdoor (0.71); bounds 0.8
    // and 0.9 of the unfiltered error (about 1.3 x the measured ratios), and outdoor above
    // indoor.
    assert!(
        e_in < 0.8 * e_noisy,
        "indoor {e_in} vs unfiltered {e_noisy}"
    );
    assert!(
        e_out < 0.9 * e_noisy,
        "outdoor {e_out} vs unfiltered {e_noisy}"
    );
    assert!(e_in < e_out, "indoor {e_in} vs outdoor {e_out}");
}

#[test]
fn progress_reaches_every_part_of_every_iteration() {
    use std::sync::Mutex;
    let (set, _) = textured_plane(6, 5, 2, 17, 0.01, 1.0);
    let s = fast(&[7, 3]);
    let seen = Mutex::new(Vec::new());
    let out = rpf::filter_with_progress(&set, &s, &|p| seen.lock().unwrap().push(p)).unwrap();
    let seen = seen.into_inner().unwrap();
    assert_eq!(seen.len(), 10);
    assert!(
        seen.iter()
            .any(|p| p.iteration == 1 && p.parts_done == 5 && p.box_size == 3)
    );
    let last = seen
        .iter()
        .find(|p| p.iteration == 1 && p.parts_done == 5)
        .unwrap();
    assert!((last.fraction(&s.box_sizes) - 1.0).abs() < 1e-12);
    assert_eq!(out.iterations.len(), 2);
    assert!(out.iterations.iter().all(|i| i.mean_neighbours >= 2.0));
}

#[test]
fn settings_are_the_thesis_defaults_and_are_checked() {
    let s = RpfSettings::default();
    assert_eq!(s.box_sizes, vec![55, 35, 17, 7]);
    assert_eq!(s.sigma2_8, Auto::Auto);
    assert_eq!(s.sigma2_8(), 0.02);
    assert_eq!(s.mi_buckets, 5);
    assert_eq!(s.sample_fraction, 0.5);
    assert_eq!(s.final_box, 1);
    assert_eq!(
        RpfSettings::for_setting(Setting::Outdoor).sigma2_8,
        Auto::Set(0.002)
    );
    assert_eq!(RpfSettings::for_setting(Setting::Indoor).sigma2_8(), 0.02);
    let (set, _) = textured_plane(3, 3, 2, 18, 0.01, 1.0);
    for bad in [
        RpfSettings {
            sigma2_8: Auto::Set(0.0),
            ..s.clone()
        },
        RpfSettings {
            sigma2_8: Auto::Set(f32::NAN),
            ..s.clone()
        },
        RpfSettings {
            box_sizes: vec![],
            ..s.clone()
        },
        RpfSettings {
            box_sizes: vec![55, 0],
            ..s.clone()
        },
        RpfSettings {
            mi_buckets: 1,
            ..s.clone()
        },
        RpfSettings {
            mi_buckets: 17,
            ..s.clone()
        },
        RpfSettings {
            sample_fraction: 0.0,
            ..s.clone()
        },
        RpfSettings {
            feature_tolerance: -3.0,
            ..s.clone()
        },
        RpfSettings {
            tolerance_floor: f32::INFINITY,
            ..s.clone()
        },
        RpfSettings {
            final_box: 2,
            ..s.clone()
        },
    ] {
        assert!(filter(&set, &bad).is_err(), "{bad:?}");
    }
    // A sample set that does not match its dimensions, or holds NaN.
    let mut broken = set.clone();
    broken.samples.pop();
    let e = format!("{:#}", filter(&broken, &s).unwrap_err());
    assert!(e.contains("needs 18"), "{e}");
    let mut nan = set.clone();
    nan.samples[5].normal2[1] = f32::NAN;
    let e = format!("{:#}", filter(&nan, &s).unwrap_err());
    assert!(e.contains("normal2.y") && e.contains("pixel 2, 0"), "{e}");
}

/// `final_box = 3` is the 3 × 3 mean of the `final_box = 1` image (fewer pixels at the
/// border), §3.1.1's box filter.
#[test]
fn the_three_by_three_final_box_averages_the_pixel_means() {
    let (set, _) = textured_plane(9, 7, 3, 19, 0.01, 1.0);
    let one = filter(&set, &fast(&[5, 3])).unwrap();
    let three = filter(
        &set,
        &RpfSettings {
            final_box: 3,
            ..fast(&[5, 3])
        },
    )
    .unwrap();
    let (w, h) = (9i64, 7i64);
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f64; 3];
            let mut count = 0.0;
            for qy in (y - 1).max(0)..=(y + 1).min(h - 1) {
                for qx in (x - 1).max(0)..=(x + 1).min(w - 1) {
                    let p = one.pixels[(qy * w + qx) as usize];
                    (0..3).for_each(|k| acc[k] += p[k] as f64);
                    count += 1.0;
                }
            }
            let want = acc.map(|a| (a / count) as f32);
            assert_eq!(three.pixels[(y * w + x) as usize], want, "({x}, {y})");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Memory and the samples.bin file
// ---------------------------------------------------------------------------------------------

#[test]
fn memory_is_26_floats_per_sample_and_checked_before_allocating() {
    // §5.1.1: 26 · 4 B · 8 spp · 1280 · 720 ≈ 731 MB.
    assert_eq!(samples::memory_bytes(1280, 720, 8), 766_771_200);
    assert_eq!(
        samples::memory_bytes(u32::MAX, u32::MAX, u32::MAX),
        u64::MAX
    );
    assert!(samples::check_memory(1280, 720, 8, 800 << 20).is_ok());
    let e = samples::check_memory(1280, 720, 8, 512 << 20)
        .unwrap_err()
        .to_string();
    assert!(e.contains("at most 5 spp"), "{e}");
    assert!(rpf::working_memory_bytes(512, 512, 8, &RpfSettings::default()) > 0);
}

fn to_bytes(set: &SampleSet) -> Vec<u8> {
    let mut v = Vec::new();
    set.write_to(&mut v).unwrap();
    v
}

fn read_bytes(bytes: &[u8]) -> anyhow::Result<SampleSet> {
    SampleSet::read_from(&mut Cursor::new(bytes), bytes.len() as u64, None)
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

/// Where the sample vectors of a version-2 file start: after the header, the record's length
/// and the record.
fn vectors_start(bytes: &[u8]) -> usize {
    HEADER_BYTES as usize + 4 + u32_at(bytes, HEADER_BYTES as usize) as usize
}

/// The same set as a version-1 file (no record).
fn version_1_bytes(set: &SampleSet) -> Vec<u8> {
    let v2 = to_bytes(set);
    let mut v1 = v2[..HEADER_BYTES as usize].to_vec();
    v1[8..12].copy_from_slice(&1u32.to_le_bytes());
    v1.extend_from_slice(&v2[vectors_start(&v2)..]);
    v1
}

#[test]
fn sample_files_round_trip() {
    let (mut set, _) = textured_plane(5, 3, 2, 19, 0.01, 1.0);
    let bytes = to_bytes(&set);
    let start = vectors_start(&bytes);
    assert_eq!(bytes.len(), start + 104 * 30);
    assert_eq!(&bytes[..8], &MAGIC);
    assert_eq!(u32_at(&bytes, 8), samples::VERSION);
    assert_eq!(samples::VERSION, 2);
    assert_eq!([12, 16, 20, 24].map(|at| u32_at(&bytes, at)), [5, 3, 2, 26]);
    // The record is UTF-8 TOML.
    let record = std::str::from_utf8(&bytes[32..start]).unwrap();
    assert!(record.parse::<toml::Table>().is_ok(), "{record}");
    // Little-endian floats in field order.
    let first = to_floats(&set.samples[0]);
    let f =
        |k: usize| f32::from_le_bytes(bytes[start + 4 * k..start + 4 + 4 * k].try_into().unwrap());
    assert_eq!((0..26).map(f).collect::<Vec<_>>(), first.to_vec());
    assert_eq!(read_bytes(&bytes).unwrap(), set);

    // A version-1 file (no record) still reads, with an empty record.
    let v1 = version_1_bytes(&set);
    assert_eq!(v1.len() as u64, HEADER_BYTES + 104 * 30);
    assert_eq!(read_bytes(&v1).unwrap(), set);

    // A full record comes back as it was written.
    let mut scene = SceneInfo::unknown();
    scene.scene_size = 12.5;
    scene.setting = Setting::Outdoor;
    scene.seed = 9;
    let mut rpf_table = toml::Table::new();
    rpf_table.insert("seed".into(), toml::Value::Integer(3));
    set.record = RenderRecord {
        scene: Some(scene.clone()),
        filter: Some("rpf".into()),
        settings: [("rpf".to_string(), rpf_table)].into(),
        extra: [("spp".to_string(), "2".to_string())].into(),
    };
    let with_record = read_bytes(&to_bytes(&set)).unwrap();
    assert_eq!(with_record, set);
    // ... and the frame made from it carries the scene information.
    let frame = with_record.clone().into_frame().unwrap();
    assert_eq!(frame.info().scene, scene);
    assert_eq!(
        SampleSet::from_frame(&frame, set.record.clone()).unwrap(),
        set
    );

    let dir = tempdir("rpf");
    let path = dir.join("samples.bin");
    set.write(&path).unwrap();
    assert!(samples::is_sample_file(&path));
    assert_eq!(SampleSet::read(&path).unwrap(), set);
    // Filtering the file gives what filtering the set gives.
    let s = fast(&[5]);
    assert_eq!(
        filter(&SampleSet::read(&path).unwrap(), &s).unwrap(),
        filter(&set, &s).unwrap()
    );
    std::fs::write(dir.join("other.bin"), b"not samples").unwrap();
    assert!(!samples::is_sample_file(&dir.join("other.bin")));
    let missing = SampleSet::read(&dir.join("missing.bin")).unwrap_err();
    assert!(format!("{missing:#}").contains("missing.bin"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_sample_files_give_clear_errors() {
    let (set, _) = textured_plane(4, 2, 2, 20, 0.01, 1.0);
    let good = to_bytes(&set);
    let start = vectors_start(&good);
    let err = |bytes: &[u8]| format!("{:#}", read_bytes(bytes).unwrap_err());

    assert!(err(&good[..10]).contains("truncated"));
    assert!(err(&good[..good.len() - 1]).contains("truncated"));
    assert!(err(&good[..HEADER_BYTES as usize]).contains("truncated"));
    assert!(err(&good[..start]).contains("truncated"));

    let mut extra = good.clone();
    extra.extend_from_slice(&[0; 4]);
    assert!(err(&extra).contains("do not match"));

    let mut magic = good.clone();
    magic[0] = b'X';
    assert!(err(&magic).contains("bad magic"));

    let mut version = good.clone();
    version[8..12].copy_from_slice(&7u32.to_le_bytes());
    assert!(err(&version).contains("version 7"));

    let mut floats = good.clone();
    floats[24..28].copy_from_slice(&27u32.to_le_bytes());
    assert!(err(&floats).contains("27 floats"));

    let mut zero = good.clone();
    zero[20..24].copy_from_slice(&0u32.to_le_bytes());
    assert!(err(&zero).contains("at least 1"));

    // Dimensions of a huge image in a small file: an error before anything is allocated.
    let mut huge = good.clone();
    huge[12..16].copy_from_slice(&100_000u32.to_le_bytes());
    huge[16..20].copy_from_slice(&100_000u32.to_le_bytes());
    assert!(err(&huge).contains("truncated"));

    // A record longer than the file, or not TOML.
    let mut long = good.clone();
    long[28..32].copy_from_slice(&(good.len() as u32).to_le_bytes());
    assert!(
        err(&long).contains("render record claims"),
        "{}",
        err(&long)
    );
    let mut garbled = good.clone();
    garbled[32..start].fill(b'=');
    assert!(err(&garbled).contains("render record"), "{}", err(&garbled));

    // A header that matches the length but not the memory budget.
    let budget = SampleSet::read_from(&mut Cursor::new(&good), good.len() as u64, Some(100));
    assert!(format!("{:#}", budget.unwrap_err()).contains("spp"));

    // A non-finite value: named by pixel, sample and field, in either version.
    let at = 104 * 5 + 4 * 23; // vector 5 = pixel (2, 0) sample 1, color.r
    let mut inf = good.clone();
    inf[start + at..start + at + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let mut inf_v1 = version_1_bytes(&set);
    let at_v1 = HEADER_BYTES as usize + at;
    inf_v1[at_v1..at_v1 + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    for e in [err(&inf), err(&inf_v1)] {
        assert!(
            e.contains("color.r") && e.contains("pixel 2, 0, sample 1"),
            "{e}"
        );
    }

    // Writing refuses what reading would refuse.
    let mut nan = set.clone();
    nan.samples[0].world2[0] = f32::NAN;
    assert!(nan.write_to(&mut Vec::new()).is_ok()); // the raw writer does not check
    let dir = tempdir("rpf-bad");
    assert!(nan.write(&dir.join("nan.bin")).is_err());
    assert!(!dir.join("nan.bin").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------------------------
// Timing (not run by default): cargo test --release --test rpf -- --ignored --nocapture
// ---------------------------------------------------------------------------------------------

#[test]
#[ignore]
fn timing_64x64_at_8_spp_default_boxes() {
    let (set, clean) = textured_plane(64, 64, 8, 21, 0.01, 1.0);
    let start = std::time::Instant::now();
    let out = rpf::filter_with_progress(&set, &RpfSettings::default(), &|_| {}).unwrap();
    let t = start.elapsed();
    eprintln!(
        "RPF 64x64 at 8 spp, boxes 55/35/17/7, {} threads: {:.2} s; MSE {:.5} -> {:.5}",
        rayon::current_num_threads(),
        t.as_secs_f64(),
        mse(&unfiltered(&set), &clean),
        mse(&out.image, &clean)
    );
    for i in &out.iterations {
        eprintln!(
            "  box {:2}: {:.2} s, mean |N| {:.0}",
            i.box_size,
            i.time.as_secs_f64(),
            i.mean_neighbours
        );
    }
}
