//! Alg. 6 lines 1-14, the neighbourhood N of a pixel, fast: the same N as [`select_plain`],
//! the direct transcription of the readings in [`super::preprocess`], which the tests compare
//! it with.
//!
//! Where the time went (perf, one thread, a 160² crop of Cornell diffuse at 8 spp): 42 % of
//! RPF in the plain selection, for ~12,100 draws per pixel at b = 55 of which ~2,200 samples
//! end in N. Three changes, none of which changes N:
//!
//! * **The acceptance test as intervals.** Line 8 rejects a sample when some feature has
//!   `d > κσ ∧ (d > floor ∨ σ > floor)`, d = |f − m| in f64. For fixed m, σ, κ and floor the
//!   rejected values of f are those below some f32 `lo` or above some f32 `hi` (d grows with
//!   |f − m| and f64 rounding keeps that order), so the test becomes two f32 comparisons per
//!   feature, one AVX-512 comparison pair for all 15. [`Gate::new`] finds `lo` and `hi` by
//!   stepping one f32 at a time from m ∓ the tolerance with the f64 test itself, so they are
//!   exact; a pixel with a non-finite statistic keeps the f64 test.
//! * **The features of every sample in one cache line** ([`FeatureLine`]): the test reads one
//!   line per candidate instead of the two a 104-byte sample vector spans, and the candidates
//!   are prefetched (their indices are known before the first test).
//! * **The random numbers in batches** (AVX-512): the draws of a pixel are a fixed stream of a
//!   counter-based generator, so 64 values at a time are hashed and mapped through the alias
//!   table eight lanes wide; the loop that consumes them (redraws included) stays serial and
//!   takes them in the same order.

use super::cpu::Level;
use super::draws;
use super::preprocess::{FEATURES, FeatureGate, OffsetTable, PixelRng, features};
use crate::layout::SampleVector;

/// The 15 scene features of one sample and a 0, in one 64-byte line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
pub struct FeatureLine(pub [f32; 16]);

impl FeatureLine {
    pub fn of(s: &SampleVector) -> FeatureLine {
        let mut line = [0.0; 16];
        line[..FEATURES].copy_from_slice(&features(s));
        FeatureLine(line)
    }
}

/// What [`select`] needs besides the pixel.
pub struct Selection<'a> {
    pub samples: &'a [SampleVector],
    /// [`FeatureLine::of`] every sample (only [`select`] reads them).
    pub lines: &'a [FeatureLine],
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub table: &'a OffsetTable,
    /// Draws after the pixel's own samples: M − spp.
    pub draws: usize,
    pub kappa_world: f64,
    pub kappa_other: f64,
    pub floor: f64,
}

/// The acceptance test of one pixel: feature k passes when `lo[k] ≤ f ≤ hi[k]` (a NaN passes,
/// as its d is NaN and `NaN > x` is false); `exact` when some bound could not be derived.
#[derive(Clone, Debug)]
pub struct Gate {
    pub lo: [f32; 16],
    pub hi: [f32; 16],
    pub exact: Option<FeatureGate>,
}

impl Gate {
    pub fn new(g: FeatureGate) -> Gate {
        let mut lo = [f32::NEG_INFINITY; 16];
        let mut hi = [f32::INFINITY; 16];
        for k in 0..FEATURES {
            match bounds(g.mean[k], g.kappa[k] * g.sigma[k], g.sigma[k], g.floor) {
                Some((l, h)) => (lo[k], hi[k]) = (l, h),
                None => {
                    return Gate {
                        lo,
                        hi,
                        exact: Some(g),
                    };
                }
            }
        }
        Gate {
            lo,
            hi,
            exact: None,
        }
    }

    /// Whether the sample with these features passes (scalar).
    #[inline]
    pub fn accepts(&self, line: &FeatureLine, sample: &SampleVector) -> bool {
        if let Some(g) = &self.exact {
            return g.accepts(sample);
        }
        !line
            .0
            .iter()
            .zip(self.lo.iter().zip(&self.hi))
            .any(|(&f, (&lo, &hi))| f < lo || f > hi)
    }
}

