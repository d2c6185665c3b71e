//! `aaf-indirect`: diffuse indirect light filtered by AAF (Wang 2013 ch. 4) and by sheared
//! filtering (Yan et al. 2015 §3.1, the GI effect) against Monte Carlo and against each other
//! at equal quality: the seed's claims for its ROOM and SIBENIK scenes ("equal quality AAF
//! requires 6× as many samples as our method, and is 4× slower", Fig. 8; "filter overhead
//! ≈ 1.2× AAF's", Table II). Not in the default set.
//!
//! Each point is one render at the study's size against the 2048-spp reference:
//!
//! - **Monte Carlo**: `spp` path samples, each carrying one indirect path;
//! - **AAF, not adaptive**: 16 path samples (the direct light, unfiltered, and the rest of the
//!   image) and `n` indirect samples for every receiver (sparse = max = n), filtered;
//! - **AAF, adaptive**: the same with the sparse pass at 9 and eq. 4.6's n(x) clamped to a
//!   maximum, the average spent Σn / N² on the x axis;
//! - **Sheared**: the same 16 path samples and the l × l GI field over the v-plane (l = 2, 3,
//!   4), filtered by `sheared` with effect "gi"; one more row at l = 3 without the shear.
//!
//! The x axis is the indirect samples per pixel (`indirect_spp`: Monte Carlo's path samples;
//! the filters' pass samples, Σ / N²), as the seed counts them; `rays_spp` adds the path
//! samples. The error is the whole image's, so the scenes of this study should have a
//! nearly noise-free direct term (scenes/room_gi.toml: one small light, the seed's point
//! light) or the filters' shared 16-spp direct noise sets a floor under both (cornell_diffuse:
//! the area light's penumbrae; its tables compare relMSE as well). Scenes: room_gi, or those
//! `--scene` names that have a pinhole camera (GI is a pinhole effect).

use anyhow::{Context as _, Result};

use super::curves::{MSE, REL_MSE, curve, loglog_where, sheared_against_aaf};
use super::pass_study::{error_figures, render_point, study_scenes};
use super::study::{Sizes, StudyScene, reference_image, sizes};
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::aaf_indirect::{AafIndirect, AafIndirectSettings};
use crate::filters::sheared::{DOF_STEPS, DofKernel, Effect, Sheared, ShearedSettings};
use crate::filters::{Auto, Configured};
use crate::metrics;

/// Path samples per pixel of the filtered renders (the direct light and the rest of the image).
const PATH_SPP: u32 = 16;

/// The bundled scene the study runs on when the run names no pinhole scene.
const DEFAULT_SCENE: &str = "room_gi";

/// The filter of a row (Monte Carlo's is unused).
enum Cell {
    Aaf(AafIndirectSettings),
    Sheared(ShearedSettings),
}

/// One render of the study: (method, setting, filter).
fn plan(quick: bool) -> Vec<(&'static str, u32, Cell)> {
    let aaf = |sparse, max| {
        Cell::Aaf(AafIndirectSettings {
            sparse_spp: sparse,
            max_spp: max,
            ..Default::default()
        })
    };
    let sheared = |side, shear| {
        Cell::Sheared(ShearedSettings {
            side,
            shear,
            effect: Auto::Set(Effect::Gi),
            ..Default::default()
        })
    };
    let mut v = Vec::new();
    let mc: &[u32] = if quick {
        &[4, 16, 64]
    } else {
        &[4, 8, 16, 32, 64, 128, 256]
    };
    for &spp in mc {
        v.push(("mc", spp, aaf(16, 16)));
    }
    // The sparse pass takes whole strata: squares.
    let fixed: &[u32] = if quick { &[4, 16] } else { &[4, 9, 16, 36, 64] };
    for &n in fixed {
        v.push(("aaf-fixed", n, aaf(n, n)));
    }
    let max: &[u32] = if quick {
        &[36]
    } else {
        &[16, 36, 64, 100, 196]
    };
    for &m in max {
        v.push(("aaf-adaptive", m, aaf(9, m)));
    }
    let sides: &[u32] = if quick { &[3] } else { &[2, 3, 4] };
    for &l in sides {
        v.push(("sheared", l, sheared(l, 1.0)));
    }
    v.push(("sheared-no-shear", 3, sheared(3, 0.0)));
    v
}

const COLUMNS: [&str; 12] = [
    "scene",
    "size",
    "method",
    "setting",
    "path_spp",
    "indirect_spp",
    "rays_spp",
    "mse_rgb",
    "rms",
    "rel_mse",
    "mse_luv",
    "seconds",
];

