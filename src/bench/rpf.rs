//! RPF against the thesis's own measurements (ch. 5), two studies that are not in the default
//! set (each takes hours at 512 × 512 on a 2-core CPU; `--size 256` screens in a quarter):
//!
//! - `rpf-readings`: the error of RPF at 8 spp on the thesis's five scenes with each reading
//!   the port made where the text is open, one at a time from the defaults (the colours of the
//!   range term, the mutual-information buckets, κ of Alg. 6 line 8, σ²₈ of §5.1.4, the final
//!   box filter), against the thesis's "≈ 4× lower MSE" (§5.2.2, Table 5.4); and each image's
//!   mean colour against the reference's (measured: RPF darkens, 0.6-2.4 % on the Cornell
//!   boxes and 7 % on the conference room, whose fireflies its range term weighs down).
//! - `rpf-scale`: Tables 5.3-5.4 and Figs. 5.13-5.15: the Cornell scenes unscaled and scaled
//!   down ×2, ×4, ×8, RPF's time and error against the (unscaled) reference, and the error
//!   between the filtered unscaled and scaled images, beside the thesis's values.

use std::time::Instant;

use anyhow::Result;

use super::study::{STUDY_SEED, StudyScene, reference_image, sizes};
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::rpf::{self, RangeColors, Rpf, RpfSettings, SampleSet};
use crate::filters::{Auto, FilterKind};
use crate::imaging::RgbImage;
use crate::layout::outputs::{Output, OutputSet};
use crate::metrics;

/// The scenes of the thesis's experiments (ch. 5 used the three Cornell boxes; ch. 7 all five).
pub const THESIS_SCENES: [&str; 5] = [
    "cornell_diffuse",
    "cornell_glossy",
    "cornell_plane",
    "conference",
    "outside",
];

/// Table 5.4 (unscaled, ×2, ×4, ×8 scaled down): MSE in CIELUV unfiltered and filtered.
const TABLE_5_4: [(&str, [(f64, f64); 4]); 3] = [
    (
        "cornell_diffuse",
        [
            (42.317, 8.642),
            (41.444, 8.653),
            (41.108, 8.794),
            (40.993, 8.852),
        ],
    ),
    (
        "cornell_glossy",
        [
            (40.248, 9.063),
            (38.503, 8.969),
            (38.684, 9.029),
            (38.881, 9.086),
        ],
    ),
    (
        "cornell_plane",
        [
            (39.920, 18.749),
            (36.517, 12.346),
            (36.724, 12.170),
            (36.163, 12.280),
        ],
    ),
];

/// Table 5.3: mean filter time in seconds over three runs, one core of an i5-3570K.
const TABLE_5_3: [(&str, [f64; 4]); 3] = [
    ("cornell_diffuse", [4623.67, 4686.67, 4765.33, 5652.00]),
    ("cornell_glossy", [4072.33, 4062.67, 4092.67, 4396.00]),
    ("cornell_plane", [5412.67, 3712.67, 3719.33, 3742.00]),
];

/// The scale factors of Tables 5.3-5.4: unscaled, scaled down ×2, ×4, ×8.
const SCALES: [u32; 4] = [1, 2, 4, 8];

/// A reading of RPF: a label and how it changes the (scene-specialised) defaults.
pub struct Reading {
    pub label: &'static str,
    pub what: &'static str,
    pub apply: fn(&mut RpfSettings),
}

/// Every reading measured by `rpf-readings`, the defaults first.
pub fn readings() -> Vec<Reading> {
    let r = |label, what, apply| Reading { label, what, apply };
    vec![
        r("defaults", "the port's defaults", |_| {}),
        r(
            "range-original",
            "eq. 5.2's colour distance on the original colours",
            |s| s.range_colors = RangeColors::Original,
        ),
        r("buckets-3", "3 histogram buckets (Alg. 7)", |s| {
            s.mi_buckets = 3
        }),
        r("buckets-8", "8 histogram buckets", |s| s.mi_buckets = 8),
        r("buckets-16", "16 histogram buckets", |s| s.mi_buckets = 16),
        r(
            "buckets-unit",
            "Peng's buckets, one standard deviation wide (the code Sen & Darabi cite)",
            |s| s.mi_bucketing = rpf::MiBucketing::Unit,
        ),
        r(
            "kappa-3",
            "κ = 3 for world positions too (Alg. 6 line 8 read as 3 everywhere)",
            |s| s.world_position_tolerance = 3.0,
        ),
        r(
            "kappa-30",
            "κ = 30 for every feature (line 8 read as 30 everywhere)",
            |s| s.feature_tolerance = 30.0,
        ),
        r(
            "sigma2-0.002",
            "σ²₈ = 0.002 (§5.1.4's outdoor value)",
            |s| s.sigma2_8 = Auto::Set(0.002),
        ),
        r(
            "sigma2-0.02",
            "σ²₈ = 0.02 (§5.1.4's indoor value)",
            |s| s.sigma2_8 = Auto::Set(0.02),
        ),
        r(
            "sigma2-0.2",
            "σ²₈ = 0.2 (ten times the indoor value)",
            |s| s.sigma2_8 = Auto::Set(0.2),
        ),
        r(
            "box-3x3",
            "final box filter over 3 × 3 pixels (§3.1.1's box filter)",
            |s| s.final_box = 3,
        ),
    ]
}

