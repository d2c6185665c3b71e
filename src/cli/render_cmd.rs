//! `noisefree render`: progressive rendering with a progress bar, optional filtering after
//! each frame, images and AOVs out.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use super::filter_args::FilterArgs;
use crate::gpu::Gpu;
use crate::imaging;
use crate::render::{RenderOptions, Renderer};
use crate::scene;

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// The scene description (.toml).
    pub scene: PathBuf,
    /// Samples per pixel (overrides [render] spp).
    #[arg(long)]
    pub spp: Option<u32>,
    #[arg(long)]
    pub width: Option<u32>,
    #[arg(long)]
    pub height: Option<u32>,
    #[arg(long)]
    pub seed: Option<u32>,
    /// Depth at which Russian roulette starts (overrides [render] max_depth).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Tone-mapped sRGB PNG [default: out/<scene>.png].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Linear float OpenEXR [default: the PNG's path with .exr].
    #[arg(long)]
    pub exr: Option<PathBuf>,
    /// Do not write the EXR.
    #[arg(long)]
    pub no_exr: bool,
    /// With a filter: also write the unfiltered image as a linear EXR.
    #[arg(long, value_name = "FILE.exr")]
    pub exr_unfiltered: Option<PathBuf>,
    /// Also write every per-pixel buffer (FilterVector means, feature variances, mean
    /// directions, spp) to one multi-channel OpenEXR.
    #[arg(long, value_name = "FILE.exr")]
    pub aovs: Option<PathBuf>,
    /// Also write a false-colour PNG of every per-pixel buffer into this folder.
    #[arg(long, value_name = "DIR")]
    pub aov_png: Option<PathBuf>,
    /// Stop after this many seconds even if fewer than spp samples are done.
    #[arg(long, value_name = "SECONDS")]
    pub time_limit: Option<f64>,
    /// OpenCL device number from `noisefree devices` (or NOISEFREE_DEVICE).
    #[arg(long)]
    pub device: Option<usize>,
    /// PNG exposure in stops (the image is multiplied by 2^EV before tone mapping).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Build the generic kernel with every effect compiled in, for comparison.
    #[arg(long)]
    pub all_features: bool,
    /// Print the effects compiled into the kernel and why.
    #[arg(long)]
    pub explain: bool,
    /// Work-group size of the path tracer, e.g. 8x8 [default: chosen by the driver].
    #[arg(long, value_parser = parse_size)]
    pub local_size: Option<[usize; 2]>,
    /// Filter after every frame (launch), not only at the end, and print min / median / max
    /// filter kernel time over the frames.
    #[arg(long)]
    pub timings: bool,
    /// Clamp each path sample's colour to at most this value (fewer fireflies, some bias)
    /// [default: the scene's [render] clamp, else off].
    #[arg(long)]
    pub clamp: Option<f32>,
    /// On Ctrl-C, write the images rendered so far (otherwise nothing is written and existing
    /// outputs stay as they were).
    #[arg(long)]
    pub save_partial: bool,
    /// Also store every sample's Random Parameter Filtering vector (26 floats, thesis §5.1.1)
    /// in a samples file for `noisefree filter FILE --method rpf`.
    #[arg(long, value_name = "FILE.bin")]
    pub save_samples: Option<PathBuf>,
    #[command(flatten)]
    pub filter: FilterArgs,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

fn parse_size(s: &str) -> std::result::Result<[usize; 2], String> {
    let (a, b) = s
        .split_once('x')
        .ok_or_else(|| format!("expected WxH, e.g. 8x8, got {s:?}"))?;
    let a: usize = a
        .trim()
        .parse()
        .map_err(|_| format!("bad width in {s:?}"))?;
    let b: usize = b
        .trim()
        .parse()
        .map_err(|_| format!("bad height in {s:?}"))?;
    if a == 0 || b == 0 {
        return Err("work-group sizes must be positive".into());
    }
    Ok([a, b])
}