/// `aaf-indirect` (module docs).
pub fn aaf_indirect(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    // The bundled scenes are not all of the run by default: most have a noisy direct term
    // (area lights) that sets a floor under every filtered row's MSE (module docs).
    let scenes = study_scenes(ctx, "aaf-indirect", false, DEFAULT_SCENE, |st| {
        st.info.camera.lens_radius <= 0.0
    })?;
    let mut t = ctx.table("aaf-indirect", &COLUMNS, 4, fresh)?;
    let size = format!("{}x{}", s.width, s.height);
    for (path, study) in &scenes {
        study_scene(ctx, &mut t, path, study, &size)?;
    }
    let mut md = format!(
        "# Diffuse indirect light: AAF and sheared filtering against Monte Carlo and each \
         other\n\n`noisefree bench --study aaf-indirect`: each scene at {size}, each render \
         against the {}-spp reference (MSE in linear RGB, relMSE, MSE in CIELUV). The \
         filtered rows take {PATH_SPP} path samples per pixel (the direct light, unfiltered, \
         and the rest of the image) plus their indirect samples; `indirect spp` counts the \
         latter (Σ / N²; Monte Carlo: its path samples), `rays spp` both. \"MC spp at equal \
         MSE\" is the Monte Carlo spp of equal MSE (log-log interpolation of the Monte Carlo \
         rows, slope −1 beyond them: *). Seconds: kernel time of the render, the sampling \
         passes and the filter.\n\n",
        s.reference_spp
    );
    for (_, study) in &scenes {
        md.push_str(&scene_report(ctx, &t, &study.name, &size)?);
    }
    std::fs::write(ctx.out.join("aaf-indirect.md"), md).context("writing aaf-indirect.md")
}

