//! `noisefree bench`: every speed and quality figure of the project comes from here, as CSV +
//! Markdown + PNG plots under results/. Runs are resumable: a measurement already in a study's
//! CSV is not repeated (delete the file, or pass --fresh, to measure again).
//!
//! It runs from any folder: the bundled scenes come from `--scenes`, else from the source tree
//! the binary was built from, else from `./scenes`; what it writes (results, ground-truth cache)
//! goes under the current folder unless `--out` and `--cache` say otherwise.
//!
//! Studies:
//! - `render-speed`: per scene, samples/s and Mrays/s of the specialised and the generic
//!   megakernel side by side, and kernel build times cold and cached (thesis ch. 4; the
//!   "simulate only what a scene calls for" measurement).
//! - `statistics`: the cost of the per-pixel statistics (thesis §6.2.2): samples/s without
//!   them, with the feature means, with the variances, side by side.
//! - `filter-speed`: the data-driven filter's kernel time over kernel widths, resolutions,
//!   variants and work-group sizes (thesis §7.1-7.2, Figs. 7.2-7.12).
//! - `quality`: every scene, unfiltered and with each filter, against a cached reference,
//!   with contact sheets (thesis §7.3, Fig. 7.18).
//! - `accuracy-time`: error against wall-clock time for every method, and the headline
//!   figures (equal-quality sample reduction, equal-time error ratio).
//! - `sweep`: Table 7.1's one-parameter-at-a-time sweep and hypotheses 1-3 (§7.3), plus the
//!   variance scales s_f the thesis leaves open.
//! - `path-density` (only when asked): the path-density filter of DeCoro 2009 ch. 5 over
//!   8-64 spp, accumulated against per-frame, with its chains and the α-trimmed baselines.
//! - `balance` (only when asked, with `--devices`): several devices sharing each frame
//!   (thesis §4.2): each device's share and idle time per frame, with and without
//!   re-balancing, and where the filter runs.
//! - `aaf-shadows` (only when asked): AAF soft shadows against Monte Carlo on Grids, error
//!   against light samples and against time (Wang 2013 Fig. 3.6), the spp map (`aaf`).
//! - `aaf-indirect` (only when asked): diffuse indirect light, AAF (Wang 2013 ch. 4) and
//!   sheared filtering's GI against Monte Carlo and each other at equal quality, on room_gi
//!   or the pinhole scenes `--scene` names (`aaf_indirect`).
//! - `aaf-cost` (only when asked): the AAF filters' kernel time against the occluder's
//!   triangle count (0.2K-200K), beside the sampling passes' and the path tracer's (`aaf_cost`).
//! - `rpf-readings`, `rpf-scale` (only when asked; hours): RPF's readings against the
//!   thesis's gain, and Tables 5.3-5.4 (`rpf`).
//! - `roofline`: each image filter kernel's achieved GFLOP/s and GB/s against the device's
//!   own peaks, measured by micro-kernels in the same run (`roofline/`).
//! - `tracers`: the megakernel, the wavefront tracer and the megakernel on the skip-index
//!   BVH side by side per scene: samples/s, same bytes, the wavefront's time per step
//!   (`tracers`).
//!
//! Files: `speed` holds the first three studies; `quality`, `accuracy_time` and `sweep` one
//! study each, with `study` for what those three share and `curves` for the log-log maths of
//! the headline figures. `ground_truth` is the cache of many-spp reference images (not to be
//! confused with `render::cpu`, the CPU mirror of the kernels); `table` the resumable CSV
//! tables, `plot` the charts and contact sheets and `folders` the scenes and results folders.

pub mod aaf;
pub mod aaf_cost;
pub mod aaf_indirect;
pub mod accuracy_time;
pub mod balance;
pub mod curves;
pub mod filter_speed;
pub mod folders;
pub mod ground_truth;
pub mod oidn;
pub mod pass_study;
pub mod path_density;
pub mod plot;
pub mod quality;
pub mod roofline;
pub mod rpf;
pub mod speed;
pub mod study;
pub mod sweep;
pub mod sweep_report;
pub mod table;
pub mod tracers;

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};

