//! Pre-processing (thesis §5.1.2, Algorithm 6): the neighbourhood N of a pixel and its
//! normalisation.
//!
//! Readings of Algorithm 6:
//!
//! * **Line 2, 4-5: which samples are drawn.** N starts with the pixel's own `spp` samples
//!   (in their order, so entry `i < spp` of N is sample `i` of the pixel). Then `M − spp`
//!   draws, `M = ⌊b² · spp · f⌋` with `f` = [`super::RpfSettings::sample_fraction`] (½ in the
//!   thesis: "kernel-width² · (8spp/2)", 12,100 for b = 55 at 8 spp). A draw picks a pixel
//!   offset (dx, dy) from a Gaussian of σ_p = b/4 rounded to whole pixels, *conditioned* on
//!   lying inside the b × b box (|dx|, |dy| ≤ ⌊b/2⌋), inside the image and outside P ("from
//!   sample inside neighborhood but outside P"): such offsets are redrawn, not counted as a
//!   draw. Each axis is drawn from the Gaussian's mass on each whole-pixel cell of the box
//!   (an alias table). Then one of the pixel's `spp` samples is picked
//!   uniformly (§5.1.2: "Then we randomly sample one out of x samples in the pixel").
//! * **Duplicates.** "If a sample gets sampled more than once, we ignore it and continue to
//!   the next sample": a repeated sample uses up its draw and is not added again. N is thus a
//!   set; the acceptance test is a function of the sample alone, so we make all draws first
//!   and then test each drawn sample once, in memory order (same N, cache-friendly reads).
//! * **Line 8, the garbled acceptance test.** Printed as
//!   `|f_j,k − m_p,k| > 3|30 σ_p,k and |f_j,k − m_p,k| > 0.1 or σ_p,k > 0.1`. We read `3|30`
//!   as "3, or 30 for world positions" (§5.1.2: both the first and the second bounce's world
//!   position get 30; normals and texture get 3), and the `and ... or` as
//!   `d > κσ ∧ (d > 0.1 ∨ σ > 0.1)` with `d = |f_j,k − m_p,k|`: the sample is rejected when
//!   any feature is farther than κ standard deviations from the pixel's mean *and* either that
//!   distance or the standard deviation exceeds 0.1. (Reading it as `(… ∧ …) ∨ σ > 0.1` would
//!   reject every neighbour of any pixel with one noisy feature, which cannot be meant.) Since
//!   κ ≥ 1, this is the same as `d > max(κσ, 0.1)`: the 0.1 is a floor under the tolerance, so
//!   a feature that is constant inside the pixel (σ = 0, e.g. the normal of a flat wall) still
//!   accepts neighbours within 0.1 of it. The 0.1 is in scene units, the only place where the
//!   scale of the scene enters RPF (§5.2, Table 5.4).
//! * **Which statistics.** The pixel's mean and standard deviation (line 3) are over its `spp`
//!   samples of the original features, with the population standard deviation (divide by n),
//!   computed in f64.
//! * **Lines 15-18: normalisation.** The printed indentation puts it inside the loop; it is
//!   done once, after N is complete (the text: "After we are done looping over M − x samples,
//!   each sample in N is normalized"). Every element is standardised over N:
//!   `(x − μ_N) / σ_N` (population σ, f64); an element that is the same for every sample of N
//!   (σ_N = 0) becomes 0 for all of them instead of 0/0.

use super::cpu::Level;
use crate::layout::SampleVector;

/// Number of scene features (Table 5.1): world1, normal1, world2, normal2, texture1.
pub const FEATURES: usize = 15;

/// The 15 scene features of a sample, in the order world1, normal1, world2, normal2, texture1.
#[inline]
pub fn features(s: &SampleVector) -> [f32; FEATURES] {
    let mut f = [0.0; FEATURES];
    f[0..3].copy_from_slice(&s.world1);
    f[3..6].copy_from_slice(&s.normal1);
    f[6..9].copy_from_slice(&s.world2);
    f[9..12].copy_from_slice(&s.normal2);
    f[12..15].copy_from_slice(&s.texture1);
    f
}

/// Whether feature `k` (order of [`features`]) is a world position (tolerance 30σ, not 3σ).
#[inline]
pub fn is_world_position(k: usize) -> bool {
    k < 3 || (6..9).contains(&k)
}

/// Counter-based random numbers for one pixel in one iteration: a SplitMix64 stream whose
/// start is a hash of (seed, pixel, iteration). No state is shared between pixels, so the
/// neighbourhoods do not depend on the number of threads or the order pixels are filtered in.
#[derive(Clone, Debug)]
pub struct PixelRng(u64);

