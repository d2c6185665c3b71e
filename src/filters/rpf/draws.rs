//! The random draws of Alg. 6 lines 4-5 for one pixel: M − spp offsets from the box's rounded
//! Gaussian (redrawn outside the image and at (0, 0)) and a sample number each, marked in a
//! bitset over the box's samples (a repeat marks nothing new: "we ignore it").
//!
//! The draws are a fixed stream of a counter-based generator ([`PixelRng`]), so every path
//! takes the same values in the same order:
//!
//! * generic: one value at a time;
//! * AVX-512, where at least 3 draws in 4 land inside the image (every pixel whose box lies
//!   inside it, where the only redraw is (0, 0), about 1 in 1,200 draws at b = 55, and most
//!   near the border): 16 draws at a time are computed on speculation (their 48 values hashed
//!   at their stream positions, offsets looked up in the alias table by permutes) and the
//!   ones before the first redraw kept; that draw is redone serially and the next 16 start
//!   after it;
//! * AVX-512 elsewhere (boxes cut hard by the border): values hashed and mapped 64 at a time,
//!   which pairs a draw accepts found as one bit mask, and the draws walked through it without
//!   a branch per pair ([`draw_rejecting`]); a table of more than 64 offsets (a box over 63)
//!   consumes such batches serially ([`Stream`]).

use super::cpu::Level;
use super::preprocess::{OffsetTable, PixelRng, mix64};

/// The offsets that keep a draw inside the image: (dx, dy) with x.0 ≤ dx ≤ x.1, y.0 ≤ dy ≤
/// y.1, not (0, 0).
#[derive(Clone, Copy, Debug)]
pub(super) struct Clip {
    pub x: (i32, i32),
    pub y: (i32, i32),
}

/// SplitMix64's increment.
const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// Marks `draws` draws in `visited` (bit key = ((dy + h) · side + dx + h) · spp + s).
pub(super) fn draw(
    level: Level,
    table: &OffsetTable,
    spp: u32,
    draws: usize,
    clip: Clip,
    rng: &mut PixelRng,
    visited: &mut [u64],
) {
    let half = table.half;
    let side = 2 * half as usize + 1;
    let accept = |dx: i32, dy: i32| {
        (clip.x.0..=clip.x.1).contains(&dx)
            && (clip.y.0..=clip.y.1).contains(&dy)
            && (dx != 0 || dy != 0)
    };
    let mut mark = |dx: i32, dy: i32, s: u32| {
        let key = ((dy + half) as usize * side + (dx + half) as usize) * spp as usize + s as usize;
        visited[key / 64] |= 1u64 << (key % 64);
    };
    match level {
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => {
            if let Some(small) = table.small_table() {
                // SAFETY: the CPU has AVX-512 F, DQ, VL, BW (`Level::detect`).
                return unsafe {
                    if mostly_accepted(table, clip) {
                        draw_speculating(table, small, spp, draws, clip, rng, visited)
                    } else {
                        draw_rejecting(table, small, spp, draws, clip, rng, visited)
                    }
                };
            }
            let mut stream = Stream::new(rng);
            for _ in 0..draws {
                let (dx, dy) = loop {
                    let dx = stream.next(table, spp).0;
                    let dy = stream.next(table, spp).0;
                    if accept(dx, dy) {
                        break (dx, dy);
                    }
                };
                mark(dx, dy, stream.next(table, spp).1);
            }
        }
        _ => {
            for _ in 0..draws {
                let (dx, dy) = loop {
                    let dx = table.sample(rng.next_u64());
                    let dy = table.sample(rng.next_u64());
                    if accept(dx, dy) {
                        break (dx, dy);
                    }
                };
                mark(dx, dy, rng.below(spp));
            }
        }
    }
}

/// Whether a draw lands inside `clip` at least 3 times in 4 (so that 16 draws computed on
/// speculation are mostly kept): the box inside the image (only (0, 0) is redrawn) and most
/// pixels near its border.
fn mostly_accepted(table: &OffsetTable, clip: Clip) -> bool {
    let mass = |(lo, hi): (i32, i32)| (lo..=hi).map(|d| table.mass(d)).sum::<f64>();
    mass(clip.x) * mass(clip.y) - table.mass(0).powi(2) >= 0.75
}

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// mix64 of `state + (index + 1) · golden` for the 8 indices `base + offsets`: the values the
/// generator returns at those positions of its stream. `golden_offsets` is `offsets · golden`
/// (mod 2^64, like every product here), so the counter is one broadcast and one addition:
/// `state + (base + 1) · golden + offsets · golden`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq")]
fn hash8(state: u64, base: u64, golden_offsets: __m512i) -> __m512i {
    let start = state.wrapping_add((base + 1).wrapping_mul(GOLDEN));
    let mut z = _mm512_add_epi64(_mm512_set1_epi64(start as i64), golden_offsets);
    z = _mm512_xor_si512(z, _mm512_srli_epi64::<30>(z));
    z = _mm512_mullo_epi64(z, _mm512_set1_epi64(0xbf58_476d_1ce4_e5b9_u64 as i64));
    z = _mm512_xor_si512(z, _mm512_srli_epi64::<27>(z));
    z = _mm512_mullo_epi64(z, _mm512_set1_epi64(0x94d0_49bb_1331_11eb_u64 as i64));
    _mm512_xor_si512(z, _mm512_srli_epi64::<31>(z))
}

