//! Random Parameter Filtering (Sen & Darabi 2012) as thesis ch. 5 describes it: per-sample
//! vectors of screen position, random parameters, scene features and colour (§5.1.1,
//! Table 5.1; [`samples`]), a random neighbourhood per pixel (§5.1.2, Alg. 6;
//! [`preprocess`]), mutual information between the elements (§5.1.3, Alg. 7, eqs. 5.3-5.14;
//! [`mi`], [`weights`]) and a cross-bilateral filter of every sample (§5.1.4, eqs. 5.2,
//! 5.15-5.18; `filter.rs`), over the box sizes 55, 35, 17, 7, each iteration filtering the
//! output of the one before, and a box filter of each pixel's samples at the end.
//!
//! Every reading of a garbled or ambiguous formula is written where it is implemented:
//! Alg. 6 (line 8's acceptance test, the draws, the normalisation) in [`preprocess`], the
//! buckets of Alg. 7 in [`mi`], eqs. 5.4-5.17 in [`weights`], eqs. 5.2 and 5.18 and which
//! colours they use in `filter.rs`.
//!
//! # Host, not OpenCL
//!
//! RPF runs on the host in Rust, in parallel over image rows with rayon. §5.2.3 gives the
//! reasons it does not suit the device, and they hold for us: the neighbourhood N of every
//! pixel is a random, data-dependent subset of up to 12,100 samples (b = 55 at 8 spp) whose
//! size is only known after the acceptance test, so per-work-item memory is unbounded and
//! unpredictable; the samples are gathered from random places (no coalescing); and every
//! pixel builds ~190 joint histograms, which wants private scratch that a GPU work-item does
//! not have. RPF is not meant to be interactive (thesis: 4,000-5,700 s per 512 × 512 frame on
//! one core, Table 5.3), so a multi-threaded host implementation that is simple to check is the
//! better trade. The renderer only has to copy the sample vectors back.
//!
//! # Speed (issue 14: ≤ 40 s per 512 × 512 frame at 8 spp on 2 cores, results unchanged)
//!
//! Per pixel and iteration the work is: ~M random draws (12,100 at b = 55), an acceptance test
//! of every distinct drawn sample, the gather and standardisation of N (~2,400 samples at
//! b = 55 on Cornell diffuse), 26 variables bucketed and ~190 mutual informations, and eq. 5.18
//! for the pixel's samples over N. Each step has a plain path and an AVX-512 path chosen at
//! run time ([`cpu::Level`]); every path gives the same bytes (tests/rpf_levels.rs compares
//! them, and the golden images of the commits that made them fast are bit-identical to
//! before):
//!
//! * draws: 16 at a time on speculation, hashed at their stream positions (`draws.rs`);
//! * acceptance test: exact f32 intervals on 64-byte feature lines, prefetched ([`select`]);
//! * gather: 16 × 16 transposes of the feature and sample lines ([`gather`]);
//! * standardisation: eight rows' f64 sums side by side, each in the plain order
//!   ([`preprocess::standardize_rows`]);
//! * mutual information: buckets as bitsets, joint counts by population count (`bitsets.rs`);
//! * eq. 5.18: the pixel's samples in f64 lanes, glibc's `expf` reproduced bit for bit
//!   ([`kernel`]);
//! * work order: rows of 32-column strips handed out one at a time, so the two threads'
//!   boxes overlap in the shared L3 (`filter_at_level`).
//!
//! Measured side by side on the loaded 2-core build machine: results/README.md ("RPF time per frame").
//!
//! # Determinism
//!
//! The random numbers of a pixel are a counter-based hash of (seed, pixel, iteration)
//! ([`preprocess::PixelRng`]); nothing depends on thread ids or on the order pixels are done
//! in, and each pixel's sums run in a fixed order. The same seed gives the same bytes with any
//! number of threads (tests/rpf.rs) and on any instruction-set level (tests/rpf_levels.rs).
//!
//! # Memory
//!
//! The sample vectors need 26 · 4 · spp · W · H bytes ([`samples::memory_bytes`];
//! [`samples::check_memory`] says before allocating whether they fit and how many spp or rows
//! would). The filter adds two colours and two 64-byte lines per sample (24 + 128 bytes:
//! [`select::FeatureLine`], [`gather::RestLine`]) and, per thread, scratch for the
//! largest neighbourhood (≈ 51 · 4 · 1.5 · M bytes); allocations that fail are errors, not
//! aborts.