/// SplitMix64's output function.
#[inline]
pub(super) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl PixelRng {
    pub fn new(seed: u32, pixel: u64, iteration: u32) -> PixelRng {
        let a = mix64(seed as u64 ^ 0x5250_465f_7365_6564); // "RPF_seed"
        let b = mix64(a ^ pixel.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        PixelRng(mix64(b ^ ((iteration as u64) << 32 | 0x6974)))
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.0)
    }

    /// The counter, for generators that compute many values of the stream at once (value k
    /// after this is `mix64(counter + k · golden)`, k = 1, 2, ...).
    pub(super) fn raw(&mut self) -> &mut u64 {
        &mut self.0
    }

    /// Uniform in [0, 1) with 53 random bits.
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform integer in [0, n), n ≥ 1 (multiply-shift, bias below 2⁻³²).
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * n as u64) >> 32) as u32
    }
}

/// The distribution of one axis of a pixel offset: a Gaussian of σ_p = b/4 rounded to whole
/// pixels, over the box's offsets −h..=h (h = ⌊b/2⌋). Each cell's mass is integrated with
/// Simpson's rule; offsets are drawn in constant time from Walker's alias table.
#[derive(Clone, Debug)]
pub struct OffsetTable {
    pub half: i32,
    pub sigma: f64,
    /// Normalised mass of offset k − half.
    mass: Vec<f64>,
    /// Alias table: column k keeps itself when the 32-bit uniform is below `keep[k]`, else
    /// gives `alias[k]`.
    keep: Vec<u64>,
    alias: Vec<u32>,
    /// The table in u32 for at most 64 offsets (boxes up to 63): keep clamped to u32::MAX,
    /// which changes nothing because a column that keeps itself always (2^32) is its own
    /// alias.
    small: Option<([u32; 64], [u32; 64])>,
}

impl OffsetTable {
    pub fn new(box_size: u32) -> OffsetTable {
        let half = (box_size / 2) as i32;
        let sigma = box_size as f64 / 4.0;
        let g = |t: f64| (-t * t / (2.0 * sigma * sigma)).exp();
        let mut mass: Vec<f64> = (-half..=half)
            .map(|d| {
                const STEPS: usize = 32;
                let (a, h) = (d as f64 - 0.5, 1.0 / STEPS as f64);
                let mut s = g(a) + g(a + 1.0);
                for i in 1..STEPS {
                    s += g(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
                }
                s * h / 3.0
            })
            .collect();
        let total: f64 = mass.iter().sum();
        mass.iter_mut().for_each(|m| *m /= total);
        // Vose's construction, deterministic.
        let n = mass.len();
        let mut scaled: Vec<f64> = mass.iter().map(|m| m * n as f64).collect();
        let mut keep = vec![1u64 << 32; n];
        let mut alias: Vec<u32> = (0..n as u32).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&k| scaled[k] < 1.0);
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            keep[s] = (scaled[s] * (1u64 << 32) as f64) as u64;
            alias[s] = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        let small = (n <= 64).then(|| {
            let mut k32 = [0u32; 64];
            let mut a32 = [0u32; 64];
            for k in 0..n {
                debug_assert!(keep[k] < 1 << 32 || alias[k] == k as u32);
                k32[k] = keep[k].min(u32::MAX as u64) as u32;
                a32[k] = alias[k];
            }
            (k32, a32)
        });
        OffsetTable {
            half,
            sigma,
            mass,
            small,
            keep,
            alias,
        }
    }

    /// The alias table: `(keep, alias)` of [`Self::sample`].
    pub(super) fn alias_table(&self) -> (&[u64], &[u32]) {
        (&self.keep, &self.alias)
    }

    /// [`Self::alias_table`] in u32 for at most 64 offsets.
    pub(super) fn small_table(&self) -> Option<&([u32; 64], [u32; 64])> {
        self.small.as_ref()
    }

    /// Mass of offset `d` (normalised over the box).
    pub fn mass(&self, d: i32) -> f64 {
        self.mass[(d + self.half) as usize]
    }

    /// An offset in −half..=half from 64 random bits.
    #[inline]
    pub fn sample(&self, bits: u64) -> i32 {
        let n = self.keep.len() as u64;
        let column = ((bits >> 32) * n) >> 32;
        let k = if (bits & 0xffff_ffff) < self.keep[column as usize] {
            column as u32
        } else {
            self.alias[column as usize]
        };
        k as i32 - self.half
    }
}

