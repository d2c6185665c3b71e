//! Speed studies of the renderer: the megakernel per scene (specialised vs generic) and the
//! cost of the per-pixel statistics. The filters' speed is in `filter_speed.rs`.

use std::time::Duration;

use anyhow::Result;

use super::study::scene_name;
use super::table::{ResultTable, num};
use super::{Context, bar};

use crate::gpu::Gpu;
use crate::layout::outputs::{Output, OutputSet};
use crate::render::{RenderOptions, Renderer};
use crate::scene::{self, Scene};

pub(super) fn options(scene: &Scene, w: u32, h: u32) -> RenderOptions {
    let mut o = RenderOptions::for_scene(scene);
    o.frame.width = w;
    o.frame.height = h;
    o
}

/// Kernel time per sample of a renderer, measured over `launches` launches of `spp` samples
/// after a one-sample warm-up: (samples/s, Mrays/s).
pub(super) fn throughput(r: &mut Renderer, spp: u32, launches: u32) -> Result<(f64, f64)> {
    r.render_samples(1)?;
    let (mut t, mut rays, mut n) = (Duration::ZERO, 0u64, 0u32);
    for _ in 0..launches {
        let s = r.render_samples(spp)?;
        t += s.kernel_time;
        rays += s.rays;
        n += spp;
    }
    let secs = t.as_secs_f64().max(1e-9);
    Ok((n as f64 / secs, rays as f64 / secs / 1e6))
}

/// Samples per launch so that one launch takes about `target` seconds.
pub(super) fn calibrate(r: &mut Renderer, target: f64) -> Result<u32> {
    let s = r.render_samples(1)?;
    Ok(((target / s.kernel_time.as_secs_f64().max(1e-6)) as u32).clamp(1, 256))
}

