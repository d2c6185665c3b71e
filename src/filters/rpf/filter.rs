//! One pixel of one RPF iteration: neighbourhood (Alg. 6), dependencies (Alg. 7), weights
//! (eqs. 5.8-5.17) and the cross-bilateral filter of every sample (eqs. 5.2, 5.18).
//!
//! Readings of §5.1.4:
//!
//! * **Which colours.** The mutual information always uses the *original* noisy colours of the
//!   samples in N ("only the original noisy samples are used to calculate the mutual
//!   information"); the features never change. The colours that are averaged (c′_j of eq.
//!   5.18) are the *current* ones, the output of the previous iteration ("the filtered pixel
//!   samples are stored and will become the new samples for the next iteration"). The colour
//!   distance of eq. 5.2 (c̄_i − c̄_j) uses the current colours too, standardised over N like
//!   every other element ([`RangeColors::Current`]); [`RangeColors::Original`] uses the
//!   standardised original colours instead, as the NVIDIA reference implementation does.
//! * **Eq. 5.2 / 5.18.** The weight of neighbour j for sample i is
//!   `exp(−Σ_k α_k (c̄_i,k − c̄_j,k)² / (2σ_c²) − Σ_k β_k (f̄_i,k − f̄_j,k)² / (2σ_f²))` over the
//!   3 colour channels and the 15 features of Table 5.1, both standardised over N; the spatial
//!   term is dropped because N was drawn with the spatial Gaussian (§5.1.2). N contains the
//!   pixel's own samples, sample i included (weight 1), so the denominator of eq. 5.18 is at
//!   least 1. The average is evaluated as `c′_i + Σ_j w_ij (c′_j − c′_i) / Σ_j w_ij` in f64,
//!   which is eq. 5.18 rearranged: a constant image comes out bit for bit constant and huge
//!   colours cannot overflow. Weights are computed in f32; `exp(−d)` for d ≥ 105 is 0 in f32
//!   and is not evaluated.

use super::kernel;
use super::mi::MiWorkspace;
use super::cpu::Level;
use super::preprocess::{self, OffsetTable, PixelRng};
use super::select::{self, FeatureLine, SelectScratch, Selection};
use super::gather::{self, RestLine, ROWS};
use super::samples::{FLOATS_PER_SAMPLE, SampleSet};
use super::weights::{self, COLORS, Dependencies, FEATURES, POSITIONS, RANDOMS, Weights};
use super::{MiBucketing, RangeColors, RpfSettings};
use crate::imaging::RgbImage;
use rayon::prelude::*;

/// Numbers of the mutual-information variables (the 26 elements of Table 5.1): screen
/// position, random parameters, features, colour.
const P0: usize = 0;
const R0: usize = P0 + POSITIONS;
const F0: usize = R0 + RANDOMS;
const C0: usize = F0 + FEATURES;
/// The gathered row of each variable.
const MI_ROWS: [usize; FLOATS_PER_SAMPLE] = {
    let mut rows = [0; FLOATS_PER_SAMPLE];
    let mut v = 0;
    while v < FLOATS_PER_SAMPLE {
        rows[v] = match v {
            _ if v < R0 => gather::P_ROW + v - P0,
            _ if v < F0 => gather::R_ROW + v - R0,
            _ if v < C0 => gather::F_ROW + v - F0,
            _ => gather::C_ROW + v - C0,
        };
        v += 1;
    }
    rows
};
/// The rows standardised over N: the 26 elements and the current colours.
const STANDARDIZED: [usize; FLOATS_PER_SAMPLE + COLORS] = {
    let mut rows = [0; FLOATS_PER_SAMPLE + COLORS];
    let mut k = 0;
    while k < FLOATS_PER_SAMPLE {
        rows[k] = MI_ROWS[k];
        k += 1;
    }
    while k < FLOATS_PER_SAMPLE + COLORS {
        rows[k] = gather::CUR_ROW + k - FLOATS_PER_SAMPLE;
        k += 1;
    }
    rows
};
/// Mutual informations per pixel (Alg. 7): each colour with every random parameter, position
/// and feature; each feature with every random parameter and position.
const MI_PAIR_COUNT: usize =
    COLORS * (RANDOMS + POSITIONS + FEATURES) + FEATURES * (RANDOMS + POSITIONS);
/// The pairs of Alg. 7 in the order `analyze` stores them: per colour its randoms,
/// positions and features, then per feature its randoms and positions.
const MI_PAIRS: [(usize, usize); MI_PAIR_COUNT] = {
    let mut pairs = [(0, 0); MI_PAIR_COUNT];
    let mut p = 0;
    let mut k = 0;
    while k < COLORS {
        let mut l = 0;
        while l < RANDOMS + POSITIONS + FEATURES {
            pairs[p] = match l {
                _ if l < RANDOMS => (C0 + k, R0 + l),
                _ if l < RANDOMS + POSITIONS => (C0 + k, P0 + l - RANDOMS),
                _ => (C0 + k, F0 + l - RANDOMS - POSITIONS),
            };
            p += 1;
            l += 1;
        }
        k += 1;
    }
    while k < COLORS + FEATURES {
        let f = k - COLORS;
        let mut l = 0;
        while l < RANDOMS + POSITIONS {
            pairs[p] = if l < RANDOMS {
                (F0 + f, R0 + l)
            } else {
                (F0 + f, P0 + l - RANDOMS)
            };
            p += 1;
            l += 1;
        }
        k += 1;
    }
    pairs
};

