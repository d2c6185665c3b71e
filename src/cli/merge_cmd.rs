//! `noisefree merge`: partial renders (`render --samples A..B --partial part.nfp`, `--tile`)
//! merged into the render of all their samples (src/stats/merge/), then written as `render`
//! writes a render: the image (filtered as the render chose, or with --filter), its EXR, the
//! AOVs. Or the parts bundled into one partial file (--partial). Every part is checked against
//! the others before anything is read or written; on any error nothing is written.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Args;

use super::filter_cmd::{FilterChoice, filter_frame};
use crate::filters::Registry;
use crate::imaging;
use crate::stats::merge::{CostSummary, Plan};

#[derive(Args, Debug, Clone)]
pub struct MergeArgs {
    /// The partial files, in any order (they are merged in the order of their samples).
    #[arg(required = true, value_name = "PART.nfp")]
    pub parts: Vec<PathBuf>,
    /// Tone-mapped sRGB PNG of the merged render.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Linear float OpenEXR of the merged render.
    #[arg(long)]
    pub exr: Option<PathBuf>,
    /// Every per-pixel output the parts gathered, as one multi-channel OpenEXR (as `render
    /// --aovs` writes it).
    #[arg(long, value_name = "FILE.exr")]
    pub aovs: Option<PathBuf>,
    /// Also write the unfiltered image as a linear EXR (with a filter).
    #[arg(long, value_name = "FILE.exr")]
    pub exr_unfiltered: Option<PathBuf>,
    /// Write every piece of the parts into one partial file, unchanged (merging it later
    /// gives the same bytes as merging the parts).
    #[arg(long, value_name = "FILE.nfp")]
    pub partial: Option<PathBuf>,
    /// Filter to apply: a registered filter or none [default: the one the render chose].
    #[arg(long, value_name = "NAME")]
    pub filter: Option<String>,
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// OpenCL device number from `noisefree devices` (or NOISEFREE_DEVICE), for the filter.
    #[arg(long)]
    pub device: Option<usize>,
    #[arg(long, short)]
    pub quiet: bool,
    /// The filter settings given on the command line, per filter.
    #[arg(skip)]
    pub settings: BTreeMap<String, toml::Table>,
}

pub fn run(args: &MergeArgs, registry: &Registry) -> Result<()> {
    let outputs = [&args.out, &args.exr, &args.aovs, &args.exr_unfiltered];
    for p in outputs.iter().copied().chain([&args.partial]).flatten() {
        imaging::check_output_path(p)?;
    }
    if outputs.iter().all(|p| p.is_none()) && args.partial.is_none() {
        bail!(
            "nothing to write: give --out FILE.png, --exr FILE.exr, --aovs FILE.exr and/or \
             --partial FILE.nfp"
        );
    }
    if let Some(name) = args.filter.as_deref().filter(|n| *n != "none") {
        registry.get(name).context("--filter")?;
    }
    if outputs.iter().all(|p| p.is_none()) {
        let plan = Plan::bundle(&args.parts)?;
        let id = &plan.identity;
        let path = args.partial.as_ref().expect("checked above");
        plan.write_bundle(path)?;
        say!(
            "bundled {} piece(s) of {} ({}x{}, {} spp) -> {}",
            plan.order.len(),
            id.scene,
            id.width,
            id.height,
            id.spp,
            path.display()
        );
        return Ok(());
    }
    let plan = Plan::new(&args.parts)?;
    let id = &plan.identity;
    let bar = crate::render::progress_bar(plan.order.len() as u32, args.quiet);
    bar.set_message("merging pieces");
    let merged = plan.merge(|done| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    let name = args
        .filter
        .clone()
        .or(merged.record.filter.clone())
        .unwrap_or_else(|| "none".into());
    let choice = FilterChoice {
        name: &name,
        flags: &args.settings,
        device: args.device,
        quiet: args.quiet,
        repeat: 1,
        profile: false,
    };
    let image = filter_frame(&merged.frame, &merged.record, &choice, registry)?.image;
    // Everything is computed: now the files, each through a temporary name.
    if let Some(p) = &args.partial {
        plan.write_bundle(p)?;
    }
    if let Some(p) = &args.out {
        imaging::write_png(p, &image, args.exposure)?;
    }
    if let Some(p) = &args.exr {
        imaging::write_exr(p, &image)?;
    }
    if let Some(p) = &args.exr_unfiltered {
        imaging::write_exr(p, &merged.frame.beauty()?)?;
    }
    if let Some(p) = &args.aovs {
        crate::stats::aov::write_aov_exr(p, &merged.frame, &merged.record)?;
    }
    say!(
        "merged {} piece(s) from {} file(s): {} at {}x{}, {} spp, {} -> {}",
        plan.order.len(),
        plan.files.len(),
        id.scene,
        id.width,
        id.height,
        id.spp,
        if name == "none" {
            "unfiltered".to_string()
        } else {
            format!("filtered with {name}")
        },
        outputs
            .iter()
            .copied()
            .flatten()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    say!("{}", describe_cost(&merged.cost));
    Ok(())
}

/// "rendering took 12.3 s of device time (per piece: min 2.9 s, median 3.1 s, max 3.3 s)
/// on <device>, 120.5 Mrays".
pub fn describe_cost(c: &CostSummary) -> String {
    let mut s = c.seconds.clone();
    s.sort_by(f64::total_cmp);
    let total: f64 = s.iter().sum();
    let (min, median, max) = match s.as_slice() {
        [] => (0.0, 0.0, 0.0),
        v => (v[0], v[v.len() / 2], v[v.len() - 1]),
    };
    format!(
        "rendering took {total:.2} s of device time (per piece: min {min:.2} s, median \
         {median:.2} s, max {max:.2} s) on {}, {:.1} Mrays",
        c.devices.join(", "),
        c.rays as f64 / 1e6
    )
}