/// The 8-spp sample vectors and the unfiltered image of a study scene.
fn render_samples(ctx: &Context, study: &StudyScene) -> Result<(SampleSet, RgbImage)> {
    let s = sizes(ctx);
    let outputs = OutputSet::of(&[Output::Colour, Output::Samples]);
    let mut r = study.renderer(ctx, &s, outputs, 8)?;
    r.render_samples(8)?;
    let frame = r.frame();
    Ok((
        SampleSet::from_frame(&frame, Default::default())?,
        frame.beauty()?,
    ))
}

/// RPF with `settings` and the seconds it took.
fn run_rpf(ctx: &Context, set: &SampleSet, settings: &RpfSettings) -> Result<(RgbImage, f64)> {
    let start = Instant::now();
    let bar = if ctx.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(1000)
    };
    let callback = rpf::progress_bar_callback(&bar, &settings.box_sizes);
    let out = rpf::filter_with_progress(set, settings, &callback)?;
    bar.finish_and_clear();
    Ok((out.image, start.elapsed().as_secs_f64()))
}

/// Mean of each channel of `img` over the mean of `reference`'s.
fn mean_ratio(img: &RgbImage, reference: &RgbImage) -> [f64; 3] {
    let mean = |i: &RgbImage| {
        let mut m = [0.0f64; 3];
        for p in &i.pixels {
            for k in 0..3 {
                m[k] += p[k] as f64;
            }
        }
        m
    };
    let (a, b) = (mean(img), mean(reference));
    std::array::from_fn(|k| a[k] / b[k])
}

/// The thesis's scenes among the run's (all of them when none is one of the five).
fn thesis_scenes(ctx: &Context) -> Vec<std::path::PathBuf> {
    let named: Vec<_> = ctx
        .scenes
        .iter()
        .filter(|p| {
            THESIS_SCENES
                .iter()
                .any(|n| p.ends_with(format!("{n}.toml")))
        })
        .cloned()
        .collect();
    if named.is_empty() {
        ctx.scenes.clone()
    } else {
        named
    }
}

