//! `aaf-shadows`: Wang 2013 Fig. 3.6 and its claim ("adaptive AAF at 27 average spp matches
//! Monte Carlo at 165 spp") on Grids, the scene it was measured on. Not in the default set.
//!
//! Three curves of error against samples per pixel, each point one render at the study's size
//! against the 2048-spp reference:
//!
//! - **Monte Carlo**: `spp` path samples, each with one shadow ray to the light (Grids is
//!   direct light only);
//! - **AAF, not adaptive**: 16 path samples for the rest of the image, and `n` light samples
//!   for every receiver (sparse = max = n), filtered;
//! - **AAF, adaptive**: the same with the sparse pass at 9 and eq. 3.5's n(x) clamped to a
//!   maximum, the average spent Σn / N² on the x axis.
//!
//! The seed counts only the light samples of AAF (its renders have no path samples); ours keep
//! 16 path samples per pixel for silhouettes and other light, each with a shadow ray, so the
//! table gives both counts and the Monte Carlo spp of equal MSE for both. Every row has its
//! kernel time (render, shadow passes and filter), for the error-against-time figure.

use anyhow::{Result, bail};

use super::curves::loglog_where;
use super::plot::{Chart, Series, line_chart};
use super::study::{STUDY_SEED, StudyScene, reference_image, sizes};
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::Configured;
use crate::filters::aaf_shadows::{AafShadowSettings, AafShadows};
use crate::imaging::write_rgb8_png;
use crate::layout::outputs::{Output, OutputSet};
use crate::metrics::mse_rgb;
use crate::render::Renderer;

/// Path samples per pixel of the AAF renders (the rest of the image, and the replaced term).
const AAF_PATH_SPP: u32 = 16;

/// One render of the study: (method, setting, path spp, shadow sampling).
fn plan(quick: bool) -> Vec<(&'static str, u32, AafShadowSettings)> {
    let aaf = |sparse, max| AafShadowSettings {
        sparse_spp: sparse,
        max_spp: max,
        ..Default::default()
    };
    let mut v = Vec::new();
    let mc: &[u32] = if quick {
        &[4, 16, 64]
    } else {
        &[4, 8, 16, 32, 64, 128, 256]
    };
    for &spp in mc {
        v.push(("mc", spp, AafShadowSettings::default()));
    }
    let fixed: &[u32] = if quick { &[4, 16] } else { &[4, 9, 16, 36, 64] };
    for &n in fixed {
        v.push(("aaf-fixed", n, aaf(n, n)));
    }
    let max: &[u32] = if quick {
        &[36]
    } else {
        &[16, 36, 64, 100, 196, 400]
    };
    for &m in max {
        v.push(("aaf-adaptive", m, aaf(9, m)));
    }
    v
}

const COLUMNS: [&str; 10] = [
    "scene",
    "size",
    "method",
    "setting",
    "path_spp",
    "light_spp",
    "shadow_rays_spp",
    "mse_rgb",
    "rms",
    "seconds",
];

