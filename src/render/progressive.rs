//! Progressive rendering (thesis §4.2.3): launches of growing size until the samples or the
//! time are spent, with a progress bar and a hook after every launch (a filter, a viewer).

use std::time::{Duration, Instant};

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};

use super::SplitRenderer;

/// When a progressive render stops.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Samples per pixel to reach.
    pub spp: u32,
    /// Stop after this many seconds even if fewer samples are done.
    pub time_limit: Option<f64>,
}

/// A progress bar for `spp` samples per pixel (hidden when `quiet`).
pub fn progress_bar(spp: u32, quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(spp as u64)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} spp  {msg}  ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// Renders until the budget is spent or `stop()` says so (checked between launches), updating
/// `bar`; `after_frame` runs after each launch. Launch sizes grow towards ~0.5 s per launch:
/// responsive progress, few launches, and well under GPU watchdog limits. The image does not
/// depend on the batching (tests/determinism.rs).
pub fn render_progressively(
    renderer: &mut SplitRenderer,
    budget: Budget,
    bar: &ProgressBar,
    stop: &dyn Fn() -> bool,
    mut after_frame: impl FnMut(&SplitRenderer) -> Result<()>,
) -> Result<()> {
    let start = Instant::now();
    let limit = budget.time_limit.map(Duration::from_secs_f64);
    let spp = budget.spp;
    let mut batch = 1u32;
    while renderer.samples_done() < spp && !stop() {
        if let Some(limit) = limit
            && start.elapsed() >= limit
        {
            break;
        }
        let count = batch.min(spp - renderer.samples_done());
        let stats = renderer.render_samples(count)?;
        after_frame(renderer)?;
        let per_sample = stats.kernel_time.as_secs_f64() / count as f64;
        let mut next = (0.5 / per_sample.max(1e-6)) as u32;
        if let Some(limit) = limit {
            let left = limit.saturating_sub(start.elapsed()).as_secs_f64();
            next = next.min((left / per_sample.max(1e-6)) as u32);
        }
        batch = next.clamp(1, batch.saturating_mul(4).max(1));
        bar.set_position(renderer.samples_done() as u64);
        let secs = renderer.kernel_time_total.as_secs_f64().max(1e-9);
        bar.set_message(format!(
            "{:.2} spp/s  {:.1} Mrays/s",
            renderer.samples_done() as f64 / secs,
            renderer.rays_total as f64 / secs / 1e6
        ));
    }
    bar.finish_and_clear();
    Ok(())
}
