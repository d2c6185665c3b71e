//! `roofline` (issue 14): how close each image filter kernel comes to what the device can do
//! (Williams, Waterman & Patterson, CACM 2009). The device's ceilings are measured on the
//! device itself by micro-kernels (`peaks`: FMA throughput, the price of one `exp`, STREAM's
//! triad bandwidth); each filter's arithmetic and compulsory traffic are counted from its
//! source and the frame (`models`), and divided by its kernel time from OpenCL profiling
//! events. The result: achieved GFLOP/s against the arithmetic peak, GB/s against the
//! bandwidth, and both against the roofline min(peak, intensity x bandwidth).
//!
//! Everything is measured anew on every run (nothing resumed), so the ceilings and the
//! kernels come from the same run on the same, equally loaded, device.
//!
//! Counted: the data-driven filter's variants (thesis §6.3, kw 21), à-trous's (scalar and
//! packed) and bmfr's four largest kernels (its non-local means, the fit, the selection and
//! the fit's application, each timed by profiling events within one run of the filter, at its
//! defaults; and the whole filter, its other kernels' time with no flops), and stylized
//! shadows' distance step (DeCoro eq. 3.2, both lights of two_lights_shadows; and the whole
//! filter, as for bmfr); `--method NAME`
//! keeps the kernels labelled NAME or NAME-... (e.g. `--method atrous`: both à-trous kernels),
//! all by default. Not counted: RPF, path-density and the AAF/sheared passes, whose arithmetic
//! depends on the data (mutual-information buckets, kNN ring scans); their times are in the
//! quality study. bmfr's kernels for a thin lens (the prefilter, the emission) do not run on
//! these two scenes.

pub mod models;
pub mod peaks;

use std::time::Duration;

use anyhow::Result;

use super::plot::{Chart, Series, line_chart};
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::atrous::{self, Atrous, AtrousSettings};
use crate::filters::ddf::{Ddf, DdfSettings, DirectionTerm, Variant};
use crate::filters::{Configured, FilterKind};
use crate::render::Frame;
use models::Work;
use peaks::Peaks;

/// The kernels measured: a label and how to configure it.
const KERNELS: &[&str] = &[
    "ddf-naive",
    "ddf-vector",
    "ddf-rows",
    "ddf-rows+holes",
    "ddf-packed",
    "ddf-packed+holes",
    // The fast mode (a polynomial exp in the weights).
    "ddf-packed-fast",
    "ddf-packed-fast+holes",
    "atrous-scalar",
    "atrous-packed",
    // One run of bmfr, a row per modelled kernel and one for the whole filter.
    "bmfr",
    // Stylized shadows' distance step and the whole filter, on their own scene.
    STYLIZED,
];

/// The label of stylized shadows, measured on [`STYLIZED_SCENE`] only.
const STYLIZED: &str = "stylized-shadows";

/// Stylized shadows need sphere lights whose shadows fall in view: the scene of DeCoro's
/// eq. 3.1 with two of them, where st_distance is the slowest (results/README.md).
const STYLIZED_SCENE: &str = "two_lights_shadows";

/// The scenes: a closed room (every pixel a surface) and Outside (a sky the filters skip).
const SCENES: &[&str] = &["cornell_diffuse", "outside"];

/// The data-driven filter's settings for a label of [`KERNELS`] (defaults otherwise: kw 21).
fn ddf_settings(label: &str) -> DdfSettings {
    let variant = match label {
        "ddf-naive" => Variant::Naive,
        "ddf-vector" => Variant::Vector,
        l if l.starts_with("ddf-packed") => Variant::Packed,
        _ => Variant::Rows,
    };
    DdfSettings {
        variant,
        holes: label.ends_with("+holes"),
        fast_exp: label.contains("-fast"),
        ..Default::default()
    }
}