/// `aaf-shadows` (module docs).
pub fn aaf_shadows(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let path = ctx.scene_file("grids")?;
    if !path.exists() {
        bail!(
            "the aaf-shadows study renders {}, which is missing",
            path.display()
        );
    }
    let mut t = ctx.table("aaf-shadows", &COLUMNS, 4, fresh)?;
    let size = format!("{}x{}", s.width, s.height);
    let study = StudyScene::load(&path, &s, STUDY_SEED)?;
    let reference = reference_image(ctx, &path, &s)?;
    let cells = plan(ctx.quick);
    let pb = bar(ctx, cells.len() as u64, "aaf-shadows");
    for (method, setting, settings) in cells {
        let key = vec![
            study.name.clone(),
            size.clone(),
            method.to_string(),
            setting.to_string(),
        ];
        pb.set_message(format!("aaf-shadows: {method} {setting}"));
        if t.has(&key) {
            pb.inc(1);
            continue;
        }
        let (img, path_spp, light_spp, seconds, spp_map) = if method == "mc" {
            let mut r = study.renderer(ctx, &s, OutputSet::colour(), setting)?;
            r.render_samples(setting)?;
            let img = r.frame().beauty()?;
            (img, setting, setting as f64, r.kernel_time_total, None)
        } else {
            let c = Configured::typed::<AafShadows>(settings, &study.info)?;
            let mut r = aaf_renderer(ctx, &study, &s, &c)?;
            r.render_samples(AAF_PATH_SPP)?;
            let (_, stats) = r.shadow_stats().expect("the shadow output");
            let frame = r.frame();
            let run = c.prepare(frame.info(), &ctx.gpu)?.run(&frame)?;
            let filter_time = run.kernel_time.unwrap_or(run.wall_time);
            // The spp map of one adaptive row (max 100, the default) as a picture.
            let map = if method == "aaf-adaptive" && setting == 100 {
                let [(_, spp), _] = crate::stats::aov::shadow_pictures(&frame)?;
                Some(spp)
            } else {
                None
            };
            let secs = r.kernel_time_total + filter_time;
            (run.image, AAF_PATH_SPP, stats.average_spp, secs, map)
        };
        let mse = mse_rgb(&img, &reference)?;
        let mut row = key;
        row.push(path_spp.to_string());
        let rays = light_spp + if method == "mc" { 0.0 } else { path_spp as f64 };
        row.extend([light_spp, rays, mse, mse.sqrt(), seconds.as_secs_f64()].map(num));
        t.push(row)?;
        if let Some(bytes) = spp_map {
            let p = ctx.out.join(format!("aaf-spp-{}.png", study.name));
            write_rgb8_png(&p, &bytes, s.width, s.height)?;
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    report(ctx, &t, &study.name, &size)
}

/// A renderer gathering what `c` (aaf-shadows) needs, its shadow sampling set.
fn aaf_renderer(
    ctx: &Context,
    study: &StudyScene,
    s: &super::study::Sizes,
    c: &Configured,
) -> Result<Renderer> {
    let mut o = super::study::options(&study.scene, s, study.arrays.params.seed);
    o.outputs = OutputSet::colour().union(c.needs());
    debug_assert!(o.outputs.contains(Output::Shadows));
    c.adjust_render(&mut o);
    Renderer::with_arrays(ctx.gpu.clone(), &study.scene, study.arrays.clone(), &o)
}

/// The curves of one method from the table: (x, MSE) by `x_column`, sorted by x.
fn curve(t: &ResultTable, at: (&str, &str), method: &str, x_column: &str) -> Vec<(f64, f64)> {
    let (scene, size) = at;
    let mut v: Vec<(f64, f64)> = t
        .records()
        .iter()
        .filter(|r| r["scene"] == scene && r["size"] == size && r["method"] == method)
        .filter_map(|r| Some((r[x_column].parse().ok()?, r["mse_rgb"].parse().ok()?)))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// aaf-shadows.md (the table with Monte Carlo's spp at equal MSE) and the two figures.
fn report(ctx: &Context, t: &ResultTable, scene: &str, size: &str) -> Result<()> {
    let reference_spp = sizes(ctx).reference_spp;
    let at = (scene, size);
    let mc = curve(t, at, "mc", "light_spp");
    let mc_time = curve(t, at, "mc", "seconds");
    let mut md = format!(
        "# AAF soft shadows against Monte Carlo (Wang 2013 Fig. 3.6)\n\n\
         `noisefree bench --study aaf-shadows`: Grids at {}, each render against the {}-spp \
         reference (MSE in linear RGB). AAF renders take 16 path samples per pixel for the \
         rest of the image plus the light samples of the shadow passes; `light_spp` counts \
         the latter (the seed's axis: Σn / N² for the adaptive rows), `shadow_rays_spp` both. \
         \"MC spp at equal MSE\" is the Monte Carlo spp of equal MSE (log-log interpolation of \
         the Monte Carlo rows, slope −1 beyond them: marked *), the ratios it over light spp \
         and over shadow rays spp, and \"MC seconds at equal MSE\" Monte Carlo's time for that \
         MSE, interpolated the same way. Seconds: kernel time of the render, the shadow passes \
         and the filter.\n\n\
         | method | setting | light spp | shadow rays spp | RMS | seconds | MC spp at equal MSE | ratio (light) | ratio (rays) | MC seconds at equal MSE |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
        size, reference_spp
    );
    for r in t
        .records()
        .iter()
        .filter(|r| r["scene"] == scene && r["size"] == size)
    {
        let (light, rays, mse): (f64, f64, f64) = (
            r["light_spp"].parse()?,
            r["shadow_rays_spp"].parse()?,
            r["mse_rgb"].parse()?,
        );
        let equal = if r["method"] == "mc" {
            None
        } else {
            loglog_where(&mc, mse)
        };
        let time = if r["method"] == "mc" {
            None
        } else {
            loglog_where(&mc_time, mse)
        };
        let time = time.map_or(String::new(), |(x, ex)| {
            format!("{x:.3}{}", if ex { "*" } else { "" })
        });
        let (eq, ratio_l, ratio_r) = match equal {
            Some((x, extrapolated)) => (
                format!("{x:.0}{}", if extrapolated { "*" } else { "" }),
                format!("{:.2}", x / light),
                format!("{:.2}", x / rays),
            ),
            None => ("".into(), "".into(), "".into()),
        };
        md.push_str(&format!(
            "| {} | {} | {:.1} | {:.1} | {} | {} | {eq} | {ratio_l} | {ratio_r} | {time} |\n",
            r["method"], r["setting"], light, rays, r["rms"], r["seconds"]
        ));
    }
    md.push_str(&format!(
        "\nFigures: `aaf-shadows-{scene}.png` (RMS against light samples per pixel, log-log, as \
         Fig. 3.6), `aaf-shadows-time-{scene}.png` (RMS against seconds), `aaf-spp-{scene}.png` \
         (the adaptive row with max 100: samples per pixel, colour-mapped from 0 to the most \
         any pixel took).\n"
    ));
    std::fs::write(ctx.out.join("aaf-shadows.md"), md)?;
    let rms = |c: Vec<(f64, f64)>| c.into_iter().map(|(x, m)| (x, m.sqrt())).collect();
    let methods = [
        ("mc", "Monte Carlo"),
        ("aaf-fixed", "AAF, not adaptive"),
        ("aaf-adaptive", "AAF, adaptive (sparse 9)"),
    ];
    let series = |x: &str| -> Vec<Series> {
        methods
            .iter()
            .map(|(m, label)| Series {
                label: label.to_string(),
                points: rms(curve(t, at, m, x)),
            })
            .collect()
    };
    let chart = |title: &str, x_label: &str| Chart {
        title: title.into(),
        x_label: x_label.into(),
        y_label: "RMS error (linear RGB)".into(),
        log_x: true,
        log_y: true,
    };
    line_chart(
        &ctx.out.join(format!("aaf-shadows-{scene}.png")),
        &chart(
            &format!("{scene}: error against light samples (Fig. 3.6)"),
            "light samples per pixel",
        ),
        &series("light_spp"),
    )?;
    line_chart(
        &ctx.out.join(format!("aaf-shadows-time-{scene}.png")),
        &chart(
            &format!("{scene}: error against time"),
            "kernel seconds (render, shadow passes, filter)",
        ),
        &series("seconds"),
    )
}
