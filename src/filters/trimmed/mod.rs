//! α-trimmed means of each pixel's samples, the robust-estimator baselines of DeCoro 2009
//! §5.2 (after Lee & Redner [53]) that the path-density filter is measured against: "the upper
//! and lower α order statistics of samples are discarded, and the location parameter
//! estimated as the mean of the remaining samples"; the median is the 0.5-trimmed mean. The
//! seed shows them losing energy on the ceiling and on specular highlights and shifting the
//! colour of a two-light scene: they are baselines that fail, kept to show that they do.
//!
//! Choices: samples are ordered by luminance (Rec. 709 Y) and trimmed whole, so a kept sample
//! keeps its colour (per-channel order statistics would mix channels of different samples);
//! ⌊α·n⌋ samples go from each end; α ≥ 0.5 is the median (the mean of the middle two for an
//! even count); samples whose colour is not finite are dropped first, and a pixel without any
//! finite sample is black. Ties in luminance keep the sample order (a stable sort), so the
//! result does not depend on anything but the samples.
//!
//! It runs on the host: a sort of each pixel's few samples is plain Rust and the filter is
//! only a baseline (it has no kernel, so nothing to compare).

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, bail};
use rayon::prelude::*;

use super::{FilterKind, FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::layout::SampleVector;
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::render::{Frame, FrameInfo};

crate::filter_settings! {
    /// The α-trimmed mean's parameter.
    pub struct TrimmedSettings, flags "trim-" {
        /// α in [0, 0.5]: the fraction of samples dropped from each end of the luminance
        /// order (the seed: 0.1, 0.01; 0.5 is the median).
        pub alpha: f64 = 0.1,
    }
}

/// Rec. 709 luminance, the order of the samples.
fn luminance(c: &[f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The α-trimmed mean of the colours `samples` (see the module docs).
pub fn trimmed_mean(samples: &[[f32; 3]], alpha: f64) -> [f32; 3] {
    let mut v: Vec<[f32; 3]> = samples
        .iter()
        .copied()
        .filter(|c| c.iter().all(|x| x.is_finite()))
        .collect();
    let n = v.len();
    if n == 0 {
        return [0.0; 3];
    }
    v.sort_by(|a, b| luminance(a).total_cmp(&luminance(b)));
    let (lo, hi) = if alpha >= 0.5 {
        ((n - 1) / 2, n / 2 + 1)
    } else {
        let t = (alpha * n as f64).floor() as usize;
        (t, n - t)
    };
    let kept = &v[lo..hi];
    let mut sum = [0.0f64; 3];
    for c in kept {
        for k in 0..3 {
            sum[k] += c[k] as f64;
        }
    }
    sum.map(|s| (s / kept.len() as f64) as f32)
}

/// The α-trimmed means of every pixel of a frame's stored samples.
pub fn filter(frame: &Frame, alpha: f64) -> Result<RgbImage> {
    frame.require(OutputSet::of(&[Output::Samples]), "the trimmed-mean filter")?;
    let info = frame.info();
    let (stored, capacity) = (
        info.samples_stored() as usize,
        info.sample_capacity as usize,
    );
    let all: &[SampleVector] = frame.host_slice(BufferId::SampleVectors)?;
    let pixels = all
        .par_chunks(capacity.max(1))
        .map(|px| {
            let colours: Vec<[f32; 3]> = px[..stored].iter().map(|s| s.color).collect();
            trimmed_mean(&colours, alpha)
        })
        .collect();
    Ok(RgbImage {
        width: info.width,
        height: info.height,
        pixels,
    })
}

/// The α-trimmed mean in the registry.
pub struct Trimmed;

impl FilterKind for Trimmed {
    type Settings = TrimmedSettings;
    const NAME: &'static str = "trimmed-mean";
    const SUMMARY: &'static str =
        "the α-trimmed mean of each pixel's samples (DeCoro 2009 §5.2 baseline; α 0.5: median)";

    fn check(s: &TrimmedSettings) -> Result<()> {
        if !(0.0..=0.5).contains(&s.alpha) {
            bail!(
                "the trimmed-mean alpha must be in [0, 0.5] (0.5: the median), got {}",
                s.alpha
            );
        }
        Ok(())
    }

    fn needs(_: &TrimmedSettings) -> OutputSet {
        OutputSet::of(&[Output::Samples])
    }

    fn prepare(
        s: &TrimmedSettings,
        _: &FrameInfo,
        _: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        Ok(Box::new(s.clone()))
    }
}

impl PreparedFilter for TrimmedSettings {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        let start = Instant::now();
        let image = filter(frame, self.alpha)?;
        Ok(FilterRun {
            image,
            wall_time: start.elapsed(),
            kernel_time: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trims_by_luminance_and_the_median_is_the_middle() {
        let s = |v: f32| [v, v, v];
        let samples: Vec<[f32; 3]> = (0..10).map(|i| s(i as f32)).collect();
        // α = 0.1 of 10 drops one from each end: the mean of 1..=8.
        assert_eq!(trimmed_mean(&samples, 0.1), s(4.5));
        // α = 0.01 of 10 drops nothing.
        assert_eq!(trimmed_mean(&samples, 0.01), s(4.5));
        let mut odd = samples.clone();
        odd.push(s(1000.0));
        assert_eq!(trimmed_mean(&odd, 0.5), s(5.0));
        assert_eq!(trimmed_mean(&samples, 0.5), s(4.5));
        // A firefly is gone with α = 0.1 and kept with α = 0.
        let mut firefly = vec![s(1.0); 9];
        firefly.push(s(1000.0));
        assert_eq!(trimmed_mean(&firefly, 0.1), s(1.0));
        assert!(trimmed_mean(&firefly, 0.0)[0] > 100.0);
        // Non-finite samples are dropped; none left is black.
        assert_eq!(trimmed_mean(&[s(f32::NAN), s(2.0)], 0.0), s(2.0));
        assert_eq!(trimmed_mean(&[s(f32::INFINITY)], 0.5), [0.0; 3]);
        // One sample: itself, whatever α.
        assert_eq!(trimmed_mean(&[[1.0, 2.0, 3.0]], 0.5), [1.0, 2.0, 3.0]);
    }
}
