//! `noisefree compare`, `noisefree reference`, `noisefree cache`.

use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Args;

use crate::bench::ground_truth::{self, ReferenceRequest};
use crate::gpu::Gpu;
use crate::imaging;
use crate::metrics::{self, ErrorScale};

#[derive(Args, Debug, Clone)]
pub struct CompareArgs {
    /// The image to judge (OpenEXR, linear RGB).
    pub test: PathBuf,
    /// The reference (OpenEXR, linear RGB).
    pub reference: PathBuf,
    /// Print the metrics as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a false-colour map of the per-pixel CIELUV error (log scale 1e-2 to 1e3).
    #[arg(long, value_name = "PATH.png")]
    pub error_map: Option<PathBuf>,
}

pub fn compare(args: &CompareArgs) -> Result<()> {
    if let Some(p) = &args.error_map {
        imaging::check_output_path(p)?;
    }
    let test = imaging::read_exr_rgb(&args.test)?;
    let reference = imaging::read_exr_rgb(&args.reference)?;
    let m = metrics::compare(&test, &reference).with_context(|| {
        format!(
            "comparing {} with {}",
            args.test.display(),
            args.reference.display()
        )
    })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&m)?);
    } else {
        println!("{m}");
    }
    if let Some(p) = &args.error_map {
        let map = metrics::error_map(&test, &reference, ErrorScale::default())?;

        imaging::write_atomically(p, |tmp| {
            image::save_buffer_with_format(
                tmp,
                &map.rgb8,
                map.width,
                map.height,
                image::ColorType::Rgb8,
                image::ImageFormat::Png,
            )
            .map_err(|e| anyhow::anyhow!("encoding PNG: {e}"))
        })?;
    }
    Ok(())
}

#[derive(Args, Debug, Clone)]
pub struct ReferenceArgs {
    /// The scene to render a ground truth of.
    pub scene: PathBuf,
    /// Samples per pixel (the thesis used 2048).
    #[arg(long, default_value_t = ground_truth::DEFAULT_REFERENCE_SPP)]
    pub spp: u32,
    #[arg(long, default_value_t = 512)]
    pub width: u32,
    #[arg(long, default_value_t = 512)]
    pub height: u32,
    #[arg(long, default_value_t = ground_truth::REFERENCE_SEED)]
    pub seed: u32,
    /// Cache folder [default: cache/references].
    #[arg(long)]
    pub cache: Option<PathBuf>,
    #[arg(long)]
    pub device: Option<usize>,
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn reference(args: &ReferenceArgs) -> Result<()> {
    if args.spp == 0 || args.width == 0 || args.height == 0 {
        bail!("--spp, --width and --height must be at least 1");
    }
    let gpu = Gpu::open(args.device)?;
    let req = ReferenceRequest {
        scene: args.scene.clone(),
        width: args.width,
        height: args.height,
        spp: args.spp,
        seed: args.seed,
    };
    let cache = args
        .cache
        .clone()
        .unwrap_or_else(ground_truth::default_cache);
    let (_, file, cached) = ground_truth::get_or_render(&gpu, &req, &cache, args.quiet)?;
    println!(
        "{} {}",
        if cached { "cached:" } else { "rendered:" },
        file.display()
    );
    Ok(())
}

#[derive(Args, Debug, Clone)]
pub struct CacheArgs {
    /// Delete every cached kernel binary.
    #[arg(long)]
    pub clear: bool,
}

pub fn cache(args: &CacheArgs) -> Result<()> {
    let Some(dir) = crate::gpu::default_cache_dir() else {
        bail!("no kernel cache folder: set NOISEFREE_CACHE_DIR or HOME");
    };
    let files: Vec<_> = std::fs::read_dir(&dir)
        .map(|d| d.flatten().collect())
        .unwrap_or_default();
    let bytes: u64 = files
        .iter()
        .filter_map(|e| e.metadata().ok())
        .map(|m| m.len())
        .sum();
    if args.clear {
        for f in &files {
            std::fs::remove_file(f.path())?;
        }
        println!(
            "removed {} kernel binaries ({}) from {}",
            files.len(),
            crate::gpu::human_bytes(bytes),
            dir.display()
        );
    } else {
        println!(
            "{}: {} kernel binaries, {}",
            dir.display(),
            files.len(),
            crate::gpu::human_bytes(bytes)
        );
    }
    Ok(())
}