/// `((bits >> 32) · m) >> 32` of two halves of 8 values, as 16 u32 lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn scale16(z: [__m512i; 2], m: u32) -> __m512i {
    let m = _mm512_set1_epi64(m as i64);
    let f = |z: __m512i| {
        _mm512_cvtepi64_epi32(_mm512_srli_epi64::<32>(_mm512_mul_epu32(
            _mm512_srli_epi64::<32>(z),
            m,
        )))
    };
    _mm512_inserti64x4::<1>(_mm512_castsi256_si512(f(z[0])), f(z[1]))
}

/// [`OffsetTable::sample`] of 16 values (two halves of 8) with the u32 table.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn offsets16(z: [__m512i; 2], table: &OffsetTable, small: &([u32; 64], [u32; 64])) -> __m512i {
    let n = table.alias_table().0.len() as u32;
    let column = scale16(z, n);
    let low = _mm512_inserti64x4::<1>(
        _mm512_castsi256_si512(_mm512_cvtepi64_epi32(z[0])),
        _mm512_cvtepi64_epi32(z[1]),
    );
    // SAFETY: 64 u32 per table, 16 per load.
    let lookup = |t: &[u32; 64]| unsafe {
        let p = t.as_ptr() as *const __m512i;
        let lower = _mm512_permutex2var_epi32(_mm512_loadu_si512(p), column, _mm512_loadu_si512(p.add(1)));
        let upper = _mm512_permutex2var_epi32(_mm512_loadu_si512(p.add(2)), column, _mm512_loadu_si512(p.add(3)));
        _mm512_mask_blend_epi32(_mm512_test_epi32_mask(column, _mm512_set1_epi32(32)), lower, upper)
    };
    let (keep, alias) = (lookup(&small.0), lookup(&small.1));
    let stay = _mm512_cmplt_epu32_mask(low, keep);
    _mm512_sub_epi32(
        _mm512_mask_blend_epi32(stay, alias, column),
        _mm512_set1_epi32(table.half),
    )
}

/// [`draw`] 16 draws at a time on speculation (module docs), for a `clip` that rejects few.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx512bw")]
fn draw_speculating(
    table: &OffsetTable,
    small: &([u32; 64], [u32; 64]),
    spp: u32,
    draws: usize,
    clip: Clip,
    rng: &mut PixelRng,
    visited: &mut [u64],
) {
    let state = *rng.raw();
    let half = table.half;
    let side = 2 * half + 1;
    let value = |p: u64| mix64(state.wrapping_add((p + 1).wrapping_mul(GOLDEN)));
    // Lane k of draw-value c sits at stream position p + 3k + c (times golden: hash8).
    let lanes = |c: u64, first: u64| {
        let at = |k: u64| ((3 * (first + k) + c).wrapping_mul(GOLDEN)) as i64;
        _mm512_set_epi64(at(7), at(6), at(5), at(4), at(3), at(2), at(1), at(0))
    };
    let offs: [[__m512i; 2]; 3] = std::array::from_fn(|c| [lanes(c as u64, 0), lanes(c as u64, 8)]);
    let mut p = 0u64;
    let mut done = 0usize;
    let mut keys = [0u32; 16];
    while done < draws {
        let want = (draws - done).min(16);
        let z = |c: usize| [hash8(state, p, offs[c][0]), hash8(state, p, offs[c][1])];
        let dx = offsets16(z(0), table, small);
        let dy = offsets16(z(1), table, small);
        let s = scale16(z(2), spp);
        let inside = |v: __m512i, (lo, hi): (i32, i32)| {
            _mm512_cmpge_epi32_mask(v, _mm512_set1_epi32(lo))
                & _mm512_cmple_epi32_mask(v, _mm512_set1_epi32(hi))
        };
        let zero = _mm512_cmpeq_epi32_mask(dx, _mm512_setzero_si512())
            & _mm512_cmpeq_epi32_mask(dy, _mm512_setzero_si512());
        let rejected = !(inside(dx, clip.x) & inside(dy, clip.y)) | zero;
        let clean = (rejected.trailing_zeros() as usize).min(want);
        let h = _mm512_set1_epi32(half);
        let cell = _mm512_add_epi32(
            _mm512_mullo_epi32(_mm512_add_epi32(dy, h), _mm512_set1_epi32(side)),
            _mm512_add_epi32(dx, h),
        );
        let key = _mm512_add_epi32(_mm512_mullo_epi32(cell, _mm512_set1_epi32(spp as i32)), s);
        // SAFETY: 16 u32.
        unsafe { _mm512_storeu_si512(keys.as_mut_ptr() as *mut __m512i, key) };
        let words = visited.as_mut_ptr();
        for &k in &keys[..clean] {
            // SAFETY: an accepted draw's key is below side² · spp ≤ 64 · visited.len()
            // (|dx|, |dy| ≤ half, s < spp), checked in debug builds.
            debug_assert!((k as usize / 64) < visited.len());
            unsafe { *words.add(k as usize / 64) |= 1u64 << (k % 64) };
        }
        done += clean;
        p += 3 * clean as u64;
        if clean < want {
            // Draw `done` was rejected at p, p + 1: redraw serially, then its sample number.
            let (dx, dy) = loop {
                let dx = table.sample(value(p));
                let dy = table.sample(value(p + 1));
                p += 2;
                if (clip.x.0..=clip.x.1).contains(&dx)
                    && (clip.y.0..=clip.y.1).contains(&dy)
                    && (dx != 0 || dy != 0)
                {
                    break (dx, dy);
                }
            };
            let s = (((value(p) >> 32) * spp as u64) >> 32) as u32;
            p += 1;
            let key = (((dy + half) * side + dx + half) as u32 * spp + s) as usize;
            visited[key / 64] |= 1u64 << (key % 64);
            done += 1;
        }
    }
}