/// The filter of `label`, configured for `frame`, and the work it does on it.
fn configure(label: &str, frame: &Frame) -> Result<(Configured, Work)> {
    let info = &frame.info().scene;
    let fv = frame.filter_vectors()?;
    let (w, h) = (frame.width(), frame.height());
    if let Some(variant) = label.strip_prefix("atrous-") {
        let s = AtrousSettings {
            variant: match variant {
                "packed" => atrous::Variant::Packed,
                _ => atrous::Variant::Scalar,
            },
            ..Default::default()
        };
        // The packed kernel does the same counted work: lanes past the image's edge and
        // masked-out taps are not useful work, so they are not counted.
        let work = models::atrous_work(fv, w, h, s.iterations);
        return Ok((Configured::typed::<Atrous>(s, info)?, work));
    }
    let s = ddf_settings(label);
    let mut effective = s.clone();
    Ddf::specialise(&mut effective, info);
    let mut extra = 0.0;
    if effective.uses_texture2() {
        extra += models::DDF_TEXTURE2_FLOPS;
    }
    extra += match effective.direction {
        DirectionTerm::Thesis => 0.0,
        DirectionTerm::Difference => models::DDF_DIRECTION_DIFFERENCE_FLOPS,
        DirectionTerm::Neighbour => models::DDF_DIRECTION_NEIGHBOUR_FLOPS,
    };
    let p = effective.params(w, h, 1.0, 1.0);
    let work = models::ddf_work(
        fv,
        w,
        h,
        p.half_width as u32,
        p.step as u32,
        effective.keeps_sky(),
        extra,
    );
    Ok((Configured::typed::<Ddf>(s, info)?, work))
}

/// bmfr at its defaults on an 8-spp n × n frame of `scene` (with the outputs bmfr reads): for
/// each modelled kernel its work and best time over `runs` runs after a warm-up (profiling
/// events), then the whole filter ("bmfr-all": the modelled work over every kernel's time).
fn bmfr_kernels(
    ctx: &Context,
    scene: &crate::scene::Scene,
    n: u32,
    runs: usize,
) -> Result<Vec<(String, Work, Duration)>> {
    use crate::filters::bmfr::{Bmfr, BmfrSettings, kept, nlm};
    use crate::gpu::profile;
    use crate::layout::Float4;
    use crate::layout::outputs::BufferId;

    let s = BmfrSettings::default();
    // The outputs bmfr reads once specialised to the scene (`emission` follows its lights).
    let mut effective = s.clone();
    Bmfr::specialise(
        &mut effective,
        &super::filter_speed::scene_info(scene, n, n)?,
    );
    let frame = super::filter_speed::filter_input_with(ctx, scene, n, n, effective.needs())?;
    let info = &frame.info().scene;
    let shape = models::BmfrShape {
        features: effective.features(),
        block: effective.block_size,
        grids: effective.grids,
        nlm_radius: effective.nlm_radius,
        estimate_radius: effective.estimate_radius(),
        select_radius: effective.select_radius,
        nlm_patch: effective.nlm_patch,
    };
    let fv = frame.filter_vectors()?;
    let pos: &[Float4] = frame.host_slice(BufferId::Positions)?;
    let odd: &[Float4] = frame.host_slice(BufferId::OddHalves)?;
    let spp = frame.info().spp as f32;
    let split = effective.splits_emission();
    let classes: Vec<f32> = (0..fv.len())
        .map(|i| nlm::class(&fv[i], &pos[i], &odd[i], spp, split))
        .collect();
    let fitted = (0..fv.len())
        .filter(|&i| !kept(&fv[i], &pos[i], spp, split))
        .count() as u64;
    // The packed kernels on CPU devices, the work-group ones elsewhere: the same useful work
    // (both non-local means kernels evaluate each tap's term once per offset).
    let modelled = [
        (
            ["bmfr_nlm_packed", "bmfr_nlm"],
            models::bmfr_nlm_work(&classes, n, n, &shape),
        ),
        (
            ["bmfr_fit_packed", "bmfr_fit"],
            models::bmfr_fit_work(n, n, &shape),
        ),
        (
            ["bmfr_select_nlm_packed", "bmfr_select_nlm"],
            models::bmfr_select_work(n, n, &shape),
        ),
        (
            ["bmfr_apply_packed", "bmfr_apply"],
            models::bmfr_apply_work(fitted, n, n, &shape),
        ),
    ];
    let f = Configured::typed::<Bmfr>(s, info)?;
    let mut prepared = f.prepare(frame.info(), &ctx.gpu)?;
    prepared.run(&frame)?;
    let mut best = std::collections::BTreeMap::<String, Duration>::new();
    let mut best_all = Duration::MAX;
    for _ in 0..runs {
        profile::start();
        let run = prepared.run(&frame);
        let kernels = profile::finish()?;
        run?;
        let mut all = Duration::ZERO;
        for k in kernels {
            all += k.time;
            let b = best.entry(k.kernel).or_insert(Duration::MAX);
            *b = (*b).min(k.time);
        }
        best_all = best_all.min(all);
    }
    let mut out = Vec::new();
    let mut total = Work::default();
    for (names, work) in modelled {
        let Some((kernel, time)) = names.iter().find_map(|k| best.get(*k).map(|t| (k, t))) else {
            anyhow::bail!("roofline: bmfr ran none of {names:?} (src/filters/bmfr/device.rs)");
        };
        total += work;
        out.push((format!("bmfr: {kernel}"), work, *time));
    }
    out.push((
        "bmfr-all (every kernel's time)".to_string(),
        total,
        best_all,
    ));
    Ok(out)
}