mod bitsets;
pub mod cpu;
mod draws;
pub mod gather;
pub mod kernel;
pub mod mi;
pub mod mi_unit;
pub mod preprocess;
mod run;
pub mod select;
pub mod weights;

mod filter;

use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::Auto;
use crate::imaging::RgbImage;
use crate::scene::Setting;
pub use crate::stats::samples::{self, SampleSet, check_memory, memory_bytes};
pub use filter::PixelInfo;
pub use run::{Progress, Rpf, RpfRun, progress_bar_callback};
pub use weights::Weights;

/// σ²_8 of eq. 5.17 for indoor scenes ("noisy").
pub const SIGMA2_8_INDOOR: f32 = 0.02;
/// σ²_8 of eq. 5.17 for outdoor scenes ("less noise").
pub const SIGMA2_8_OUTDOOR: f32 = 0.002;
/// Columns per strip of the work order (see `filter_at_level`).
const STRIP: usize = 32;

/// The box sizes of the four iterations (§5.1.2).
pub const BOX_SIZES: [u32; 4] = [55, 35, 17, 7];

/// σ²_8 of eq. 5.17 for a scene's setting: indoor scenes are noisier.
pub fn sigma2_8_for(setting: Setting) -> f32 {
    match setting {
        Setting::Indoor => SIGMA2_8_INDOOR,
        Setting::Outdoor => SIGMA2_8_OUTDOOR,
    }
}

/// Which colours the range term of eq. 5.2 compares (see `filter.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RangeColors {
    /// The colours of the previous iteration (the default reading).
    Current,
    /// The original noisy colours in every iteration (the NVIDIA reference implementation).
    Original,
}

/// How Alg. 7 buckets a variable (see [`mi`], [`mi_unit`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MiBucketing {
    /// `mi_buckets` equal buckets over the variable's range in N.
    Range,
    /// Peng's: one bucket per standard deviation (the standardised value rounded).
    Unit,
}

crate::filter_settings! {
    /// Parameters of RPF (thesis ch. 5).
    pub struct RpfSettings, flags "rpf-" {
        /// σ²_8 of eq. 5.17 (a variance); auto: from the scene's [render] setting, 0.02
        /// indoors, 0.002 outdoors (§5.1.4).
        pub sigma2_8: Auto<f32> = Auto::Auto,
        /// Seed of the neighbourhood sampling.
        pub seed: u32 = 0,
        /// Box size b of each iteration, largest first (§5.1.2: 55, 35, 17, 7). The box covers
        /// the offsets −⌊b/2⌋..=⌊b/2⌋ (an even b is widened by one); σ_p = b/4.
        pub box_sizes: Vec<u32> = BOX_SIZES.to_vec(),
        /// Histogram buckets per variable for the mutual information (Alg. 7; 2 to 16), as in
        /// the NVIDIA reference implementation.
        pub mi_buckets: usize = 5,
        /// Buckets of Alg. 7: "range" (`mi_buckets` equal buckets over each variable's range
        /// in N) or "unit" (one per standard deviation of the standardised values: Peng's
        /// rounding, the code Sen & Darabi cite; `mi_buckets` is then unused).
        pub mi_bucketing: MiBucketing = MiBucketing::Range,
        /// M = ⌊b² · spp · sample_fraction⌋ samples considered per pixel (§5.1.2: ½).
        pub sample_fraction: f32 = 0.5,
        /// Standard deviations a world position may lie from the pixel's mean (Alg. 6 line 8:
        /// 30).
        pub world_position_tolerance: f32 = 30.0,
        /// Standard deviations a normal or texture value may lie from the mean (Alg. 6 line
        /// 8: 3).
        pub feature_tolerance: f32 = 3.0,
        /// Floor under the tolerance, in feature units (Alg. 6 line 8: 0.1).
        pub tolerance_floor: f32 = 0.1,
        /// Colours of the range term of eq. 5.2: "current" (the previous iteration's) or
        /// "original".
        pub range_colors: RangeColors = RangeColors::Current,
        /// Side of the final box filter in pixels: 1, the mean of each pixel's filtered
        /// samples (§5.1.4); 3, those means box-filtered over 3 × 3 pixels as well (§3.1.1's
        /// box filter, the other reading of "each pixel is box-filtered").
        pub final_box: u32 = 1,
    }
}

