//! The data-driven filter (thesis ch. 6): every kernel variant against the plain Rust reference,
//! and the behaviour the equations promise (constant images, edges, sky, the direction term,
//! holes, tiny images, underflow).

mod common;

use common::*;
use noisefree::filters::Auto;
use noisefree::filters::ddf::{DdfKernel, DdfSettings, DirectionTerm, Variant, reference};
use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::layout::{FilterVector, SKY_DEPTH};
use noisefree::metrics::mse_luv;
use noisefree::scene::Scene;

/// Every kernel variant: (variant, work-group of the rows variant).
const VARIANTS: [(Variant, u32); 5] = [
    (Variant::Naive, 64),
    (Variant::Vector, 64),
    (Variant::Rows, 64),
    (Variant::Rows, 256),
    // 16 pixels per work-item (its own work-group size): the 70-, 33-, 20- and 9-pixel-wide
    // images below end in partial groups of 16.
    (Variant::Packed, 64),
];

fn label((v, wg): (Variant, u32)) -> String {
    match v {
        Variant::Rows => format!("rows/{wg}"),
        _ => format!("{v:?}").to_lowercase(),
    }
}

/// The device kernel of variant `v` with settings `s` on `b`.
fn device(b: &Buffers, s: &DdfSettings, (variant, work_group): (Variant, u32)) -> RgbImage {
    let s = DdfSettings {
        variant,
        work_group,
        ..s.clone()
    };
    let mut f = DdfKernel::new(gpu(), &s, b.width, b.height).unwrap();
    f.filter(&b.frame()).unwrap().image
}

const ROWS: (Variant, u32) = (Variant::Rows, 64);
const PACKED: (Variant, u32) = (Variant::Packed, 64);

/// Largest relative difference allowed between a device kernel and the Rust reference.
/// Measured on PoCL (CPU): at most 2.8e-7 (every_variant_matches_the_rust_reference, kw 21,
/// holes, difference direction term; 0 on the synthetic images). The bound is 3.5x that, a few
/// float32 ulps, leaving room for OpenCL's exp (3 ulp allowed) on other devices.
const MAX_REL_TO_REFERENCE: f32 = 1e-6;