/// Stylized shadows at their defaults on an 8-spp n × n frame of [`STYLIZED_SCENE`]: the
/// distance step (every stylized light's st_distance launches of a run, their work summed)
/// with its best time over `runs` runs after a warm-up, then the whole filter
/// ("stylized-shadows-all": the distance step's work over every kernel's time).
fn stylized_kernels(ctx: &Context, n: u32, runs: usize) -> Result<Vec<(String, Work, Duration)>> {
    use crate::filters::PreparedFilter;
    use crate::filters::stylized::light_plane;
    use crate::filters::stylized::{StylizedKernel, StylizedSettings, StylizedShadows};
    use crate::gpu::profile;
    use crate::layout::ShadowPixel;
    use crate::layout::outputs::BufferId;

    let scene = crate::scene::load_scene(&ctx.scene_file(STYLIZED_SCENE)?)?;
    let info = super::filter_speed::scene_info(&scene, n, n)?;
    let configured = Configured::typed::<StylizedShadows>(StylizedSettings::default(), &info)?;
    let frame = super::filter_speed::filter_input_for(ctx, &scene, n, n, &configured)?;
    let mut s = StylizedSettings::default();
    StylizedShadows::specialise(&mut s, &info);
    let lights = s.stylized_lights();
    let mut k = StylizedKernel::new(ctx.gpu.clone(), &s, &lights, n, n)?;
    k.filter(&frame)?;
    let mut work = Work::default();
    for (i, &light) in lights.iter().enumerate() {
        let pixels: Vec<ShadowPixel> = light_plane(&frame, BufferId::ShadowPixels, light)?;
        let st = k.light_stages(i)?;
        work += models::stylized_distance_work(
            &pixels,
            &st.distance,
            st.contour_points,
            s.contour_samples,
        );
    }
    let (mut best, mut best_all) = (Duration::MAX, Duration::MAX);
    for _ in 0..runs {
        // A filter that has seen these shadow pixels keeps its distances (the editing loop of
        // `view`): each timed run does the frame's whole work again.
        k.forget();
        profile::start();
        let run = k.filter(&frame);
        let kernels = profile::finish()?;
        run?;
        let distance = kernels
            .iter()
            .filter(|t| t.kernel == "st_distance")
            .map(|t| t.time);
        best = best.min(distance.sum());
        best_all = best_all.min(kernels.iter().map(|t| t.time).sum());
    }
    Ok(vec![
        (format!("{STYLIZED}: st_distance"), work, best),
        (
            format!("{STYLIZED}-all (every kernel's time)"),
            work,
            best_all,
        ),
    ])
}