/// What a finished render reports.
#[derive(Clone, Debug)]
pub struct RenderSummary {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seconds: f64,
    pub kernel_seconds: f64,
    pub rays: u64,
    pub filter_times: Vec<Duration>,
}

impl RenderSummary {
    pub fn mrays_per_second(&self) -> f64 {
        self.rays as f64 / self.kernel_seconds.max(1e-9) / 1e6
    }
    pub fn spp_per_second(&self) -> f64 {
        self.spp as f64 / self.kernel_seconds.max(1e-9)
    }
}

/// "pathtrace.cl compiled in 1.20 s, ddf.cl from the disk cache in 0.02 s".
pub fn describe_builds(builds: &[crate::gpu::BuildRecord]) -> String {
    use crate::gpu::BuildSource;
    builds
        .iter()
        .map(|b| match b.source {
            BuildSource::Compiled => format!("{} compiled in {:.2} s", b.main, b.seconds),
            BuildSource::Disk => format!("{} from the disk cache in {:.2} s", b.main, b.seconds),
            BuildSource::Memory => format!("{} already built", b.main),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn default_output(scene: &Path, ext: &str) -> PathBuf {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    PathBuf::from("out").join(format!("{stem}.{ext}"))
}

/// Set by the Ctrl-C handler; the render loop stops after the launch in flight.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// The error of a render stopped by Ctrl-C without --save-partial (exit status 130).
#[derive(Debug)]
pub struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "interrupted: nothing was written (use --save-partial to keep what was rendered)"
        )
    }
}

impl std::error::Error for Interrupted {}

/// Installs the Ctrl-C handler once per process.
fn catch_ctrl_c() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // If another handler is already installed, Ctrl-C keeps its default meaning.
        let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::SeqCst));
    });
}

pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Renders progressively until `spp` samples or the time limit, showing progress;
/// `after_frame` runs after each launch. Stops early (after the launch in flight) on Ctrl-C.
pub fn progressive(
    renderer: &mut Renderer,
    spp: u32,
    time_limit: Option<f64>,
    quiet: bool,
    mut after_frame: impl FnMut(&Renderer) -> Result<()>,
) -> Result<()> {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(spp as u64)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} spp  {msg}  ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let limit = time_limit.map(Duration::from_secs_f64);
    // Launch sizes grow towards ~0.5 s per launch: responsive progress, few launches, and well
    // under GPU watchdog limits. The image does not depend on the batching (tests/determinism).
    let mut batch = 1u32;
    while renderer.samples_done() < spp && !interrupted() {
        if let Some(limit) = limit
            && start.elapsed() >= limit
        {
            break;
        }
        let count = batch.min(spp - renderer.samples_done());
        let stats = renderer.render_samples(count)?;
        after_frame(renderer)?;
        let per_sample = stats.kernel_time.as_secs_f64() / count as f64;
        let mut next = (0.5 / per_sample.max(1e-6)) as u32;
        if let Some(limit) = limit {
            let left = limit.saturating_sub(start.elapsed()).as_secs_f64();
            next = next.min((left / per_sample.max(1e-6)) as u32);
        }
        batch = next.clamp(1, batch.saturating_mul(4).max(1));
        bar.set_position(renderer.samples_done() as u64);
        let secs = renderer.kernel_time_total.as_secs_f64().max(1e-9);
        bar.set_message(format!(
            "{:.2} spp/s  {:.1} Mrays/s",
            renderer.samples_done() as f64 / secs,
            renderer.rays_total as f64 / secs / 1e6
        ));
    }
    bar.finish_and_clear();
    Ok(())
}