/// Time until the megakernel for `scene` has rendered its first sample (an 8 x 8 image):
/// program build plus the first launch, where drivers such as PoCL finish compiling. Cold:
/// from source with the driver's caches off; cached: from noisefree's disk cache.
fn build_times(ctx: &Context, scene: &Scene, o: &RenderOptions) -> Result<(f64, f64)> {
    let dir = std::env::temp_dir().join(format!("noisefree-bench-kcache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let index = Some(ctx.gpu.summary.index);
    let mut tiny = o.clone();
    tiny.frame.width = 8;
    tiny.frame.height = 8;
    let ready = |gpu: std::sync::Arc<Gpu>| -> Result<f64> {
        let start = std::time::Instant::now();
        let mut r = Renderer::new(gpu, scene, &tiny)?;
        r.render_samples(1)?;
        Ok(start.elapsed().as_secs_f64())
    };
    let cold = ready(Gpu::open_with_cache(index, Some(dir.clone()))?)?;
    let cached = ready(Gpu::open_with_cache(index, Some(dir.clone()))?)?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok((cold, cached))
}

/// Per scene: build times and throughput of the specialised and the generic megakernel,
/// measured side by side (alternating launches, so both see the same machine state).
pub fn render_speed(ctx: &Context, fresh: bool) -> Result<()> {
    let (w, h) = if ctx.quick { (96, 96) } else { (512, 512) };
    let columns = [
        "scene",
        "width",
        "height",
        "kernel",
        "ready_cold_s",
        "ready_cached_s",
        "spp_per_s",
        "mrays_per_s",
        "features",
    ];
    let mut t = ctx.table("render-speed", &columns, 4, fresh)?;
    let pb = bar(ctx, ctx.scenes.len() as u64, "render speed");
    for path in &ctx.scenes {
        let name = scene_name(path);
        pb.set_message(format!("render speed: {name}"));
        let key = |k: &str| vec![name.clone(), w.to_string(), h.to_string(), k.to_string()];
        if t.has(&key("specialised")) && t.has(&key("generic")) {
            pb.inc(1);
            continue;
        }
        let scene = scene::load_scene(path)?;
        let spec_o = options(&scene, w, h);
        let mut gen_o = spec_o.clone();
        gen_o.all_features = true;
        let (spec_cold, spec_warm) = build_times(ctx, &scene, &spec_o)?;
        let (gen_cold, gen_warm) = build_times(ctx, &scene, &gen_o)?;
        let mut spec = Renderer::new(ctx.gpu.clone(), &scene, &spec_o)?;
        let mut gen_r = Renderer::new(ctx.gpu.clone(), &scene, &gen_o)?;
        let spp = calibrate(&mut spec, if ctx.quick { 0.2 } else { 1.0 })?;
        // Interleave: specialised, generic, specialised, generic.
        let rounds = if ctx.quick { 1 } else { 3 };
        let (mut s_spp, mut s_ray, mut g_spp, mut g_ray) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..rounds {
            let (a, b) = throughput(&mut spec, spp, 1)?;
            let (c, d) = throughput(&mut gen_r, spp, 1)?;
            s_spp += a / rounds as f64;
            s_ray += b / rounds as f64;
            g_spp += c / rounds as f64;
            g_ray += d / rounds as f64;
        }
        for (k, cold, warm, sps, mrs, feats) in [
            (
                "specialised",
                spec_cold,
                spec_warm,
                s_spp,
                s_ray,
                spec.features.tag(),
            ),
            (
                "generic",
                gen_cold,
                gen_warm,
                g_spp,
                g_ray,
                gen_r.features.tag(),
            ),
        ] {
            if !t.has(&key(k)) {
                let mut row = key(k);
                row.extend([num(cold), num(warm), num(sps), num(mrs), feats]);
                t.push(row)?;
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    write_render_speed_md(ctx, &t)
}

fn write_render_speed_md(ctx: &Context, t: &ResultTable) -> Result<()> {
    let recs = t.records();
    let mut md = String::from(
        "# Megakernel speed per scene: specialised versus generic\n\n\
         Kernel time from OpenCL profiling events; the two kernels run alternately in one run.\n\
         Ready: seconds from loading the scene to the first sample of an 8x8 image (program build,\n\
         scene upload and BVH, and the first launch, where PoCL finishes compiling); `cold` builds\n\
         from source with the driver's caches off, `cached` loads the program binary from\n\
         noisefree's disk cache.\n\n\
         | scene | size | specialised spp/s | generic spp/s | speed-up | specialised Mrays/s | generic Mrays/s | ready cold s (spec. / gen.) | ready cached s (spec. / gen.) |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    for s in recs.iter().filter(|r| r["kernel"] == "specialised") {
        let Some(g) = recs.iter().find(|r| {
            r["kernel"] == "generic"
                && r["scene"] == s["scene"]
                && r["width"] == s["width"]
                && r["height"] == s["height"]
        }) else {
            continue;
        };
        let ratio = s["spp_per_s"].parse::<f64>().unwrap_or(0.0)
            / g["spp_per_s"].parse::<f64>().unwrap_or(1.0);
        md.push_str(&format!(
            "| {} | {}x{} | {} | {} | {} | {} | {} | {} / {} | {} / {} |\n",
            s["scene"],
            s["width"],
            s["height"],
            s["spp_per_s"],
            g["spp_per_s"],
            num(ratio),
            s["mrays_per_s"],
            g["mrays_per_s"],
            s["ready_cold_s"],
            g["ready_cold_s"],
            s["ready_cached_s"],
            g["ready_cached_s"]
        ));
    }
    std::fs::write(ctx.out.join("render-speed.md"), md)?;
    Ok(())
}

/// The statistics stage's cost: samples/s of the same scene without statistics, with the
/// feature means, with means and variances (all one run, interleaved).
pub fn statistics_cost(ctx: &Context, fresh: bool) -> Result<()> {
    let (w, h) = if ctx.quick { (96, 96) } else { (512, 512) };
    let mut t = ctx.table(
        "statistics",
        &[
            "scene",
            "width",
            "height",
            "statistics",
            "spp_per_s",
            "relative",
        ],
        4,
        fresh,
    )?;
    let configs: [(&str, OutputSet); 3] = [
        ("none", OutputSet::colour()),
        ("means", OutputSet::of(&[Output::Features])),
        (
            "means+variances",
            OutputSet::of(&[Output::Features, Output::Variance]),
        ),
    ];
    let pb = bar(ctx, ctx.scenes.len() as u64, "statistics cost");
    for path in &ctx.scenes {
        let name = scene_name(path);
        pb.set_message(format!("statistics cost: {name}"));
        let key = |k: &str| vec![name.clone(), w.to_string(), h.to_string(), k.to_string()];
        if configs.iter().all(|(k, _)| t.has(&key(k))) {
            pb.inc(1);
            continue;
        }
        let scene = scene::load_scene(path)?;
        let mut renderers = Vec::new();
        for (_, outputs) in &configs {
            let mut o = options(&scene, w, h);
            o.outputs = *outputs;
            renderers.push(Renderer::new(ctx.gpu.clone(), &scene, &o)?);
        }
        let spp = calibrate(&mut renderers[0], if ctx.quick { 0.2 } else { 1.0 })?;
        let rounds = if ctx.quick { 1 } else { 3 };
        let mut rates = vec![0.0; configs.len()];
        for _ in 0..rounds {
            for (i, r) in renderers.iter_mut().enumerate() {
                rates[i] += throughput(r, spp, 1)?.0 / rounds as f64;
            }
        }
        for (i, (k, _)) in configs.iter().enumerate() {
            if !t.has(&key(k)) {
                let mut row = key(k);
                row.extend([num(rates[i]), num(rates[i] / rates[0])]);
                t.push(row)?;
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    std::fs::write(
        ctx.out.join("statistics.md"),
        format!(
            "# Cost of the per-pixel statistics (thesis §6.2.2)\n\n\
             Samples/s of the megakernel without statistics, with the FilterVector feature means, and\n\
             with the means and Welford variances; kernel time from profiling events, interleaved in\n\
             one run. `relative` is samples/s over the `none` row.\n\n{}",
            t.markdown()
        ),
    )?;
    Ok(())
}