use crate::gpu::Gpu;
use folders::no_scenes_dir;
pub use folders::{bundled_scenes, device_slug, scenes_dir};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Study {
    RenderSpeed,
    Statistics,
    FilterSpeed,
    Quality,
    AccuracyTime,
    Sweep,
    /// The path-density filter (DeCoro 2009 ch. 5): error and rejected fractions over spp,
    /// accumulated against per-frame, its chains and the α-trimmed baselines (not in the
    /// default set).
    PathDensity,
    /// Several devices per frame (needs --devices with two or more; not in the default set).
    Balance,
    /// AAF soft shadows against Monte Carlo on Grids, Wang 2013 Fig. 3.6 (not in the default
    /// set).
    AafShadows,
    /// Diffuse indirect light: AAF and sheared filtering against Monte Carlo and each other at
    /// equal quality, on room_gi or the run's pinhole scenes (not in the default set).
    AafIndirect,
    /// The AAF filters' cost against the triangle count, beside the sampling passes and the
    /// path tracer (not in the default set).
    AafCost,
    /// RPF's readings against the thesis's gain (not in the default set: hours).
    RpfReadings,
    /// RPF against the scene scale, Tables 5.3-5.4 (not in the default set: hours).
    RpfScale,
    /// Each image filter kernel's GFLOP/s and GB/s against the device's measured peaks.
    Roofline,
    /// The megakernel, the wavefront tracer and the skip-index BVH side by side per scene.
    Tracers,
}

#[derive(Args, Debug, Clone, PartialEq)]
pub struct BenchArgs {
    /// Studies to run (repeatable) [default: all].
    #[arg(long, value_enum)]
    pub study: Vec<Study>,
    /// Shorthand for --study render-speed: specialised versus generic kernels.
    #[arg(long)]
    pub specialisation: bool,
    /// Shorthand for --study statistics.
    #[arg(long)]
    pub statistics: bool,
    /// A reduced set (small images, few samples, few cells) that finishes in minutes on PoCL.
    #[arg(long)]
    pub quick: bool,
    /// Results folder [default: results/<device>, or results/quick with --quick, under the
    /// current folder].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Ground-truth image cache, reused across runs [default: cache/references under the
    /// current folder, as for `noisefree reference`].
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// Samples per pixel of the ground-truth images (thesis §7: 2048) [default: 2048, 256
    /// with --quick].
    #[arg(long, value_name = "N")]
    pub reference_spp: Option<u32>,
    /// Width and height of the quality studies' images and references (quality,
    /// accuracy-time, sweep, rpf-*) [default: 512, the thesis's; 64 with --quick].
    #[arg(long, value_name = "N")]
    pub size: Option<u32>,
    /// Largest spp of the filters' curves in the accuracy-time study (a power of 2; up to the
    /// unfiltered curve's 1024), to show whether a filter keeps improving as samples grow
    /// (filters that read every sample stop at 8 regardless) [default: 64].
    #[arg(long, value_name = "N")]
    pub filter_spp: Option<u32>,
    /// Measure again even what the CSV files already hold.
    #[arg(long)]
    pub fresh: bool,
    /// OpenCL device number from `noisefree devices` (or NOISEFREE_DEVICE).
    #[arg(long)]
    pub device: Option<usize>,
    /// Several devices (`--devices 1,0`): the balance study shares frames among them; the
    /// other studies run on the first.
    #[command(flatten)]
    pub multi: crate::filters::MultiDeviceArgs,
    /// Scenes to use (repeatable) [default: every scene of the bundled scenes folder]; the
    /// sweep runs those of its plan named here (by file name), and writes its report from every
    /// row of its table.
    #[arg(long)]
    pub scene: Vec<PathBuf>,
    /// Methods of the quality and accuracy-time studies and kernels of the roofline
    /// (repeatable): a filter's name, or `oidn`; a name also keeps its variants (`ddf` the
    /// thesis's ddf-holes and ddf-nosky, `bmfr` bmfr-fit and bmfr-guided, `oidn` every
    /// quality; in the roofline `atrous` both à-trous kernels); the unfiltered image is always
    /// in [default: every method].
    #[arg(long, value_name = "NAME")]
    pub method: Vec<String>,
    /// The bundled scenes folder (the sweep and filter-speed read their scenes from it too)
    /// [default: scenes/ of the source tree this binary was built from, else ./scenes].
    #[arg(long, value_name = "DIR")]
    pub scenes: Option<PathBuf>,
    #[arg(long, short)]
    pub quiet: bool,
    /// Run it on a Slurm cluster: the references the studies need as job arrays of N sample
    /// ranges each, merged into the cache, then the benchmark itself as one job (its timings
    /// must come from one device): write the job folder and submit it.
    #[arg(long, value_name = "N")]
    pub slurm: Option<u32>,
    /// With --slurm: print the job instead of writing and submitting it.
    #[arg(long, requires = "slurm")]
    pub dry_run: bool,
    /// With --slurm: the job folder [default: slurm/bench or slurm/bench-quick].
    #[arg(long, value_name = "DIR", requires = "slurm")]
    pub job_dir: Option<PathBuf>,
}