/// The best kernel time of `runs` runs after a warm-up, each doing the frame's whole work
/// (`PreparedFilter::forget`).
fn best_time(ctx: &Context, f: &Configured, frame: &Frame, runs: usize) -> Result<Duration> {
    let mut prepared = f.prepare(frame.info(), &ctx.gpu)?;
    prepared.run(frame)?;
    let mut best = Duration::MAX;
    for _ in 0..runs {
        prepared.forget();
        best = best.min(prepared.run(frame)?.time());
    }
    Ok(best)
}

/// The table row of one kernel: its work over its time, against the ceilings.
fn row(scene: &str, size: &str, label: &str, w: &Work, t: Duration, pk: &Peaks) -> Vec<String> {
    let s = t.as_secs_f64();
    let gflop = w.flop_equivalents(pk.exp_flops()) / 1e9;
    let gbyte = w.bytes / 1e9;
    let intensity = gflop / gbyte;
    let attainable = pk.attainable(intensity);
    let mut r = vec![scene.to_string(), size.to_string(), label.to_string()];
    r.extend(
        [
            s * 1e3,
            w.taps as f64 / 1e6,
            gflop,
            gflop / s,
            100.0 * gflop / s / pk.gflops,
            100.0 * gflop / s / pk.gflops_scalar,
            gbyte / s,
            100.0 * gbyte / s / pk.gbps,
            intensity,
            attainable,
            100.0 * gflop / s / attainable,
        ]
        .map(num),
    );
    r
}

