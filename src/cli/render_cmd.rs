//! `noisefree render`: progressive rendering with a progress bar, optional filtering after
//! each frame, images and AOVs out; or, with `--partial`, a range of the samples (and a tile)
//! of a render into a partial file for `noisefree merge`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use clap::Args;

use super::interrupt::{Interrupted, catch_ctrl_c, interrupted};
use super::partial_render::{check_partial_flags, parse_output, parse_range, write_part};

use crate::bvh::BvhLayout;
use crate::filters::{Configured, DeviceFilter, FilterRequest, MultiDeviceArgs, Registry};
use crate::imaging;
use crate::layout::outputs::{Output, OutputSet};
use crate::render::{
    Budget, RenderOptions, SceneArrays, SceneInfo, Tile, Tracer, progress_bar, render_progressively,
};
use crate::scene;
use crate::stats::RenderRecord;
use crate::stats::partial::{PieceInfo, RenderIdentity};
use crate::stats::samples::SampleSet;

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
    #[command(flatten)]
    pub multi: MultiDeviceArgs,
    /// PNG exposure in stops (the image is multiplied by 2^EV before tone mapping).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Build the generic kernel with every effect compiled in, for comparison.
    #[arg(long)]
    pub all_features: bool,
    /// Print the effects compiled into the kernel and why.
    #[arg(long)]
    pub explain: bool,
    /// The kernels that trace the paths: the thesis's megakernel, or one kernel per step over
    /// queues of paths (wavefront, Laine et al. 2013). The image is the same bytes.
    #[arg(long, value_enum, default_value_t = Tracer::Megakernel)]
    pub tracer: Tracer,
    /// With --tracer wavefront: paths in flight at most (whole rows of them) [default: 16,384
    /// on a CPU, 1,048,576 on a GPU]. The image does not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub wave_paths: Option<u32>,
    /// The BVH the rays walk: the thesis's binary tree with skip indices (Alg. 4), or eight
    /// children per node tested in float8 lanes. The image is the same bytes.
    #[arg(long, value_enum, default_value_t = BvhLayout::default())]
    pub bvh: BvhLayout,
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
    /// in a samples file for `noisefree filter FILE --filter rpf`.
    #[arg(long, value_name = "FILE.bin")]
    pub save_samples: Option<PathBuf>,
    /// Filter to apply: a registered filter (ddf, rpf, atrous, ...) or none [default: the
    /// scene's [filter] method, else none]. Its settings are the flags under "Settings of the
    /// ... filter" below, or the scene's [filter.NAME] table.
    #[arg(long, value_name = "NAME")]
    pub filter: Option<String>,
    /// The filter settings given on the command line, per filter (filled from the flags the
    /// registry adds, src/cli/mod.rs).
    #[arg(skip)]
    pub settings: BTreeMap<String, toml::Table>,
    /// Render only samples A to B-1 of the --spp samples per pixel (with --partial): the
    /// parts of a render made of such ranges merge exactly into the whole (`noisefree merge`).
    #[arg(long, value_name = "A..B", value_parser = parse_range)]
    pub samples: Option<std::ops::Range<u32>>,
    /// Render only this rectangle of the image, WxH+X+Y (with --partial): for images whose
    /// outputs do not fit one device; the tiles merge like sample ranges.
    #[arg(long, value_name = "WxH+X+Y", value_parser = Tile::parse)]
    pub tile: Option<Tile>,
    /// Write the render's outputs (every accumulator, not an image) to a partial file for
    /// `noisefree merge`, instead of images.
    #[arg(long, value_name = "FILE.nfp")]
    pub partial: Option<PathBuf>,
    /// Also gather these outputs (comma-separated: features, variance, position, samples),
    /// e.g. so that a partial render's merge can write AOVs or run any filter.
    #[arg(long, value_name = "OUTPUTS", value_delimiter = ',', value_parser = parse_output)]
    pub gather: Vec<Output>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// A real-time preview instead of the path tracer: `subtractive` (DeCoro 2009 ch. 4,
    /// environment-lit scenes: unshadowed direct light minus low-resolution shadows).
    #[arg(long, value_name = "MODE")]
    pub preview: Option<String>,
    /// --preview subtractive: shadow-casting lights sampled from the environment.
    #[arg(long, default_value_t = 32)]
    pub preview_lights: u32,
    /// --preview subtractive: one shadow sample per F×F pixels (4: 1/16 … 32: 1/1024).
    #[arg(long, value_name = "F", default_value_t = 4)]
    pub shadow_block: u32,
    /// --preview subtractive: lights of the unshadowed term C.
    #[arg(long, default_value_t = 1024)]
    pub unshadowed_lights: u32,
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