/// `rpf-readings` (module docs).
pub fn rpf_readings(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let columns = [
        "scene",
        "reading",
        "size",
        "mse_luv",
        "unfiltered_mse_luv",
        "gain",
        "ssim",
        "mean_r",
        "mean_g",
        "mean_b",
        "unfiltered_mean",
        "seconds",
    ];
    let mut t = ctx.table("rpf-readings", &columns, 3, fresh)?;
    let size = format!("{}x{}", s.width, s.height);
    let scenes = thesis_scenes(ctx);
    let all = readings();
    let pb = bar(ctx, (scenes.len() * all.len()) as u64, "rpf-readings");
    for path in &scenes {
        let study = StudyScene::load(path, &s, STUDY_SEED)?;
        let key = |r: &Reading| vec![study.name.clone(), r.label.to_string(), size.clone()];
        if all.iter().all(|r| t.has(&key(r))) {
            pb.inc(all.len() as u64);
            continue;
        }
        let reference = reference_image(ctx, path, &s)?;
        ctx.say(&format!("rpf-readings: {} at 8 spp", study.name));
        let (set, noisy) = render_samples(ctx, &study)?;
        let before = metrics::compare(&noisy, &reference)?.mse_luv;
        let noisy_mean = mean_ratio(&noisy, &reference).iter().sum::<f64>() / 3.0;
        for r in &all {
            pb.set_message(format!("rpf-readings: {} {}", study.name, r.label));
            if t.has(&key(r)) {
                pb.inc(1);
                continue;
            }
            let mut settings = RpfSettings::default();
            Rpf::specialise(&mut settings, &study.info);
            (r.apply)(&mut settings);
            let (img, secs) = run_rpf(ctx, &set, &settings)?;
            let m = metrics::compare(&img, &reference)?;
            let ratio = mean_ratio(&img, &reference);
            let mut row = key(r);
            row.extend([m.mse_luv, before, before / m.mse_luv, m.ssim].map(num));
            row.extend(ratio.map(num));
            row.extend([num(noisy_mean), num(secs)]);
            t.push(row)?;
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    std::fs::write(ctx.out.join("rpf-readings.md"), readings_report(&t)?)?;
    Ok(())
}

fn readings_report(t: &ResultTable) -> Result<String> {
    let mut md = String::from(
        "# RPF: the readings against the thesis's gain (§5.2.2, Table 5.4)\n\n\
         `noisefree bench --study rpf-readings`: RPF at 8 spp on the thesis's scenes with each \
         reading the port made where the text is open, one at a time from the defaults. `gain` \
         is the unfiltered MSE over RPF's (MSE in CIELUV against the reference, the thesis's \
         metric); the thesis reports \"≈ 4× lower MSE\" (Table 5.4: 4.9× Cornell diffuse, \
         4.4× glossy, 2.1× plane, unscaled). `mean_*` is the image's mean colour over the \
         reference's (`unfiltered_mean`: the unfiltered image's, all channels).\n\n\
         Readings:\n\n",
    );
    for r in readings() {
        md.push_str(&format!("- `{}`: {}\n", r.label, r.what));
    }
    md.push_str("\nGain per scene and reading:\n\n");
    let recs = t.records();
    for size in super::table::distinct(&recs, "size") {
        let scenes: Vec<&str> = super::table::distinct(&recs, "scene")
            .into_iter()
            .filter(|sc| recs.iter().any(|r| r["scene"] == *sc && r["size"] == size))
            .collect();
        md.push_str(&format!("{size}:\n\n| reading | "));
        md.push_str(&scenes.join(" | "));
        md.push_str(" | mean |\n|---|");
        md.push_str(&"---|".repeat(scenes.len() + 1));
        md.push('\n');
        for r in readings() {
            let gains: Vec<Option<f64>> = scenes
                .iter()
                .map(|sc| {
                    recs.iter()
                        .find(|x| x["scene"] == *sc && x["reading"] == r.label && x["size"] == size)
                        .and_then(|x| x["gain"].parse().ok())
                })
                .collect();
            if gains.iter().all(Option::is_none) {
                continue;
            }
            let known: Vec<f64> = gains.iter().flatten().copied().collect();
            let mean = known.iter().sum::<f64>() / known.len() as f64;
            md.push_str(&format!("| `{}` | ", r.label));
            for g in &gains {
                md.push_str(&g.map_or("".into(), |g| format!("{g:.2}x")));
                md.push_str(" | ");
            }
            md.push_str(&format!("{mean:.2}x |\n"));
        }
        md.push('\n');
    }
    md.push_str("All measurements:\n\n");
    md.push_str(&t.markdown());
    Ok(md)
}

/// `rpf-scale` (module docs).
pub fn rpf_scale(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let columns = [
        "scene",
        "scale_down",
        "size",
        "unfiltered_mse_luv",
        "mse_luv",
        "gain",
        "mse_vs_unscaled",
        "seconds",
        "thesis_unfiltered",
        "thesis_mse",
        "thesis_seconds",
    ];
    let mut t = ctx.table("rpf-scale", &columns, 3, fresh)?;
    let size = format!("{}x{}", s.width, s.height);
    let pb = bar(ctx, (TABLE_5_4.len() * SCALES.len()) as u64, "rpf-scale");
    for (i, (name, thesis)) in TABLE_5_4.iter().enumerate() {
        let path = ctx.scene_file(name)?;
        let key = |f: u32| vec![name.to_string(), f.to_string(), size.clone()];
        if SCALES.iter().all(|&f| t.has(&key(f))) {
            pb.inc(SCALES.len() as u64);
            continue;
        }
        let reference = reference_image(ctx, &path, &s)?;
        let scene = crate::scene::load_scene(&path)?;
        let mut unscaled: Option<RgbImage> = None;
        for (k, &f) in SCALES.iter().enumerate() {
            pb.set_message(format!("rpf-scale: {name} /{f}"));
            let study = StudyScene::from_scene(name, scene.scaled(1.0 / f as f32), &s, STUDY_SEED)?;
            let (set, noisy) = render_samples(ctx, &study)?;
            let mut settings = RpfSettings::default();
            Rpf::specialise(&mut settings, &study.info);
            let (img, secs) = run_rpf(ctx, &set, &settings)?;
            let vs_unscaled = match &unscaled {
                None => 0.0,
                Some(u) => metrics::compare(&img, u)?.mse_luv,
            };
            if !t.has(&key(f)) {
                let before = metrics::compare(&noisy, &reference)?.mse_luv;
                let after = metrics::compare(&img, &reference)?.mse_luv;
                let mut row = key(f);
                row.extend([before, after, before / after, vs_unscaled, secs].map(num));
                row.extend([thesis[k].0, thesis[k].1, TABLE_5_3[i].1[k]].map(num));
                t.push(row)?;
            }
            if f == 1 {
                unscaled = Some(img);
            }
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    let mut md = String::from(
        "# RPF against the scene scale (thesis Tables 5.3-5.4, Figs. 5.10-5.15)\n\n\
         `noisefree bench --study rpf-scale`: the Cornell scenes unscaled and scaled down ×2, \
         ×4, ×8 (geometry, lights and camera scaled together, so the image is the same), \
         8 spp. `mse_luv`: RPF against the unscaled scene's reference (MSE in CIELUV, the \
         thesis's metric); `mse_vs_unscaled`: RPF's image of the scaled scene against RPF's \
         image of the unscaled one (Figs. 5.13-5.15); `seconds`: RPF's wall-clock time on this \
         machine, every thread. The thesis's columns are Table 5.4's MSE and Table 5.3's mean \
         time on one core of an i5-3570K. The scale only enters RPF through the 0.1 floor of \
         Alg. 6 line 8, in scene units.\n\n",
    );
    md.push_str(&t.markdown());
    std::fs::write(ctx.out.join("rpf-scale.md"), md)?;
    Ok(())
}