/// The f32 interval [lo, hi] of the values f with `!(d > a ∧ (d > floor ∨ σ > floor))`,
/// d = |f − mean| in f64 and a = κσ; an empty interval (lo > hi) when no f32 passes; None when
/// a parameter is not finite (the caller keeps the f64 test).
fn bounds(mean: f64, a: f64, sigma: f64, floor: f64) -> Option<(f32, f32)> {
    if !(mean.is_finite() && a.is_finite() && sigma.is_finite() && floor.is_finite()) {
        return None;
    }
    let c = mean as f32;
    if !c.is_finite() {
        return None;
    }
    let pass = |f: f32| {
        let d = (f as f64 - mean).abs();
        !(d > a && (d > floor || sigma > floor))
    };
    // d is smallest at the f32 values next to the mean; none passes: nothing does.
    let Some(start) = [c, c.next_up(), c.next_down()].into_iter().find(|&f| pass(f)) else {
        return Some((f32::INFINITY, f32::NEG_INFINITY));
    };
    // The tolerance: reject iff d > t (module docs of preprocess). Each bound is searched
    // from a guess (m ± t rounded to f32) over the f32 values in order, galloping, then
    // bisecting; every probe is checked with `pass`, so the bounds are exact whatever the
    // guess (near 0 one f64 rounding step can span millions of f32 values).
    let t = if sigma > floor { a } else { a.max(floor) };
    let hi = last_passing(&pass, start, 1, mean + t);
    let lo = last_passing(&pass, start, -1, mean - t);
    Some((lo, hi))
}

/// An f32's place in the order of the finite f32 values (−0 and +0 share 0).
fn key(f: f32) -> i64 {
    let bits = f.to_bits();
    if bits >> 31 == 1 {
        -((bits & 0x7fff_ffff) as i64)
    } else {
        bits as i64
    }
}

fn from_key(k: i64) -> f32 {
    if k < 0 {
        f32::from_bits((-k) as u32 | 0x8000_0000)
    } else {
        f32::from_bits(k as u32)
    }
}

/// The last f32 from `start` (which passes) in direction `dir` (±1) that passes, for a
/// predicate that passes up to some point and fails after it, probing first near `guess`.
fn last_passing(pass: &impl Fn(f32) -> bool, start: f32, dir: i64, guess: f64) -> f32 {
    let end = key(if dir > 0 { f32::MAX } else { -f32::MAX });
    let beyond = |k: i64| (k - key(start)) * dir;
    // `good` passes, `bad` fails (None: nothing found to fail yet); both gallop from the
    // guess, so a guess a few values off costs a few probes.
    let mut good = key(start);
    let mut bad = None;
    let g = key((guess as f32).clamp(-f32::MAX, f32::MAX));
    let mut step = 1i64;
    if beyond(g) > 0 {
        if pass(from_key(g)) {
            good = g;
        } else {
            bad = Some(g);
            loop {
                let k = g - dir * step;
                if beyond(k) <= 0 {
                    break;
                }
                if pass(from_key(k)) {
                    good = k;
                    break;
                }
                bad = Some(k);
                step *= 2;
            }
        }
    }
    step = 1;
    while bad.is_none() && good != end {
        let k = if (end - good) * dir <= step {
            end
        } else {
            good + dir * step
        };
        if pass(from_key(k)) {
            good = k;
            step *= 2;
        } else {
            bad = Some(k);
        }
    }
    if let Some(mut bad) = bad {
        while (bad - good).abs() > 1 {
            let mid = good + (bad - good) / 2;
            if pass(from_key(mid)) {
                good = mid;
            } else {
                bad = mid;
            }
        }
    }
    from_key(good)
}

/// Reusable buffers of [`select`].
#[derive(Default)]
pub struct SelectScratch {
    visited: Vec<u64>,
    candidates: Vec<u32>,
}

