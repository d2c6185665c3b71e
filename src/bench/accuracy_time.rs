//! Accuracy against time: error against wall-clock time (render + filter) for every method, the
//! project's headline (what accuracy costs in time), and its report.

use std::time::{Duration, Instant};

use anyhow::Result;

use super::curves::{loglog_at, loglog_where};
use super::plot::{Chart, Series, line_chart};
use super::study::{Candidate, STUDY_SEED, StudyScene, reference_image, sizes};
use super::table::{ResultTable, distinct, num};
use super::{Context, bar};
use crate::metrics;

/// One point of an error-versus-time curve.
#[derive(Clone, Copy, Debug)]
struct Point {
    spp: u32,
    /// Samples per pixel of the filter's own sampling passes (AAF's), besides `spp`.
    pass_spp: f64,
    seconds: f64,
    error: f64,
}

/// Study 3: error against wall-clock time (render + filter) for unfiltered path tracing at
/// 1..1024 spp and each filter at 1..64 spp (`--filter-spp`); the equal-quality sample reduction and the
/// equal-time error ratio of each filter at 8 spp.
pub fn accuracy_time(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let columns = [
        "scene", "method", "spp", "pass_spp", "seconds", "mse_luv", "rel_mse",
    ];
    let mut t = ctx.table("accuracy-time", &columns, 3, fresh)?;
    let unfiltered_max = if ctx.quick { 32 } else { 1024 };
    // RPF's cost grows with every stored sample (minutes per 512x512 frame at 8 spp on a
    // 2-core CPU); such curves stop at 8 spp, the spp of the headline.
    let max_spp = |c: &Candidate| -> u32 {
        match c {
            Candidate::Unfiltered => unfiltered_max,
            _ if ctx.quick || c.reads_every_sample() => 8,
            _ => ctx.filter_spp.unwrap_or(64).min(unfiltered_max),
        }
    };
    let oidn = super::oidn::Oidn::find();
    if oidn.is_none() {
        ctx.say(super::oidn::NOT_SET_UP);
    }
    let pb = bar(ctx, ctx.scenes.len() as u64, "accuracy against time");
    for path in &ctx.scenes {
        let study = StudyScene::load(path, &s, STUDY_SEED)?;
        let name = study.name.clone();
        pb.set_message(format!("accuracy against time: {name}"));
        let reference = reference_image(ctx, path, &s)?;
        let methods = study.methods()?;
        let mut extra = study.chains()?;
        extra.extend(study.bmfr_variants()?);
        for candidate in Candidate::all(&methods, &extra, oidn.as_ref())
            .into_iter()
            .filter(|c| ctx.wants(&c.label()))
        {
            let max_spp = max_spp(&candidate);
            let label = candidate.label();
            let checkpoints: Vec<u32> = (0..)
                .map(|i| 1u32 << i)
                .take_while(|&n| n <= max_spp)
                .collect();
            let done = checkpoints
                .iter()
                .all(|spp| t.has(&[name.clone(), label.clone(), spp.to_string()]));
            if !done {
                ctx.say(&format!(
                    "accuracy-time: {name} {label} up to {max_spp} spp"
                ));
                let outputs = candidate.needs();
                let filter = candidate.filter();
                let mut r = study.renderer_for(ctx, &s, outputs, max_spp, filter)?;
                let mut prepared = candidate.prepare(ctx, r.frame().info())?;
                // Warm-up: one frame builds and loads everything, then the render restarts.
                r.render_samples(1)?;
                prepared.run(&r.frame())?;
                let mut r2 = study.renderer_for(ctx, &s, outputs, max_spp, filter)?;
                let mut render_time = Duration::ZERO;
                // The sampling passes run once, before the first samples: their spp is
                // read back once (the light field is ~2 kB a pixel).
                let mut pass_spp = None;
                for &spp in &checkpoints {
                    let start = Instant::now();
                    r2.render_samples(spp - r2.samples_done())?;
                    render_time += start.elapsed();
                    let frame = r2.frame();
                    let (img, filter_time) = prepared.run(&frame)?;
                    let key = vec![name.clone(), label.clone(), spp.to_string()];
                    if !t.has(&key) {
                        let m = metrics::compare(&img, &reference)?;
                        let mut row = key;
                        row.extend([
                            num(match pass_spp {
                                Some(v) => v,
                                None => *pass_spp.insert(frame.pass_spp()?),
                            }),
                            num((render_time + filter_time).as_secs_f64()),
                            num(m.mse_luv),
                            num(m.rel_mse),
                        ]);
                        t.push(row)?;
                    }
                }
                drop(r);
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    accuracy_time_report(ctx, &t)
}

/// Plots and the headline table of the accuracy-time study, from every scene the CSV holds
/// (runs over a few scenes at a time add up to one report).
fn accuracy_time_report(ctx: &Context, t: &ResultTable) -> Result<()> {
    let records = t.records();
    let scenes = distinct(&records, "scene");
    let mut headline = String::from(
        "| scene | method | error at 8 spp (MSE-LUV) | time at 8 spp (s) | unfiltered spp for the same error | equal-quality sample reduction | unfiltered error at the same time | equal-time error ratio |\n|---|---|---|---|---|---|---|---|\n",
    );
    for &name in &scenes {
        // The unfiltered curve first: the headline figures are read off it.
        let mut labels: Vec<&str> = vec!["unfiltered"];
        labels.extend(
            distinct(records.iter().filter(|r| r["scene"] == name), "method")
                .into_iter()
                .filter(|l| *l != "unfiltered"),
        );
        let curves: Vec<(String, Vec<Point>)> = labels
            .iter()
            .map(|&label| {
                let mut pts: Vec<Point> = records
                    .iter()
                    .filter(|r| r["scene"] == name && r["method"] == label)
                    .map(|r| Point {
                        spp: r["spp"].parse().unwrap_or(0),
                        pass_spp: r["pass_spp"].parse().unwrap_or(f64::NAN),
                        seconds: r["seconds"].parse().unwrap_or(f64::NAN),
                        error: r["mse_luv"].parse().unwrap_or(f64::NAN),
                    })
                    .collect();
                pts.sort_by_key(|p| p.spp);
                (label.to_string(), pts)
            })
            .collect();
        let series: Vec<Series> = curves
            .iter()
            .map(|(l, p)| Series {
                label: l.clone(),
                points: p.iter().map(|q| (q.seconds, q.error)).collect(),
            })
            .collect();
        line_chart(
            &ctx.out.join(format!("accuracy-time-{name}.png")),
            &Chart {
                title: format!("{name}: error against time (render + filter)"),
                x_label: "seconds (wall clock)".into(),
                y_label: "MSE in CIELUV".into(),
                log_x: true,
                log_y: true,
            },
            &series,
        )?;
        // Headline figures from the curves.
        let unfiltered = &curves[0].1;
        let by_spp: Vec<(f64, f64)> = unfiltered.iter().map(|p| (p.spp as f64, p.error)).collect();
        let by_time: Vec<(f64, f64)> = {
            let mut v: Vec<(f64, f64)> = unfiltered.iter().map(|p| (p.seconds, p.error)).collect();
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            v
        };
        for (label, pts) in curves.iter().skip(1) {
            let Some(at8) = pts.iter().find(|p| p.spp == 8) else {
                continue;
            };
            let (spp_equal, ex1) = loglog_where(&by_spp, at8.error).unwrap_or((f64::NAN, true));
            let (err_equal_time, ex2) =
                loglog_at(&by_time, at8.seconds, -1.0).unwrap_or((f64::NAN, true));
            let mark = |e: bool| if e { " (extrapolated)" } else { "" };
            headline.push_str(&format!(
                "| {name} | {label} | {} | {} | {}{} | {}x | {}{} | {}x |\n",
                num(at8.error),
                num(at8.seconds),
                num(spp_equal),
                mark(ex1),
                num(spp_equal / (8.0 + at8.pass_spp)),
                num(err_equal_time),
                mark(ex2),
                num(err_equal_time / at8.error),
            ));
        }
    }
    let mut md = String::from(
        "# What accuracy costs in time\n\n\
         Error (MSE in CIELUV against the reference) against wall-clock time of rendering plus\n\
         filtering, for unfiltered path tracing at 1, 2, 4, ... spp and for each filter. From the\n\
         curves, for each filter at 8 spp:\n\n\
         - **equal-quality sample reduction**: the unfiltered spp that reaches the filter's error,\n  divided by the filter's samples per pixel, 8 plus its sampling passes' `pass_spp` (log-log interpolation; past the end of the unfiltered curve it is extended\n  with slope -1, MSE ~ 1/spp, and marked);\n\
         - **equal-time error ratio**: the unfiltered error at the same wall-clock time, divided\n  by the filter's error (above 1: the filter is the better use of the time).\n\n",
    );
    md.push_str(&super::study::methods_markdown());
    md.push_str(&headline);
    md.push('\n');
    for name in &scenes {
        md.push_str(&format!("![{name}](accuracy-time-{name}.png)\n\n"));
    }
    md.push_str("## All measurements\n\n");
    md.push_str(&t.markdown());
    std::fs::write(ctx.out.join("accuracy-time.md"), md)?;
    Ok(())
}
