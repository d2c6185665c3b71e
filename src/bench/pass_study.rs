//! What the `aaf-shadows` and `aaf-indirect` studies share: each point is one render of Monte
//! Carlo at some spp, or of a filter that adds its own sampling passes (AAF's light or indirect
//! samples, the sheared filter's l × l field) to a fixed number of path samples; the scenes
//! they run on; and their log-log figures of error against samples and against time.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Result, bail};

use super::Context;
use super::curves::curve;
use super::plot::{Chart, Series, line_chart};
use super::study::{STUDY_SEED, Sizes, StudyScene, sizes};
use super::table::ResultTable;
use crate::filters::Configured;
use crate::imaging::RgbImage;
use crate::layout::outputs::OutputSet;
use crate::render::Frame;

/// One point's render: the image, its path spp, the pass samples per pixel (Σ / N²; Monte
/// Carlo: its spp) and the kernel time of the render, its passes and the filter.
pub(super) struct Point {
    pub image: RgbImage,
    pub path_spp: u32,
    pub pass_spp: f64,
    pub seconds: Duration,
}

/// Monte Carlo at `spp` (no filter), or `filter` over `path_spp` path samples and its own
/// passes; `inspect` sees a filtered frame and the filter's kernel time (for per-row extras:
/// spp maps, per-step times).
pub(super) fn render_point(
    ctx: &Context,
    study: &StudyScene,
    s: &Sizes,
    filter: Option<Configured>,
    spp: u32,
    mut inspect: impl FnMut(&Frame, Duration) -> Result<()>,
) -> Result<Point> {
    let Some(c) = filter else {
        let mut r = study.renderer(ctx, s, OutputSet::colour(), spp)?;
        r.render_samples(spp)?;
        return Ok(Point {
            image: r.frame().beauty()?,
            path_spp: spp,
            pass_spp: spp as f64,
            seconds: r.kernel_time_total,
        });
    };
    let outputs = OutputSet::colour().union(c.needs());
    let mut r = study.renderer_for(ctx, s, outputs, spp, Some(&c))?;
    r.render_samples(spp)?;
    let frame = r.frame();
    let pass_spp = frame.pass_spp()?;
    let run = c.prepare(frame.info(), &ctx.gpu)?.run(&frame)?;
    let filter_time = run.kernel_time.unwrap_or(run.wall_time);
    inspect(&frame, filter_time)?;
    Ok(Point {
        image: run.image,
        path_spp: spp,
        pass_spp,
        seconds: r.kernel_time_total + filter_time,
    })
}

/// The scenes of a study: those of the run that `keep` accepts (only when `--scene` named
/// them, unless `all_of_run`), else the bundled `default` scene.
pub(super) fn study_scenes(
    ctx: &Context,
    study: &str,
    all_of_run: bool,
    default: &str,
    keep: impl Fn(&StudyScene) -> bool,
) -> Result<Vec<(PathBuf, StudyScene)>> {
    let s = sizes(ctx);
    let mut scenes = Vec::new();
    for path in ctx.scenes.iter().filter(|_| all_of_run || ctx.scenes_named) {
        let st = StudyScene::load(path, &s, STUDY_SEED)?;
        if keep(&st) {
            scenes.push((path.clone(), st));
        }
    }
    if scenes.is_empty() {
        let path = ctx.scene_file(default)?;
        if !path.exists() {
            bail!(
                "the {study} study renders {}, which is missing",
                path.display()
            );
        }
        let st = StudyScene::load(&path, &s, STUDY_SEED)?;
        scenes.push((path, st));
    }
    Ok(scenes)
}

/// `{prefix}-{scene}.png` (RMS against `x_column`, log-log) and `{prefix}-time-{scene}.png`
/// (RMS against seconds): one line per (method, label).
pub(super) fn error_figures(
    ctx: &Context,
    t: &ResultTable,
    at: (&str, &str),
    prefix: &str,
    methods: &[(&str, &str)],
    (x_column, x_label, what): (&str, &str, &str),
) -> Result<()> {
    let series = |x: &str| -> Vec<Series> {
        methods
            .iter()
            .map(|(m, label)| Series {
                label: label.to_string(),
                points: curve(t, at, m, x)
                    .into_iter()
                    .map(|(x, mse)| (x, mse.sqrt()))
                    .collect(),
            })
            .collect()
    };
    let chart = |title: String, x_label: &str| Chart {
        title,
        x_label: x_label.into(),
        y_label: "RMS error (linear RGB)".into(),
        log_x: true,
        log_y: true,
    };
    let scene = at.0;
    line_chart(
        &ctx.out.join(format!("{prefix}-{scene}.png")),
        &chart(format!("{scene}: error against {what}"), x_label),
        &series(x_column),
    )?;
    line_chart(
        &ctx.out.join(format!("{prefix}-time-{scene}.png")),
        &chart(
            format!("{scene}: error against time"),
            "kernel seconds (render, passes, filter)",
        ),
        &series("seconds"),
    )
}