pub fn render(args: &RenderArgs) -> Result<RenderSummary> {
    let start = Instant::now();
    let scene = scene::load_scene(&args.scene)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let mut options = RenderOptions::for_scene(&scene);
    options.frame.width = args.width.unwrap_or(options.frame.width);
    options.frame.height = args.height.unwrap_or(options.frame.height);
    options.frame.seed = args.seed.unwrap_or(options.frame.seed);
    options.frame.max_depth = args.max_depth.unwrap_or(options.frame.max_depth);
    for (v, flag) in [
        (options.frame.width, "--width"),
        (options.frame.height, "--height"),
    ] {
        if v == 0 {
            bail!("{flag} 0: the image must be at least 1x1 pixels");
        }
    }
    let spp = args.spp.unwrap_or(scene.render.spp);
    if spp == 0 {
        bail!("--spp must be at least 1");
    }
    if let Some(t) = args.time_limit
        && !(t > 0.0 && t.is_finite())
    {
        bail!("--time-limit must be a positive number of seconds");
    }
    if let Some(c) = args.clamp {
        if !(c >= 0.0 && c.is_finite()) {
            bail!("--clamp must be >= 0 (0 = off), got {c}");
        }
        options.frame.sample_clamp = c;
    }
    let context = || format!("in {}", args.scene.display());
    let method = args
        .filter
        .method(scene.filter.as_ref())
        .with_context(context)?;
    let filter_method = args
        .filter
        .build(method, scene.filter.as_ref(), scene.render.setting)
        .with_context(context)?;
    options.all_features = args.all_features;
    options.local_size = args.local_size;
    // The statistics stage and the sample vectors are compiled in only when something reads
    // them.
    if let Some(m) = &filter_method {
        let need = m.outputs(spp);
        options.outputs.features |= need.features;
        options.outputs.variance |= need.variance;
        options.outputs.sample_vectors = need.sample_vectors;
    }
    if args.aovs.is_some() || args.aov_png.is_some() {
        options.outputs.features = true;
        options.outputs.variance = true;
    }
    if args.save_samples.is_some() {
        options.outputs.features = true;
        options.outputs.sample_vectors = Some(spp);
    }
    if options.outputs.sample_vectors.is_some() {
        let budget = crate::filters::rpf::samples::available_memory_bytes().unwrap_or(u64::MAX);
        crate::filters::rpf::samples::check_memory(
            options.frame.width,
            options.frame.height,
            spp,
            budget,
        )?;
    }

    // Outputs: explicit paths must be writable now, before minutes of rendering.
    let png_path = args
        .out
        .clone()
        .unwrap_or_else(|| default_output(&args.scene, "png"));
    let exr_path = if args.no_exr {
        None
    } else {
        Some(
            args.exr
                .clone()
                .unwrap_or_else(|| png_path.with_extension("exr")),
        )
    };
    for (given, path) in [
        (args.out.is_some(), Some(&png_path)),
        (args.exr.is_some() || args.out.is_some(), exr_path.as_ref()),
    ] {
        if let Some(path) = path {
            if !given && let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
            }
            imaging::check_output_path(path)?;
        }
    }
    for p in [&args.aovs, &args.exr_unfiltered, &args.save_samples]
        .into_iter()
        .flatten()
    {
        imaging::check_output_path(p)?;
    }

    let gpu = Gpu::open(args.device)?;
    let compile_start = Instant::now();
    let mut renderer = Renderer::new(gpu.clone(), &scene, &options)?;
    let mut filter = match &filter_method {
        Some(m) => {
            let mut f = m.prepare(&gpu, &scene, &renderer)?;
            f.show_progress(!args.quiet);
            Some(f)
        }
        None => None,
    };
    if !args.quiet {
        eprintln!(
            "device: {} | {} triangles, {} BVH nodes (built in {:.2} s), {} spheres, {} lights",
            gpu.summary.name,
            renderer.arrays.tri_geom.len(),
            renderer.arrays.nodes.len(),
            renderer.arrays.bvh_stats.build_time.as_secs_f64(),
            renderer.arrays.spheres.len(),
            renderer.arrays.lights.len(),
        );
        eprintln!(
            "compiling kernels: {} (ready in {:.2} s)",
            describe_builds(&gpu.builds()),
            compile_start.elapsed().as_secs_f64()
        );
    }
    if args.explain {
        println!("kernel features for {}:", args.scene.display());
        for f in &renderer.features.features {
            println!(
                "  {:<24} {:<3}  {}",
                f.define,
                if f.on { "on" } else { "off" },
                f.why
            );
        }
        println!("  camera: {}", renderer.arrays.focus_note);
    }
    let mut filter_times = Vec::new();
    let mut last_filtered = None;
    catch_ctrl_c();
    progressive(&mut renderer, spp, args.time_limit, args.quiet, |r| {
        if args.timings
            && let Some(f) = filter.as_mut()
            && f.on_device()
        {
            let out = f.run(r)?;
            filter_times.push(out.kernel_time.unwrap_or(out.wall_time));
            last_filtered = Some(out.image);
        }
        Ok(())
    })?;
    if interrupted() {
        if !args.save_partial || renderer.samples_done() == 0 {
            return Err(Interrupted.into());
        }
        eprintln!(
            "interrupted after {} spp: writing what was rendered (--save-partial)",
            renderer.samples_done()
        );
        last_filtered = None; // filter the final state below
    }
    let buffers = renderer.read_buffers()?;
    let unfiltered = buffers.beauty();
    let image = match filter.as_mut() {
        Some(f) => match last_filtered {
            Some(img) => img,
            None => {
                let out = f.run(&renderer)?;
                filter_times.push(out.kernel_time.unwrap_or(out.wall_time));
                out.image
            }
        },
        None => unfiltered.clone(),
    };
    imaging::write_png(&png_path, &image, args.exposure)?;
    if let Some(p) = &exr_path {
        imaging::write_exr(p, &image)?;
    }
    if let Some(p) = &args.exr_unfiltered {
        imaging::write_exr(p, &unfiltered)?;
    }
    if let Some(p) = &args.save_samples {
        let (n, samples) = renderer.read_sample_vectors()?;
        crate::filters::rpf::SampleSet::new(renderer.width(), renderer.height(), n, samples)?
            .write(p)?;
    }
    if let Some(p) = &args.aovs {
        let mut meta = std::collections::BTreeMap::new();
        meta.insert("scene".to_string(), args.scene.display().to_string());
        meta.insert("seed".to_string(), renderer.arrays.params.seed.to_string());
        meta.insert(
            "camera".to_string(),
            crate::stats::aovs::camera_to_text(&renderer.arrays.params),
        );
        crate::stats::aovs::write_aov_exr(p, &buffers, &meta)?;
    }
    if let Some(dir) = &args.aov_png {
        crate::stats::aovs::write_aov_pngs(dir, &buffers, args.exposure)?;
    }
    let summary = RenderSummary {
        width: renderer.width(),
        height: renderer.height(),
        spp: renderer.samples_done(),
        seconds: start.elapsed().as_secs_f64(),
        kernel_seconds: renderer.kernel_time_total.as_secs_f64(),
        rays: renderer.rays_total,
        filter_times,
    };
    println!(
        "{}x{} {} spp in {:.2} s (kernel {:.2} s): {:.2} spp/s, {:.2} Mrays/s -> {}{}",
        summary.width,
        summary.height,
        summary.spp,
        summary.seconds,
        summary.kernel_seconds,
        summary.spp_per_second(),
        summary.mrays_per_second(),
        png_path.display(),
        exr_path
            .map(|p| format!(", {}", p.display()))
            .unwrap_or_default()
    );
    if let Some(m) = &filter_method {
        let what = if m.name() == "rpf" {
            "wall-clock"
        } else {
            "kernel"
        };
        super::print_timings(
            &format!("{} filter ({what} time)", m.name()),
            &summary.filter_times,
        );
    }
    Ok(summary)
}
