//! RPF in the filter registry, and its progress reports.

use std::sync::Arc;
use std::time::Instant;

use anyhow::Result;

use super::{RpfSettings, SampleSet, filter, filter_with_progress, sigma2_8_for};
use crate::filters::{Auto, FilterKind, FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::{Output, OutputSet};
use crate::render::{Frame, FrameInfo, SceneInfo};
use crate::scene::Setting;

/// Where a running filter is (for progress bars).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// 0-based iteration.
    pub iteration: usize,
    pub iterations: usize,
    pub box_size: u32,
    /// Parts of this iteration done (a part is a row of one strip of columns).
    pub parts_done: u32,
    pub parts: u32,
}

impl Progress {
    /// Fraction of the whole filter done, weighting iterations by b² (their cost).
    pub fn fraction(&self, box_sizes: &[u32]) -> f64 {
        let cost = |b: &u32| (*b as f64).powi(2);
        let total: f64 = box_sizes.iter().map(cost).sum();
        let before: f64 = box_sizes[..self.iteration.min(box_sizes.len())]
            .iter()
            .map(cost)
            .sum();
        let this = cost(&self.box_size) * self.parts_done as f64 / self.parts.max(1) as f64;
        ((before + this) / total.max(1.0)).min(1.0)
    }
}

/// A progress callback that drives an indicatif bar of length 1000.
pub fn progress_bar_callback(
    bar: &indicatif::ProgressBar,
    box_sizes: &[u32],
) -> impl Fn(Progress) + Sync {
    let bar = bar.clone();
    let sizes = box_sizes.to_vec();
    move |p: Progress| {
        bar.set_position((p.fraction(&sizes) * 1000.0) as u64);
        bar.set_message(format!(
            "RPF iteration {}/{} (box {})",
            p.iteration + 1,
            p.iterations,
            p.box_size
        ));
    }
}

/// RPF in the registry.
pub struct Rpf;

impl FilterKind for Rpf {
    type Settings = RpfSettings;
    const NAME: &'static str = "rpf";
    const SUMMARY: &'static str =
        "Random Parameter Filtering, thesis ch. 5 (on the host; slow, reads every sample)";

    fn check(s: &RpfSettings) -> Result<()> {
        s.validate()
    }

    /// σ²_8 on auto follows the scene's indoor/outdoor setting (§5.1.4).
    fn specialise(s: &mut RpfSettings, scene: &SceneInfo) -> Vec<String> {
        if !s.sigma2_8.is_auto() {
            return Vec::new();
        }
        let v = sigma2_8_for(scene.setting);
        s.sigma2_8 = Auto::Set(v);
        vec![format!(
            "sigma2_8 = {v}: the scene is {} (§5.1.4)",
            match scene.setting {
                Setting::Indoor => "indoors",
                Setting::Outdoor => "outdoors",
            }
        )]
    }

    /// Every sample's vector (§5.1.1).
    fn needs(_: &RpfSettings) -> OutputSet {
        OutputSet::of(&[Output::Samples])
    }

    fn prepare(
        s: &RpfSettings,
        _frame: &FrameInfo,
        _gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        Ok(Box::new(RpfRun {
            settings: s.clone(),
            progress: false,
        }))
    }
}

/// RPF ready to run: it runs on the host, on the frame's sample vectors.
pub struct RpfRun {
    settings: RpfSettings,
    progress: bool,
}

impl PreparedFilter for RpfRun {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        let start = Instant::now();
        frame.require(Rpf::needs(&self.settings), "Random Parameter Filtering")?;
        let set = SampleSet::from_frame(frame, Default::default())?;
        let image = if self.progress {
            let bar = indicatif::ProgressBar::new(1000);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{spinner} {msg:32} [{elapsed_precise}] {bar:30} ETA {eta}",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            let callback = progress_bar_callback(&bar, &self.settings.box_sizes);
            let out = filter_with_progress(&set, &self.settings, &callback);
            bar.finish_and_clear();
            out?.image
        } else {
            filter(&set, &self.settings)?
        };
        Ok(FilterRun {
            image,
            wall_time: start.elapsed(),
            kernel_time: None,
        })
    }

    fn interactive(&self) -> bool {
        false
    }

    fn show_progress(&mut self, on: bool) {
        self.progress = on;
    }
}