/// [`draw`] for a `clip` that rejects many draws (a box cut by the image's border): the
/// stream's values 64 at a time from the current position (offsets and sample numbers as in
/// [`draw_speculating`]), which pairs of them a draw would accept as one bit mask, and the
/// draws walked through it without a branch per pair: a pair at position j accepted marks
/// (dx, dy, s) = values (j, j + 1, j + 2) and moves on by 3, a rejected one by 2 (its key,
/// which is inside the box either way, ORs in nothing). The serial loop's branch on each
/// pair was mispredicted about as often as the border rejects (12-26 ns a draw near the
/// border against 2.3 inside).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx512bw")]
fn draw_rejecting(
    table: &OffsetTable,
    small: &([u32; 64], [u32; 64]),
    spp: u32,
    draws: usize,
    clip: Clip,
    rng: &mut PixelRng,
    visited: &mut [u64],
) {
    let state = *rng.raw();
    let half = table.half;
    let side = 2 * half as usize + 1;
    let golden8 = |first: u64| {
        let at = |k: u64| ((first + k).wrapping_mul(GOLDEN)) as i64;
        _mm512_set_epi64(at(7), at(6), at(5), at(4), at(3), at(2), at(1), at(0))
    };
    let offs: [__m512i; 8] = std::array::from_fn(|k| golden8(8 * k as u64));
    let mut offset = [0i32; 64];
    let mut sample = [0u32; 64];
    let (mut p, mut done) = (0u64, 0usize);
    let words = visited.as_mut_ptr();
    while done < draws {
        // Values p .. p + 63 of the stream.
        let (mut inx, mut iny, mut zero) = (0u64, 0u64, 0u64);
        for q in 0..4 {
            let z = [hash8(state, p, offs[2 * q]), hash8(state, p, offs[2 * q + 1])];
            let o = offsets16(z, table, small);
            let s = scale16(z, spp);
            let inside = |(lo, hi): (i32, i32)| {
                _mm512_cmpge_epi32_mask(o, _mm512_set1_epi32(lo))
                    & _mm512_cmple_epi32_mask(o, _mm512_set1_epi32(hi))
            };
            inx |= (inside(clip.x) as u64) << (16 * q);
            iny |= (inside(clip.y) as u64) << (16 * q);
            zero |= (_mm512_cmpeq_epi32_mask(o, _mm512_setzero_si512()) as u64) << (16 * q);
            // SAFETY: 16 values at 16 q < 64.
            unsafe {
                _mm512_storeu_si512(offset.as_mut_ptr().add(16 * q) as *mut __m512i, o);
                _mm512_storeu_si512(sample.as_mut_ptr().add(16 * q) as *mut __m512i, s);
            }
        }
        // Bit j: the pair (j, j + 1) is a draw the serial loop accepts.
        let accepted = inx & (iny >> 1) & !(zero & (zero >> 1));
        let mut j = 0usize;
        while j + 2 < 64 && done < draws {
            let a = ((accepted >> j) & 1) as usize;
            let (dx, dy, s) = (offset[j], offset[j + 1], sample[j + 2]);
            let key = ((dy + half) as usize * side + (dx + half) as usize) * spp as usize + s as usize;
            // SAFETY: |dx|, |dy| ≤ half and s < spp, so key < side² · spp ≤ 64 · visited.len().
            debug_assert!(key / 64 < visited.len());
            unsafe { *words.add(key / 64) |= (a as u64) << (key % 64) };
            j += 2 + a;
            done += a;
        }
        p += j as u64;
    }
}