/// The acceptance test of Alg. 6 line 8 for one pixel: per feature, the pixel's mean and the
/// tolerance max(κσ, floor) (see the module docs for the reading).
#[derive(Clone, Debug)]
pub struct FeatureGate {
    pub mean: [f64; FEATURES],
    pub sigma: [f64; FEATURES],
    pub kappa: [f64; FEATURES],
    pub floor: f64,
}

impl FeatureGate {
    /// Mean and population standard deviation of the features of `pixel`'s samples.
    pub fn new(pixel: &[SampleVector], kappa_world: f64, kappa_other: f64, floor: f64) -> Self {
        let n = pixel.len().max(1) as f64;
        let mut mean = [0.0f64; FEATURES];
        for s in pixel {
            for (m, f) in mean.iter_mut().zip(features(s)) {
                *m += f as f64;
            }
        }
        mean.iter_mut().for_each(|m| *m /= n);
        let mut var = [0.0f64; FEATURES];
        for s in pixel {
            for (k, f) in features(s).into_iter().enumerate() {
                let d = f as f64 - mean[k];
                var[k] += d * d;
            }
        }
        let sigma = var.map(|v| (v / n).sqrt());
        let kappa = std::array::from_fn(|k| {
            if is_world_position(k) {
                kappa_world
            } else {
                kappa_other
            }
        });
        FeatureGate {
            mean,
            sigma,
            kappa,
            floor,
        }
    }

    /// Alg. 6 lines 6-11: false ("flag ← 0") when some feature k has
    /// `d > κσ ∧ (d > floor ∨ σ > floor)`.
    #[inline]
    pub fn accepts(&self, s: &SampleVector) -> bool {
        for (k, f) in features(s).into_iter().enumerate() {
            let d = (f as f64 - self.mean[k]).abs();
            let sigma = self.sigma[k];
            if d > self.kappa[k] * sigma && (d > self.floor || sigma > self.floor) {
                return false;
            }
        }
        true
    }
}

