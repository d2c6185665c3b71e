//! The data-driven filter's kernel time (thesis §7.1-7.2): per scene (Figs. 7.2-7.6 for the
//! unoptimised kernel, 7.7-7.12 for the optimised ones, Fig. 7.11 with the sky-box filling the
//! view), over kernel widths, resolutions, kernel variants and work-group sizes, with the lower
//! and upper bounds the thesis reports (min / max over repeated runs) and the median.

use std::time::Duration;

use anyhow::Result;
use glam::Vec3;

use super::plot::{Chart, Series, panel_chart};
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::ddf::{DdfKernel, DdfSettings, PACKED_GROUP, Variant};
use crate::layout::outputs::{Output, OutputSet};
use crate::render::{Frame, RenderOptions, Renderer, SceneArrays, SceneInfo};
use crate::scene::{self, Scene};

/// The scenes of Figs. 7.2-7.12; `outside_sky` is Outside looking straight up, so that the
/// sky-box fills the view (Fig. 7.11: every pixel takes the sky special case of §6.3.4).
const SCENES: &[&str] = &[
    "cornell_diffuse",
    "cornell_glossy",
    "cornell_plane",
    "outside",
    "outside_sky",
    "conference",
];

/// The kernel variants: the unoptimised one (Figs. 7.2-7.6), float16 loads (§6.3.1), local
/// memory rows (§6.3.2) and rows with holes (§6.3.3; Figs. 7.7-7.12), then ours for CPUs,
/// 16 pixels per work-item on float16 lanes, without and with holes.
const VARIANTS: &[&str] = &[
    "naive",
    "vector",
    "rows",
    "rows+holes",
    "packed",
    "packed+holes",
];

/// The work-groups a variant is measured at: the unoptimised kernel at the thesis's 64 and 256
/// (`groups`), the other thesis variants at the first of them (on PoCL the work-group moved
/// their times by < 5 %: the 2026-11-21 run, 45b476f, measured both), the packed variant at
/// its fixed group ([`PACKED_GROUP`] work-items; PoCL's own choice crashed at 512 x 512).
fn groups_of(variant: &str, groups: &[usize]) -> Vec<usize> {
    match variant {
        "naive" => groups.to_vec(),
        v if v.starts_with("packed") => vec![PACKED_GROUP],
        _ => groups[..1].to_vec(),
    }
}

/// A scene by its name in the table (`outside_sky`: Outside with the camera turned to the sky).
fn load(ctx: &Context, name: &str) -> Result<Scene> {
    let file = name.strip_suffix("_sky").unwrap_or(name);
    let mut scene = scene::load_scene(&ctx.scene_file(file)?)?;
    if name.ends_with("_sky") {
        let c = &mut scene.camera;
        c.target = c.origin + Vec3::Y * 10.0;
        c.up = Vec3::Z;
    }
    Ok(scene)
}

/// Rendered 8-spp outputs of `scene` at `w` x `h`, the filter's input (on the device).
pub(super) fn filter_input(ctx: &Context, scene: &Scene, w: u32, h: u32) -> Result<Frame> {
    filter_input_with(
        ctx,
        scene,
        w,
        h,
        OutputSet::of(&[Output::Features, Output::Variance]),
    )
}

/// What a filter may know of `scene` rendered at w × h (to specialise it before rendering
/// the outputs it reads).
pub(super) fn scene_info(scene: &Scene, w: u32, h: u32) -> Result<SceneInfo> {
    let mut o = RenderOptions::for_scene(scene);
    (o.frame.width, o.frame.height) = (w, h);
    Ok(SceneInfo::new(scene, &SceneArrays::build(scene, &o.frame)?))
}

/// [`filter_input`] with the outputs a filter reads (e.g. bmfr's positions and half buffers).
pub(super) fn filter_input_with(
    ctx: &Context,
    scene: &Scene,
    w: u32,
    h: u32,
    outputs: OutputSet,
) -> Result<Frame> {
    render_input(ctx, scene, w, h, |o| o.outputs = outputs)
}

/// [`filter_input`] rendered as `filter` asks (its outputs and how they are gathered, e.g.
/// stylized shadows' planes of several sphere lights).
pub(super) fn filter_input_for(
    ctx: &Context,
    scene: &Scene,
    w: u32,
    h: u32,
    filter: &crate::filters::Configured,
) -> Result<Frame> {
    render_input(ctx, scene, w, h, |o| {
        o.outputs = filter.needs();
        filter.adjust_render(o);
    })
}

/// 8 spp of `scene` at w × h with the scene's render options as `set` changes them.
fn render_input(
    ctx: &Context,
    scene: &Scene,
    w: u32,
    h: u32,
    set: impl FnOnce(&mut RenderOptions),
) -> Result<Frame> {
    let mut o = RenderOptions::for_scene(scene);
    (o.frame.width, o.frame.height) = (w, h);
    set(&mut o);
    let mut r = Renderer::new(ctx.gpu.clone(), scene, &o)?;
    r.render_samples(8)?;
    Ok(r.frame())
}

