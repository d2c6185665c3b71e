//! `noisefree bench --study balance --devices 1,0`: several devices sharing each frame (thesis
//! §4.2: "Each render device is assigned to a specific part of the screen depending on the
//! speed of the device"). Per scene, viewer-like frames (one sample per pixel, then the
//! data-driven filter) in four configurations, measured frame by frame in turn so that all of
//! them see the same machine load:
//!
//! - `one-device`: the first device alone, the whole frame;
//! - `static`: the rows shared evenly and kept so (what the thesis does for two identical
//!   GPUs);
//! - `balanced`: from the same even split, re-balanced from the measured kernel times after
//!   every frame (src/render/balance.rs), the filter on the merged film (the primary device);
//! - `balanced-bands`: the same, each device filtering its own band with the border rows its
//!   filter reads (src/filters/placement.rs).
//!
//! All split configurations start even rather than from the devices' own figures (compute
//! units × clock, what `render --devices` starts from), so that the balancer has a wrong split
//! to correct; where it settles shows how good that first guess would have been.
//!
//! balance.csv holds, per frame and device, the rows the device rendered, its kernel time and
//! how long it waited for the slowest device (idle); balance.md the means once the split has
//! settled and the speed-ups against one device; balance-<scene>.png the shares and idle times
//! per frame.

use std::collections::BTreeMap;
use std::time::Instant;

use anyhow::{Result, bail};

use super::plot::{Chart, Series, line_chart};
use super::study::scene_name;
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::{DeviceFilter, FilterRequest, Placement, Registry};
use crate::render::{RenderOptions, SceneArrays, SceneInfo, SplitRenderer};
use crate::scene;

const MODES: [&str; 4] = ["one-device", "static", "balanced", "balanced-bands"];

const COLUMNS: [&str; 13] = [
    "scene",
    "mode",
    "frame",
    "device",
    "device_name",
    "rows",
    "share_pct",
    "kernel_ms",
    "idle_ms",
    "transfer_ms",
    "filter_ms",
    "frame_ms",
    "moved_rows",
];

