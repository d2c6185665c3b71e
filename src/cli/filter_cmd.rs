//! `noisefree filter`: filters offline, from an AOV file written by `render --aovs` (the
//! data-driven and à-trous filters) or a samples file written by `render --save-samples`
//! (Random Parameter Filtering).

use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Args;

use super::filter_args::{FilterArgs, Method};
use crate::filters::UploadedBuffers;
use crate::filters::atrous::AtrousFilter;
use crate::filters::ddf::DdfFilter;
use crate::filters::method::run_rpf;
use crate::filters::rpf::samples::{SampleSet, is_sample_file};
use crate::gpu::Gpu;
use crate::imaging;
use crate::scene::Setting;

#[derive(Args, Debug, Clone)]
pub struct FilterCommandArgs {
    /// An AOV file (`render --aovs`) or, for RPF, a samples file (`render --save-samples`).
    pub input: PathBuf,
    /// The filter [default: rpf for a samples file, ddf for an AOV file].
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// RPF: the scene is outdoors (sigma^2_8 = 0.002 instead of 0.02, §5.1.4).
    #[arg(long)]
    pub outdoor: bool,
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
    /// Run a device filter this many times and print min / median / max kernel time.
    #[arg(long, default_value_t = 1)]
    pub repeat: u32,
    #[arg(long, short)]
    pub quiet: bool,
    #[command(flatten)]
    pub filter: FilterArgs,
}

pub fn run(args: &FilterCommandArgs) -> Result<()> {
    for p in [&args.out, &args.exr].into_iter().flatten() {
        imaging::check_output_path(p)?;
    }
    if args.out.is_none() && args.exr.is_none() {
        bail!("nothing to write: give --out FILE.png and/or --exr FILE.exr");
    }
    if !args.input.exists() {
        bail!("{}: no such file", args.input.display());
    }
    let samples_file = is_sample_file(&args.input);
    let method = args
        .method
        .or(args.filter.filter)
        .unwrap_or(if samples_file {
            Method::Rpf
        } else {
            Method::Ddf
        });
    let setting = if args.outdoor {
        Setting::Outdoor
    } else {
        Setting::Indoor
    };
    let (image, what) = match method {
        Method::Rpf => {
            if !samples_file {
                bail!(
                    "{}: RPF filters a samples file (write one with `render --save-samples FILE`)",
                    args.input.display()
                );
            }
            let set = SampleSet::read(&args.input)?;
            let settings = args.filter.rpf(None, setting)?;
            let start = std::time::Instant::now();
            let image = run_rpf(&set, &settings, !args.quiet)?;
            println!(
                "RPF filtered {}x{} ({} spp) in {:.1} s",
                set.width,
                set.height,
                set.spp,
                start.elapsed().as_secs_f64()
            );
            (image, args.input.display().to_string())
        }
        m => {
            if samples_file {
                bail!(
                    "{}: a samples file holds no per-pixel buffers; use --method rpf, or an AOV file",
                    args.input.display()
                );
            }
            let (buffers, meta) = crate::stats::aovs::read_aov_exr(&args.input)?;
            let image = match m {
                Method::None => buffers.beauty(),
                Method::Ddf | Method::Atrous => {
                    let gpu = Gpu::open(args.device)?;
                    let up = UploadedBuffers::new(&gpu, &buffers)?;
                    let mut times = Vec::new();
                    let mut image = None;
                    let mut ddf;
                    let mut atrous;
                    let run: &mut dyn FnMut() -> Result<crate::filters::Filtered> =
                        if m == Method::Ddf {
                            let (settings, variant) = args.filter.ddf(None)?;
                            ddf = DdfFilter::new(
                                gpu.clone(),
                                &settings,
                                variant,
                                buffers.width,
                                buffers.height,
                            )?;
                            &mut || ddf.run(&up.view())
                        } else {
                            let camera_text = meta.get("camera").with_context(|| {
                            format!(
                                "{}: no camera in the AOV file (re-render it with this version)",
                                args.input.display()
                            )
                        })?;
                            let camera = crate::stats::aovs::camera_from_text(camera_text)?;
                            atrous = AtrousFilter::new(
                                gpu.clone(),
                                &args.filter.atrous(None)?,
                                &camera,
                                buffers.width,
                                buffers.height,
                            )?;
                            &mut || atrous.run(&up.view())
                        };
                    for _ in 0..args.repeat.max(1) {
                        let out = run().context("filtering")?;
                        times.push(out.kernel_time);
                        image = Some(out.image);
                    }
                    super::print_timings(
                        &format!("{m:?} filter kernel time").to_lowercase(),
                        &times,
                    );
                    image.expect("at least one run")
                }
                Method::Rpf => unreachable!("handled above"),
            };
            (
                image,
                format!("{} ({} spp)", args.input.display(), buffers.spp),
            )
        }
    };
    if let Some(p) = &args.out {
        imaging::write_png(p, &image, args.exposure)?;
    }
    if let Some(p) = &args.exr {
        imaging::write_exr(p, &image)?;
    }
    println!("filtered {}x{} from {what}", image.width, image.height);
    Ok(())
}