impl BenchArgs {
    /// The `noisefree bench` arguments that run these studies again, without the Slurm flags
    /// (what the job runs after the references are merged).
    pub fn to_args(&self) -> Vec<String> {
        let mut v = vec!["bench".to_string()];
        let path = |p: &PathBuf| p.display().to_string();
        for s in &self.study {
            let name = s.to_possible_value().expect("no skipped studies");
            v.extend(["--study".into(), name.get_name().to_string()]);
        }
        for (on, flag) in [
            (self.specialisation, "--specialisation"),
            (self.statistics, "--statistics"),
            (self.quick, "--quick"),
            (self.fresh, "--fresh"),
            (self.quiet, "--quiet"),
        ] {
            if on {
                v.push(flag.into());
            }
        }
        for (value, flag) in [
            (&self.out, "--out"),
            (&self.cache, "--cache"),
            (&self.scenes, "--scenes"),
        ] {
            if let Some(p) = value {
                v.extend([flag.into(), path(p)]);
            }
        }
        if let Some(n) = self.reference_spp {
            v.extend(["--reference-spp".into(), n.to_string()]);
        }
        if let Some(n) = self.size {
            v.extend(["--size".into(), n.to_string()]);
        }
        if let Some(n) = self.filter_spp {
            v.extend(["--filter-spp".into(), n.to_string()]);
        }
        if let Some(d) = self.device {
            v.extend(["--device".into(), d.to_string()]);
        }
        v.extend(self.multi.to_args());
        for s in &self.scene {
            v.extend(["--scene".into(), path(s)]);
        }
        for m in &self.method {
            v.extend(["--method".into(), m.clone()]);
        }
        v
    }
}

/// The studies, scenes and bundled scenes folder a run of `args` uses.
struct Selection {
    studies: Vec<Study>,
    scenes: Vec<PathBuf>,
    scenes_dir: Option<PathBuf>,
}

fn select(args: &BenchArgs) -> Result<Selection> {
    if args.reference_spp == Some(0) {
        bail!("--reference-spp must be at least 1");
    }
    let known: Vec<&str> = crate::filters::Registry::builtin()
        .names()
        .into_iter()
        .chain(["oidn", "unfiltered"])
        .collect();
    if let Some(m) = args.method.iter().find(|m| !known.contains(&m.as_str())) {
        bail!(
            "--method {m}: no such method (noisefree has: {})",
            known.join(", ")
        );
    }
    if args.size.is_some_and(|n| !(8..=8192).contains(&n)) {
        bail!("--size must be 8 to 8192 pixels");
    }
    if args
        .filter_spp
        .is_some_and(|n| !n.is_power_of_two() || n > 1024)
    {
        bail!("--filter-spp must be a power of 2 from 1 to 1024");
    }
    let mut studies = args.study.clone();
    if args.specialisation {
        studies.push(Study::RenderSpeed);
    }
    if args.statistics {
        studies.push(Study::Statistics);
    }
    if studies.is_empty() {
        studies = vec![
            Study::FilterSpeed,
            Study::Quality,
            Study::AccuracyTime,
            Study::Sweep,
            Study::RenderSpeed,
            Study::Tracers,
            Study::Statistics,
            Study::Roofline,
        ];
    }
    studies.dedup();
    // The bundled scenes are needed unless --scene names every scene and no study reads a
    // bundled scene by name (filter-speed and the sweep do): fail before measuring anything.
    let scenes_dir = scenes_dir(args.scenes.as_deref())?;
    let needs_bundled = args.scene.is_empty()
        || studies.iter().any(|s| {
            matches!(
                s,
                Study::FilterSpeed
                    | Study::Sweep
                    | Study::RpfScale
                    | Study::AafShadows
                    | Study::AafIndirect
                    | Study::AafCost
                    | Study::Roofline
            )
        });
    if scenes_dir.is_none() && needs_bundled {
        return Err(no_scenes_dir());
    }
    let mut scenes = match &scenes_dir {
        Some(dir) if args.scene.is_empty() => bundled_scenes(dir)?,
        _ => args.scene.clone(),
    };
    if args.quick && args.scene.is_empty() {
        scenes.retain(|p| p.ends_with("cornell_diffuse.toml"));
    }
    Ok(Selection {
        studies,
        scenes,
        scenes_dir,
    })
}