/// The rows of one scene.
fn study_scene(
    ctx: &Context,
    t: &mut ResultTable,
    path: &std::path::Path,
    study: &StudyScene,
    size: &str,
) -> Result<()> {
    let s = sizes(ctx);
    let reference = reference_image(ctx, path, &s)?;
    let cells = plan(ctx.quick);
    let pb = bar(ctx, cells.len() as u64, "aaf-indirect");
    for (method, setting, cell) in cells {
        let key = vec![
            study.name.clone(),
            size.to_string(),
            method.to_string(),
            setting.to_string(),
        ];
        pb.set_message(format!("aaf-indirect: {} {method} {setting}", study.name));
        if t.has(&key) {
            pb.inc(1);
            continue;
        }
        let filter = match cell {
            _ if method == "mc" => None,
            Cell::Aaf(a) => Some(Configured::typed::<AafIndirect>(a, &study.info)?),
            Cell::Sheared(sh) => Some(Configured::typed::<Sheared>(sh, &study.info)?),
        };
        let spp = if method == "mc" { setting } else { PATH_SPP };
        let point = render_point(ctx, study, &s, filter, spp, |frame, _| {
            if method == "sheared" && setting == 3 {
                sheared_steps(ctx, frame, &s, &study.name)?;
            }
            Ok(())
        })?;
        let (img, path_spp, indirect, seconds) =
            (point.image, point.path_spp, point.pass_spp, point.seconds);
        let m = metrics::compare(&img, &reference)?;
        let mut row = key;
        row.push(path_spp.to_string());
        let rays = indirect + if method == "mc" { 0.0 } else { path_spp as f64 };
        row.extend(
            [
                indirect,
                rays,
                m.mse_rgb,
                m.mse_rgb.sqrt(),
                m.rel_mse,
                m.mse_luv,
                seconds.as_secs_f64(),
            ]
            .map(num),
        );
        t.push(row)?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(())
}

/// sheared-gi-steps-SCENE.md: the kernel time of each step of the sheared GI filter (l = 3) on
/// `frame`, the median of five runs of its own kernel, and its memory.
fn sheared_steps(
    ctx: &Context,
    frame: &crate::render::Frame,
    s: &Sizes,
    scene: &str,
) -> Result<()> {
    let settings = ShearedSettings {
        side: 3,
        effect: Auto::Set(Effect::Gi),
        light: Auto::Set(-1),
        ..Default::default()
    };
    let mut k = DofKernel::gi(ctx.gpu.clone(), settings.gi_params(s.width, s.height))?;
    let mut runs: Vec<[f64; 5]> = Vec::new();
    for _ in 0..5 {
        k.filter_rows(frame, 0..s.height)?;
        runs.push(k.step_times().map(|d| d.as_secs_f64() * 1e3));
    }
    let medians: Vec<f64> = (0..DOF_STEPS.len())
        .map(|i| {
            let mut v: Vec<f64> = runs.iter().map(|r| r[i]).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        })
        .collect();
    let total: f64 = medians.iter().sum();
    let mut md = format!(
        "# Sheared GI filter on {scene}: kernel time per step (l = 3, {} x {}, median of 5 \
         runs)\n\n| step | ms | share |\n|---|---|---|\n",
        s.width, s.height
    );
    for (name, ms) in DOF_STEPS.iter().zip(&medians) {
        md.push_str(&format!(
            "| {name} | {ms:.2} | {:.0}% |\n",
            100.0 * ms / total
        ));
    }
    md.push_str(&format!(
        "\nTotal {total:.2} ms. Memory of the GI field and the filter's buffers: {} B per \
         pixel, {:.1} MiB here (O(N² l²): `ShearedSettings::memory_bytes`).\n",
        settings.memory_bytes(1, 1),
        settings.memory_bytes(s.width, s.height) as f64 / (1u64 << 20) as f64
    ));
    std::fs::write(ctx.out.join(format!("sheared-gi-steps-{scene}.md")), md)?;
    Ok(())
}

/// One scene's section of aaf-indirect.md: every row with Monte Carlo's spp at equal MSE, the
/// sheared rows against both AAF curves, and the two figures.
fn scene_report(ctx: &Context, t: &ResultTable, scene: &str, size: &str) -> Result<String> {
    let at = (scene, size);
    let mc = curve(t, at, "mc", "indirect_spp");
    let mut md = format!(
        "## {scene}\n\n\
         | method | setting | indirect spp | rays spp | RMS | relMSE | MSE-LUV | seconds | MC spp at equal MSE | ratio (indirect) | ratio (rays) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for r in t
        .records()
        .iter()
        .filter(|r| r["scene"] == scene && r["size"] == size)
    {
        let (indirect, rays, mse): (f64, f64, f64) = (
            r["indirect_spp"].parse()?,
            r["rays_spp"].parse()?,
            r["mse_rgb"].parse()?,
        );
        let equal = (r["method"] != "mc")
            .then(|| loglog_where(&mc, mse))
            .flatten();
        let (eq, ratio_i, ratio_r) = match equal {
            Some((x, ex)) => (
                format!("{x:.0}{}", if ex { "*" } else { "" }),
                format!("{:.2}", x / indirect),
                format!("{:.2}", x / rays),
            ),
            None => Default::default(),
        };
        md.push_str(&format!(
            "| {} | {} | {indirect:.1} | {rays:.1} | {} | {} | {} | {} | {eq} | {ratio_i} | {ratio_r} |\n",
            r["method"], r["setting"], r["rms"], r["rel_mse"], r["mse_luv"], r["seconds"]
        ));
    }
    // Both metrics: where the direct light's noise (the same 16 path samples in every
    // filtered row) dominates the MSE, its curves are flat and only relMSE separates them.
    for metric in [&MSE, &REL_MSE] {
        for aaf in ["aaf-adaptive", "aaf-fixed"] {
            md.push_str(&format!(
                "\n### Sheared filtering against {aaf} at equal {} (Yan et al. 2015)\n\n",
                metric.name
            ));
            md.push_str(&sheared_against_aaf(
                t,
                at,
                aaf,
                "indirect_spp",
                "indirect",
                metric,
            ));
        }
    }
    md.push_str(&format!(
        "\nFigures: `aaf-indirect-{scene}.png` (RMS against indirect samples per pixel, \
         log-log), `aaf-indirect-time-{scene}.png` (RMS against seconds); kernel time per step \
         of the sheared filter: `sheared-gi-steps-{scene}.md`.\n\n"
    ));
    let methods = [
        ("mc", "Monte Carlo"),
        ("aaf-fixed", "AAF, not adaptive"),
        ("aaf-adaptive", "AAF, adaptive (sparse 9)"),
        ("sheared", "sheared (l = 2, 3, 4)"),
    ];
    error_figures(
        ctx,
        t,
        at,
        "aaf-indirect",
        &methods,
        (
            "indirect_spp",
            "indirect samples per pixel",
            "indirect samples",
        ),
    )?;
    Ok(md)
}