/// Dimensions of the weight of eq. 5.2: 3 colours + 15 features.
const DIMS: usize = COLORS + FEATURES;
const _: () = assert!(DIMS == kernel::MAX_DIMS);

/// Per-iteration constants shared by all pixels.
pub(super) struct Iteration<'a> {
    pub set: &'a SampleSet,
    /// [`FeatureLine::of`] every sample.
    pub lines: &'a [FeatureLine],
    /// [`RestLine::of`] every sample, with the current colours of this iteration.
    pub rest: &'a [RestLine],
    /// The instruction-set level of the inner loops.
    pub level: Level,
    pub settings: &'a RpfSettings,
    /// 0-based iteration index (t of eqs. 5.9 and 5.14).
    pub t: u32,
    pub table: OffsetTable,
    /// M − spp (Alg. 6 line 4).
    pub draws: usize,
    /// σ² of eq. 5.17.
    pub sigma2: f64,
}

impl<'a> Iteration<'a> {
    pub fn new(
        set: &'a SampleSet,
        lines: &'a [FeatureLine],
        rest: &'a [RestLine],
        level: Level,
        settings: &'a RpfSettings,
        t: u32,
        box_size: u32,
    ) -> Self {
        Iteration {
            set,
            lines,
            rest,
            level,
            settings,
            t,
            table: OffsetTable::new(box_size),
            draws: draws(box_size, set.spp, settings.sample_fraction),
            sigma2: weights::base_variance(settings.sigma2_8(), set.spp),
        }
    }
}

/// M − spp: M = ⌊b² · spp · fraction⌋ (§5.1.2) neighbour draws after the pixel's own samples.
pub(super) fn draws(box_size: u32, spp: u32, fraction: f32) -> usize {
    let m = (box_size as f64 * box_size as f64 * spp as f64 * fraction as f64).floor() as usize;
    m.saturating_sub(spp as usize)
}

/// The largest neighbourhood an iteration can collect: the pixel's samples plus the draws, at
/// most every sample in the box.
pub(super) fn max_neighbours(box_size: u32, spp: u32, fraction: f32) -> usize {
    let side = 2 * (box_size as usize / 2) + 1;
    (spp as usize + draws(box_size, spp, fraction)).min(side * side * spp as usize)
}

/// Reusable per-thread buffers (no allocation per pixel once grown).
pub(super) struct Scratch {
    select: SelectScratch,
    indices: Vec<u32>,
    /// `ROWS` rows of `cap` values: the elements of the rest and feature lines ([`gather`]).
    rows: Vec<f32>,
    cap: usize,
    current: Vec<[f32; 3]>,
    /// `DIMS` rows of `cap` scaled, standardised values for the weights.
    dims: Vec<f32>,
    weigh: kernel::WeighScratch,
    mi: MiWorkspace,
}

impl Scratch {
    pub fn new(settings: &RpfSettings, level: Level) -> Scratch {
        Scratch {
            select: SelectScratch::default(),
            indices: Vec::new(),
            rows: Vec::new(),
            cap: 0,
            current: Vec::new(),
            dims: Vec::new(),
            weigh: kernel::WeighScratch::default(),
            mi: match settings.mi_bucketing {
                MiBucketing::Range => MiWorkspace::with_level(settings.mi_buckets, level),
                MiBucketing::Unit => MiWorkspace::unit(level),
            },
        }
    }

    fn ensure(&mut self, n: usize) {
        if n > self.cap {
            // Grow geometrically; the extra 16 floats keep the rows from starting at addresses
            // a power of two apart, which would map all of them to the same cache sets.
            let cap = n.max(self.cap * 3 / 2).next_multiple_of(16) + 16;
            self.rows.resize(ROWS * cap, 0.0);
            self.dims.resize(DIMS * cap, 0.0);
            self.cap = cap;
        }
    }
}

/// What one pixel's filtering found (for statistics and tests).
#[derive(Clone, Debug, PartialEq)]
pub struct PixelInfo {
    /// |N| including the pixel's own samples.
    pub neighbours: usize,
    pub weights: Weights,
}