/// The filter `render` runs: the flag, else the scene's `[filter] method`; "none" or neither:
/// no filter.
fn chosen_filter<'a>(
    args: &RenderArgs,
    scene: &scene::Scene,
    configured: &'a [Configured],
) -> Result<Option<&'a Configured>> {
    let name = match (&args.filter, &scene.filter.method) {
        (Some(n), _) => n.as_str(),
        (None, Some(n)) => n.as_str(),
        (None, None) => return Ok(None),
    };
    if name == "none" {
        return Ok(None);
    }
    match configured.iter().find(|c| c.name() == name) {
        Some(c) => Ok(Some(c)),
        None => {
            let names: Vec<&str> = configured.iter().map(|c| c.name()).collect();
            let origin = if args.filter.is_some() {
                "--filter".to_string()
            } else {
                let line = scene
                    .filter
                    .method_line
                    .map(|l| format!(":{l}"))
                    .unwrap_or_default();
                format!("{}{line}: [filter] method", args.scene.display())
            };
            bail!(
                "{origin}: no filter named {name:?}; noisefree has: none, {}",
                names.join(", ")
            )
        }
    }
}

pub fn render(args: &RenderArgs, registry: &Registry) -> Result<RenderSummary> {
    let start = Instant::now();
    check_partial_flags(args)?;
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
    let range = args.samples.clone().unwrap_or(0..spp);
    if range.end > spp {
        bail!(
            "--samples {}..{} runs past the render's {spp} samples per pixel (--spp)",
            range.start,
            range.end
        );
    }
    if let Some(t) = args.tile {
        t.check_within(options.frame.width, options.frame.height)
            .context("--tile")?;
    }
    options.first_sample = range.start;
    options.tile = args.tile;
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
    options.all_features = args.all_features;
    options.local_size = args.local_size;
    options.tracer = args.tracer;
    options.bvh = args.bvh;
    if args.wave_paths.is_some() && args.tracer != Tracer::Wavefront {
        bail!("--wave-paths sets the wavefront tracer's paths in flight: add --tracer wavefront");
    }
    options.wave_paths = args.wave_paths.map(|n| n as usize);
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
        // A partial render writes no image (check_partial_flags).
        if let Some(path) = path.filter(|_| args.partial.is_none()) {
            if !given && let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
            }
            imaging::check_output_path(path)?;
        }
    }
    for p in [
        &args.aovs,
        &args.exr_unfiltered,
        &args.save_samples,
        &args.partial,
    ]
    .into_iter()
    .flatten()
    {
        imaging::check_output_path(p)?;
    }

    let gpus = args.multi.open(args.device)?;
    if let Some(name) = &args.preview {
        return super::preview_cmd::run(
            args,
            name,
            &scene,
            &options.frame,
            gpus[0].clone(),
            &png_path,
            exr_path.as_deref(),
        );
    }
    // The scene arrays first: the filters specialise to what they say (effects, camera, size).
    let arrays = SceneArrays::build(&scene, &options.frame)?;
    let info = SceneInfo::new(&scene, &arrays);
    let request = FilterRequest {
        scene: scene.filter.settings.clone(),
        scene_origin: args.scene.display().to_string(),
        scene_lines: scene.filter.lines.clone(),
        flags: args.settings.clone(),
        ..Default::default()
    };
    // Every filter is configured, so that the AOV file records settings for each.
    let configured = registry.configure_all(&request, &info)?;
    let chosen = chosen_filter(args, &scene, &configured)?;
    for name in args.settings.keys() {
        if chosen.is_none_or(|c| c.name() != name) {
            eprintln!(
                "warning: settings of the {name} filter are given, but {} (--filter {name} runs it)",
                match chosen {
                    Some(c) => format!("the {} filter runs", c.name()),
                    None => "no filter runs".to_string(),
                }
            );
        }
    }
    for w in chosen.iter().flat_map(|c| c.warnings()) {
        eprintln!("{w}");
    }
    // The outputs are compiled in only when something reads them.
    let mut outputs = OutputSet::colour();
    if let Some(c) = chosen {
        outputs = outputs.union(c.needs());
        c.adjust_render(&mut options);
    }
    if args.aovs.is_some() || args.aov_png.is_some() {
        outputs = outputs.union(OutputSet::of(&[Output::Features, Output::Variance]));
    }
    if args.save_samples.is_some() {
        outputs = outputs.with(Output::Samples);
    }
    outputs = outputs.union(OutputSet::of(&args.gather));
    options.outputs = outputs;
    // What the light-field output will hold, recorded in the partial files' identity.
    let outputs = options.recorded_outputs();
    let count = range.end - range.start;
    if outputs.contains(Output::Samples) {
        options.sample_capacity = count;
        let budget = crate::memory::available_memory_bytes().unwrap_or(u64::MAX);
        let tile = options.tile();
        crate::stats::samples::check_memory(tile.width, tile.height, count, budget)?;
    }
    let identity = args.partial.as_ref().map(|_| RenderIdentity {
        scene: args.scene.display().to_string(),
        scene_hash: crate::render::scene_hash(&arrays),
        kernel_hash: crate::render::kernel_hash(),
        width: options.frame.width,
        height: options.frame.height,
        seed: options.frame.seed,
        spp,
        outputs: outputs.closed(),
        shadow_lights: if outputs.closed().contains(Output::Shadows) {
            options.shadows.lights.lights()
        } else {
            Vec::new()
        },
        record: RenderRecord::default(),
    });

    let compile_start = Instant::now();
    let mut film = args.multi.film(&gpus, &scene, arrays, &options)?;
    let mut filter = match chosen.filter(|_| args.partial.is_none()) {
        Some(c) => {
            let mut f = DeviceFilter::prepare(c, &mut film, args.multi.filter_placement)?;
            f.show_progress(!args.quiet);
            Some(f)
        }
        None => None,
    };
    let renderer = film.primary();
    if !args.quiet {
        let walked = match renderer.bvh {
            BvhLayout::Skip => "skip-index walk".to_string(),
            BvhLayout::Wide => {
                let wide = &renderer.arrays.wide_bvh;
                format!(
                    "walked as {} eight-wide nodes, {} leaves, stack {}",
                    wide.nodes.len(),
                    wide.packs.len(),
                    wide.stack_entries()
                )
            }
        };
        eprintln!(
            "device: {} | {} triangles, {} BVH nodes (built in {:.2} s; {walked}), {} spheres, {} lights",
            film.describe(),
            renderer.arrays.tri_geom.len(),
            renderer.arrays.nodes.len(),
            renderer.arrays.bvh_stats.build_time.as_secs_f64(),
            renderer.arrays.spheres.len(),
            renderer.arrays.lights.len(),
        );
        let builds: Vec<_> = gpus.iter().flat_map(|g| g.builds()).collect();
        eprintln!(
            "compiling kernels: {} (ready in {:.2} s)",
            describe_builds(&builds),
            compile_start.elapsed().as_secs_f64()
        );
    }
    if args.explain {
        say!("kernel features for {}:", args.scene.display());
        for f in &renderer.features.features {
            say!(
                "  {:<24} {:<3}  {}",
                f.define,
                if f.on { "on" } else { "off" },
                f.why
            );
        }
        say!("  camera: {}", renderer.arrays.focus_note);
        say!("  outputs: {}", renderer.outputs().names().join(", "));
        if let Some(c) = chosen {
            say!("filter {} ({}):", c.name(), args.scene.display());
            for line in c.describe().lines() {
                say!("  {line}");
            }
        }
    }
    let mut filter_times = Vec::new();
    let mut last_filtered = None;
    catch_ctrl_c();
    let bar = progress_bar(count, args.quiet);
    let budget = Budget {
        spp: count,
        time_limit: args.time_limit,
    };
    render_progressively(&mut film, budget, &bar, &interrupted, |r| {
        if args.timings
            && let Some(f) = filter.as_mut()
            && f.interactive()
        {
            let out = f.run(r)?;
            filter_times.push(out.time());
            last_filtered = Some(out.image);
        }
        Ok(())
    })?;
    if interrupted() {
        if !args.save_partial || film.samples_done() == 0 {
            return Err(Interrupted.into());
        }
        eprintln!(
            "interrupted after {} spp: writing what was rendered (--save-partial)",
            film.samples_done()
        );
        last_filtered = None; // filter the final state below
    }
    let record = RenderRecord {
        scene: Some(film.scene_info().clone()),
        filter: chosen.map(|c| c.name().to_string()),
        settings: configured
            .iter()
            .map(|c| (c.name().to_string(), c.requested().clone()))
            .collect(),
        extra: BTreeMap::from([
            ("scene".to_string(), args.scene.display().to_string()),
            ("spp".to_string(), film.samples_done().to_string()),
        ]),
    };
    let frame = film.frame()?;
    let summary = RenderSummary {
        width: film.width(),
        height: film.height(),
        spp: film.samples_done(),
        seconds: start.elapsed().as_secs_f64(),
        kernel_seconds: film.kernel_time_total.as_secs_f64(),
        rays: film.rays_total,
        filter_times: Vec::new(),
    };
    if let (Some(path), Some(identity)) = (&args.partial, identity) {
        let info = PieceInfo {
            tile: film.primary().tile(),
            samples: range,
            rays: film.rays_total,
            seconds: summary.kernel_seconds,
            device: film.describe(),
        };
        write_part(path, identity, record, &frame, info, &summary)?;
        return Ok(summary);
    }
    let unfiltered = frame.beauty()?;
    let image = match filter.as_mut() {
        Some(f) => match last_filtered {
            Some(img) => img,
            None => {
                let out = f.run(&film)?;
                filter_times.push(out.time());
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
        SampleSet::from_frame(&frame, record.clone())?.write(p)?;
    }
    if let Some(p) = &args.aovs {
        crate::stats::aov::write_aov_exr(p, &frame, &record)?;
    }
    if let Some(dir) = &args.aov_png {
        crate::stats::aov::write_aov_pngs(dir, &frame, args.exposure)?;
    }
    let summary = RenderSummary {
        seconds: start.elapsed().as_secs_f64(),
        filter_times,
        ..summary
    };
    say!(
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
    if let Some((sampling, stats)) = film.primary().shadow_stats() {
        let lights = sampling.lights.lights();
        let what = match lights.as_slice() {
            [one] => format!("shadow samples of sphere light {one}"),
            // The stats count every (pixel, plane): per light, averaged over the lights.
            many => format!(
                "shadow samples of sphere lights {many:?}, per light (the mean of the {} \
                 lights; all of them: {:.2} spp over the image)",
                many.len(),
                stats.average_spp * many.len() as f64
            ),
        };
        print_pass_stats(&what, &stats, sampling.sparse_spp, sampling.max_spp);
    }
    if let Some((sampling, stats)) = film.primary().indirect_stats() {
        print_pass_stats(
            "indirect samples",
            &stats,
            sampling.sparse_spp,
            sampling.max_spp,
        );
    }
    if let (Some(c), Some(f)) = (chosen, &filter) {
        let what = if f.interactive() {
            "kernel"
        } else {
            "wall-clock"
        };
        super::print_timings(
            &format!("{} filter ({what} time)", c.name()),
            &summary.filter_times,
        );
    }
    Ok(summary)
}

/// One line on an adaptive sampling pass (AAF's shadow or indirect samples): the average spp
/// the seed reports (Σn/N²), per receiver, the largest, and what the passes cost.
fn print_pass_stats(what: &str, stats: &crate::render::ShadowStats, sparse: u32, max: u32) {
    say!(
        "{what}: {:.2} spp on average over the image (Σn/N²), {:.2} over its {} receivers, {} \
         at most (sparse {sparse}, max {max}); {:.1} Mrays in {:.3} s",
        stats.average_spp,
        stats.receiver_spp,
        stats.receivers,
        stats.max_spp,
        stats.rays as f64 / 1e6,
        stats.kernel_time.as_secs_f64()
    );
}