/// A configuration's film and filter.
struct Run {
    mode: &'static str,
    film: SplitRenderer,
    filter: DeviceFilter,
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

pub fn balance(ctx: &Context, fresh: bool) -> Result<()> {
    if ctx.gpus.len() < 2 {
        bail!(
            "the balance study shares frames among several devices: pass --devices with two or \
             more (on PoCL: POCL_DEVICES=\"pthread basic\" noisefree bench --study balance \
             --devices 1,0)"
        );
    }
    let (size, frames) = if ctx.quick { (64, 8) } else { (256, 30) };
    // The scenes: a sky over geometry (rows of very different cost) and a closed room.
    let mut scenes = ctx.scenes.clone();
    if ctx.scenes_dir.is_some() && scenes.len() > 2 {
        let pick = if ctx.quick {
            vec!["cornell_diffuse"]
        } else {
            vec!["outside", "cornell_glossy"]
        };
        scenes.retain(|p| pick.contains(&scene_name(p).as_str()));
    }
    let mut t = ctx.table("balance", &COLUMNS, 4, fresh)?;
    let pb = bar(ctx, (scenes.len() * frames) as u64, "balance");
    for path in &scenes {
        let name = scene_name(path);
        if t.has(&[name.clone(), "balanced".into(), "0".into(), "0".into()]) {
            pb.inc(frames as u64);
            continue;
        }
        pb.set_message(format!("balance: {name}"));
        let scene = scene::load_scene(path)?;
        let mut o = RenderOptions::for_scene(&scene);
        o.frame.width = size;
        o.frame.height = size;
        let arrays = SceneArrays::build(&scene, &o.frame)?;
        let info = SceneInfo::new(&scene, &arrays);
        let registry = Registry::builtin();
        let ddf = registry.get("ddf")?;
        let configured = registry.configure(ddf, &FilterRequest::default(), &info)?;
        o.outputs = o.outputs.union(configured.needs());
        let mut runs = Vec::new();
        for mode in MODES {
            let gpus = if mode == "one-device" {
                &ctx.gpus[..1]
            } else {
                &ctx.gpus[..]
            };
            let mut film = SplitRenderer::new(gpus, &scene, arrays.clone(), &o)?;
            film.balancer.enabled = mode != "static";
            let placement = if mode == "balanced-bands" {
                Placement::Bands
            } else {
                Placement::Merged
            };
            let filter = DeviceFilter::prepare(&configured, &mut film, placement)?;
            runs.push(Run { mode, film, filter });
        }
        // A warm-up frame each (kernel builds, first launches), not recorded; then the even
        // split.
        for r in &mut runs {
            r.film.render_samples(1)?;
            r.filter.run(&r.film)?;
            let even = r.film.balancer.split(&vec![1.0; r.film.parts().len()]);
            r.film.set_bands(even)?;
        }
        for frame in 0..frames {
            for r in &mut runs {
                let start = Instant::now();
                r.film.render_samples(1)?;
                let split = r.film.last_frame().cloned().unwrap_or_default();
                let filtered = Instant::now();
                r.filter.run(&r.film)?;
                let filter_ms = ms(filtered.elapsed());
                let frame_ms = ms(start.elapsed());
                for (i, d) in split.devices.iter().enumerate() {
                    t.push(vec![
                        name.clone(),
                        r.mode.to_string(),
                        frame.to_string(),
                        i.to_string(),
                        r.film.parts()[i].gpu.summary.name.clone(),
                        d.rows.len().to_string(),
                        num(100.0 * d.rows.len() as f64 / size as f64),
                        num(ms(d.kernel)),
                        num(ms(split.idle(i))),
                        num(ms(split.transfer)),
                        num(filter_ms),
                        num(frame_ms),
                        split.moved_rows.to_string(),
                    ])?;
                }
            }
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    report(ctx, &t, frames)
}

/// Mean of `column` over the records of (scene, mode, device) from frame `from` on.
fn mean(
    records: &[BTreeMap<&str, &str>],
    scene: &str,
    mode: &str,
    device: Option<&str>,
    from: usize,
    column: &str,
) -> f64 {
    let v: Vec<f64> = records
        .iter()
        .filter(|r| r["scene"] == scene && r["mode"] == mode)
        .filter(|r| device.is_none_or(|d| r["device"] == d))
        .filter(|r| r["frame"].parse::<usize>().is_ok_and(|f| f >= from))
        .filter_map(|r| r[column].parse::<f64>().ok())
        .collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// balance.md and one chart per scene, from the table (so a resumed run reports everything).
fn report(ctx: &Context, t: &ResultTable, frames: usize) -> Result<()> {
    let records = t.records();
    let scenes = super::table::distinct(&records, "scene");
    let devices = super::table::distinct(&records, "device");
    let names: BTreeMap<&str, &str> = records
        .iter()
        .map(|r| (r["device"], r["device_name"]))
        .collect();
    // The split settles within a few frames (src/render/balance.rs halves the distance each
    // frame); the means skip the first third.
    let from = frames / 3;
    let mut md = format!(
        "# Several devices per frame (thesis §4.2)\n\n`noisefree bench --study balance \
         --devices ...`: viewer-like frames (1 spp, then the data-driven filter) on {}; the \
         split configurations start from an even split; means over frames {from}-{} (the \
         split settles in the first frames). Every configuration \
         renders its frame in turn, so all see the same machine load. Idle: how long a device \
         waited for the slowest one (kernel times from OpenCL profiling events). Transfer: \
         copying bands to the primary (merged) and rows that changed hands. Frame: render, \
         transfer and filter, wall clock.\n\n",
        devices
            .iter()
            .map(|d| format!("device {d} = {}", names[d]))
            .collect::<Vec<_>>()
            .join(", "),
        frames - 1
    );
    for scene in &scenes {
        md.push_str(&format!(
            "## {scene}\n\n| mode | shares (%) | kernel ms per device | idle ms per device | transfer ms | filter ms | frame ms | frame time vs one device |\n|---|---|---|---|---|---|---|---|\n"
        ));
        let one = mean(&records, scene, "one-device", None, from, "frame_ms");
        for mode in MODES {
            let per = |col: &str| {
                devices
                    .iter()
                    .filter(|d| mode != "one-device" || **d == "0")
                    .map(|d| num(mean(&records, scene, mode, Some(d), from, col)))
                    .collect::<Vec<_>>()
                    .join(" / ")
            };
            let frame = mean(&records, scene, mode, None, from, "frame_ms");
            md.push_str(&format!(
                "| {mode} | {} | {} | {} | {} | {} | {} | {} |\n",
                per("share_pct"),
                per("kernel_ms"),
                per("idle_ms"),
                num(mean(&records, scene, mode, None, from, "transfer_ms")),
                num(mean(&records, scene, mode, None, from, "filter_ms")),
                num(frame),
                num(frame / one.max(1e-9)),
            ));
        }
        md.push_str(&format!("\n![{scene}](balance-{scene}.png)\n\n"));
        chart(ctx, &records, scene, &devices)?;
    }
    std::fs::write(ctx.out.join("balance.md"), md)?;
    Ok(())
}

/// Device 0's share and every device's idle time per frame, static against balanced.
fn chart(
    ctx: &Context,
    records: &[BTreeMap<&str, &str>],
    scene: &str,
    devices: &[&str],
) -> Result<()> {
    let points = |mode: &str, device: &str, column: &str| -> Vec<(f64, f64)> {
        records
            .iter()
            .filter(|r| r["scene"] == scene && r["mode"] == mode && r["device"] == device)
            .filter_map(|r| Some((r["frame"].parse().ok()?, r[column].parse().ok()?)))
            .collect()
    };
    let mut series = Vec::new();
    for mode in ["static", "balanced", "balanced-bands"] {
        series.push(Series {
            label: format!("{mode}: device 0 share (%)"),
            points: points(mode, "0", "share_pct"),
        });
    }
    for mode in ["static", "balanced"] {
        for d in devices {
            series.push(Series {
                label: format!("{mode}: device {d} idle (ms)"),
                points: points(mode, d, "idle_ms"),
            });
        }
    }
    let chart = Chart {
        title: format!("{scene}: device 0's share of the rows and each device's idle time"),
        x_label: "frame".into(),
        y_label: "share (%) / idle (ms)".into(),
        log_x: false,
        log_y: false,
    };
    line_chart(
        &ctx.out.join(format!("balance-{scene}.png")),
        &chart,
        &series,
    )
}
