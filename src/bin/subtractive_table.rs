//! The RMS / time table of the subtractive shadow preview against the additive form (DeCoro
//! 2009 ch. 4, Fig. 4.4; digest shared/notes/seed-decoro.md §2.5):
//! `cargo run --release --bin subtractive_table -- [OUT_DIR] [SCENE] [SIZE] [GT_SPP]`
//! (defaults results/subtractive, scenes/outside.toml, 256, 256).
//!
//! Rows: additive (the visible lights summed at every pixel) and subtractive (C from 1024
//! unshadowed lights minus S′, S at 1/f² of the pixels) at equal |E|. Errors against two
//! references: the additive form with 4096 lights (the seed's "1000-light reference") and the
//! path tracer at GT_SPP samples (which has the indirect and specular light the preview
//! leaves out, §2.4). Times: kernel time from profiling events (S / additive sum + compose)
//! and the host's shadow rays (rayon), on a loaded 2-core machine: compare ratios only.
//! Writes table.md, and PNGs of the references and of the subtractive/additive at 32 lights.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context as _, Result};
use noisefree::gpu::Gpu;
use noisefree::imaging::{RgbImage, write_png};
use noisefree::metrics::mse_rgb;
use noisefree::render::subtractive::{self as sub, Settings, device::SubtractiveKernels};
use noisefree::render::{FrameSettings, RenderOptions, Renderer, SceneArrays};

const REFERENCE_LIGHTS: u32 = 4096;
const REFERENCE_SEED: u32 = 7;
const LIGHTS: [u32; 3] = [8, 32, 128];
/// Shadow block sides f: S at 1/1 (the seed's "full sampling"), 1/16, 1/256, 1/1024 of
/// the pixels.
const BLOCKS: [u32; 4] = [1, 4, 16, 32];

/// RMS in linear RGB (the seed's "rms").
fn rms(a: &RgbImage, b: &RgbImage) -> f64 {
    mse_rgb(a, b).expect("images of one size").sqrt()
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "results/subtractive".into()));
    let scene_path = PathBuf::from(args.next().unwrap_or_else(|| "scenes/outside.toml".into()));
    let size: u32 = args.next().map_or(Ok(256), |s| s.parse()).context("SIZE")?;
    let gt_spp: u32 = args
        .next()
        .map_or(Ok(256), |s| s.parse())
        .context("GT_SPP")?;
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let scene = noisefree::scene::load_scene(&scene_path)?;
    sub::check_scene(&scene)?;
    let gpu = Gpu::open(None)?;
    let mut frame = FrameSettings::from_scene(&scene);
    frame.width = size;
    frame.height = size;

    eprintln!("path tracer: {gt_spp} spp at {size}²");
    let mut o = RenderOptions::for_scene(&scene);
    o.frame = frame.clone();
    let mut renderer = Renderer::new(gpu.clone(), &scene, &o)?;
    let mut done = 0;
    while done < gt_spp {
        let n = (gt_spp - done).min(32);
        renderer.render_samples(n)?;
        done += n;
    }
    let truth = renderer.frame().beauty()?;
    write_png(&out.join("path-traced.png"), &truth, 0.0)?;

    let arrays = SceneArrays::build(&scene, &frame)?;
    let g = sub::gbuffer(&arrays);
    let k = SubtractiveKernels::new(gpu.clone())?;
    let dg = k.upload(&g)?;
    eprintln!("reference: additive, {REFERENCE_LIGHTS} lights");
    let many = sub::additive(&arrays, &g, &dg, &k, REFERENCE_LIGHTS, REFERENCE_SEED)?;
    let many = sub::to_rgb(size, size, &many.image);
    write_png(&out.join("reference-4096-lights.png"), &many, 0.0)?;
    let base = Settings::default();
    let e = sub::environment_lights(&arrays, base.lights, base.seed);
    let c_set = sub::unshadowed_set(&arrays, &base, &e);
    let c_sum = k.unshadowed(&dg, &c_set)?;
    let c = sub::unshadowed(&arrays, &dg, &k, &base, &e)?;
    let map_error = rms(
        &sub::to_rgb(size, size, &c.image),
        &sub::to_rgb(size, size, &c_sum.image),
    );

    let mut t = String::new();
    writeln!(
        t,
        "Subtractive vs additive shadows (DeCoro 2009 ch. 4), {} at {size}², device {}.\n\
         RMS (linear RGB) against the additive form with {REFERENCE_LIGHTS} lights and against the \
         path tracer at {gt_spp} spp (which has the indirect and specular light the preview leaves \
         out). C: the prefiltered irradiance map ({}×{}) of {} unshadowed lights, one lookup per \
         pixel: {:.2} ms per frame (the direct sum over those lights: {:.2} ms; RMS between \
         the two {:.5}). Times on a loaded \
         2-core machine (compare within the table only): kernels from OpenCL profiling events, \
         rays on the host (rayon).\n",
        scene_path.display(),
        gpu.summary.name,
        sub::MAP_W,
        sub::MAP_H,
        c_set.len(),
        c.time.as_secs_f64() * 1e3,
        c_sum.time.as_secs_f64() * 1e3,
        map_error,
    )?;
    writeln!(
        t,
        "| form | lights | shadow samples | RMS vs {REFERENCE_LIGHTS} lights | RMS vs path tracer | shadow rays | ray ms (host) | kernel ms | frame ms (rays + kernels + C) |"
    )?;
    writeln!(t, "|---|---|---|---|---|---|---|---|---|")?;
    let row = |t: &mut String,
               form: &str,
               lights: u32,
               frac: &str,
               p: &sub::Preview,
               img: &RgbImage|
     -> Result<()> {
        let frame_ms = (p.ray_time
            + p.kernel_time
            + if form == "additive" {
                std::time::Duration::ZERO
            } else {
                c.time
            })
        .as_secs_f64()
            * 1e3;
        writeln!(
            t,
            "| {form} | {lights} | {frac} | {:.4} | {:.4} | {} | {:.1} | {:.2} | {:.1} |",
            rms(img, &many),
            rms(img, &truth),
            p.rays,
            p.ray_time.as_secs_f64() * 1e3,
            p.kernel_time.as_secs_f64() * 1e3,
            frame_ms,
        )?;
        Ok(())
    };
    for lights in LIGHTS {
        eprintln!("{lights} lights");
        let a = sub::additive(&arrays, &g, &dg, &k, lights, base.seed)?;
        let ai = sub::to_rgb(size, size, &a.image);
        row(&mut t, "additive", lights, "1/1", &a, &ai)?;
        if lights == 32 {
            write_png(&out.join("additive-32.png"), &ai, 0.0)?;
        }
        for block in BLOCKS {
            let s = Settings {
                lights,
                block,
                ..base.clone()
            };
            let p = sub::subtractive(&arrays, &g, &dg, &k, &c.image, &s)?;
            let pi = sub::to_rgb(size, size, &p.image);
            row(
                &mut t,
                "subtractive",
                lights,
                &format!("1/{}", block * block),
                &p,
                &pi,
            )?;
            if lights == 32 {
                write_png(&out.join(format!("subtractive-32-f{block}.png")), &pi, 0.0)?;
            }
        }
    }
    std::fs::write(out.join("table.md"), &t)?;
    print!("{t}");
    Ok(())
}
