//! `noisefree filter`: filters the per-pixel buffers of an AOV file offline.

use std::path::PathBuf;

use anyhow::{Context as _, Result};
use clap::Args;

use super::filter_args::{FilterArgs, Method};
use crate::filters::UploadedBuffers;
use crate::filters::ddf::DdfFilter;
use crate::gpu::Gpu;
use crate::output;

#[derive(Args, Debug, Clone)]
pub struct FilterCommandArgs {
    /// An AOV file written by `noisefree render --aovs`.
    pub input: PathBuf,
    /// The filter [default: ddf].
    #[arg(long, value_enum)]
    pub method: Option<Method>,
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
    /// Run the filter this many times and print min / median / max kernel time.
    #[arg(long, default_value_t = 1)]
    pub repeat: u32,
    #[command(flatten)]
    pub filter: FilterArgs,
}

pub fn run(args: &FilterCommandArgs) -> Result<()> {
    for p in [&args.out, &args.exr].into_iter().flatten() {
        output::check_output_path(p)?;
    }
    if args.out.is_none() && args.exr.is_none() {
        anyhow::bail!("nothing to write: give --out FILE.png and/or --exr FILE.exr");
    }
    let (buffers, _meta) = crate::stats::aovs::read_aov_exr(&args.input)?;
    let method = args.method.or(args.filter.filter).unwrap_or(Method::Ddf);
    let (image, times) = match method {
        Method::None => (buffers.beauty(), Vec::new()),
        Method::Ddf => {
            let (settings, variant) = args.filter.ddf(None)?;
            let gpu = Gpu::open(args.device)?;
            let up = UploadedBuffers::new(&gpu, &buffers)?;
            let mut f = DdfFilter::new(gpu, &settings, variant, buffers.width, buffers.height)?;
            let mut times = Vec::new();
            let mut image = None;
            for _ in 0..args.repeat.max(1) {
                let out = f.run(&up.view()).context("filtering")?;
                times.push(out.kernel_time);
                image = Some(out.image);
            }
            super::print_timings(&format!("data-driven filter ({})", variant.label()), &times);
            (image.expect("at least one run"), times)
        }
    };
    let _ = times;
    if let Some(p) = &args.out {
        output::write_png(p, &image, args.exposure)?;
    }
    if let Some(p) = &args.exr {
        output::write_exr(p, &image)?;
    }
    println!(
        "filtered {}x{} ({} spp) from {}",
        buffers.width,
        buffers.height,
        buffers.spp,
        args.input.display()
    );
    Ok(())
}