/// Alg. 6 lines 1-14: fills `out` with the sample indices of N: the pixel's own samples first,
/// then the accepted neighbours in memory order. The same N as [`select_plain`].
#[allow(clippy::too_many_arguments)]
pub fn select(
    sel: &Selection<'_>,
    level: Level,
    x: u32,
    y: u32,
    rng: &mut PixelRng,
    scratch: &mut SelectScratch,
    out: &mut Vec<u32>,
) {
    let spp = sel.spp as usize;
    let (w, h) = (sel.width as i64, sel.height as i64);
    let pixel = y as usize * sel.width as usize + x as usize;
    let first = pixel * spp;
    out.clear();
    out.extend((first..first + spp).map(|i| i as u32));
    let half = sel.table.half;
    let (xlo, xhi) = ((-half).max(-(x as i32)), half.min(w as i32 - 1 - x as i32));
    let (ylo, yhi) = ((-half).max(-(y as i32)), half.min(h as i32 - 1 - y as i32));
    if (xlo == 0 && xhi == 0 && ylo == 0 && yhi == 0) || sel.draws == 0 {
        return; // no pixel in the box but P itself
    }
    let side = 2 * half as usize + 1;
    let visited = &mut scratch.visited;
    visited.clear();
    // One word more than the keys need: the AVX-512 walk reads 16 keys from any bit, two
    // words at a time.
    visited.resize((side * side * spp).div_ceil(64) + 1, 0);
    let clip = draws::Clip {
        x: (xlo, xhi),
        y: (ylo, yhi),
    };
    draws::draw(level, sel.table, sel.spp, sel.draws, clip, rng, visited);
    // The drawn samples in key order, which is memory order: key = (row · side + column) ·
    // spp + s, so the sample index is key + row · (w − side) · spp + the box's first sample.
    let walk = BoxWalk {
        side,
        spp,
        base: ((y as i64 - half as i64) * w + (x as i64 - half as i64)) * spp as i64,
        step: (w - side as i64) * spp as i64,
    };
    let candidates = &mut scratch.candidates;
    candidates.clear();
    #[cfg(target_arch = "x86_64")]
    if level == Level::Avx512 {
        // SAFETY: the CPU has AVX-512 F and POPCNT (`Level::detect`).
        unsafe { walk.candidates_avx512(visited, candidates) };
    } else {
        walk.candidates(visited, candidates);
    }
    #[cfg(not(target_arch = "x86_64"))]
    walk.candidates(visited, candidates);
    let gate = Gate::new(FeatureGate::new(
        &sel.samples[first..first + spp],
        sel.kappa_world,
        sel.kappa_other,
        sel.floor,
    ));
    test_candidates(sel, level, &gate, candidates, out);
}

/// The box's keys (bits of `visited`) as sample indices: key k of box row r is sample
/// `base + r · step + k`.
struct BoxWalk {
    side: usize,
    spp: usize,
    base: i64,
    step: i64,
}

impl BoxWalk {
    /// The set keys' samples, in key order, one bit at a time.
    fn candidates(&self, visited: &[u64], out: &mut Vec<u32>) {
        let row_keys = (self.side * self.spp) as i64;
        let (mut row, mut row_end) = (0i64, row_keys);
        for (word, &bits) in visited.iter().enumerate() {
            let mut bits = bits;
            while bits != 0 {
                let key = (word * 64) as i64 + bits.trailing_zeros() as i64;
                bits &= bits - 1;
                while key >= row_end {
                    row += 1;
                    row_end += row_keys;
                }
                out.push((self.base + key + row * self.step) as u32);
            }
        }
    }

