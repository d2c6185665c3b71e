//! Kernel time of each step of the sheared depth-of-field filter (kernels/filters/
//! sheared_dof.cl), or of the GI filter (kernels/filters/sheared_gi.cl) with EFFECT = gi, and
//! its memory per pixel, on a scene's lens (or GI) field:
//! `cargo run --release --example sheared_dof_steps -- SCENE.toml WIDTH HEIGHT L RUNS [gi]`.
//! Times come from OpenCL profiling events; the median of RUNS runs is printed per step
//! (results/README.md, the sheared depth-of-field and GI sections).

use anyhow::{Context as _, Result, bail};
use noisefree::filters::Auto;
use noisefree::filters::sheared::{DOF_STEPS, DofKernel, Effect, ShearedSettings};
use noisefree::gpu::Gpu;
use noisefree::layout::LightFieldPixel;
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::render::{RenderOptions, Renderer};
use noisefree::scene::load_scene;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (gi, args) = match args.as_slice() {
        [rest @ .., last] if last == "gi" => (true, rest),
        all => (false, all),
    };
    let [scene, w, h, l, runs] = args else {
        bail!("usage: sheared_dof_steps SCENE.toml WIDTH HEIGHT L RUNS [gi]");
    };
    let (w, h, l, runs): (u32, u32, u32, usize) =
        (w.parse()?, h.parse()?, l.parse()?, runs.parse()?);
    let scene =
        load_scene(std::path::Path::new(scene)).with_context(|| format!("loading {scene}"))?;
    let gpu = Gpu::open(None)?;
    let settings = ShearedSettings {
        side: l,
        effect: Auto::Set(if gi { Effect::Gi } else { Effect::Dof }),
        light: Auto::Set(-1),
        ..Default::default()
    };
    let mut o = RenderOptions::for_scene(&scene);
    o.frame.width = w;
    o.frame.height = h;
    o.outputs = OutputSet::of(&[Output::Colour, Output::LightField]);
    o.shadows = settings.sampling();
    let mut r = Renderer::new(gpu.clone(), &scene, &o)?;
    r.render_samples(1)?;
    let frame = r.frame();
    let field = frame.host_slice::<LightFieldPixel>(BufferId::LightFieldPixels)?;
    let fallback = field.iter().filter(|lf| lf.extra_samples > 0.0).count();
    if gi {
        let receivers = field.iter().filter(|lf| lf.count > 0.0).count();
        println!("GI receivers {receivers}, {fallback} of them with a reflector hit (s = z)");
    } else {
        println!(
            "fallback pixels (s_min s_max < 0): {fallback} of {} ({:.2} extra spp on average)",
            field.len(),
            field.iter().map(|lf| lf.extra_samples as f64).sum::<f64>() / field.len() as f64
        );
    }
    let mut k = if gi {
        DofKernel::gi(gpu, settings.gi_params(w, h))?
    } else {
        DofKernel::new(gpu, settings.dof_params(scene.camera.lens_radius, w, h))?
    };
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); DOF_STEPS.len()];
    for _ in 0..runs.max(1) {
        k.filter_rows(&frame, 0..h)?;
        for (t, d) in times.iter_mut().zip(k.step_times()) {
            t.push(d.as_secs_f64() * 1e3);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let medians: Vec<f64> = times.iter_mut().map(median).collect();
    let total: f64 = medians.iter().sum();
    println!("l = {l}, {w} x {h}, median of {runs} runs (kernel ms):");
    for (name, ms) in DOF_STEPS.iter().zip(&medians) {
        println!("  {name:8} {ms:8.2} ms  {:4.0}%", 100.0 * ms / total);
    }
    println!(
        "  total    {total:8.2} ms; memory {} B per pixel ({:.1} MiB)",
        settings.memory_bytes(1, 1),
        settings.memory_bytes(w, h) as f64 / (1u64 << 20) as f64
    );
    Ok(())
}