/// The random numbers of a pixel, hashed and mapped 64 at a time (AVX-512): value k of the
/// stream is the same as the k-th `rng.next_u64()`, seen as an offset ([`OffsetTable::sample`])
/// and as a sample number (`PixelRng::below(spp)`).
#[cfg(target_arch = "x86_64")]
struct Stream<'r> {
    rng: &'r mut PixelRng,
    offset: [i32; BATCH],
    sample: [u32; BATCH],
    at: usize,
}

#[cfg(target_arch = "x86_64")]
const BATCH: usize = 64;

#[cfg(target_arch = "x86_64")]
impl<'r> Stream<'r> {
    fn new(rng: &'r mut PixelRng) -> Self {
        Stream {
            rng,
            offset: [0; BATCH],
            sample: [0; BATCH],
            at: BATCH,
        }
    }

    #[inline(always)]
    fn next(&mut self, table: &OffsetTable, spp: u32) -> (i32, u32) {
        if self.at == BATCH {
            // SAFETY: only constructed on the AVX-512 path (`Level::detect`).
            unsafe { self.refill(table, spp) };
            self.at = 0;
        }
        let k = self.at;
        self.at += 1;
        (self.offset[k], self.sample[k])
    }

    #[target_feature(enable = "avx512f,avx512dq,avx512vl")]
    fn refill(&mut self, table: &OffsetTable, spp: u32) {
        use std::arch::x86_64::*;
        let (keep, alias) = table.alias_table();
        let state = self.rng.raw();
        const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;
        let lanes = _mm512_set_epi64(8, 7, 6, 5, 4, 3, 2, 1);
        let mut counter = _mm512_add_epi64(
            _mm512_set1_epi64(*state as i64),
            _mm512_mullo_epi64(lanes, _mm512_set1_epi64(GOLDEN as i64)),
        );
        let stride = _mm512_set1_epi64(GOLDEN.wrapping_mul(8) as i64);
        let n = _mm512_set1_epi64(keep.len() as i64);
        let spp = _mm512_set1_epi64(spp as i64);
        let half = _mm256_set1_epi32(table.half);
        let low32 = _mm512_set1_epi64(0xffff_ffff);
        for chunk in 0..BATCH / 8 {
            // mix64 of preprocess.rs, eight lanes.
            let mut z = counter;
            z = _mm512_xor_si512(z, _mm512_srli_epi64::<30>(z));
            z = _mm512_mullo_epi64(z, _mm512_set1_epi64(0xbf58_476d_1ce4_e5b9_u64 as i64));
            z = _mm512_xor_si512(z, _mm512_srli_epi64::<27>(z));
            z = _mm512_mullo_epi64(z, _mm512_set1_epi64(0x94d0_49bb_1331_11eb_u64 as i64));
            z = _mm512_xor_si512(z, _mm512_srli_epi64::<31>(z));
            counter = _mm512_add_epi64(counter, stride);
            // OffsetTable::sample: column = ((bits >> 32) · n) >> 32, kept when the low 32
            // bits are below keep[column], else alias[column].
            let top = _mm512_srli_epi64::<32>(z);
            let column = _mm512_srli_epi64::<32>(_mm512_mul_epu32(top, n));
            // SAFETY: column < keep.len() = alias.len().
            let (kept, other) = unsafe {
                (
                    _mm512_i64gather_epi64::<8>(column, keep.as_ptr() as *const i64),
                    _mm512_i64gather_epi32::<4>(column, alias.as_ptr() as *const i32),
                )
            };
            let stay = _mm512_cmplt_epu64_mask(_mm512_and_si512(z, low32), kept);
            let k = _mm256_mask_blend_epi32(stay, other, _mm512_cvtepi64_epi32(column));
            let offset = _mm256_sub_epi32(k, half);
            // PixelRng::below(spp).
            let s = _mm512_cvtepi64_epi32(_mm512_srli_epi64::<32>(_mm512_mul_epu32(top, spp)));
            // SAFETY: 8 lanes at 8 · chunk < BATCH.
            unsafe {
                _mm256_storeu_si256(self.offset.as_mut_ptr().add(8 * chunk) as *mut __m256i, offset);
                _mm256_storeu_si256(self.sample.as_mut_ptr().add(8 * chunk) as *mut __m256i, s);
            }
        }
        *state = state.wrapping_add(GOLDEN.wrapping_mul(BATCH as u64));
    }
}