    /// [`Self::candidates`] 16 keys at a time: per box row, the 16 bits from each key on are
    /// a mask that compresses the 16 consecutive sample indices (a register compress and a
    /// full store: a compressing store to memory is microcoded on AMD's Zen 4).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,popcnt")]
    fn candidates_avx512(&self, visited: &[u64], out: &mut Vec<u32>) {
        use std::arch::x86_64::*;
        let row_keys = self.side * self.spp;
        // 16 slack values for the last full store.
        out.reserve(self.side * row_keys + 16);
        assert!(visited.len() * 64 >= self.side * row_keys + 64);
        let iota = _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0);
        let dst = out.as_mut_ptr();
        let mut len = out.len();
        for row in 0..self.side {
            let first = row * row_keys;
            let offset = self.base + row as i64 * self.step;
            for k in (first..first + row_keys).step_by(16) {
                let (word, shift) = (k / 64, k % 64);
                // SAFETY: word + 1 < visited.len() (the assertion: k < side · row_keys).
                let pair = unsafe {
                    (*visited.get_unchecked(word) as u128)
                        | ((*visited.get_unchecked(word + 1) as u128) << 64)
                };
                let keep = (first + row_keys - k).min(16);
                let bits = (pair >> shift) as u32 & ((1u32 << keep) - 1);
                if bits == 0 {
                    continue;
                }
                let mask = bits as __mmask16;
                let index = _mm512_add_epi32(_mm512_set1_epi32((offset + k as i64) as i32), iota);
                // SAFETY: len + 16 ≤ capacity: at most side · row_keys values are written
                // before this store, and 16 of slack were reserved.
                unsafe {
                    _mm512_storeu_si512(
                        dst.add(len) as *mut __m512i,
                        _mm512_maskz_compress_epi32(mask, index),
                    )
                };
                len += bits.count_ones() as usize;
            }
        }
        // SAFETY: the first `len` values were written above (or were there before).
        unsafe { out.set_len(len) };
    }
}

/// Appends the candidates that pass the gate to `out`, in order.
fn test_candidates(
    sel: &Selection<'_>,
    level: Level,
    gate: &Gate,
    candidates: &[u32],
    out: &mut Vec<u32>,
) {
    #[cfg(target_arch = "x86_64")]
    if level == Level::Avx512 && gate.exact.is_none() {
        // SAFETY: the CPU has AVX-512 F (`Level::detect`).
        return unsafe { test_avx512(sel.lines, gate, candidates, out) };
    }
    let _ = level;
    out.extend(candidates.iter().copied().filter(|&i| {
        let i = i as usize;
        gate.accepts(&sel.lines[i], &sel.samples[i])
    }));
}

/// How far ahead the candidates' feature lines are prefetched.
const PREFETCH: usize = 32;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn test_avx512(lines: &[FeatureLine], gate: &Gate, candidates: &[u32], out: &mut Vec<u32>) {
    use std::arch::x86_64::*;
    // SAFETY: `lo`/`hi` hold 16 floats; the loads are unaligned.
    let (lo, hi) = unsafe {
        (
            _mm512_loadu_ps(gate.lo.as_ptr()),
            _mm512_loadu_ps(gate.hi.as_ptr()),
        )
    };
    out.reserve(candidates.len());
    let dst = out.as_mut_ptr();
    let mut len = out.len();
    for (k, &i) in candidates.iter().enumerate() {
        if let Some(&ahead) = candidates.get(k + PREFETCH) {
            let p = &lines[ahead as usize] as *const FeatureLine as *const i8;
            // A prefetch is only a hint: it cannot fault.
            _mm_prefetch::<_MM_HINT_T0>(p);
        }
        let line = &lines[i as usize];
        // SAFETY: a FeatureLine is 16 floats, 64-byte aligned.
        let f = unsafe { _mm512_load_ps(line.0.as_ptr()) };
        // Ordered, non-signalling compares: false for NaN, as f < lo and f > hi are.
        let out_of = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(f, lo) | _mm512_cmp_ps_mask::<_CMP_GT_OQ>(f, hi);
        // Without a branch (whether a neighbour passes is hard to predict): write the index
        // and keep it by advancing the length.
        // SAFETY: len < out.len() + candidates.len() ≤ capacity.
        unsafe { dst.add(len).write(i) };
        len += usize::from(out_of == 0);
    }
    // SAFETY: the first `len` values are written.
    unsafe { out.set_len(len) };
}