/// The ground-truth images the studies of `args` compare with, each once: what `bench
/// --slurm` renders on the cluster before the benchmark runs.
pub fn reference_requests(args: &BenchArgs) -> Result<Vec<ground_truth::ReferenceRequest>> {
    let sel = select(args)?;
    let sizes = study::sizes_for(args.quick, args.reference_spp, args.size);
    let mut paths: Vec<PathBuf> = Vec::new();
    for s in &sel.studies {
        match s {
            Study::Quality | Study::AccuracyTime | Study::PathDensity => {
                paths.extend(sel.scenes.iter().cloned())
            }
            Study::Sweep => {
                let dir = sel.scenes_dir.as_ref().ok_or_else(no_scenes_dir)?;
                for name in sweep::sweep_scenes(args.quick) {
                    paths.push(dir.join(format!("{name}.toml")));
                }
            }
            Study::AafShadows => {
                let dir = sel.scenes_dir.as_ref().ok_or_else(no_scenes_dir)?;
                paths.push(dir.join("grids.toml"));
            }
            // The scenes --scene names (the study keeps the pinhole ones), else room_gi.
            Study::AafIndirect if !args.scene.is_empty() => paths.extend(args.scene.clone()),
            Study::AafIndirect => {
                let dir = sel.scenes_dir.as_ref().ok_or_else(no_scenes_dir)?;
                paths.push(dir.join("room_gi.toml"));
            }
            Study::RpfReadings => {
                let dir = sel.scenes_dir.as_ref().ok_or_else(no_scenes_dir)?;
                for name in rpf::THESIS_SCENES {
                    paths.push(dir.join(format!("{name}.toml")));
                }
            }
            Study::RpfScale => {
                let dir = sel.scenes_dir.as_ref().ok_or_else(no_scenes_dir)?;
                for name in &rpf::THESIS_SCENES[..3] {
                    paths.push(dir.join(format!("{name}.toml")));
                }
            }
            Study::RenderSpeed
            | Study::Tracers
            | Study::Statistics
            | Study::FilterSpeed
            | Study::Balance
            | Study::AafCost
            | Study::Roofline => {}
        }
    }
    let mut seen = std::collections::BTreeSet::new();
    paths.retain(|p| seen.insert(p.clone()));
    Ok(paths
        .iter()
        .map(|p| study::reference_request(p, &sizes))
        .collect())
}

/// Everything a study needs.
pub struct Context {
    pub gpu: Arc<Gpu>,
    /// Every device of --devices (the first is `gpu`); `gpu` alone without it.
    pub gpus: Vec<Arc<Gpu>>,
    /// --filter-placement and --no-rebalance, for the balance study.
    pub multi: crate::filters::MultiDeviceArgs,
    pub out: PathBuf,
    pub quick: bool,
    pub quiet: bool,
    pub scenes: Vec<PathBuf>,
    /// Whether `--scene` chose `scenes` (else they are the bundled ones).
    pub scenes_named: bool,
    /// The bundled scenes folder, if one was found.
    pub scenes_dir: Option<PathBuf>,
    /// Where ground-truth images are cached.
    pub reference_cache: PathBuf,
    /// `--reference-spp`, if given.
    pub reference_spp: Option<u32>,
    /// `--method`: the methods of the quality studies (empty: all).
    pub methods: Vec<String>,
    /// `--size`, if given.
    pub size: Option<u32>,
    /// `--filter-spp`, if given.
    pub filter_spp: Option<u32>,
}

impl Context {
    /// A CSV in the results folder, emptied first with --fresh.
    pub fn table(
        &self,
        name: &str,
        columns: &[&str],
        keys: usize,
        fresh: bool,
    ) -> Result<table::ResultTable> {
        let path = self.out.join(format!("{name}.csv"));
        if fresh && path.exists() {
            std::fs::remove_file(&path)?;
        }
        table::ResultTable::open(&path, columns, keys)
    }

    /// A bundled scene by name, e.g. "cornell_diffuse", in the bundled scenes folder.
    pub fn scene_file(&self, name: &str) -> Result<PathBuf> {
        let dir = self.scenes_dir.as_ref().ok_or_else(no_scenes_dir)?;
        Ok(dir.join(format!("{name}.toml")))
    }

    /// Whether `--method` keeps a candidate labelled `label` (unfiltered always).
    pub fn wants(&self, label: &str) -> bool {
        label == "unfiltered"
            || self.methods.is_empty()
            || self
                .methods
                .iter()
                .any(|m| label == m || label.starts_with(&format!("{m}-")))
    }

