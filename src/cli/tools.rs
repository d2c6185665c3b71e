//! `noisefree compare`, `noisefree reference`, `noisefree cache`.

use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Args;

use super::slurm;
use crate::bench::ground_truth::{self, ReferenceRequest};
use crate::gpu::Gpu;
use crate::imaging;
use crate::metrics::worst::{self, PixelMetric};
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
    /// Also list the N pixels with the largest error, each with its share of the image's.
    #[arg(long, value_name = "N")]
    pub worst: Option<usize>,
    /// The error --worst ranks by: the pixel's term of MSE in CIELUV, or of relative MSE.
    #[arg(long, value_enum, default_value_t = PixelMetric::Luv, requires = "worst")]
    pub worst_by: PixelMetric,
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
    let ranked = match args.worst {
        Some(n) => Some(worst::worst_pixels(&test, &reference, args.worst_by, n)?),
        None => None,
    };
    let text = match (&ranked, args.json) {
        (Some(pixels), true) => serde_json::to_string_pretty(&serde_json::json!({
            "metrics": m,
            "worst_by": args.worst_by,
            "worst": pixels,
        }))?,
        (None, true) => serde_json::to_string_pretty(&m)?,
        (Some(pixels), false) => format!("{m}\n{}", worst_table(pixels, args.worst_by)),
        (None, false) => m.to_string(),
    };
    say!("{text}");
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

/// `--worst`'s table: one pixel a line, with the running total of the shares.
fn worst_table(pixels: &[worst::PixelError], by: PixelMetric) -> String {
    let name = match by {
        PixelMetric::Luv => "CIELUV",
        PixelMetric::RelMse => "relMSE",
    };
    let total: f64 = pixels.iter().map(|p| p.share).sum();
    let mut out = format!(
        "the {} pixels with the largest {name} error hold {:.1} % of it:\n\
         {:>5} {:>5}  {:>30}  {:>30}  {:>10}  {:>7}  {:>7}",
        pixels.len(),
        100.0 * total,
        "x",
        "y",
        "test rgb",
        "reference rgb",
        "error",
        "share",
        "so far"
    );
    let rgb = |c: [f32; 3]| format!("{:.4} {:.4} {:.4}", c[0], c[1], c[2]);
    let mut so_far = 0.0;
    for p in pixels {
        so_far += p.share;
        out.push_str(&format!(
            "\n{:>5} {:>5}  {:>30}  {:>30}  {:>10.4e}  {:>6.2}%  {:>6.2}%",
            p.x,
            p.y,
            rgb(p.test),
            rgb(p.reference),
            p.error,
            100.0 * p.share,
            100.0 * so_far
        ));
    }
    out
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
    /// Render it on a Slurm cluster instead, as a job array of N sample ranges and a merge job
    /// into the cache (scripts/slurm/): write the job folder and submit it.
    #[arg(long, value_name = "N")]
    pub slurm: Option<u32>,
    /// With --slurm: print the job instead of writing and submitting it.
    #[arg(long, requires = "slurm")]
    pub dry_run: bool,
    /// With --slurm: the job folder [default: slurm/reference-<scene>-<W>x<H>-<spp>spp].
    #[arg(long, value_name = "DIR", requires = "slurm")]
    pub job_dir: Option<PathBuf>,
    /// Merge these partial renders of the reference (what --slurm's tasks write) into the
    /// cache instead of rendering it.
    #[arg(long, value_name = "PART.nfp", num_args = 1.., conflicts_with = "slurm")]
    pub from_parts: Vec<PathBuf>,
}