impl RpfSettings {
    /// The defaults with σ²_8 for `setting`.
    pub fn for_setting(setting: Setting) -> Self {
        RpfSettings {
            sigma2_8: Auto::Set(sigma2_8_for(setting)),
            ..Default::default()
        }
    }

    /// σ²_8 (auto, before specialisation: the indoor value).
    pub fn sigma2_8(&self) -> f32 {
        self.sigma2_8.or(SIGMA2_8_INDOOR)
    }

    /// Checks every parameter; errors say which and why.
    pub fn validate(&self) -> Result<()> {
        let sigma2_8 = self.sigma2_8();
        if !(sigma2_8 > 0.0 && sigma2_8.is_finite()) {
            bail!(
                "RPF sigma2_8 must be a positive variance (0.02 indoors, 0.002 outdoors), got \
                 {sigma2_8}"
            );
        }
        if self.box_sizes.is_empty() {
            bail!("RPF needs at least one iteration (box sizes 55, 35, 17, 7)");
        }
        if let Some(b) = self.box_sizes.iter().find(|&&b| b == 0 || b > 1023) {
            bail!("RPF box size {b} is out of range (1 to 1023 pixels)");
        }
        if !(2..=mi::MAX_BUCKETS).contains(&self.mi_buckets) {
            bail!(
                "RPF mi_buckets must be 2 to {}, got {}",
                mi::MAX_BUCKETS,
                self.mi_buckets
            );
        }
        if !(self.sample_fraction > 0.0 && self.sample_fraction <= 4.0) {
            bail!(
                "RPF sample_fraction must be in (0, 4], got {}",
                self.sample_fraction
            );
        }
        for (name, v) in [
            ("world_position_tolerance", self.world_position_tolerance),
            ("feature_tolerance", self.feature_tolerance),
        ] {
            if !(v >= 1.0 && v.is_finite()) {
                bail!("RPF {name} must be at least 1 standard deviation, got {v}");
            }
        }
        if !matches!(self.final_box, 1 | 3) {
            bail!(
                "RPF final_box must be 1 (each pixel's samples) or 3 (3 x 3 pixels), got {}",
                self.final_box
            );
        }
        if !(self.tolerance_floor >= 0.0 && self.tolerance_floor.is_finite()) {
            bail!(
                "RPF tolerance_floor must be finite and not negative, got {}",
                self.tolerance_floor
            );
        }
        Ok(())
    }
}

/// Statistics of one iteration.
#[derive(Clone, Debug, PartialEq)]
pub struct IterationStats {
    pub box_size: u32,
    pub time: Duration,
    /// Mean |N| over the pixels (own samples included).
    pub mean_neighbours: f64,
}

/// The filtered image and how each iteration went.
#[derive(Clone, Debug)]
pub struct RpfOutput {
    pub image: RgbImage,
    pub iterations: Vec<IterationStats>,
}

/// Filters `set` with RPF and returns the box-filtered image.
pub fn filter(set: &SampleSet, settings: &RpfSettings) -> Result<RgbImage> {
    Ok(filter_with_progress(set, settings, &|_| {})?.image)
}