/// Alg. 6 and Alg. 7 for pixel (x, y): fills `scratch` with N (standardised) and returns the
/// weights.
fn analyze(it: &Iteration<'_>, x: u32, y: u32, scratch: &mut Scratch) -> PixelInfo {
    let set = it.set;
    let s = it.settings;
    let pixel = y as u64 * set.width as u64 + x as u64;
    let mut rng = PixelRng::new(s.seed, pixel, it.t);
    let sel = Selection {
        samples: &set.samples,
        lines: it.lines,
        width: set.width,
        height: set.height,
        spp: set.spp,
        table: &it.table,
        draws: it.draws,
        kappa_world: s.world_position_tolerance as f64,
        kappa_other: s.feature_tolerance as f64,
        floor: s.tolerance_floor as f64,
    };
    select::select(
        &sel,
        it.level,
        x,
        y,
        &mut rng,
        &mut scratch.select,
        &mut scratch.indices,
    );
    let n = scratch.indices.len();
    scratch.ensure(n);
    let cap = scratch.cap;
    gather::gather(
        it.level,
        &scratch.indices,
        (it.lines, it.rest),
        &mut scratch.rows,
        cap,
        &mut scratch.current,
    );
    // Alg. 6 lines 15-18: standardise every element over N.
    preprocess::standardize_rows(it.level, &mut scratch.rows, cap, &STANDARDIZED, n);
    // Alg. 7 on the 26 original elements.
    let mi = &mut scratch.mi;
    mi.load(&scratch.rows, &MI_ROWS, cap, n);
    let mut mi_values = [0.0f64; MI_PAIRS.len()];
    mi.mi_batch(&MI_PAIRS, &mut mi_values);
    let mut values = mi_values.iter().copied();
    let mut d = Dependencies::default();
    for k in 0..COLORS {
        d.color_random[k] = std::array::from_fn(|_| values.next().unwrap_or(0.0));
        d.color_position[k] = std::array::from_fn(|_| values.next().unwrap_or(0.0));
        d.color_feature[k] = std::array::from_fn(|_| values.next().unwrap_or(0.0));
    }
    for k in 0..FEATURES {
        d.feature_random[k] = std::array::from_fn(|_| values.next().unwrap_or(0.0));
        d.feature_position[k] = std::array::from_fn(|_| values.next().unwrap_or(0.0));
    }
    PixelInfo {
        neighbours: n,
        weights: weights::weights(&d, it.t),
    }
}

/// Filters the `spp` samples of pixel (x, y) into `out` (eq. 5.18).
pub(super) fn filter_pixel(
    it: &Iteration<'_>,
    x: u32,
    y: u32,
    scratch: &mut Scratch,
    out: &mut [[f32; 3]],
) -> PixelInfo {
    let info = analyze(it, x, y, scratch);
    let n = info.neighbours;
    let cap = scratch.cap;
    let w = &info.weights;
    // Eqs. 5.15-5.17: 1 / (2σ_c²) = 1 / (2σ_f²).
    let inv = weights::inverse_two_sigma2(w.w_r_c, it.sigma2);
    // Fold α, β and 1/(2σ²) into the coordinates: the exponent of eq. 5.2 becomes a squared
    // distance. Dimensions with a zero factor are left out.
    let color_row = match it.settings.range_colors {
        RangeColors::Current => gather::CUR_ROW,
        RangeColors::Original => gather::C_ROW,
    };
    let mut active = 0;
    let factors = (0..COLORS)
        .map(|k| (color_row + k, w.alpha[k] as f64))
        .chain((0..FEATURES).map(|k| (gather::F_ROW + k, w.beta[k] as f64)));
    for (row, factor) in factors {
        let scale = (factor * inv).sqrt() as f32;
        if !(scale > 0.0 && scale.is_finite()) {
            continue;
        }
        let src = &scratch.rows[row * cap..row * cap + n];
        let dst = &mut scratch.dims[active * cap..active * cap + n];
        for (d, &r) in dst.iter_mut().zip(src) {
            *d = scale * r;
        }
        active += 1;
    }
    let spp = it.set.spp as usize;
    let nb = kernel::Neighbourhood {
        dims: &scratch.dims,
        cap,
        active,
        current: &scratch.current[..n],
    };
    kernel::weigh(it.level, &nb, &mut out[..spp], &mut scratch.weigh);
    info
}

/// The neighbourhood size and weights of one pixel (no filtering).
pub(super) fn analyze_pixel(it: &Iteration<'_>, x: u32, y: u32) -> PixelInfo {
    let mut scratch = Scratch::new(it.settings, it.level);
    analyze(it, x, y, &mut scratch)
}

/// The mean of the 3 × 3 pixels around each pixel (those inside the image), in f64, in row
/// order.
pub(super) fn box3(img: &RgbImage) -> RgbImage {
    let (w, h) = (img.width as i64, img.height as i64);
    let pixels = (0..h * w)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let mut acc = [0.0f64; 3];
            let mut count = 0.0;
            for qy in (y - 1).max(0)..=(y + 1).min(h - 1) {
                for qx in (x - 1).max(0)..=(x + 1).min(w - 1) {
                    let p = img.pixels[(qy * w + qx) as usize];
                    for k in 0..3 {
                        acc[k] += p[k] as f64;
                    }
                    count += 1.0;
                }
            }
            acc.map(|a| (a / count) as f32)
        })
        .collect();
    RgbImage {
        width: img.width,
        height: img.height,
        pixels,
    }
}
