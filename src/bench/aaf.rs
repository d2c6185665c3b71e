//! `aaf-shadows`: Wang 2013 Fig. 3.6 and its claim ("adaptive AAF at 27 average spp matches
//! Monte Carlo at 165 spp") on Grids, the scene it was measured on, and on every other scene of
//! the run with a sphere light (Curved: shadows on a curved receiver). Not in the default set.
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
//! - **Sheared** (Yan et al. 2015, issue 16): the same 16 path samples, AAF's sparse pass at 1
//!   sample and the l × l light field (l = 2, 3, 4), filtered by `sheared` with its defaults:
//!   every sphere light, one at a time, as AAF's rows (two_lights_shadows: both lights);
//!   `light_spp` is 1 + l² per light and receiver (Σ over the lights' planes / N²). Two
//!   more rows at l = 3 with η = 0 (no shear) and η of the other sign check the shear's sign
//!   on a real scene.
//!
//! The seed counts only the light samples of AAF (its renders have no path samples); ours keep
//! 16 path samples per pixel for silhouettes and other light, each with a shadow ray, so the
//! table gives both counts and the Monte Carlo spp of equal MSE for both. Every row has its
//! kernel time (render, shadow passes and filter), for the error-against-time figure.

use anyhow::{Context as _, Result};

use super::curves::{MSE, curve, loglog_where, sheared_against_aaf};
use super::pass_study::{error_figures, render_point, study_scenes};
use super::study::{StudyScene, reference_image, sizes};
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::aaf_shadows::{AafShadowSettings, AafShadows};
use crate::filters::sheared::{STEPS, Sheared, ShearedKernel, ShearedSettings};
use crate::filters::{Configured, FilterKind};
use crate::imaging::write_rgb8_png;
use crate::layout::outputs::Output;
use crate::metrics::mse_rgb;

/// Path samples per pixel of the AAF renders (the rest of the image, and the replaced term).
const AAF_PATH_SPP: u32 = 16;

/// The filter of a row: AAF's settings (also Monte Carlo's, unused) or the sheared filter's.
enum Cell {
    Aaf(AafShadowSettings),
    Sheared(ShearedSettings),
}