/// `roofline` (module docs).
pub fn roofline(ctx: &Context) -> Result<()> {
    let columns = [
        "scene",
        "size",
        "kernel",
        "ms",
        "mtaps",
        "gflop",
        "gflops",
        "pct_peak",
        "pct_scalar_peak",
        "gbps",
        "pct_bandwidth",
        "flops_per_byte",
        "roof_gflops",
        "pct_roof",
    ];
    let mut t = ctx.table("roofline", &columns, 3, true)?;
    let (scenes, n, runs) = if ctx.quick {
        (&SCENES[..1], 64, 2)
    } else {
        (SCENES, 512, 5)
    };
    let per_scene = |l: &&&str| ctx.wants(l) && **l != STYLIZED;
    let kernels = KERNELS.iter().filter(per_scene).count();
    let stylized = ctx.wants(STYLIZED);
    let pb = bar(
        ctx,
        (1 + scenes.len() * kernels + stylized as usize) as u64,
        "roofline",
    );
    pb.set_message("roofline: the device's ceilings");
    let pk = peaks::measure(&ctx.gpu, ctx.quick)?;
    pb.inc(1);
    let size = format!("{n}x{n}");
    for name in scenes {
        let scene = crate::scene::load_scene(&ctx.scene_file(name)?)?;
        let frame = super::filter_speed::filter_input(ctx, &scene, n, n)?;
        for label in KERNELS.iter().filter(per_scene) {
            pb.set_message(format!("roofline: {name} {label}"));
            if *label == "bmfr" {
                for (kernel, work, time) in bmfr_kernels(ctx, &scene, n, runs)? {
                    t.push(row(name, &size, &kernel, &work, time, &pk))?;
                }
                pb.inc(1);
                continue;
            }
            let (f, work) = configure(label, &frame)?;
            let time = best_time(ctx, &f, &frame, runs)?;
            t.push(row(name, &size, label, &work, time, &pk))?;
            pb.inc(1);
        }
    }
    if stylized {
        pb.set_message(format!("roofline: {STYLIZED_SCENE} {STYLIZED}"));
        for (kernel, work, time) in stylized_kernels(ctx, n, runs)? {
            t.push(row(STYLIZED_SCENE, &size, &kernel, &work, time, &pk))?;
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    write_report(ctx, &t, &pk)
}

fn write_report(ctx: &Context, t: &ResultTable, pk: &Peaks) -> Result<()> {
    let recs = t.records();
    let scalar = Peaks {
        gflops: pk.gflops_scalar,
        ..*pk
    };
    let mut series = vec![
        Series {
            label: "roofline (float16 FMA, triad)".into(),
            points: roof_points(pk, &recs),
        },
        Series {
            label: "ceiling of float chains".into(),
            points: roof_points(&scalar, &recs),
        },
    ];
    for r in &recs {
        let p = (
            r["flops_per_byte"].parse().unwrap_or(f64::NAN),
            r["gflops"].parse().unwrap_or(f64::NAN),
        );
        series.push(Series {
            label: format!("{} {}", r["kernel"], r["scene"]),
            points: vec![p],
        });
    }
    line_chart(
        &ctx.out.join("roofline.png"),
        &Chart {
            title: format!("Roofline of {}", ctx.gpu.summary.name),
            x_label: "arithmetic intensity (flops per compulsory byte)".into(),
            y_label: "GFLOP/s".into(),
            log_x: true,
            log_y: true,
        },
        &series,
    )?;
    let md = format!(
        "# Roofline (issue 14)\n\n\
         `noisefree bench --study roofline`: the device's ceilings measured by micro-kernels \
         (kernels/bench/roofline.cl) in the same run as the filters: fused multiply-adds on 8 \
         independent float16 chains per work-item **{:.1} GFLOP/s** (on float chains, which \
         only the compiler can vectorise: **{:.1} GFLOP/s**); `exp` on float16s **{:.2} G/s** \
         ({:.3} G/s on floats), so one exp costs **{:.1} flops**; STREAM triad **{:.1} GB/s**; \
         ridge at {:.1} flops/byte.\n\n\
         Each filter's flops are counted from its source (src/bench/roofline/models.rs; each \
         `exp` at the measured price) and its taps exactly from the frame (8 spp); bytes are \
         compulsory traffic (every buffer read once, the output written once). `pct_peak`: \
         achieved GFLOP/s over the FMA peak, `pct_scalar_peak` over the float-chain peak (a \
         kernel above 100 % of it was vectorised); `pct_bandwidth`: compulsory GB/s over the triad; \
         `roof_gflops` = min(peak, intensity x bandwidth), `pct_roof` the achieved share of \
         it. Kernel times: best of several runs, OpenCL profiling events; bmfr's kernels each \
         their best within runs of the whole filter, and `bmfr-all` the four kernels' work \
         over the best run's total kernel time (its other kernels add time, not flops).\n\n\
         ![roofline](roofline.png)\n\n{}",
        pk.gflops,
        pk.gflops_scalar,
        pk.gexps,
        pk.gexps_scalar,
        pk.exp_flops(),
        pk.gbps,
        pk.ridge(),
        t.markdown()
    );
    std::fs::write(ctx.out.join("roofline.md"), md)?;
    Ok(())
}

/// The roof as a polyline from below the lowest to above the highest intensity measured.
fn roof_points(pk: &Peaks, recs: &[std::collections::BTreeMap<&str, &str>]) -> Vec<(f64, f64)> {
    let xs: Vec<f64> = recs
        .iter()
        .filter_map(|r| r["flops_per_byte"].parse::<f64>().ok())
        .filter(|x| x.is_finite() && *x > 0.0)
        .collect();
    let lo = xs.iter().copied().fold(pk.ridge(), f64::min) / 4.0;
    let hi = xs.iter().copied().fold(pk.ridge(), f64::max) * 4.0;
    let mut pts = vec![(lo, pk.attainable(lo))];
    if pk.ridge() > lo && pk.ridge() < hi {
        pts.push((pk.ridge(), pk.gflops));
    }
    pts.push((hi, pk.attainable(hi)));
    pts
}