    pub fn say(&self, msg: &str) {
        if !self.quiet {
            eprintln!("{msg}");
        }
    }
}

/// A progress bar over a study's cells (hidden with --quiet).
pub fn bar(ctx: &Context, len: u64, what: &str) -> indicatif::ProgressBar {
    let b = if ctx.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(len)
    };
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg:40} [{elapsed_precise}] {bar:25} {pos}/{len}  ETA {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    b.set_message(what.to_string());
    b
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let Selection {
        studies,
        scenes,
        scenes_dir,
    } = select(args)?;
    let gpus = args.multi.open(args.device)?;
    let gpu = gpus[0].clone();
    // Outputs go under the current folder unless --out (and --cache) say otherwise.
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("results").join(if args.quick {
            "quick".to_string()
        } else {
            device_slug(&gpu)
        })
    });
    std::fs::create_dir_all(&out)?;
    let ctx = Context {
        gpu,
        gpus,
        multi: args.multi.clone(),
        out,
        quick: args.quick,
        quiet: args.quiet,
        scenes,
        scenes_named: !args.scene.is_empty(),
        scenes_dir,
        reference_cache: args
            .cache
            .clone()
            .unwrap_or_else(ground_truth::default_cache),
        reference_spp: args.reference_spp,
        methods: args.method.clone(),
        filter_spp: args.filter_spp,
        size: args.size,
    };
    ctx.say(&format!(
        "device: {} | bundled scenes: {} | results in {}",
        ctx.gpu.summary.name,
        ctx.scenes_dir
            .as_deref()
            .map_or("none".into(), |d| d.display().to_string()),
        ctx.out.display()
    ));
    for s in studies {
        match s {
            Study::RenderSpeed => speed::render_speed(&ctx, args.fresh)?,
            Study::Statistics => speed::statistics_cost(&ctx, args.fresh)?,
            Study::FilterSpeed => filter_speed::filter_speed(&ctx, args.fresh)?,
            Study::Quality => quality::quality(&ctx, args.fresh)?,
            Study::AccuracyTime => accuracy_time::accuracy_time(&ctx, args.fresh)?,
            Study::Sweep => sweep::sweep(&ctx, args.fresh)?,
            Study::PathDensity => path_density::path_density(&ctx, args.fresh)?,
            Study::Balance => balance::balance(&ctx, args.fresh)?,
            Study::AafShadows => aaf::aaf_shadows(&ctx, args.fresh)?,
            Study::AafIndirect => aaf_indirect::aaf_indirect(&ctx, args.fresh)?,
            Study::AafCost => aaf_cost::aaf_cost(&ctx)?,
            Study::RpfReadings => rpf::rpf_readings(&ctx, args.fresh)?,
            Study::RpfScale => rpf::rpf_scale(&ctx, args.fresh)?,
            Study::Roofline => roofline::roofline(&ctx)?,
            Study::Tracers => tracers::tracers(&ctx, args.fresh)?,
        }
    }
    write_device_info(&ctx)?;
    Ok(())
}

/// device.md: what the results were measured on.
fn write_device_info(ctx: &Context) -> Result<()> {
    let s = &ctx.gpu.summary;
    // The commit the binary was built from (build.rs), wherever the run is: a binary copied to
    // another machine must not report that machine's checkout.
    let commit = env!("NOISEFREE_COMMIT");
    let text = format!(
        "# Device\n\n| | |\n|---|---|\n| device | {} ({}){} |\n| platform | {} |\n| OpenCL | {} |\n| driver | {} |\n| compute units | {} |\n| max clock | {} MHz |\n| global memory | {} |\n| local memory | {} |\n| host CPUs | {} |\n| commit | {} |\n| command | `noisefree bench{}` |\n",
        s.name,
        s.kind,
        ctx.gpus[1..]
            .iter()
            .map(|g| format!(
                ", then {} ({} compute units)",
                g.summary.name, g.summary.compute_units
            ))
            .collect::<String>(),
        s.platform,
        s.version,
        s.driver,
        s.compute_units,
        s.max_clock_mhz,
        crate::gpu::human_bytes(s.global_mem_bytes),
        crate::gpu::human_bytes(s.local_mem_bytes),
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(0),
        commit,
        std::env::args()
            .skip(2)
            .map(|a| format!(" {a}"))
            .collect::<String>()
    );
    std::fs::write(ctx.out.join("device.md"), text)?;
    Ok(())
}