/// One render of the study: (method, setting, filter).
fn plan(quick: bool) -> Vec<(&'static str, u32, Cell)> {
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
        v.push(("mc", spp, Cell::Aaf(AafShadowSettings::default())));
    }
    let fixed: &[u32] = if quick { &[4, 16] } else { &[4, 9, 16, 36, 64] };
    for &n in fixed {
        v.push(("aaf-fixed", n, Cell::Aaf(aaf(n, n))));
    }
    let max: &[u32] = if quick {
        &[36]
    } else {
        &[16, 36, 64, 100, 196, 400]
    };
    for &m in max {
        v.push(("aaf-adaptive", m, Cell::Aaf(aaf(9, m))));
    }
    let sheared = |side, shear| {
        Cell::Sheared(ShearedSettings {
            side,
            shear,
            ..Default::default()
        })
    };
    let sides: &[u32] = if quick { &[3] } else { &[2, 3, 4] };
    for &l in sides {
        v.push(("sheared", l, sheared(l, 1.0)));
    }
    v.push(("sheared-no-shear", 3, sheared(3, 0.0)));
    v.push(("sheared-other-sign", 3, sheared(3, -1.0)));
    if !quick {
        // The light's sigma_y against the default 0.7 (src/filters/sheared/mod.rs).
        for (name, light_sigma) in [
            ("sheared-light-sigma-0.5", 0.5),
            ("sheared-light-sigma-0.6", 0.6),
            ("sheared-light-sigma-0.8", 0.8),
            ("sheared-light-sigma-1.0", 1.0),
        ] {
            let s = ShearedSettings {
                side: 3,
                light_sigma,
                ..Default::default()
            };
            v.push((name, 3, Cell::Sheared(s)));
        }
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

/// `aaf-shadows` (module docs): on every scene of the run with a sphere light (of the bundled
/// ones Grids, Curved, two_lights_shadows, toasters_dof and room_gi), or Grids when there is
/// none (`--quick` keeps only the Cornell box).
pub fn aaf_shadows(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let scenes = study_scenes(ctx, "aaf-shadows", true, "grids", |st| {
        !st.info.sphere_lights.is_empty()
    })?;
    let mut t = ctx.table("aaf-shadows", &COLUMNS, 4, fresh)?;
    let size = format!("{}x{}", s.width, s.height);
    for (path, study) in &scenes {
        study_scene(ctx, &mut t, path, study, &size)?;
    }
    let names: Vec<&str> = scenes.iter().map(|(_, st)| st.name.as_str()).collect();
    report(ctx, &t, &names, &size)
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
    let pb = bar(ctx, cells.len() as u64, "aaf-shadows");
    for (method, setting, cell) in cells {
        let key = vec![
            study.name.clone(),
            size.to_string(),
            method.to_string(),
            setting.to_string(),
        ];
        pb.set_message(format!("aaf-shadows: {} {method} {setting}", study.name));
        if t.has(&key) {
            pb.inc(1);
            continue;
        }
        let filter = match cell {
            _ if method == "mc" => None,
            Cell::Aaf(a) => Some(Configured::typed::<AafShadows>(a, &study.info)?),
            Cell::Sheared(sh) => Some(Configured::typed::<Sheared>(sh, &study.info)?),
        };
        let spp = if method == "mc" {
            setting
        } else {
            AAF_PATH_SPP
        };
        let mut spp_map = None;
        // The light samples of the sparse + adaptive passes and the light field's l² of every
        // receiver, over the image (Σ / N²), are the point's pass spp.
        let point = render_point(ctx, study, &s, filter, spp, |frame, filter_time| {
            debug_assert!(frame.outputs().contains(Output::Shadows));
            // The spp map of one adaptive row (max 100, the default) as a picture, and with
            // several lights what each light spent and the filter's time.
            if method == "aaf-adaptive" && setting == 100 {
                let [(_, spp), _] = crate::stats::aov::shadow_pictures(frame)?;
                if frame.info().shadow_lights.len() > 1 {
                    per_light(ctx, frame, &study.name, filter_time)?;
                }
                spp_map = Some(spp);
            }
            if method == "sheared" && setting == 3 {
                sheared_steps(ctx, frame, &s, &study.name)?;
            }
            Ok(())
        })?;
        let (img, path_spp, light_spp, seconds) =
            (point.image, point.path_spp, point.pass_spp, point.seconds);
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
    Ok(())
}

/// aaf-lights-SCENE.md: each light's average light spp (Σ n_l / N², eq. 3.5 with that
/// light's slopes and size) in the default adaptive row of a scene with several sphere
/// lights, their total, and the filter's kernel time (every light's four launches).
fn per_light(
    ctx: &Context,
    frame: &crate::render::Frame,
    scene: &str,
    filter_time: std::time::Duration,
) -> Result<()> {
    let info = frame.info();
    let pixels = (info.width as f64 * info.height as f64).max(1.0);
    let mut md = format!(
        "# aaf-shadows on {scene}: light samples per light (sparse 9, max 100; {} x {})\n\n\
         | sphere light | radius | light spp (Σ n_l / N²) | max n_l |\n|---|---|---|---|\n",
        info.width, info.height
    );
    let mut total = 0.0;
    for &l in &info.shadow_lights {
        let own = frame.light_plane(l, "the aaf-shadows study")?;
        let plane = own.as_ref().unwrap_or(frame);
        let px: &[crate::layout::ShadowPixel] =
            plane.host_slice(crate::layout::outputs::BufferId::ShadowPixels)?;
        let sum: f64 = px.iter().map(|p| p.samples as f64).sum();
        let max = px.iter().map(|p| p.samples as u32).max().unwrap_or(0);
        total += sum / pixels;
        let radius = info
            .scene
            .sphere_lights
            .get(l as usize)
            .map_or(0.0, |c| c[3]);
        md.push_str(&format!(
            "| {l} | {radius} | {:.2} | {max} |\n",
            sum / pixels
        ));
    }
    md.push_str(&format!(
        "| all | | {total:.2} | |\n\nFilter kernel time (every light's prepare, two 1-D \
         passes and compose): {:.2} ms.\n",
        filter_time.as_secs_f64() * 1e3
    ));
    std::fs::write(ctx.out.join(format!("aaf-lights-{scene}.md")), md)
        .context("writing the per-light spp")
}

/// sheared-steps-SCENE.md: the kernel time of each step of the sheared filter (l = 3) on `frame`,
/// filtered once more by its own kernel (every sphere light, as the study's rows: each step's
/// time summed over the lights), and its memory.
fn sheared_steps(
    ctx: &Context,
    frame: &crate::render::Frame,
    s: &super::study::Sizes,
    scene: &str,
) -> Result<()> {
    let info = &frame.info().scene;
    let mut settings = ShearedSettings::default();
    Sheared::specialise(&mut settings, info);
    let lights = settings.lights_of(info)?;
    let mut k = ShearedKernel::new(
        ctx.gpu.clone(),
        &settings,
        &lights,
        info.scene_centre,
        s.width,
        s.height,
    )?;
    k.filter(frame)?;
    let times = k.step_times();
    let total: f64 = times.iter().map(|t| t.as_secs_f64()).sum();
    let mut md = format!(
        "# Sheared filter on {scene}: kernel time per step (l = 3, {} x {}, {} sphere \
         light(s), each step summed over them, one run)\n\n\
         | step | ms | share |\n|---|---|---|\n",
        s.width,
        s.height,
        lights.len()
    );
    for (name, t) in STEPS.iter().zip(times) {
        let ms = t.as_secs_f64() * 1e3;
        md.push_str(&format!(
            "| {name} | {ms:.2} | {:.0}% |
",
            100.0 * t.as_secs_f64() / total
        ));
    }
    md.push_str(&format!(
        "\nTotal {:.2} ms. Memory of the light fields (one per light) and the filter's \
         buffers: {} B per pixel, \
         {:.1} MiB here (O(N² l²): `ShearedSettings::memory_bytes`).\n",
        total * 1e3,
        settings.memory_bytes(1, 1),
        settings.memory_bytes(s.width, s.height) as f64 / (1u64 << 20) as f64
    ));
    std::fs::write(ctx.out.join(format!("sheared-steps-{scene}.md")), md)?;
    Ok(())
}

/// The sheared rows against adaptive AAF ([`sheared_against_aaf`] on the light samples).
fn sheared_section(t: &ResultTable, at: (&str, &str)) -> String {
    let mut md = String::from(
        "\n### Sheared filtering against adaptive AAF at equal quality (Yan et al. 2015)\n\n\
         Every sphere light filtered, a light at a time, as in AAF's rows; light spp: 1 (the \
         sparse pass) + l² per light and receiver, Σ / N².\n\n",
    );
    md.push_str(&sheared_against_aaf(
        t,
        at,
        "aaf-adaptive",
        "light_spp",
        "light",
        &MSE,
    ));
    md
}

/// aaf-shadows.md (per scene: the table with Monte Carlo's spp at equal MSE, and the sheared
/// rows against AAF) and each scene's two figures.
fn report(ctx: &Context, t: &ResultTable, scenes: &[&str], size: &str) -> Result<()> {
    let reference_spp = sizes(ctx).reference_spp;
    let mut md = format!(
        "# AAF soft shadows against Monte Carlo (Wang 2013 Fig. 3.6)\n\n\
         `noisefree bench --study aaf-shadows`: each scene with a sphere light at {}, each \
         render against the {}-spp reference (MSE in linear RGB). AAF renders take 16 path \
         samples per pixel for the rest of the image plus the light samples of the shadow \
         passes; `light_spp` counts the latter (the seed's axis: Σn / N² for the adaptive \
         rows), `shadow_rays_spp` both. \"MC spp at equal MSE\" is the Monte Carlo spp of \
         equal MSE (log-log interpolation of the Monte Carlo rows, slope −1 beyond them: \
         marked *), the ratios it over light spp and over shadow rays spp, and \"MC seconds at \
         equal MSE\" Monte Carlo's time for that MSE, interpolated the same way. Seconds: \
         kernel time of the render, the shadow passes and the filter.\n\n",
        size, reference_spp
    );
    for scene in scenes {
        md.push_str(&scene_report(ctx, t, scene, size)?);
    }
    std::fs::write(ctx.out.join("aaf-shadows.md"), md).context("writing aaf-shadows.md")
}

/// One scene's section of aaf-shadows.md, and its figures.
fn scene_report(ctx: &Context, t: &ResultTable, scene: &str, size: &str) -> Result<String> {
    let at = (scene, size);
    let mc = curve(t, at, "mc", "light_spp");
    let mc_time = curve(t, at, "mc", "seconds");
    let mut md = format!(
        "## {scene}\n\n\
         | method | setting | light spp | shadow rays spp | RMS | seconds | MC spp at equal MSE | ratio (light) | ratio (rays) | MC seconds at equal MSE |\n\
         |---|---|---|---|---|---|---|---|---|---|\n"
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
    md.push_str(&sheared_section(t, at));
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
        "aaf-shadows",
        &methods,
        (
            "light_spp",
            "light samples per pixel",
            "light samples (Fig. 3.6)",
        ),
    )?;
    Ok(md)
}