pub fn reference(args: &ReferenceArgs) -> Result<()> {
    if args.spp == 0 || args.width == 0 || args.height == 0 {
        bail!("--spp, --width and --height must be at least 1");
    }
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
    if let Some(n) = args.slurm {
        let name = format!(
            "reference-{}-{}x{}-{}spp",
            stem(&req.scene),
            req.width,
            req.height,
            req.spp
        );
        let job = slurm::Job {
            what: format!(
                "noisefree reference {} --slurm {n}: {} spp in {n} ranges, merged into {}",
                req.scene.display(),
                req.spp,
                cache.display()
            ),
            tasks: n,
            renders: vec![reference_job(&req, &cache, args.device)],
            final_command: None,
        };
        let dir = args
            .job_dir
            .clone()
            .unwrap_or_else(|| slurm::default_dir(&name));
        return job.run(&dir, args.dry_run);
    }
    if !args.from_parts.is_empty() {
        let (file, cost) = ground_truth::store_merged(&req, &cache, &args.from_parts)?;
        say!("merged: {}", file.display());
        say!("{}", super::merge_cmd::describe_cost(&cost));
        return Ok(());
    }
    let gpu = Gpu::open(args.device)?;
    let (_, file, cached) = ground_truth::get_or_render(&gpu, &req, &cache, args.quiet)?;
    say!(
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
        say!(
            "removed {} kernel binaries ({}) from {}",
            files.len(),
            crate::gpu::human_bytes(bytes),
            dir.display()
        );
    } else {
        say!(
            "{}: {} kernel binaries, {}",
            dir.display(),
            files.len(),
            crate::gpu::human_bytes(bytes)
        );
    }
    Ok(())
}

/// `bench --slurm N`: the references the studies need, each a job array of N ranges merged
/// into the cache, then the benchmark itself in the merge job (its timings must come from one
/// device, and it finds the references cached).
pub fn bench_on_slurm(args: &crate::bench::BenchArgs, n: u32) -> Result<()> {
    let cache = args
        .cache
        .clone()
        .unwrap_or_else(ground_truth::default_cache);
    let renders: Vec<_> = crate::bench::reference_requests(args)?
        .iter()
        .map(|req| reference_job(req, &cache, args.device))
        .collect();
    if renders.is_empty() {
        bail!(
            "the studies chosen compare with no reference, so there is nothing to split into \
             ranges: run `noisefree bench` as one job (e.g. sbatch --wrap 'noisefree bench ...')"
        );
    }
    let mut bench = args.to_args();
    if args.cache.is_none() {
        bench.extend(["--cache".into(), slurm::arg(&cache)]);
    }
    let job = slurm::Job {
        what: format!(
            "noisefree {} --slurm {n}: the studies' references in {n} ranges each, merged into \
             {}, then the benchmark",
            bench.join(" "),
            cache.display()
        ),
        tasks: n,
        renders,
        final_command: Some(bench),
    };
    let name = if args.quick { "bench-quick" } else { "bench" };
    let dir = args
        .job_dir
        .clone()
        .unwrap_or_else(|| slurm::default_dir(name));
    job.run(&dir, args.dry_run)
}

fn stem(p: &std::path::Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into())
}

/// The parts and merge of one reference as a render of a Slurm job: its tasks render with the
/// reference's options (no filter, so colour only), its merge stores it in `cache`.
pub(super) fn reference_job(
    req: &ReferenceRequest,
    cache: &std::path::Path,
    device: Option<usize>,
) -> slurm::JobRender {
    let common = vec![
        slurm::arg(&req.scene),
        "--spp".into(),
        req.spp.to_string(),
        "--width".into(),
        req.width.to_string(),
        "--height".into(),
        req.height.to_string(),
        "--seed".into(),
        req.seed.to_string(),
    ];
    let mut render = common.clone();
    render.extend(["--filter".into(), "none".into()]);
    if let Some(d) = device {
        render.extend(["--device".into(), d.to_string()]);
    }
    let mut merge = vec!["reference".to_string()];
    merge.extend(common);
    merge.extend(["--cache".into(), slurm::arg(cache), "--from-parts".into()]);
    slurm::JobRender {
        name: format!(
            "{}-{}x{}-{}spp",
            stem(&req.scene),
            req.width,
            req.height,
            req.spp
        ),
        spp: req.spp,
        render,
        merge,
    }
}