/// Filter kernel time over scenes x resolutions x kernel widths x variants x work-group sizes,
/// min / median / max over repeated runs after a warm-up (thesis §7.1-7.2).
pub fn filter_speed(ctx: &Context, fresh: bool) -> Result<()> {
    type Plan<'a> = (&'a [&'a str], Vec<(u32, u32)>, Vec<u32>, Vec<usize>);
    let (scenes, resolutions, widths, groups): Plan = if ctx.quick {
        (&SCENES[..1], vec![(64, 48)], vec![7, 15], vec![64])
    } else {
        (
            SCENES,
            vec![(320, 240), (512, 512), (640, 480), (1280, 768)],
            vec![7, 15, 25, 55],
            vec![64, 256],
        )
    };
    let columns = [
        "scene",
        "width",
        "height",
        "kw",
        "variant",
        "work_group",
        "runs",
        "min_ms",
        "median_ms",
        "max_ms",
    ];
    let mut t = ctx.table("filter-speed", &columns, 6, fresh)?;
    let per_kw: usize = VARIANTS.iter().map(|v| groups_of(v, &groups).len()).sum();
    let cells = (scenes.len() * resolutions.len() * widths.len() * per_kw) as u64;
    let pb = bar(ctx, cells, "filter speed");
    for &name in scenes {
        let mut scene = None;
        for &(w, h) in &resolutions {
            let mut input = None;
            for &kw in &widths {
                for &variant in VARIANTS {
                    for wg in groups_of(variant, &groups) {
                        let key = vec![
                            name.to_string(),
                            w.to_string(),
                            h.to_string(),
                            kw.to_string(),
                            variant.to_string(),
                            wg.to_string(),
                        ];
                        pb.set_message(format!("filter speed: {name} {w}x{h} kw {kw} {variant}"));
                        if t.has(&key) {
                            pb.inc(1);
                            continue;
                        }
                        if scene.is_none() {
                            scene = Some(load(ctx, name)?);
                        }
                        if input.is_none() {
                            let s = scene.as_ref().expect("loaded above");
                            input = Some(filter_input(ctx, s, w, h)?);
                        }
                        let frame = input.as_ref().expect("rendered above");
                        let times = measure(ctx, frame, kw, variant, wg)?;
                        let (lo, med, hi) = crate::filters::time_summary(&times).expect("runs");
                        let ms = |d: Duration| num(d.as_secs_f64() * 1e3);
                        let mut row = key;
                        row.extend([times.len().to_string(), ms(lo), ms(med), ms(hi)]);
                        t.push(row)?;
                        pb.inc(1);
                    }
                }
            }
        }
    }
    pb.finish_and_clear();
    write_report(ctx, &t)
}

/// Kernel times of one cell: a warm-up run, then at least 2 and at most 7 (3 with --quick)
/// runs within 20 s (5 s with --quick) of kernel time.
fn measure(
    ctx: &Context,
    frame: &Frame,
    kw: u32,
    variant: &str,
    wg: usize,
) -> Result<Vec<Duration>> {
    let (v, naive_wg) = match variant {
        "naive" => (Variant::Naive, Some(wg)),
        "vector" => (Variant::Vector, Some(wg)),
        "packed" | "packed+holes" => (Variant::Packed, None),
        _ => (Variant::Rows, None),
    };
    let mut settings = DdfSettings {
        kw,
        holes: variant.ends_with("+holes"),
        variant: v,
        work_group: wg as u32,
        ..Default::default()
    };
    // Specialised like `render --filter ddf` (the sky case where the scene has a sky).
    let info = frame.info().scene.clone();
    <crate::filters::ddf::Ddf as crate::filters::FilterKind>::specialise(&mut settings, &info);
    let (w, h) = (frame.width(), frame.height());
    let mut f = DdfKernel::with_work_group(ctx.gpu.clone(), &settings, w, h, naive_wg)?;
    f.filter(frame)?; // warm-up
    let mut times = Vec::new();
    let max_runs = if ctx.quick { 3 } else { 7 };
    let budget = Duration::from_secs(if ctx.quick { 5 } else { 20 });
    let mut spent = Duration::ZERO;
    while times.len() < max_runs && (times.len() < 2 || spent < budget) {
        let k = f.filter(frame)?.time();
        spent += k;
        times.push(k);
    }
    Ok(times)
}

/// One figure per scene, a panel per resolution: the upper bound (max) kernel time against the
/// kernel width, a line per variant (work-group 64; packed at its fixed group), as the thesis's
/// figures; under it the medians at the largest kernel width. The table holds every cell.
fn write_report(ctx: &Context, t: &ResultTable) -> Result<()> {
    let recs = t.records();
    let scenes = super::table::distinct(&recs, "scene");
    let mut md = String::from(
        "# Data-driven filter speed (thesis §7.1-7.2, Figs. 7.2-7.12)\n\n\
         Input: each scene at 8 spp (`outside_sky`: Outside looking straight up, the sky-box in\n\
         full view, Fig. 7.11). Kernel time from OpenCL profiling events: min (the thesis's lower\n\
         bound), median and max (its upper bound) over repeated runs after one warm-up run. The\n\
         plots show the upper bound at work-group 64, one panel per resolution; `naive` is the\n\
         unoptimised kernel of Figs. 7.2-7.6, `rows` and `rows+holes` the optimised ones of Figs.\n\
         7.7-7.12; `packed` and `packed+holes` are ours for CPUs (16 pixels per work-item,\n\
         work-group fixed at 8).\n\n",
    );
    for name in &scenes {
        let shown: Vec<_> = recs
            .iter()
            .filter(|r| r["scene"] == *name)
            .filter(|r| r["work_group"] == "64" || r["variant"].starts_with("packed"))
            .collect();
        let mut sizes: Vec<(u32, u32)> = shown
            .iter()
            .map(|r| {
                (
                    r["width"].parse().unwrap_or(0),
                    r["height"].parse().unwrap_or(0),
                )
            })
            .collect();
        sizes.sort_by_key(|&(w, h)| (w * h, w));
        sizes.dedup();
        let at = |r: &&&std::collections::BTreeMap<&str, &str>, (w, h): (u32, u32)| {
            r["width"] == w.to_string() && r["height"] == h.to_string()
        };
        let mut panels = Vec::new();
        for &size in &sizes {
            // Every panel lists the variants in VARIANTS order, so a variant keeps its colour.
            let series: Vec<Series> = VARIANTS
                .iter()
                .map(|v| {
                    let mut points: Vec<(f64, f64)> = shown
                        .iter()
                        .filter(|r| r["variant"] == *v && at(r, size))
                        .map(|r| {
                            (
                                r["kw"].parse::<f64>().unwrap_or(0.0),
                                r["max_ms"].parse::<f64>().unwrap_or(f64::NAN),
                            )
                        })
                        .collect();
                    points.sort_by(|a, b| a.0.total_cmp(&b.0));
                    Series {
                        label: v.to_string(),
                        points,
                    }
                })
                .collect();
            let chart = Chart {
                title: format!("{}x{}", size.0, size.1),
                x_label: "kernel width kw".into(),
                y_label: "upper-bound ms".into(),
                log_x: false,
                log_y: true,
            };
            panels.push((chart, series));
        }
        let file = format!("filter-speed-{name}.png");
        panel_chart(
            &ctx.out.join(&file),
            &format!("Data-driven filter on {name}: upper-bound kernel time"),
            2,
            &panels,
        )?;
        md.push_str(&format!(
            "## {name}\n\n![filter time vs kernel width]({file})\n\n"
        ));
        md.push_str(&median_summary(&shown, &sizes));
    }
    md.push_str("## All measurements\n\n");
    md.push_str(&t.markdown());
    std::fs::write(ctx.out.join("filter-speed.md"), md)?;
    Ok(())
}

/// Median ms of each variant at each resolution's largest kernel width, and packed over rows
/// (the thesis's optimised kernel) at the same cell.
fn median_summary(
    shown: &[&std::collections::BTreeMap<&str, &str>],
    sizes: &[(u32, u32)],
) -> String {
    let cell = |v: &str, (w, h): (u32, u32)| {
        let mut kws: Vec<(u32, f64)> = shown
            .iter()
            .filter(|r| {
                r["variant"] == v && r["width"] == w.to_string() && r["height"] == h.to_string()
            })
            .filter_map(|r| Some((r["kw"].parse().ok()?, r["median_ms"].parse().ok()?)))
            .collect();
        kws.sort_by_key(|k| k.0);
        kws.last().copied()
    };
    let mut md =
        String::from("Median ms at the largest kernel width of each resolution:\n\n| variant |");
    for &(w, h) in sizes {
        let kw = VARIANTS
            .iter()
            .find_map(|v| cell(v, (w, h)))
            .map_or(0, |c| c.0);
        md.push_str(&format!(" {w}x{h} kw {kw} |"));
    }
    md.push_str("\n|---|");
    md.push_str(&"---|".repeat(sizes.len()));
    md.push('\n');
    for v in VARIANTS {
        md.push_str(&format!("| {v} |"));
        for &size in sizes {
            md.push_str(&match cell(v, size) {
                Some((_, ms)) => format!(" {} |", num(ms)),
                None => " |".into(),
            });
        }
        md.push('\n');
    }
    md.push_str("| packed / rows |");
    for &size in sizes {
        md.push_str(&match (cell("packed", size), cell("rows", size)) {
            (Some(p), Some(r)) if r.1 > 0.0 => format!(" {:.3} |", p.1 / r.1),
            _ => " |".into(),
        });
    }
    md.push_str("\n\n");
    md
}
