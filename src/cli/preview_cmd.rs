//! `noisefree render SCENE --preview subtractive`: the real-time environment-light preview of
//! DeCoro 2009 ch. 4 (src/render/subtractive), one frame written as PNG/EXR, with its kernel
//! time (profiling events), the host's shadow-ray time and the ray count printed.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Result, bail};

use super::render_cmd::{RenderArgs, RenderSummary};
use crate::gpu::Gpu;
use crate::imaging;
use crate::render::subtractive::{self as sub, Settings, device::SubtractiveKernels};
use crate::render::{FrameSettings, SceneArrays};
use crate::scene::Scene;

/// The preview modes `--preview` accepts.
pub const PREVIEWS: &[&str] = &["subtractive"];

#[allow(clippy::too_many_arguments)]
pub fn run(
    args: &RenderArgs,
    name: &str,
    scene: &Scene,
    frame: &FrameSettings,
    gpu: Arc<Gpu>,
    png: &Path,
    exr: Option<&Path>,
) -> Result<RenderSummary> {
    if name != "subtractive" {
        bail!(
            "--preview {name:?}: no such preview; noisefree has: {}",
            PREVIEWS.join(", ")
        );
    }
    // A preview is one frame of its own: the path tracer's flags would be silently ignored.
    for (given, flag) in [
        (args.filter.is_some(), "--filter"),
        (args.partial.is_some(), "--partial"),
        (args.samples.is_some(), "--samples"),
        (args.tile.is_some(), "--tile"),
        (args.aovs.is_some(), "--aovs"),
        (args.save_samples.is_some(), "--save-samples"),
        (args.spp.is_some(), "--spp"),
    ] {
        if given {
            bail!(
                "--preview {name} renders one direct-light frame without the path tracer: {flag} does not apply"
            );
        }
    }
    sub::check_scene(scene).map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))?;
    let settings = Settings {
        lights: args.preview_lights,
        block: args.shadow_block,
        unshadowed_lights: Some(args.unshadowed_lights),
        seed: frame.seed,
        ..Settings::default()
    };
    settings.validate()?;
    let start = std::time::Instant::now();
    let arrays = SceneArrays::build(scene, frame)?;
    let g = sub::gbuffer(&arrays);
    let k = SubtractiveKernels::new(gpu)?;
    let dg = k.upload(&g)?;
    let e = sub::environment_lights(&arrays, settings.lights, settings.seed);
    let c = sub::unshadowed(&arrays, &dg, &k, &settings, &e)?;
    let p = sub::subtractive(&arrays, &g, &dg, &k, &c.image, &settings)?;
    let image = sub::to_rgb(p.width, p.height, &p.image);
    imaging::write_png(png, &image, args.exposure)?;
    if let Some(path) = exr {
        imaging::write_exr(path, &image)?;
    }
    let kernel = c.time + p.kernel_time;
    if !args.quiet {
        eprintln!(
            "subtractive preview: {} lights, shadows at 1/{} of the pixels ({} rays, {:.1} ms on the host), kernels {:.2} ms (C {:.2} ms), {}",
            settings.lights,
            settings.block * settings.block,
            p.rays,
            p.ray_time.as_secs_f64() * 1e3,
            kernel.as_secs_f64() * 1e3,
            c.time.as_secs_f64() * 1e3,
            png.display()
        );
    }
    Ok(RenderSummary {
        width: p.width,
        height: p.height,
        spp: 1,
        seconds: start.elapsed().as_secs_f64(),
        kernel_seconds: kernel.as_secs_f64(),
        rays: p.rays,
        filter_times: vec![],
    })
}
