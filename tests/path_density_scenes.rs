//! The path-density filter (src/filters/path_density/) on rendered scenes: the accumulated
//! mode's rejected fraction falls with spp while the per-frame mode's does not, the chains run
//! the next filter on the cleaned colour, the two-light scenes of the study render and
//! filter, the specular interior loses its fireflies (Fig. 5.1a) and the colour grid keeps
//! its line widths in CIELAB but not with an RGB distance (Fig. 5.9). Kernel against reference and the stability cases: tests/path_density.rs.

mod common;

use common::*;
use noisefree::filters::path_density::{
    self, ColorSpace, DensityMode, PathDensityKernel, PathDensitySettings, Then,
};
use noisefree::filters::{Configured, Registry};
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::SceneInfo;

/// Rejected fraction of a rendered frame of Cornell glossy at `spp` in `mode`.
fn rejected_fraction(spp: u32, mode: DensityMode) -> f64 {
    let scene = bundled_scene("cornell_glossy");
    let mut o = options(&scene, 32, 32, 5);
    o.outputs = OutputSet::of(&[Output::Samples]);
    o.sample_capacity = spp;
    let frame = render_frame(&scene, &o, spp);
    let settings = PathDensitySettings {
        mode,
        frame_spp: 2,
        ..Default::default()
    };
    let mut k = PathDensityKernel::new(gpu(), settings.params()).unwrap();
    k.run(&frame).unwrap();
    k.densities().unwrap().fractions().0
}

#[test]
fn accumulated_rejection_falls_with_spp_and_per_frame_rejection_does_not() {
    let acc: Vec<f64> = [4, 16, 64]
        .iter()
        .map(|&n| rejected_fraction(n, DensityMode::Accumulated))
        .collect();
    let per: Vec<f64> = [4, 16, 64]
        .iter()
        .map(|&n| rejected_fraction(n, DensityMode::PerFrame))
        .collect();
    eprintln!("rejected, accumulated {acc:?}, per-frame (2 spp frames) {per:?}");
    // Measured at 4, 16, 64 spp (32 x 32, k = 10): accumulated 1.12%, 0.56%, 0.26% (halving
    // every 4x spp: 64 spp is 0.23x of 4); per-frame with 2-spp frames 2.27%, 2.46%, 2.44%
    // (flat: 1.07x), 9.3x the accumulated one at 64 spp. The bounds sit
    // between those trends.
    assert!(acc[2] < 0.35 * acc[0], "accumulated {acc:?}");
    assert!(per[2] > 0.9 * per[0], "per-frame {per:?}");
    assert!(per[2] > 5.0 * acc[2]);
}

