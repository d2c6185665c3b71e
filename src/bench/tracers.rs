//! `bench --study tracers`: the megakernel (thesis §4.3) and the wavefront tracer (Laine,
//! Karras & Aila 2013; src/render/wavefront.rs) side by side on every scene, and the megakernel
//! walking the thesis's skip-index BVH (Alg. 4) instead of the wide one (src/bvh/wide.rs):
//! samples/s from kernel time, launches alternating so all see the same machine state,
//! whether their films are the same bytes, and where the wavefront's time goes (its kernel
//! time per step).

use anyhow::Result;

use super::speed::{calibrate, options, throughput};
use super::study::scene_name;
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::bvh::BvhLayout;
use crate::render::wavefront::STEPS;
use crate::render::{Renderer, Tracer};
use crate::scene;

pub fn tracers(ctx: &Context, fresh: bool) -> Result<()> {
    let (w, h) = if ctx.quick { (96, 96) } else { (512, 512) };
    // The step shares in the order of STEPS.
    let columns = [
        "scene",
        "width",
        "height",
        "spp",
        "megakernel_spp_per_s",
        "wavefront_spp_per_s",
        "skip_bvh_spp_per_s",
        "same_bytes",
        "generate_share",
        "extend_share",
        "shade_share",
        "shadow_share",
        "accumulate_share",
    ];
    debug_assert!(
        STEPS
            .iter()
            .zip(&columns[8..])
            .all(|(s, c)| c.starts_with(s))
    );
    let mut t = ctx.table("tracers", &columns, 3, fresh)?;
    let pb = bar(ctx, ctx.scenes.len() as u64, "tracers");
    for path in &ctx.scenes {
        let name = scene_name(path);
        pb.set_message(format!("tracers: {name}"));
        let key = vec![name.clone(), w.to_string(), h.to_string()];
        if t.has(&key) {
            pb.inc(1);
            continue;
        }
        let scene = scene::load_scene(path)?;
        let mega_o = options(&scene, w, h);
        let mut wave_o = mega_o.clone();
        wave_o.tracer = Tracer::Wavefront;
        let mut skip_o = mega_o.clone();
        skip_o.bvh = BvhLayout::Skip;
        let mut mega = Renderer::new(ctx.gpu.clone(), &scene, &mega_o)?;
        let mut wave = Renderer::new(ctx.gpu.clone(), &scene, &wave_o)?;
        let mut skip = Renderer::new(ctx.gpu.clone(), &scene, &skip_o)?;
        let spp = calibrate(&mut mega, if ctx.quick { 0.2 } else { 1.0 })?;
        wave.render_samples(1)?;
        skip.render_samples(1)?;
        // Interleaved rounds: megakernel, wavefront, skip-index, megakernel, ...
        let rounds = if ctx.quick { 1 } else { 3 };
        let (mut m_spp, mut w_spp, mut s_spp) = (0.0, 0.0, 0.0);
        for _ in 0..rounds {
            m_spp += throughput(&mut mega, spp, 1)?.0 / rounds as f64;
            w_spp += throughput(&mut wave, spp, 1)?.0 / rounds as f64;
            s_spp += throughput(&mut skip, spp, 1)?.0 / rounds as f64;
        }
        // The three films now hold the same samples: compare them byte for byte.
        let same = films_equal(&mega, &wave)? && films_equal(&mega, &skip)?;
        let total: f64 = wave.wavefront_times.iter().map(|d| d.as_secs_f64()).sum();
        let mut row = key;
        row.extend([
            mega.samples_done().to_string(),
            num(m_spp),
            num(w_spp),
            num(s_spp),
            same.to_string(),
        ]);
        row.extend(
            wave.wavefront_times
                .iter()
                .map(|d| num(d.as_secs_f64() / total.max(1e-12))),
        );
        t.push(row)?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    write_md(ctx, &t)
}

fn films_equal(a: &Renderer, b: &Renderer) -> Result<bool> {
    let (fa, fb) = (a.frame(), b.frame());
    for buffer in fa.outputs().buffers() {
        if fa.host(buffer.id)?.as_bytes() != fb.host(buffer.id)?.as_bytes() {
            return Ok(false);
        }
    }
    Ok(a.samples_done() == b.samples_done())
}

fn write_md(ctx: &Context, t: &ResultTable) -> Result<()> {
    let mut md = String::from(
        "# Megakernel and wavefront tracer side by side, and the two BVH layouts\n\n\
         `noisefree bench --study tracers`. Samples per second from kernel time (OpenCL profiling\n\
         events; the wavefront's host round trips between its launches are not counted), the\n\
         launches alternating (three rounds, one with --quick). Both tracers walk the wide BVH;\n\
         skip-index: the megakernel walking the thesis's binary tree (Alg. 4, `--bvh skip`).\n\
         Same bytes: the three films after the same samples. Shares: the wavefront's kernel time\n\
         per step.\n\n\
         | scene | size | megakernel spp/s | wavefront spp/s | wavefront / megakernel | skip-index spp/s | wide / skip-index | same bytes | generate | extend | shade | shadow | accumulate |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let pct = |v: &str| format!("{:.1} %", v.parse::<f64>().unwrap_or(0.0) * 100.0);
    for r in t.records() {
        let value = |k: &str| r[k].parse::<f64>().unwrap_or(0.0);
        let mega = value("megakernel_spp_per_s").max(1e-12);
        md.push_str(&format!(
            "| {} | {}x{} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            r["scene"],
            r["width"],
            r["height"],
            r["megakernel_spp_per_s"],
            r["wavefront_spp_per_s"],
            num(value("wavefront_spp_per_s") / mega),
            r["skip_bvh_spp_per_s"],
            num(mega / value("skip_bvh_spp_per_s").max(1e-12)),
            if r["same_bytes"] == "true" {
                "yes"
            } else {
                "NO"
            },
            pct(r["generate_share"]),
            pct(r["extend_share"]),
            pct(r["shade_share"]),
            pct(r["shadow_share"]),
            pct(r["accumulate_share"]),
        ));
    }
    std::fs::write(ctx.out.join("tracers.md"), md)?;
    Ok(())
}
