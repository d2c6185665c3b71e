//! `noisefree filter`: filters offline, from an AOV file written by `render --aovs` or a samples
//! file written by `render --save-samples`. The file records the scene information and every
//! filter's settings of the render that wrote it, so the result is the same bytes the render
//! would have written with that filter (flags given here still win).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Args;

use crate::filters::{FilterRequest, Registry};
use crate::gpu::Gpu;
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
    let (image, timings) = filter_frame(
        &frame,
        &record,
        &FilterChoice {
            name: &name,
            flags: &args.settings,
            device: args.device,
            quiet: args.quiet,
            repeat: args.repeat,
        },
        registry,
    )
    .with_context(|| input.clone())?;
    super::print_timings(&format!("{name} filter time"), &timings);
    if let Some(p) = &args.out {
        imaging::write_png(p, &image, args.exposure)?;
    }
    if let Some(p) = &args.exr {
        imaging::write_exr(p, &image)?;
    }
    println!(
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
}

/// The image of a frame read from a file (AOV, samples or merged partial renders) filtered as
/// `choice` says, with the settings the render recorded where the command line gives none;
/// and the filter's times.
pub fn filter_frame(
    frame: &Frame,
    record: &RenderRecord,
    choice: &FilterChoice,
    registry: &Registry,
) -> Result<(imaging::RgbImage, Vec<std::time::Duration>)> {
    let name = choice.name;
    if name == "none" {
        return Ok((frame.beauty()?, Vec::new()));
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
    let mut times = Vec::new();
    let mut image = None;
    for _ in 0..choice.repeat.max(1) {
        let out = prepared.run(frame).context("filtering")?;
        times.push(out.time());
        image = Some(out.image);
    }
    Ok((image.expect("at least one run"), times))
}
