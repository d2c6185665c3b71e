//! `noisefree filter`: filters offline, from an AOV file written by `render --aovs` or a samples
//! file written by `render --save-samples`. The file records the scene information and every
//! filter's settings of the render that wrote it, so the result is the same bytes the render
//! would have written with that filter (flags given here still win).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Args;

use crate::filters::{FilterRequest, Registry};
use crate::gpu::{Gpu, profile};
use crate::imaging;
use crate::render::Frame;
use crate::stats::RenderRecord;
use crate::stats::samples::{SampleSet, is_sample_file};

#[derive(Args, Debug, Clone)]
pub struct FilterCommandArgs {
    /// An AOV file (`render --aovs`) or a samples file (`render --save-samples`).
    pub input: PathBuf,
    /// The filter [default: the one the render ran, else the first registered filter the file
    /// holds the outputs for]. `none` writes the unfiltered image.
    #[arg(long, visible_alias = "method", value_name = "NAME")]
    pub filter: Option<String>,
    /// Tone-mapped sRGB PNG of the result.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Linear float OpenEXR of the result.
    #[arg(long)]
    pub exr: Option<PathBuf>,
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// OpenCL device number from `noisefree devices` (or NOISEFREE_DEVICE).
    #[arg(long)]
    pub device: Option<usize>,
    /// Run the filter this many times and print min / median / max time.
    #[arg(long, default_value_t = 1)]
    pub repeat: u32,
    /// Also print each kernel's launches and time per run (median over the runs, from the
    /// OpenCL profiling events).
    #[arg(long)]
    pub profile: bool,
    #[arg(long, short)]
    pub quiet: bool,
    /// The filter settings given on the command line, per filter.
    #[arg(skip)]
    pub settings: BTreeMap<String, toml::Table>,
}

/// The frame and record in an AOV or samples file.
pub fn read_frame(path: &std::path::Path) -> Result<(Frame, RenderRecord)> {
    if !path.exists() {
        bail!("{}: no such file", path.display());
    }
    if is_sample_file(path) {
        let set = SampleSet::read(path)?;
        let record = set.record.clone();
        Ok((set.into_frame()?, record))
    } else {
        crate::stats::aov::read_aov_exr(path)
    }
}

pub fn run(args: &FilterCommandArgs, registry: &Registry) -> Result<()> {
    for p in [&args.out, &args.exr].into_iter().flatten() {
        imaging::check_output_path(p)?;
    }
    if args.out.is_none() && args.exr.is_none() {
        bail!("nothing to write: give --out FILE.png and/or --exr FILE.exr");
    }
    if let Some(name) = args.filter.as_deref().filter(|n| *n != "none") {
        registry.get(name).context("--filter")?;
    }
    let input = args.input.display().to_string();
    let (frame, record) = read_frame(&args.input)?;
    if record.scene.is_none() {
        eprintln!(
            "warning: {input} records no scene information (another program or an older \
             noisefree wrote it): the filters use their defaults and do not adapt to the scene"
        );
    }
    let name = match args.filter.clone().or(record.filter.clone()) {
        Some(n) => n,
        None => registry
            .filters()
            .iter()
            .find(|f| {
                registry
                    .configure(**f, &FilterRequest::default(), &frame.info().scene)
                    .is_ok_and(|c| frame.outputs().covers(c.needs()))
            })
            .map(|f| f.name().to_string())
            .with_context(|| format!("{input}: no filter can run on what this file holds"))?,
    };
    let Filtered {
        image,
        times: timings,
        kernels,
    } = filter_frame(
        &frame,
        &record,
        &FilterChoice {
            name: &name,
            flags: &args.settings,
            device: args.device,
            quiet: args.quiet,
            repeat: args.repeat,
            profile: args.profile,
        },
        registry,
    )
    .with_context(|| input.clone())?;
    super::print_timings(&format!("{name} filter time"), &timings);
    if args.profile {
        print_profile(&kernels);
    }
    if let Some(p) = &args.out {
        imaging::write_png(p, &image, args.exposure)?;
    }
    if let Some(p) = &args.exr {
        imaging::write_exr(p, &image)?;
    }
    say!(
        "filtered {}x{} ({} spp) from {input} with {name}",
        image.width,
        image.height,
        frame.info().spp
    );
    Ok(())
}