/// Buffers (features and variances) of `scene` at `w` x `h`, `spp` samples, `seed`.
fn render(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> Buffers {
    let mut o = options(scene, w, h, seed);
    o.outputs = OutputSet::of(&[Output::Features, Output::Variance]);
    Buffers::of_frame(&render_frame(scene, &o, spp))
}

/// Rendered buffers of a small Cornell box with a mirror (so texture2 varies).
fn rendered(w: u32, h: u32, spp: u32, seed: u32) -> Buffers {
    render(&cornell_with_spheres(), w, h, spp, seed)
}

#[test]
fn every_variant_matches_the_rust_reference() {
    let b = rendered(70, 45, 8, 1); // widths that are no multiple of the work-groups
    let mut worst = 0f32;
    let mut worst_of = vec![0f32; VARIANTS.len()];
    let mut packed_from_rows = 0f32;
    for holes in [false, true] {
        for kw in [1, 7, 9, 21] {
            for (direction, texture2) in [
                (DirectionTerm::Thesis, Auto::Auto),
                (DirectionTerm::Difference, Auto::Auto),
                (DirectionTerm::Neighbour, Auto::Auto),
                // What specialisation gives a scene without mirrors, glass or metal.
                (DirectionTerm::Thesis, Auto::Set(false)),
            ] {
                let s = DdfSettings {
                    kw,
                    holes,
                    direction,
                    texture2,
                    ..Default::default()
                };
                let want = reference(&b.frame(), &s).unwrap();
                assert_finite(&want, "reference");
                let rows = device(&b, &s, ROWS);
                for (k, v) in VARIANTS.into_iter().enumerate() {
                    let got = device(&b, &s, v);
                    let d = max_rel_diff(&got, &want);
                    worst = worst.max(d);
                    worst_of[k] = worst_of[k].max(d);
                    if v.0 == Variant::Packed {
                        packed_from_rows = packed_from_rows.max(max_rel_diff(&got, &rows));
                    }
                    assert!(
                        d <= MAX_REL_TO_REFERENCE,
                        "{} kw {kw} holes {holes} {direction:?} texture2 {texture2:?}: max relative \
                         difference {d:e}",
                        label(v)
                    );
                }
            }
        }
    }
    eprintln!("largest relative difference from the reference: {worst:e}");
    for (v, d) in VARIANTS.into_iter().zip(worst_of) {
        eprintln!("  {}: {d:e}", label(v));
    }
    eprintln!("packed against rows/64: {packed_from_rows:e}");
}

/// Largest relative difference of the fast mode (`fast_exp`: native_exp in the weights) from
/// the exact kernel of the same variant. Measured on PoCL (CPU): 4.2e-7 at kw 21 (packed
/// 4.0e-7), 3.0e-7 with holes; the bound is 2.4x that.
const MAX_REL_FAST_EXP: f32 = 1e-6;

#[test]
fn fast_exp_stays_near_the_exact_filter() {
    let b = rendered(70, 45, 8, 1);
    let mut worst = 0f32;
    for holes in [false, true] {
        let exact = DdfSettings {
            holes,
            ..Default::default()
        };
        let fast = DdfSettings {
            fast_exp: true,
            ..exact.clone()
        };
        for v in VARIANTS {
            let got = device(&b, &fast, v);
            assert_finite(&got, "fast exp");
            let d = max_rel_diff(&got, &device(&b, &exact, v));
            eprintln!("{} holes {holes}: {d:e}", label(v));
            worst = worst.max(d);
        }
    }
    assert!(
        worst <= MAX_REL_FAST_EXP,
        "fast exp: max relative difference {worst:e}"
    );
}

fn fv(direct: f32, indirect: f32, depth: f32, albedo: f32) -> FilterVector {
    FilterVector {
        direct: [direct; 3],
        indirect: [indirect; 3],
        depth,
        normal: [0.0, 0.0, 1.0],
        albedo: [albedo; 3],
        albedo2: [albedo; 3],
    }
}

#[test]
fn constant_image_stays_constant() {
    let b = Buffers::from_fn(33, 17, 100.0, |_, _| fv(0.3, 0.2, 5.0, 0.7));
    let mut worst = 0f32;
    for v in VARIANTS {
        for holes in [false, true] {
            let out = device(
                &b,
                &DdfSettings {
                    holes,
                    ..Default::default()
                },
                v,
            );
            for p in &out.pixels {
                for c in p {
                    worst = worst.max((c - 0.5).abs());
                    // Measured: at most 1.13e-6 from 0.5 (rounding of the 441-term weighted
                    // sums); bound 1.8x that.
                    assert!((c - 0.5).abs() < 2e-6, "{}: {c}", label(v));
                }
            }
        }
    }
    eprintln!("largest distance from 0.5: {worst:e}");
}

#[test]
fn hard_edges_in_depth_normal_and_texture_are_kept() {
    // Left half and right half differ in one feature each time; the light is noisy (a
    // deterministic pattern) but has the same mean on both sides, except for an offset that
    // the edge must keep.
    let noise = |x: u32, y: u32| ((x * 7 + y * 13) % 5) as f32 * 0.02;
    type Case = (&'static str, Box<dyn Fn(u32, u32) -> FilterVector>);
    let cases: Vec<Case> = vec![
        (
            "depth",
            Box::new(move |x, y| {
                let left = x < 16;
                let mut f = fv(
                    if left { 0.2 } else { 0.8 } + noise(x, y),
                    0.1,
                    if left { 2.0 } else { 9.0 },
                    0.5,
                );
                f.albedo2 = [0.5; 3];
                f
            }),
        ),
        (
            "normal",
            Box::new(move |x, y| {
                let left = x < 16;
                let mut f = fv(if left { 0.2 } else { 0.8 } + noise(x, y), 0.1, 3.0, 0.5);
                f.normal = if left {
                    [0.0, 0.0, 1.0]
                } else {
                    [1.0, 0.0, 0.0]
                };
                f
            }),
        ),
        (
            "texture",
            Box::new(move |x, y| {
                let left = x < 16;
                fv(
                    if left { 0.2 } else { 0.8 } + noise(x, y),
                    0.1,
                    3.0,
                    if left { 0.1 } else { 0.9 },
                )
            }),
        ),
    ];
    for (what, f) in cases {
        let b = Buffers::from_fn(32, 16, 100.0, f);
        let out = device(&b, &DdfSettings::default(), ROWS);
        let mut worst = 0f32;
        for y in 0..16 {
            for x in 0..32u32 {
                let want = if x < 16 {
                    0.2 + 0.04 + 0.1
                } else {
                    0.8 + 0.04 + 0.1
                };
                let got = out.pixels[(y * 32 + x) as usize][0];
                worst = worst.max((got - want).abs());
                // Measured: at most 5.9e-4 from the side's mean in all three cases (the noise
                // pattern does not average to exactly 0.04 over every window); bound 1.7x
                // that. Bleeding across the edge would move pixels by up to 0.3.
                assert!(
                    (got - want).abs() < 1e-3,
                    "{what} edge bled at ({x},{y}): {got} vs {want}"
                );
            }
        }
        eprintln!("{what} edge: largest distance from the side's mean {worst:e}");
    }
}

/// The filtered 8-spp image of a bundled scene is much closer to a 1024-spp reference than the
/// unfiltered one. The scene is Cornell plane, and the seeds 11 (noisy) and 100 (reference):
/// the variance-scale defaults were chosen on Cornell diffuse (with and without depth of
/// field), Cornell glossy and Outside at seed 7, so this checks them on a scene and with
/// random numbers they were not fitted to (kw and the sigmas are Table 7.2's). The settings
/// are specialised to the scene as `noisefree render --filter ddf` does (texture2 on for its
/// mirror and glass, no sky branch without an environment light).
#[test]
fn filtering_lowers_the_error_on_a_scene_not_used_for_tuning() {
    // kw = 21 (Table 7.2) was chosen for 512 x 512; at 64 x 64 it covers a third of the image
    // and blurs the textures. 128 x 128 keeps the test quick and the textures resolvable.
    let (w, h) = (128, 128);
    let scene = bundled_scene("cornell_plane");
    let truth = reference_image(&scene, w, h, 1024, 100);
    let noisy = render(&scene, w, h, 8, 11);
    // The thesis's metric, MSE in CIELUV (§5.2.2): linear-RGB MSE is dominated by the
    // anti-aliased edge of the bright light panel, which no filter is meant to change.
    let unfiltered = mse_luv(&noisy.beauty(), &truth).unwrap();
    // Measured filtered / unfiltered MSE, seed 11: 0.399 without holes, 0.466 with; over
    // seeds 11-15: 0.394-0.417 (mean 0.408, sd 0.010) and 0.466-0.489 (mean 0.477, sd
    // 0.009). Bounds: the seed-11 value plus about five standard deviations of the spread
    // across seeds (1.13x and 1.14x the seed-11 value). On Cornell diffuse (a tuning scene)
    // the ratio is 0.29-0.30 (seeds 7, 11, 12, 13).
    for (holes, bound) in [(false, 0.45), (true, 0.53)] {
        let mut s = DdfSettings {
            holes,
            ..Default::default()
        };
        <noisefree::filters::ddf::Ddf as noisefree::filters::FilterKind>::specialise(
            &mut s,
            &noisy.scene,
        );
        assert_eq!(
            (s.texture2, s.sky),
            (Auto::Set(true), Auto::Set(false)),
            "Cornell plane has a mirror and glass, and no environment light"
        );
        // Rows (the thesis's variant) and packed (the default on CPUs). Measured 2026-11-24:
        // the same ratios to four digits, 0.4021 and 0.4677.
        for v in [ROWS, PACKED] {
            let filtered = device(&noisy, &s, v);
            let e = mse_luv(&filtered, &truth).unwrap();
            eprintln!(
                "{} holes {holes}: filtered MSE {e:.5}, unfiltered {unfiltered:.5}, ratio {:.4}",
                label(v),
                e / unfiltered
            );
            assert!(
                e < bound * unfiltered,
                "{} holes {holes}: filtered MSE {e} vs unfiltered {unfiltered} (ratio {:.4} >= \
                 {bound})",
                label(v),
                e / unfiltered
            );
        }
    }
}

#[test]
fn sky_pixels_pass_through_bit_exactly() {
    // A sky whose colour changes from pixel to pixel: sky pixels share their (sentinel) depth
    // and features, so without the special case they are averaged with each other.
    let b = Buffers::from_fn(20, 10, 100.0, |x, y| {
        if (x + y) % 3 == 0 {
            fv(
                0.1 + 0.037 * x as f32,
                0.7 - 0.051 * y as f32,
                SKY_DEPTH,
                0.0,
            )
        } else {
            fv(0.5, 0.25, 4.0, 0.5)
        }
    });
    let beauty = b.beauty();
    let sky = |i: usize| b.filter_vectors[i].depth >= SKY_DEPTH;
    for v in VARIANTS {
        let out = device(&b, &DdfSettings::default(), v);
        for i in (0..beauty.pixels.len()).filter(|&i| sky(i)) {
            assert_eq!(
                out.pixels[i].map(f32::to_bits),
                beauty.pixels[i].map(f32::to_bits),
                "{}",
                label(v)
            );
        }
    }
    // Without the special case the sky is filtered like anything else: as the reference
    // filters it, and visibly changed.
    let s = DdfSettings {
        sky: Auto::Set(false),
        ..Default::default()
    };
    let want = reference(&b.frame(), &s).unwrap();
    let mut moved = 0f32;
    for i in (0..beauty.pixels.len()).filter(|&i| sky(i)) {
        for c in 0..3 {
            moved = moved.max((want.pixels[i][c] - beauty.pixels[i][c]).abs());
        }
    }
    // Measured: the largest change of a sky pixel is 0.345; bound at 0.25 (0.7x).
    assert!(
        moved > 0.25,
        "without the special case the sky should be filtered: largest change {moved}"
    );
    for v in VARIANTS {
        let d = max_rel_diff(&device(&b, &s, v), &want);
        assert!(
            d <= MAX_REL_TO_REFERENCE,
            "sky off, {}: {d:e} from the reference",
            label(v)
        );
    }
}

/// Groups of 16 sky pixels (the packed variant's work-items, and the rows variant's runs at
/// work-group 16, which then skip every tap), a group that is sky in some rows only and a
/// partial group at the right edge: sky keeps its colour, the surface pixels next to it are
/// filtered as the reference filters them.
#[test]
fn whole_groups_of_sky_pass_through() {
    let b = Buffers::from_fn(45, 6, 100.0, |x, y| {
        if x >= if y < 3 { 16 } else { 20 } {
            fv(
                0.1 + 0.021 * x as f32,
                0.7 - 0.05 * y as f32,
                SKY_DEPTH,
                0.0,
            )
        } else {
            fv(0.5 + 0.01 * (x % 3) as f32, 0.25, 4.0, 0.5)
        }
    });
    let beauty = b.beauty();
    let s = DdfSettings::default();
    let want = reference(&b.frame(), &s).unwrap();
    for v in VARIANTS.into_iter().chain([(Variant::Rows, 16)]) {
        let out = device(&b, &s, v);
        for (i, f) in b.filter_vectors.iter().enumerate() {
            if f.depth >= SKY_DEPTH {
                assert_eq!(
                    out.pixels[i].map(f32::to_bits),
                    beauty.pixels[i].map(f32::to_bits),
                    "{} pixel {i}",
                    label(v)
                );
            }
        }
        let d = max_rel_diff(&out, &want);
        assert!(
            d <= MAX_REL_TO_REFERENCE,
            "{}: {d:e} from the reference",
            label(v)
        );
    }
}

/// As printed, eq. 6.14's factor exp(-sigma2_f,3) is the same for every neighbour and cancels
/// in eq. 6.21: sigma_f direction does not change the image (Table 7.1's "rather random"
/// direction results). The difference variant does depend on it.
#[test]
fn printed_direction_factor_cancels() {
    let b = rendered(40, 30, 8, 3);
    let with = |direction, sigma: f32| {
        let mut s = DdfSettings {
            direction,
            ..Default::default()
        };
        s.sigma_f[3] = sigma;
        device(&b, &s, (Variant::Vector, 64))
    };
    let a = with(DirectionTerm::Thesis, 0.1);
    let c = with(DirectionTerm::Thesis, 10.0);
    // Measured: 1.04e-6 (rounding: the cancelling factor scales every weight); bound 1.9x.
    assert!(
        max_rel_diff(&a, &c) < 2e-6,
        "sigma_f direction changed the thesis filter: {:e}",
        max_rel_diff(&a, &c)
    );
    let d = with(DirectionTerm::Difference, 0.1);
    let e = with(DirectionTerm::Difference, 10.0);
    // Measured: some pixel changes by 98 % (relative); bound at about half that.
    assert!(
        max_rel_diff(&d, &e) > 0.5,
        "the difference variant should depend on sigma_f direction: {}",
        max_rel_diff(&d, &e)
    );
    // The neighbour's-variance reading does not cancel either.
    let g = with(DirectionTerm::Neighbour, 0.1);
    let h = with(DirectionTerm::Neighbour, 10.0);
    let moved = max_rel_diff(&g, &h);
    eprintln!("neighbour reading, sigma_f direction 0.1 against 10: {moved:e}");
    // Measured: 0.93; bound at about half that.
    assert!(
        moved > 0.5,
        "the neighbour reading should depend on sigma_f direction: {moved}"
    );
}

#[test]
fn holes_with_an_odd_half_still_include_the_centre() {
    // kw = 7: half = 3, the holes grid is -3, -1, 1, 3: the centre is off the grid. Every
    // pixel differs wildly in colour from its neighbours, so only the centre's own weight
    // (1) is significant: the output is the pixel's own colour, never 0/0.
    let b = Buffers::from_fn(9, 9, 100.0, |x, y| {
        fv(((x * 31 + y * 17) % 7) as f32 * 10.0, 0.0, 1.0, 0.5)
    });
    let s = DdfSettings {
        kw: 7,
        holes: true,
        sigma_dc: 0.01,
        ..Default::default()
    };
    let want = b.beauty();
    for v in VARIANTS {
        let out = device(&b, &s, v);
        assert_finite(&out, "holes");
        // Measured: 0 (bit-identical: the centre's weight is exp(0) = 1, the others 0).
        assert!(
            max_rel_diff(&out, &want) <= MAX_REL_TO_REFERENCE,
            "{}: the centre was not kept",
            label(v)
        );
    }
}

#[test]
fn tiny_images_wide_kernels_and_underflow() {
    for (w, h) in [(1, 1), (1, 7), (7, 1), (3, 2)] {
        let b = Buffers::from_fn(w, h, 100.0, |x, y| {
            fv(0.1 * (x + y) as f32, 0.3, 2.0 + x as f32, 0.5)
        });
        for kw in [1, 3, 51] {
            let s = DdfSettings {
                kw,
                ..Default::default()
            };
            let want = reference(&b.frame(), &s).unwrap();
            for v in VARIANTS {
                let out = device(&b, &s, v);
                assert_finite(&out, "tiny");
                // Measured: 0 (bit-identical).
                assert!(
                    max_rel_diff(&out, &want) <= MAX_REL_TO_REFERENCE,
                    "{w}x{h} kw {kw} {}",
                    label(v)
                );
            }
            if kw == 1 {
                // Measured: 0. The only weight w gives w x / w: at most two roundings.
                assert!(
                    max_rel_diff(&want, &b.beauty()) <= 2.5e-7,
                    "kw 1 must return the input"
                );
            }
        }
    }
    // Every indirect weight underflows, the centre's too (the printed direction factor with a
    // tiny sigma_f): the pixel keeps its own indirect colour instead of 0/0. Direct light is
    // filtered normally: sigma_f direction weights only indirect light, so the direct half is
    // the default filter's output on the same buffers without indirect light.
    let b = Buffers::from_fn(8, 8, 100.0, |x, y| {
        fv(0.1 * x as f32, 0.05 * y as f32, 3.0, 0.5)
    });
    let mut s = DdfSettings::default();
    s.sigma_f[3] = 1e-6;
    let want = reference(&b.frame(), &s).unwrap();
    assert_finite(&want, "underflow reference");
    let mut dark = b.clone();
    for f in &mut dark.filter_vectors {
        f.indirect = [0.0; 3];
    }
    let direct = reference(&dark.frame(), &DdfSettings::default()).unwrap();
    for (i, f) in b.filter_vectors.iter().enumerate() {
        let expected: [f32; 3] = std::array::from_fn(|c| direct.pixels[i][c] + f.indirect[c]);
        assert_eq!(
            want.pixels[i].map(f32::to_bits),
            expected.map(f32::to_bits),
            "underflow, pixel {i}: the reference gave {:?}, filtered direct + own indirect is \
             {expected:?}",
            want.pixels[i]
        );
    }
    for v in VARIANTS {
        let out = device(&b, &s, v);
        assert_finite(&out, "underflow");
        let d = max_rel_diff(&out, &want);
        // Measured: 0 (bit-identical).
        assert!(
            d <= MAX_REL_TO_REFERENCE,
            "underflow, {}: {d:e} from the reference",
            label(v)
        );
    }
}

/// Depth is compared in hundredths of the scene's size: the same buffers with every depth and
/// the scene size scaled by 1000 filter to the same image (up to rounding).
#[test]
fn depth_weights_do_not_depend_on_the_scene_units() {
    let b = rendered(40, 30, 8, 5);
    let mut scaled = b.clone();
    scaled.scene.scene_size *= 1000.0;
    for f in &mut scaled.filter_vectors {
        if f.depth < SKY_DEPTH {
            f.depth *= 1000.0;
        }
    }
    for g in scaled.variances.as_mut().unwrap() {
        g.depth *= 1.0e6;
    }
    let s = DdfSettings::default();
    let (a, c) = (
        reference(&b.frame(), &s).unwrap(),
        reference(&scaled.frame(), &s).unwrap(),
    );
    // Measured: 1.1e-6 (the scaled depths round differently); bound 1.8x.
    assert!(
        max_rel_diff(&a, &c) < 2e-6,
        "units changed the filter: {:e}",
        max_rel_diff(&a, &c)
    );
    let d = device(&scaled, &s, ROWS);
    // Measured: 2.4e-7 from the reference on the same (scaled) buffers, 1.1e-6 from the
    // unscaled ones.
    assert!(max_rel_diff(&d, &c) <= MAX_REL_TO_REFERENCE);
    assert!(max_rel_diff(&d, &a) < 2e-6 + MAX_REL_TO_REFERENCE);
}