/// Sum in f64 over four fixed lanes (a fixed order, so deterministic, but not one long chain).
fn sum_f64(values: &[f32], f: impl Fn(f64) -> f64) -> f64 {
    let mut acc = [0.0f64; 4];
    let mut chunks = values.chunks_exact(4);
    for c in &mut chunks {
        for k in 0..4 {
            acc[k] += f(c[k] as f64);
        }
    }
    for &v in chunks.remainder() {
        acc[0] += f(v as f64);
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// Standardises `values` in place over its samples (Alg. 6 lines 15-18): `(x − μ) / σ` with the
/// population σ, computed in f64; every value becomes 0 when σ = 0. Returns (μ, σ).
pub fn standardize(values: &mut [f32]) -> (f64, f64) {
    let n = values.len();
    if n == 0 {
        return (0.0, 0.0);
    }
    let mean = sum_f64(values, |v| v) / n as f64;
    let var = sum_f64(values, |v| (v - mean) * (v - mean)) / n as f64;
    let sigma = var.sqrt();
    if sigma > 0.0 && sigma.is_finite() {
        let inv = 1.0 / sigma;
        for v in values.iter_mut() {
            *v = ((*v as f64 - mean) * inv) as f32;
        }
    } else {
        values.fill(0.0);
    }
    (mean, sigma)
}

/// [`standardize`] for the rows `which` of `n` values, `rows[r * cap..][..n]`. On AVX-512 the
/// rows go [`GROUP`] at a time: each row's sums keep [`sum_f64`]'s four lanes and order (so the
/// bytes are the same), and the rows' chains run side by side instead of one waiting on the
/// next addition.
pub fn standardize_rows(level: Level, rows: &mut [f32], cap: usize, which: &[usize], n: usize) {
    assert!(n <= cap && which.iter().all(|&r| rows.len() >= (r + 1) * cap));
    #[cfg(target_arch = "x86_64")]
    if level == Level::Avx512 {
        // SAFETY: the CPU has AVX-512 F (`Level::detect`).
        return unsafe { standardize_rows_avx512(rows, cap, which, n) };
    }
    let _ = level;
    for &r in which {
        standardize(&mut rows[r * cap..r * cap + n]);
    }
}

/// Rows standardised side by side: eight four-lane chains keep the adder busy through its
/// latency (four left the mean pass waiting on it).
#[cfg(target_arch = "x86_64")]
const GROUP: usize = 8;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn standardize_rows_avx512(rows: &mut [f32], cap: usize, which: &[usize], n: usize) {
    use std::arch::x86_64::*;
    if n == 0 {
        return;
    }
    let (chunks, nf) = (n / 4, n as f64);
    // Σ f(v) over row r with sum_f64's lanes: four lanes over whole chunks of 4, the rest
    // added to lane 0 in order, then (l0 + l1) + (l2 + l3).
    let sums = |rows: &[f32], group: [usize; GROUP], mean: [f64; GROUP], square: bool| {
        let mut acc = [_mm256_setzero_pd(); GROUP];
        let means = mean.map(|m| _mm256_set1_pd(m));
        for c in 0..chunks {
            for k in 0..GROUP {
                // SAFETY: 4 values at 4c + 3 < n ≤ cap in row group[k].
                let x = unsafe { _mm_loadu_ps(rows.as_ptr().add(group[k] * cap + 4 * c)) };
                let mut v = _mm256_cvtps_pd(x);
                if square {
                    let t = _mm256_sub_pd(v, means[k]);
                    v = _mm256_mul_pd(t, t);
                }
                acc[k] = _mm256_add_pd(acc[k], v);
            }
        }
        std::array::from_fn::<f64, GROUP, _>(|k| {
            let mut lanes = [0.0f64; 4];
            // SAFETY: 4 doubles.
            unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), acc[k]) };
            for &v in &rows[group[k] * cap + 4 * chunks..group[k] * cap + n] {
                let v = v as f64;
                lanes[0] += if square { (v - mean[k]) * (v - mean[k]) } else { v };
            }
            (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
        })
    };
    let count = which.len();
    for first in (0..count).step_by(GROUP) {
        // A last group of fewer than GROUP rows repeats its last row (computed, not stored
        // twice).
        let group: [usize; GROUP] = std::array::from_fn(|k| which[(first + k).min(count - 1)]);
        let mean = sums(rows, group, [0.0; GROUP], false).map(|s| s / nf);
        let var = sums(rows, group, mean, true).map(|s| s / nf);
        for k in 0..(count - first).min(GROUP) {
            let row = &mut rows[group[k] * cap..group[k] * cap + n];
            let sigma = var[k].sqrt();
            if !(sigma > 0.0 && sigma.is_finite()) {
                row.fill(0.0);
                continue;
            }
            let (m, inv) = (_mm512_set1_pd(mean[k]), _mm512_set1_pd(1.0 / sigma));
            let mut eights = row.chunks_exact_mut(8);
            for e in &mut eights {
                // SAFETY: 8 floats, unaligned.
                unsafe {
                    let x = _mm512_cvtps_pd(_mm256_loadu_ps(e.as_ptr()));
                    let y = _mm512_cvtpd_ps(_mm512_mul_pd(_mm512_sub_pd(x, m), inv));
                    _mm256_storeu_ps(e.as_mut_ptr(), y);
                }
            }
            for v in eights.into_remainder() {
                *v = ((*v as f64 - mean[k]) * (1.0 / sigma)) as f32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_table_is_a_rounded_gaussian() {
        let t = OffsetTable::new(55);
        assert_eq!(t.half, 27);
        // Centre cell over the box's mass: erf(0.5 / (13.75 √2)) / erf(27.5 / (13.75 √2)).
        let expected = 0.029008 / 0.954500;
        assert!((t.mass(0) - expected).abs() < 1e-5, "{}", t.mass(0));
        assert!((t.mass(-5) - t.mass(5)).abs() < 1e-12);
        assert!(((-27..=27).map(|d| t.mass(d)).sum::<f64>() - 1.0).abs() < 1e-12);
        // The alias table reproduces the masses: sweep the 64-bit inputs evenly.
        for b in [1, 3, 7, 17, 55] {
            let t = OffsetTable::new(b);
            let h = t.half;
            let mut counts = vec![0u64; 2 * h as usize + 1];
            let steps = 1u64 << 20;
            let mut rng = PixelRng::new(1, 2, 3);
            for _ in 0..steps {
                let d = t.sample(rng.next_u64());
                assert!((-h..=h).contains(&d));
                counts[(d + h) as usize] += 1;
            }
            for d in -h..=h {
                let p = counts[(d + h) as usize] as f64 / steps as f64;
                let sd = (t.mass(d) / steps as f64).sqrt();
                assert!(
                    (p - t.mass(d)).abs() < 6.0 * sd + 1e-9,
                    "b {b} d {d}: {p} vs {}",
                    t.mass(d)
                );
            }
        }
    }

    #[test]
    fn standardize_constant_is_zero() {
        let mut v = [5.0f32; 7];
        assert_eq!(standardize(&mut v), (5.0, 0.0));
        assert_eq!(v, [0.0; 7]);
        let mut v = [1.0f32, 3.0];
        standardize(&mut v);
        assert_eq!(v, [-1.0, 1.0]);
    }
}
