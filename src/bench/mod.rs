//! `noisefree bench`: every speed and quality figure of the project comes from here, as CSV +
//! Markdown + PNG plots under results/. Runs are resumable: a measurement already in a study's
//! CSV is not repeated (delete the file, or pass --fresh, to measure again).
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
//!
//! Files: `speed` holds the first three studies; `quality`, `accuracy_time` and `sweep` one
//! study each, with `study` for what those three share and `curves` for the log-log maths of
//! the headline figures. `ground_truth` is the cache of many-spp reference images (not to be
//! confused with `render::cpu`, the CPU mirror of the kernels); `table` the resumable CSV
//! tables and `plot` the charts and contact sheets.

pub mod accuracy_time;
pub mod curves;
pub mod ground_truth;
pub mod plot;
pub mod quality;
pub mod speed;
pub mod study;
pub mod sweep;
pub mod table;

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};

use crate::gpu::Gpu;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Study {
    RenderSpeed,
    Statistics,
    FilterSpeed,
    Quality,
    AccuracyTime,
    Sweep,
}

#[derive(Args, Debug, Clone)]
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
    /// Results folder [default: results/<device> or results/quick].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Measure again even what the CSV files already hold.
    #[arg(long)]
    pub fresh: bool,
    /// OpenCL device number from `noisefree devices` (or NOISEFREE_DEVICE).
    #[arg(long)]
    pub device: Option<usize>,
    /// Scenes to use [default: all bundled scenes].
    #[arg(long)]
    pub scene: Vec<PathBuf>,
    #[arg(long, short)]
    pub quiet: bool,
}

/// Everything a study needs.
pub struct Context {
    pub gpu: Arc<Gpu>,
    pub out: PathBuf,
    pub quick: bool,
    pub quiet: bool,
    pub scenes: Vec<PathBuf>,
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

/// A file-system friendly name for the device, e.g. "pocl-cpu" or "nvidia-h100-80gb-hbm3".
pub fn device_slug(gpu: &Gpu) -> String {
    let s = &gpu.summary;
    let raw = if s.platform.contains("Portable Computing Language") {
        format!("pocl-{}", s.kind.to_lowercase())
    } else {
        s.name.to_lowercase()
    };
    let mut out = String::new();
    for c in raw.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c);
        } else if !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_matches('-').to_string()
}

/// The bundled scenes, the five of the thesis and their depth-of-field variants.
pub fn bundled_scenes() -> Result<Vec<PathBuf>> {
    let dir = PathBuf::from("scenes");
    if !dir.is_dir() {
        bail!("run noisefree bench from the repository root (it reads scenes/)");
    }
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    Ok(v)
}

pub fn run(args: &BenchArgs) -> Result<()> {
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
            Study::Statistics,
        ];
    }
    studies.dedup();
    let gpu = Gpu::open(args.device)?;
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("results").join(if args.quick {
            "quick".to_string()
        } else {
            device_slug(&gpu)
        })
    });
    std::fs::create_dir_all(&out)?;
    let mut scenes = if args.scene.is_empty() {
        bundled_scenes()?
    } else {
        args.scene.clone()
    };
    if args.quick && args.scene.is_empty() {
        scenes.retain(|p| p.ends_with("cornell_diffuse.toml"));
    }
    let ctx = Context {
        gpu,
        out,
        quick: args.quick,
        quiet: args.quiet,
        scenes,
    };
    ctx.say(&format!(
        "device: {} | results in {}",
        ctx.gpu.summary.name,
        ctx.out.display()
    ));
    for s in studies {
        match s {
            Study::RenderSpeed => speed::render_speed(&ctx, args.fresh)?,
            Study::Statistics => speed::statistics_cost(&ctx, args.fresh)?,
            Study::FilterSpeed => speed::filter_speed(&ctx, args.fresh)?,
            Study::Quality => quality::quality(&ctx, args.fresh)?,
            Study::AccuracyTime => accuracy_time::accuracy_time(&ctx, args.fresh)?,
            Study::Sweep => sweep::sweep(&ctx, args.fresh)?,
        }
    }
    write_device_info(&ctx)?;
    Ok(())
}

/// device.md: what the results were measured on.
fn write_device_info(ctx: &Context) -> Result<()> {
    let s = &ctx.gpu.summary;
    let commit = std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".into());
    let text = format!(
        "# Device\n\n| | |\n|---|---|\n| device | {} ({}) |\n| platform | {} |\n| OpenCL | {} |\n| driver | {} |\n| compute units | {} |\n| max clock | {} MHz |\n| global memory | {} |\n| local memory | {} |\n| host CPUs | {} |\n| commit | {} |\n| command | `noisefree bench{}` |\n",
        s.name,
        s.kind,
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