#[test]
fn chains_run_the_next_filter_on_the_cleaned_colour() {
    let scene = bundled_scene("cornell_glossy");
    let mut o = options(&scene, 24, 20, 3);
    let chain = |then| PathDensitySettings {
        then,
        ..Default::default()
    };
    let ddf =
        Configured::typed::<path_density::PathDensity>(chain(Then::Ddf), &SceneInfo::unknown())
            .unwrap();
    o.outputs = ddf.needs();
    assert!(o.outputs.contains(Output::Samples) && o.outputs.contains(Output::Variance));
    o.sample_capacity = 8;
    let frame = render_frame(&scene, &o, 8);
    let info_scene = frame.info().scene.clone();
    let run = |c: &Configured| {
        c.prepare(frame.info(), &gpu())
            .unwrap()
            .run(&frame)
            .unwrap()
            .image
    };
    // The cleaned frame holds the cleaned colour, split with indirect >= 0.
    let clean = run(&Configured::typed::<path_density::PathDensity>(
        chain(Then::None),
        &info_scene,
    )
    .unwrap());
    let ddf_needs = OutputSet::of(&[Output::Variance]);
    let cleaned = path_density::with_colour(&frame, &clean, ddf_needs).unwrap();
    for (f, c) in cleaned.filter_vectors().unwrap().iter().zip(&clean.pixels) {
        for (k, &ck) in c.iter().enumerate() {
            assert!(f.indirect[k] >= 0.0);
            assert!((f.direct[k] + f.indirect[k] - ck).abs() <= 1e-6 * ck.max(1.0));
        }
    }
    // path-density → ddf is ddf (defaults, specialised) on the cleaned frame, bit for bit.
    let registry = Registry::builtin();
    let plain = |name: &str| {
        registry
            .configure(
                registry.get(name).unwrap(),
                &Default::default(),
                &info_scene,
            )
            .unwrap()
    };
    let plain_ddf = plain("ddf");
    let chained =
        run(
            &Configured::typed::<path_density::PathDensity>(chain(Then::Ddf), &info_scene).unwrap(),
        );
    let direct = plain_ddf
        .prepare(cleaned.info(), &gpu())
        .unwrap()
        .run(&cleaned)
        .unwrap()
        .image;
    assert_eq!(chained, direct);
    let atrous = run(&Configured::typed::<path_density::PathDensity>(
        chain(Then::Atrous),
        &info_scene,
    )
    .unwrap());
    assert!(atrous.pixels.iter().flatten().all(|v| v.is_finite()));
    assert_ne!(atrous, clean);
    // path-density → bmfr is bmfr (defaults, specialised) on the cleaned frame, bit for bit
    // (a frame with bmfr's outputs: halves and positions).
    let by =
        |then| Configured::typed::<path_density::PathDensity>(chain(then), &info_scene).unwrap();
    let mut ob = o.clone();
    ob.outputs = by(Then::Bmfr).needs();
    let bmfr_frame = render_frame(&scene, &ob, 8);
    let run_on = |c: &Configured, f: &noisefree::render::Frame| {
        c.prepare(f.info(), &gpu()).unwrap().run(f).unwrap().image
    };
    let plain_bmfr = plain("bmfr");
    let clean_b = run_on(&by(Then::None), &bmfr_frame);
    let cleaned_b = path_density::with_colour(&bmfr_frame, &clean_b, plain_bmfr.needs()).unwrap();
    let via_chain = run_on(&by(Then::Bmfr), &bmfr_frame);
    assert_eq!(via_chain, run_on(&plain_bmfr, &cleaned_b));
    assert!(via_chain.pixels.iter().flatten().all(|v| v.is_finite()));
    assert_ne!(via_chain, clean_b);
}