/// [`filter`] that reports progress after every image row (from worker threads) and returns
/// per-iteration statistics.
pub fn filter_with_progress(
    set: &SampleSet,
    settings: &RpfSettings,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<RpfOutput> {
    filter_at_level(set, settings, cpu::Level::detect(), progress)
}

/// [`filter_with_progress`] on instruction-set level `level` (one of
/// [`cpu::Level::available`]); every level gives the same bytes (tests/rpf.rs).
pub fn filter_at_level(
    set: &SampleSet,
    settings: &RpfSettings,
    level: cpu::Level,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<RpfOutput> {
    settings.validate()?;
    set.validate().context("RPF input")?;
    let need = working_memory_bytes(set.width, set.height, set.spp, settings);
    if let Some(available) = samples::available_memory_bytes()
        && need > available
    {
        bail!(
            "RPF on {}x{} at {} spp needs {} of working memory besides the samples, but only {} \
             is available",
            set.width,
            set.height,
            set.spp,
            samples::human_bytes(need),
            samples::human_bytes(available)
        );
    }
    let (w, h, spp) = (set.width as usize, set.height as usize, set.spp as usize);
    let count = set.samples.len();
    let lines = feature_lines(set)?;
    let mut rest = rest_lines(set)?;
    let mut current = try_vec(count, "the RPF sample colours")?;
    current.extend(set.samples.iter().map(|s| s.color));
    let mut next = try_vec(count, "the RPF filtered colours")?;
    next.resize(count, [0.0f32; 3]);
    let iterations = settings.box_sizes.len();
    let mut stats = Vec::with_capacity(iterations);
    for (t, &b) in settings.box_sizes.iter().enumerate() {
        let start = Instant::now();
        if t > 0 {
            rest.par_iter_mut()
                .zip(&current)
                .for_each(|(line, &c)| line.set_current(c));
        }
        let it = filter::Iteration::new(set, &lines, &rest, level, settings, t as u32, b);
        let parts_done = AtomicU32::new(0);
        let neighbours = AtomicU64::new(0);
        // Work is handed out in parts, a row of one strip of STRIP columns, strip after
        // strip, from a shared counter: the threads work on neighbouring rows of the same
        // strip, so the samples their boxes read (b rows × (STRIP + b) columns, two 64-byte
        // lines per sample: 4.8 MB at b = 55) stay in the shared L3. Whole rows (a 512-wide
        // box is 29 MB) or rayon's halving split (two boxes half an image apart) overflow it
        // and wait on memory. Each part is written by the one thread that took its number.
        let strips = w.div_ceil(STRIP);
        let mut parts: Vec<Mutex<&mut [[f32; 3]]>> = Vec::with_capacity(strips * h);
        for row in next.chunks_mut(w * spp) {
            parts.extend(row.chunks_mut(STRIP * spp).map(Mutex::new));
        }
        let next_part = AtomicUsize::new(0);
        rayon::broadcast(|_| {
            let mut scratch = filter::Scratch::new(settings, level);
            loop {
                let u = next_part.fetch_add(1, Ordering::Relaxed);
                if u >= strips * h {
                    break;
                }
                let (strip, y) = (u / h, u % h);
                let mut part = parts[y * strips + strip].lock().unwrap_or_else(|e| e.into_inner());
                let x0 = strip * STRIP;
                let mut sum = 0u64;
                for (k, out) in part.chunks_mut(spp).enumerate() {
                    let x = (x0 + k) as u32;
                    let info = filter::filter_pixel(&it, x, y as u32, &mut scratch, out);
                    sum += info.neighbours as u64;
                }
                neighbours.fetch_add(sum, Ordering::Relaxed);
                let done = parts_done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(Progress {
                    iteration: t,
                    iterations,
                    box_size: b,
                    parts_done: done,
                    parts: (strips * h) as u32,
                });
            }
        });
        drop(parts);
        std::mem::swap(&mut current, &mut next);
        stats.push(IterationStats {
            box_size: b,
            time: start.elapsed(),
            mean_neighbours: neighbours.into_inner() as f64 / (w * h) as f64,
        });
    }
    // The box filter of §5.1.4: the mean of each pixel's filtered samples, as c_0 + mean of
    // the differences (exact for constant pixels).
    let pixels = current
        .par_chunks(spp)
        .map(|c| {
            let mut acc = [0.0f64; 3];
            for s in c {
                for k in 0..3 {
                    acc[k] += s[k] as f64 - c[0][k] as f64;
                }
            }
            std::array::from_fn(|k| {
                let v = c[0][k] as f64 + acc[k] / spp as f64;
                v.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32
            })
        })
        .collect();
    let mut image = RgbImage {
        width: set.width,
        height: set.height,
        pixels,
    };
    if settings.final_box == 3 {
        image = filter::box3(&image);
    }
    Ok(RpfOutput {
        image,
        iterations: stats,
    })
}

/// The neighbourhood size and the weights α, β (eqs. 5.8-5.15) RPF computes for pixel (x, y)
/// in iteration `iteration` (0-based, with that iteration's box size), from the original
/// colours. For inspection and tests (it copies the colours of the whole set on every call);
/// the filter itself does not call it.
pub fn analyze_pixel(
    set: &SampleSet,
    settings: &RpfSettings,
    iteration: usize,
    x: u32,
    y: u32,
) -> Result<PixelInfo> {
    settings.validate()?;
    set.validate()?;
    let Some(&b) = settings.box_sizes.get(iteration) else {
        bail!(
            "iteration {iteration} does not exist ({} box sizes)",
            settings.box_sizes.len()
        );
    };
    if x >= set.width || y >= set.height {
        bail!(
            "pixel ({x}, {y}) is outside the {}x{} image",
            set.width,
            set.height
        );
    }
    let lines = feature_lines(set)?;
    let rest = rest_lines(set)?;
    let level = cpu::Level::detect();
    let it = filter::Iteration::new(set, &lines, &rest, level, settings, iteration as u32, b);
    Ok(filter::analyze_pixel(&it, x, y))
}

/// Bytes RPF allocates besides the sample vectors: two colours and two lines per sample
/// plus per-thread scratch for the largest neighbourhood.
pub fn working_memory_bytes(width: u32, height: u32, spp: u32, settings: &RpfSettings) -> u64 {
    let samples = width as u64 * height as u64 * spp as u64;
    let n = settings
        .box_sizes
        .iter()
        .map(|&b| filter::max_neighbours(b, spp, settings.sample_fraction))
        .max()
        .unwrap_or(0) as u64;
    // Scratch rows grow by half again (filter.rs): per neighbour, rows of 32 + 18 + 1 floats,
    // 26 variables' bucket bits (up to 16 buckets: 2 bytes each), a bucket code, a current
    // colour, its index and a candidate index.
    let n = n + n / 2 + 32;
    let per_thread = n * (4 * (gather::ROWS as u64 + 18 + 1) + 26 * 2 + 1 + 12 + 8);
    let lines = std::mem::size_of::<select::FeatureLine>() + std::mem::size_of::<gather::RestLine>();
    samples * (24 + lines as u64)
        + per_thread * rayon::current_num_threads() as u64
}

/// The features of every sample, one cache line each ([`select`]).
fn feature_lines(set: &SampleSet) -> Result<Vec<select::FeatureLine>> {
    lines_of(set, "feature", select::FeatureLine::of)
}

/// The other elements and the current colour of every sample, one cache line each
/// ([`gather`]).
fn rest_lines(set: &SampleSet) -> Result<Vec<gather::RestLine>> {
    lines_of(set, "sample", gather::RestLine::of)
}

fn lines_of<T: Send>(
    set: &SampleSet,
    what: &str,
    of: impl Fn(&crate::layout::SampleVector) -> T + Sync + Send,
) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(set.samples.len()).map_err(|_| {
        anyhow::anyhow!(
            "cannot allocate {} for the RPF {what} lines",
            samples::human_bytes(set.samples.len() as u64 * std::mem::size_of::<T>() as u64)
        )
    })?;
    v.par_extend(set.samples.par_iter().map(of));
    Ok(v)
}

fn try_vec(n: usize, what: &str) -> Result<Vec<[f32; 3]>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        anyhow::anyhow!(
            "cannot allocate {} for {what}",
            samples::human_bytes(n as u64 * 12)
        )
    })?;
    Ok(v)
}