/// Which filter runs on a frame read from a file, and how.
pub struct FilterChoice<'a> {
    /// A registered filter, or "none" for the unfiltered image.
    pub name: &'a str,
    /// Settings given on the command line (they win over the recorded ones).
    pub flags: &'a BTreeMap<String, toml::Table>,
    pub device: Option<usize>,
    pub quiet: bool,
    /// Runs, for timings.
    pub repeat: u32,
    /// Record each run's kernels ([`crate::gpu::profile`]).
    pub profile: bool,
}

/// A frame filtered by [`filter_frame`].
pub struct Filtered {
    pub image: imaging::RgbImage,
    /// Each run's time.
    pub times: Vec<std::time::Duration>,
    /// Each run's kernels, when [`FilterChoice::profile`] asked for them.
    pub kernels: Vec<Vec<profile::KernelTime>>,
}

/// The image of a frame read from a file (AOV, samples or merged partial renders) filtered as
/// `choice` says, with the settings the render recorded where the command line gives none;
/// and the filter's times.
pub fn filter_frame(
    frame: &Frame,
    record: &RenderRecord,
    choice: &FilterChoice,
    registry: &Registry,
) -> Result<Filtered> {
    let name = choice.name;
    if name == "none" {
        return Ok(Filtered {
            image: frame.beauty()?,
            times: Vec::new(),
            kernels: Vec::new(),
        });
    }
    let filter = registry.get(name)?;
    let request = FilterRequest {
        recorded: record.settings.clone(),
        flags: choice.flags.clone(),
        ..Default::default()
    };
    let configured = registry.configure(filter, &request, &frame.info().scene)?;
    for w in configured.warnings() {
        eprintln!("{w}");
    }
    frame
        .require(configured.needs(), &format!("the {name} filter"))
        .with_context(|| {
            format!(
                "re-render with `noisefree render SCENE --filter {name} --aovs FILE.exr` (or \
                 --save-samples FILE.bin for filters that read every sample; for partial \
                 renders, --filter {name} or --gather)"
            )
        })?;
    let gpu = Gpu::open(choice.device)?;
    let mut prepared = configured.prepare(frame.info(), &gpu)?;
    prepared.show_progress(!choice.quiet);
    let (mut times, mut kernels) = (Vec::new(), Vec::new());
    let mut image = None;
    for _ in 0..choice.repeat.max(1) {
        // Each run does a new frame's whole work (a filter may skip work on a frame it saw).
        prepared.forget();
        if choice.profile {
            profile::start();
        }
        let out = prepared.run(frame).context("filtering")?;
        if choice.profile {
            kernels.push(profile::finish()?);
        }
        times.push(out.time());
        image = Some(out.image);
    }
    Ok(Filtered {
        image: image.expect("at least one run"),
        times,
        kernels,
    })
}

/// Each kernel's launches and median time per run over `runs`, with its share of the
/// median run's summed kernel time.
fn print_profile(runs: &[Vec<profile::KernelTime>]) {
    let Some(first) = runs.first() else { return };
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let totals: Vec<f64> = runs
        .iter()
        .map(|r| r.iter().map(|k| k.time.as_secs_f64() * 1e3).sum())
        .collect();
    let total = median(totals);
    say!("kernels per run (median over {} run(s)):", runs.len());
    say!(
        "  {:<40} {:>8} {:>11} {:>7}",
        "kernel",
        "launches",
        "ms",
        "share"
    );
    for k in first {
        let ms = median(
            runs.iter()
                .map(|r| {
                    r.iter()
                        .find(|o| o.kernel == k.kernel)
                        .map_or(0.0, |o| o.time.as_secs_f64() * 1e3)
                })
                .collect(),
        );
        let share = if total > 0.0 { 100.0 * ms / total } else { 0.0 };
        say!(
            "  {:<40} {:>8} {:>11.3} {:>6.1}%",
            k.kernel,
            k.launches,
            ms,
            share
        );
    }
    say!(
        "  {:<40} {:>8} {:>11.3}",
        "all kernels (median run)",
        "",
        total
    );
}