/// Through a thin lens bmfr splits the emission off and prefilters the albedo (auto): the
/// chain, whose outputs are chosen before the camera is known, gathers what those read, and
/// runs bmfr specialised to the lens on the cleaned colour, bit for bit. (Before, the
/// quality study stopped on conference_dof: no emission output.)
#[test]
fn the_bmfr_chain_runs_through_a_lens() {
    let scene = bundled_scene("cornell_diffuse_dof");
    let chain = Configured::typed::<path_density::PathDensity>(
        PathDensitySettings {
            then: Then::Bmfr,
            ..Default::default()
        },
        &SceneInfo::unknown(),
    )
    .unwrap();
    let mut o = options(&scene, 40, 32, 4);
    o.outputs = chain.needs();
    o.sample_capacity = 8;
    let frame = render_frame(&scene, &o, 8);
    let info_scene = frame.info().scene.clone();
    let registry = Registry::builtin();
    let bmfr = registry
        .configure(
            registry.get("bmfr").unwrap(),
            &Default::default(),
            &info_scene,
        )
        .unwrap();
    assert!(
        bmfr.needs().contains(Output::Emission),
        "the lens splits the emission off"
    );
    let run_on = |c: &Configured, f: &noisefree::render::Frame| {
        c.prepare(f.info(), &gpu()).unwrap().run(f).unwrap().image
    };
    let clean = run_on(
        &Configured::typed::<path_density::PathDensity>(Default::default(), &info_scene).unwrap(),
        &frame,
    );
    let cleaned = path_density::with_colour(&frame, &clean, bmfr.needs()).unwrap();
    let via_chain = run_on(&chain, &frame);
    assert_eq!(via_chain, run_on(&bmfr, &cleaned));
    assert!(via_chain.pixels.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn the_two_light_scenes_load_render_and_filter() {
    // scenes/decoro/ (not bundled scenes): the study's two-light cases stay loadable and
    // renderable, and the filter's output there is finite (their numbers: results/README.md).
    for name in ["two_lights", "two_lights_small"] {
        let scene = noisefree::scene::load_scene(&repo_path(&format!("scenes/decoro/{name}.toml")))
            .unwrap_or_else(|e| panic!("{name}: {e:#}"));
        let mut o = options(&scene, 32, 32, 1);
        o.outputs = OutputSet::of(&[Output::Samples]);
        o.sample_capacity = 8;
        let frame = render_frame(&scene, &o, 8);
        let c =
            Configured::typed::<path_density::PathDensity>(Default::default(), &frame.info().scene)
                .unwrap();
        let image = c
            .prepare(frame.info(), &gpu())
            .unwrap()
            .run(&frame)
            .unwrap()
            .image;
        assert!(
            image.pixels.iter().flatten().all(|v| v.is_finite()),
            "{name}"
        );
        let plain = frame.beauty().unwrap();
        assert_eq!((image.width, image.height), (plain.width, plain.height));
    }
}

/// A scene of scenes/decoro/ rendered at `size` x `size` with `spp` samples stored.
fn decoro_frame(name: &str, size: u32, spp: u32) -> noisefree::render::Frame {
    let scene = noisefree::scene::load_scene(&repo_path(&format!("scenes/decoro/{name}.toml")))
        .unwrap_or_else(|e| panic!("{name}: {e:#}"));
    let mut o = options(&scene, size, size, 1);
    o.outputs = OutputSet::of(&[Output::Samples]);
    o.sample_capacity = spp;
    render_frame(&scene, &o, spp)
}

/// The filtered image and the (rejected, down-weighted) fractions of `frame` with `settings`.
fn density_run(
    frame: &noisefree::render::Frame,
    settings: PathDensitySettings,
) -> (noisefree::imaging::RgbImage, (f64, f64)) {
    let mut k = PathDensityKernel::new(gpu(), settings.params()).unwrap();
    let image = k.run(frame).unwrap().image;
    (image, k.densities().unwrap().fractions())
}

fn luminance(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// The brightness (luminance sum) of the pixels beside the lines and of the cells' inner
/// pixels, each relative to `reference`'s, and their counts. Line pixels are those darker
/// than 5 % of the reference's median (the black lines and border), classified in the
/// reference; "beside" is 4-adjacent to one.
fn line_stats(
    img: &noisefree::imaging::RgbImage,
    reference: &noisefree::imaging::RgbImage,
) -> (f64, f64, usize, usize) {
    let (w, h) = (reference.width as usize, reference.height as usize);
    let lum_ref: Vec<f64> = reference.pixels.iter().map(|&c| luminance(c)).collect();
    let mut sorted = lum_ref.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let line: Vec<bool> = lum_ref.iter().map(|&l| l < 0.05 * median).collect();
    let (mut b_img, mut b_ref, mut i_img, mut i_ref, mut nb, mut ni) = (0.0, 0.0, 0.0, 0.0, 0, 0);
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            if line[p] {
                continue;
            }
            let beside = [(0i64, 1i64), (0, -1), (1, 0), (-1, 0)]
                .iter()
                .any(|(dx, dy)| {
                    let (qx, qy) = (x as i64 + dx, y as i64 + dy);
                    qx >= 0
                        && qy >= 0
                        && qx < w as i64
                        && qy < h as i64
                        && line[qy as usize * w + qx as usize]
                });
            let l = luminance(img.pixels[p]);
            if beside {
                b_img += l;
                b_ref += lum_ref[p];
                nb += 1;
            } else {
                i_img += l;
                i_ref += lum_ref[p];
                ni += 1;
            }
        }
    }
    (b_img / b_ref, i_img / i_ref, nb, ni)
}

/// Line growth per side of a line, in pixels, of `img` against `plain` (the unfiltered mean
/// of the same samples), from [`line_stats`]: how much more the pixels beside the lines lost
/// than the cells' inner pixels (a border pixel is a one-pixel strip along a line side, so
/// its relative loss is the black width it gained; the inner pixels' loss is the filter's
/// global one, not a width).
fn line_growth(
    img: &noisefree::imaging::RgbImage,
    plain: &noisefree::imaging::RgbImage,
    reference: &noisefree::imaging::RgbImage,
) -> f64 {
    let (bi, ii, _, _) = line_stats(img, reference);
    let (bp, ip, _, _) = line_stats(plain, reference);
    (1.0 - bi / bp) - (1.0 - ii / ip)
}

#[test]
fn the_colour_grid_keeps_its_line_widths_in_cielab_and_grows_them_in_rgb() {
    // DeCoro 2009 Fig. 5.9 on scenes/decoro/color_grid.toml: black lines about 1.5 pixels
    // wide at 64 x 64 between bright, noisy cells.
    let size = 64;
    let scene = noisefree::scene::load_scene(&repo_path("scenes/decoro/color_grid.toml")).unwrap();
    let reference = reference_image(&scene, size, size, 1024, 7);
    let (_, _, beside, inner) = line_stats(&reference, &reference);
    assert!(beside > 400 && inner > 2000, "{beside} {inner}");
    let mut growth = Vec::new();
    for spp in [4u32, 16] {
        let frame = decoro_frame("color_grid", size, spp);
        let plain = frame.beauty().unwrap();
        let (lab, fl) = density_run(&frame, Default::default());
        let rgb_settings = PathDensitySettings {
            color_space: ColorSpace::Rgb,
            ..Default::default()
        };
        let (rgb, fr) = density_run(&frame, rgb_settings);
        let (gl, gr) = (
            line_growth(&lab, &plain, &reference),
            line_growth(&rgb, &plain, &reference),
        );
        eprintln!(
            "{spp} spp: line growth per side (pixels) cielab {gl:.5}, rgb {gr:.5}; rejected \
             cielab {fl:?}, rgb {fr:?}; beside/inner brightness plain {:?} cielab {:?} rgb {:?}",
            line_stats(&plain, &reference),
            line_stats(&lab, &reference),
            line_stats(&rgb, &reference)
        );
        growth.push((gl, gr));
    }
    // Measured (PoCL, seed 1, reference 1024 spp seed 7): growth per side 0.0055 px (cielab)
    // and 0.100 px (rgb) at 4 spp, 0.00047 and 0.034 px at 16 spp: 18x and 73x. The RGB
    // distance rejects 7.0 % / 0.84 % of the samples against CIELAB's 0.16 % / 0.015 %, and
    // those beside the lines most (the pixels beside the lines lose 20 % / 5.5 % of their
    // brightness, the cells' inner ones 10 % / 2.1 %). Bounds: CIELAB's growth at most 2x / 4x
    // the measured, RGB's at least 0.7x, and the RGB growth at least 10x CIELAB's.
    let [(l4, r4), (l16, r16)] = growth[..] else {
        unreachable!()
    };
    assert!(
        l4.abs() < 0.01 && l16.abs() < 0.002,
        "cielab grows the lines: {growth:?}"
    );
    assert!(
        r4 > 0.07 && r16 > 0.025,
        "rgb does not grow the lines: {growth:?}"
    );
    assert!(r4 > 10.0 * l4.abs() && r16 > 10.0 * l16.abs(), "{growth:?}");
}

#[test]
fn the_specular_interior_loses_its_fireflies_and_rejects_less_with_spp() {
    // DeCoro 2009 Fig. 5.1a on scenes/decoro/specular_interior.toml: the ceiling, lit only
    // through the mirror floor and the metal walls, is fireflies at low spp.
    let size = 64;
    let scene =
        noisefree::scene::load_scene(&repo_path("scenes/decoro/specular_interior.toml")).unwrap();
    let reference = reference_image(&scene, size, size, 1024, 7);
    let mut rows = Vec::new();
    for spp in [4u32, 16, 64] {
        let frame = decoro_frame("specular_interior", size, spp);
        let plain = frame.beauty().unwrap();
        let (filtered, (rejected, reduced)) = density_run(&frame, Default::default());
        let (mp, mf) = (
            mse(&plain.pixels, &reference.pixels),
            mse(&filtered.pixels, &reference.pixels),
        );
        eprintln!(
            "{spp} spp: MSE unfiltered {mp:.5}, path-density {mf:.5} ({:.3}x); rejected \
             {rejected:.5}, down-weighted {reduced:.5}",
            mf / mp
        );
        rows.push((mp, mf, rejected));
    }
    // Measured (PoCL, seed 1, reference 1024 spp seed 7): MSE ratio filtered / unfiltered
    // 0.323, 0.589, 0.886 at 4, 16, 64 spp (the fireflies go, and the bias the filter adds
    // shrinks with them); rejected 3.25 %, 1.47 %, 0.245 % (16 spp: 0.45x, 64 spp: 0.075x of
    // 4 spp). Bounds 1.07-1.3x the measured ratios, 2x for the 64-spp rejection.
    let ratio: Vec<f64> = rows.iter().map(|(mp, mf, _)| mf / mp).collect();
    assert!(
        ratio[0] < 0.4 && ratio[1] < 0.7 && ratio[2] < 0.95,
        "MSE ratios {ratio:?}"
    );
    let rej: Vec<f64> = rows.iter().map(|r| r.2).collect();
    assert!(
        rej[1] < 0.6 * rej[0] && rej[2] < 0.15 * rej[0],
        "rejected {rej:?}"
    );
}