/// Alg. 6 lines 1-14 as [`super::preprocess`] reads them, plainly: the reference for
/// [`select`]. `visited` is scratch for the duplicate test (resized and cleared here).
pub fn select_plain(
    sel: &Selection<'_>,
    x: u32,
    y: u32,
    rng: &mut PixelRng,
    visited: &mut Vec<u64>,
    out: &mut Vec<u32>,
) {
    let spp = sel.spp as usize;
    let pixel = y as usize * sel.width as usize + x as usize;
    let first = pixel * spp;
    out.clear();
    out.extend((first..first + spp).map(|i| i as u32));
    let half = sel.table.half;
    let (xlo, xhi) = (
        (-half).max(-(x as i32)),
        half.min(sel.width as i32 - 1 - x as i32),
    );
    let (ylo, yhi) = (
        (-half).max(-(y as i32)),
        half.min(sel.height as i32 - 1 - y as i32),
    );
    if (xlo == 0 && xhi == 0 && ylo == 0 && yhi == 0) || sel.draws == 0 {
        return;
    }
    let gate = FeatureGate::new(
        &sel.samples[first..first + spp],
        sel.kappa_world,
        sel.kappa_other,
        sel.floor,
    );
    let side = 2 * half as usize + 1;
    let words = (side * side * spp).div_ceil(64);
    visited.clear();
    visited.resize(words, 0);
    // Draw first, marking each drawn sample in `visited` (a repeat sets a bit that is already
    // set: "we ignore it"); then test every drawn sample once, in memory order, which gives
    // the same set N as testing them in the order drawn but reads the samples row by row.
    for _ in 0..sel.draws {
        // Offsets outside the image and (0, 0) are drawn again (conditioning the Gaussian on
        // the box minus P inside the image). The box minus P holds a pixel of the image here,
        // and every offset of the box has a positive mass, so this ends.
        let (dx, dy) = loop {
            let dx = sel.table.sample(rng.next_u64());
            let dy = sel.table.sample(rng.next_u64());
            if (xlo..=xhi).contains(&dx) && (ylo..=yhi).contains(&dy) && (dx != 0 || dy != 0) {
                break (dx, dy);
            }
        };
        let s = rng.below(sel.spp) as usize;
        let key = ((dy + half) as usize * side + (dx + half) as usize) * spp + s;
        visited[key / 64] |= 1u64 << (key % 64);
    }
    for (word, &bits) in visited.iter().enumerate() {
        let mut bits = bits;
        while bits != 0 {
            let key = word * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let (cell, s) = (key / spp, key % spp);
            let dy = (cell / side) as i32 - half;
            let dx = (cell % side) as i32 - half;
            let q = (y as i32 + dy) as usize * sel.width as usize + (x as i32 + dx) as usize;
            let index = q * spp + s;
            if gate.accepts(&sel.samples[index]) {
                out.push(index as u32);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The f32 bounds agree with the f64 test of Alg. 6 line 8 on the values around them and
    /// on random values, for means and spreads of every scale, σ above and below the floor,
    /// and σ = 0.
    #[test]
    fn bounds_are_the_f64_test() {
        let mut state = 3u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut rejected = 0;
        for case in 0..4000 {
            let mean = (next() - 0.5) * 10f64.powi(case % 13 - 6);
            let sigma = match case % 4 {
                0 => 0.0,
                1 => 0.05 * next(),
                _ => next() * 10f64.powi(case % 7 - 3),
            };
            let kappa = if case % 2 == 0 { 3.0 } else { 30.0 };
            let floor = 0.1;
            let pass = |f: f32| {
                let d = (f as f64 - mean).abs();
                !(d > kappa * sigma && (d > floor || sigma > floor))
            };
            let (lo, hi) = bounds(mean, kappa * sigma, sigma, floor).unwrap();
            let mut check = |f: f32| {
                let fast = !(f < lo || f > hi);
                assert_eq!(fast, pass(f), "mean {mean}, σ {sigma}, κ {kappa}, f {f}");
                rejected += usize::from(!fast);
            };
            for edge in [lo, hi] {
                let mut f = edge;
                for _ in 0..4 {
                    f = f.next_down();
                }
                for _ in 0..9 {
                    check(f);
                    f = f.next_up();
                }
            }
            for _ in 0..50 {
                let t = 4.0 * (next() - 0.5);
                check((mean + t * (kappa * sigma).max(floor)) as f32);
            }
        }
        assert!(rejected > 10_000, "{rejected}");
        assert_eq!(bounds(f64::NAN, 1.0, 1.0, 0.1), None);
        assert_eq!(bounds(1e300, 1.0, 1.0, 0.1), None);
    }
}
