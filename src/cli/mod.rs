//! The command line: `noisefree devices | render | view | filter | merge | compare | reference |
//! bench | cache`.

/// `println!` for the commands' reports: a reader that closed the pipe (`noisefree ... | head`)
/// is not an error, and the command goes on to write its files and exits as it would have
/// (`println!` panics there).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

mod filter_cmd;
mod interrupt;
mod merge_cmd;
mod partial_render;
mod preview_cmd;
mod render_cmd;
mod slurm;
mod tools;

use anyhow::Result;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

use crate::filters::Registry;
use crate::gpu;
pub use filter_cmd::FilterCommandArgs;
pub use render_cmd::{RenderArgs, RenderSummary, render};

#[derive(Parser, Debug)]
#[command(
    name = "noisefree",
    version = concat!(env!("CARGO_PKG_VERSION"), " (commit ", env!("NOISEFREE_COMMIT"), ")"),
    about = "Physically based OpenCL path tracing with real-time denoising filters"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// List OpenCL platforms and devices.
    Devices,
    /// Render a scene file to a PNG (and a linear EXR), optionally filtered.
    Render(RenderArgs),
    /// Look around a scene in a window: progressive rendering filtered every frame, camera on
    /// the keyboard and mouse (keys: README "Viewer keys"; F1 in the window).
    View(crate::view::ViewArgs),
    /// Filter the per-pixel buffers of an AOV file (written by `render --aovs`) offline.
    Filter(FilterCommandArgs),
    /// Merge partial renders (`render --samples A..B --partial part.nfp`) into the render of
    /// all their samples, exactly; write its image, EXR and AOVs, filtered as the render chose.
    Merge(merge_cmd::MergeArgs),
    /// Compare an image with a reference: MSE in CIELUV, MSE and relMSE in RGB, PSNR, SSIM.
    Compare(tools::CompareArgs),
    /// Render a scene's ground truth into the reference cache (reused when current).
    Reference(tools::ReferenceArgs),
    /// Benchmarks: speed and accuracy-versus-time studies, results under results/.
    Bench(crate::bench::BenchArgs),
    /// Show or clear the kernel binary cache.
    Cache(tools::CacheArgs),
}

/// The command line of a registry: the derived commands plus, on `render` and `filter`, one
/// flag per setting of every filter (grouped by filter in `--help`).
pub fn command(registry: &Registry) -> clap::Command {
    let args = registry.clap_args();
    Cli::command()
        .mut_subcommand("render", |c| c.args(args.clone()))
        .mut_subcommand("view", |c| c.args(args.clone()))
        .mut_subcommand("filter", |c| c.args(args.clone()))
        .mut_subcommand("merge", |c| c.args(args.clone()))
}

/// Runs the command line with the built-in filters; returns the process exit code.
pub fn main() -> i32 {
    main_with(&Registry::builtin())
}

/// Runs the command line with the filters of `registry`; returns the process exit code.
pub fn main_with(registry: &Registry) -> i32 {
    let matches = command(registry).get_matches();
    let cli = match parse(registry, &matches) {
        Ok(c) => c,
        Err(e) => e.exit(),
    };
    let mut own_pocl_dir = None;
    if matches!(cli.command, Command::Bench(_)) {
        // "Cold" kernel builds must not come from the driver's own caches. PoCL still writes
        // its uncached builds under its cache folder, and two processes building the same
        // kernel there at once have been seen to fail ("Final linking of kernel render
        // failed"), so each bench process gets a folder of its own. Set before the first
        // OpenCL call, while the process has one thread.
        let pocl_dir = std::env::temp_dir().join(format!("noisefree-pocl-{}", std::process::id()));
        if std::env::var_os("POCL_CACHE_DIR").is_none() {
            own_pocl_dir = Some(pocl_dir.clone());
        }
        let pocl_dir = pocl_dir.to_string_lossy().into_owned();
        for (var, value) in [
            ("POCL_KERNEL_CACHE", "0"),
            ("POCL_CACHE_DIR", pocl_dir.as_str()),
            ("CUDA_CACHE_DISABLE", "1"),
        ] {
            if std::env::var_os(var).is_none() {
                // SAFETY: no other thread exists yet that could read the environment.
                unsafe { std::env::set_var(var, value) };
            }
        }
    }
    let result = execute(cli, registry);
    if let Some(dir) = own_pocl_dir {
        let _ = std::fs::remove_dir_all(dir);
    }
    match result {
        Ok(()) => 0,
        Err(e) if e.is::<interrupt::Interrupted>() => {
            eprintln!("{e}");
            130
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            1
        }
    }
}

/// Parses `args` (the program name first) and runs the command with the filters of
/// `registry`: the command line as a library call (tests, plug-ins).
pub fn run_args<I, T>(registry: &Registry, args: I) -> Result<()>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let matches = command(registry).try_get_matches_from(args)?;
    execute(parse(registry, &matches)?, registry)
}

fn parse(registry: &Registry, matches: &clap::ArgMatches) -> Result<Cli, clap::Error> {
    let mut cli = Cli::from_arg_matches(matches)?;
    if let Some((_, sub)) = matches.subcommand() {
        let settings = registry.flag_tables(sub);
        match &mut cli.command {
            Command::Render(a) => a.settings = settings,
            Command::View(a) => a.settings = settings,
            Command::Filter(a) => a.settings = settings,
            Command::Merge(a) => a.settings = settings,
            _ => {}
        }
    }
    Ok(cli)
}

fn execute(cli: Cli, registry: &Registry) -> Result<()> {
    match cli.command {
        Command::Devices => devices(),
        Command::Render(args) => render(&args, registry).map(|_| ()),
        Command::View(args) => crate::view::run(&args, registry),
        Command::Filter(args) => filter_cmd::run(&args, registry),
        Command::Merge(args) => merge_cmd::run(&args, registry),
        Command::Compare(args) => tools::compare(&args),
        Command::Reference(args) => tools::reference(&args),
        Command::Bench(args) => match args.slurm {
            Some(n) => tools::bench_on_slurm(&args, n),
            None => crate::bench::run(&args),
        },
        Command::Cache(args) => tools::cache(&args),
    }
}

fn devices() -> Result<()> {
    let list = gpu::list_devices()?;
    let mut platform = String::new();
    for d in list {
        if d.platform != platform {
            say!("platform: {}", d.platform);
            platform = d.platform.clone();
        }
        say!(
            "  [{}] {} ({}) — {} compute units, {} local memory, max work-group {}, {} global memory, {}, driver {}, {}",
            d.index,
            d.name,
            d.kind,
            d.compute_units,
            gpu::human_bytes(d.local_mem_bytes),
            d.max_work_group_size,
            gpu::human_bytes(d.global_mem_bytes),
            d.version,
            d.driver,
            if d.correctly_rounded_divide_sqrt {
                "division and sqrt correctly rounded"
            } else {
                "division and sqrt within OpenCL's ulp bounds"
            }
        );
    }
    Ok(())
}

/// Prints min / median / max filter kernel times (the thesis reports lower and upper bounds).
pub(crate) fn print_timings(label: &str, times: &[std::time::Duration]) {
    if let Some((lo, med, hi)) = crate::filters::time_summary(times) {
        say!(
            "{label} over {} run(s): min {:.3} ms, median {:.3} ms, max {:.3} ms",
            times.len(),
            lo.as_secs_f64() * 1e3,
            med.as_secs_f64() * 1e3,
            hi.as_secs_f64() * 1e3
        );
    }
}
