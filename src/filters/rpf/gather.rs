//! The samples of N gathered into rows (structure of arrays) for Alg. 6 lines 15-18 and
//! Alg. 7. Each sample's 26 elements and current colour live in two 64-byte lines: its
//! [`FeatureLine`] (which the acceptance test has just read, so it is usually in cache) and a
//! [`RestLine`]; on AVX-512 sixteen samples' lines are loaded and transposed 16 × 16 into
//! sixteen rows at once, instead of 29 scattered stores per sample.

use super::cpu::{self, Level};
use super::select::FeatureLine;
use crate::layout::SampleVector;

/// Rows of the gathered N: the 16 elements of the rest line, then the 16 of the feature line.
pub const ROWS: usize = 32;
/// Row of the first screen position, random parameter, original colour and current colour
/// (the rest line's layout).
pub const P_ROW: usize = 0;
pub const R_ROW: usize = 2;
pub const C_ROW: usize = 8;
pub const CUR_ROW: usize = 11;
/// Row of the first scene feature.
pub const F_ROW: usize = 16;

/// A sample's screen position, random parameters, colour and current colour (the output of
/// the previous iteration), and two zeros, in one 64-byte line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
pub struct RestLine(pub [f32; 16]);

impl RestLine {
    pub fn of(s: &SampleVector) -> RestLine {
        let mut line = [0.0; 16];
        line[P_ROW..P_ROW + 2].copy_from_slice(&s.position);
        line[R_ROW..R_ROW + 6].copy_from_slice(&s.random);
        line[C_ROW..C_ROW + 3].copy_from_slice(&s.color);
        line[CUR_ROW..CUR_ROW + 3].copy_from_slice(&s.color);
        RestLine(line)
    }

    pub fn set_current(&mut self, c: [f32; 3]) {
        self.0[CUR_ROW..CUR_ROW + 3].copy_from_slice(&c);
    }

    pub fn current(&self) -> [f32; 3] {
        [self.0[CUR_ROW], self.0[CUR_ROW + 1], self.0[CUR_ROW + 2]]
    }
}

/// Writes element e of sample `indices[j]` to `rows[e * cap + j]` for the [`ROWS`] rows, and
/// the current colours to `current`. `cap` must leave room for a last block of 16:
/// `cap ≥ n` rounded up to 16.
pub fn gather(
    level: Level,
    indices: &[u32],
    lines: (&[FeatureLine], &[RestLine]),
    rows: &mut [f32],
    cap: usize,
    current: &mut Vec<[f32; 3]>,
) {
    let n = indices.len();
    assert!(cap >= n.next_multiple_of(16) && rows.len() >= ROWS * cap);
    current.clear();
    #[cfg(target_arch = "x86_64")]
    if level == Level::Avx512 {
        // SAFETY: the CPU has AVX-512 F (`Level::detect`).
        unsafe { gather_avx512(indices, lines, rows, cap) };
        // The current colours from the gathered rows (in cache), not from the lines: the
        // first read of a neighbour's rest line waits on memory, and the gather prefetches.
        let row = |k: usize| &rows[(CUR_ROW + k) * cap..(CUR_ROW + k) * cap + n];
        current.extend(row(0).iter().zip(row(1)).zip(row(2)).map(|((&r, &g), &b)| [r, g, b]));
        return;
    }
    current.extend(indices.iter().map(|&i| lines.1[i as usize].current()));
    let _ = level;
    let (features, rest) = lines;
    for (j, &i) in indices.iter().enumerate() {
        let i = i as usize;
        for e in 0..16 {
            rows[e * cap + j] = rest[i].0[e];
            rows[(F_ROW + e) * cap + j] = features[i].0[e];
        }
    }
}

/// Blocks of this many samples ahead are prefetched.
const AHEAD: usize = 4;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn gather_avx512(
    indices: &[u32],
    (features, rest): (&[FeatureLine], &[RestLine]),
    rows: &mut [f32],
    cap: usize,
) {
    use std::arch::x86_64::*;
    let zero = [0.0f32; 16];
    for first in (0..indices.len()).step_by(16) {
        for &i in indices.iter().skip(first + 16 * AHEAD).take(16) {
            cpu::prefetch(&rest[i as usize]);
            cpu::prefetch(&features[i as usize]);
        }
        let block = &indices[first..(first + 16).min(indices.len())];
        for (half, base) in [(0, 0), (1, F_ROW)] {
            let line = |k: usize| {
                let i = block[k] as usize;
                let line = if half == 0 { &rest[i].0 } else { &features[i].0 };
                // SAFETY: 16 floats, 64-byte aligned.
                unsafe { _mm512_load_ps(line.as_ptr()) }
            };
            let r: [__m512; 16] = if block.len() == 16 {
                // A whole block with constant indices, so that the lines stay in registers
                // through the transpose (the loop below built them on the stack).
                std::array::from_fn(line)
            } else {
                let mut r = [_mm512_setzero_ps(); 16];
                for (k, rk) in r.iter_mut().enumerate() {
                    // SAFETY: 16 floats.
                    *rk = if k < block.len() { line(k) } else { unsafe { _mm512_loadu_ps(zero.as_ptr()) } };
                }
                r
            };
            let t = transpose16(r);
            for (e, te) in t.iter().enumerate() {
                // SAFETY: row base + e has room for first + 16 ≤ cap values.
                unsafe { _mm512_storeu_ps(rows.as_mut_ptr().add((base + e) * cap + first), *te) };
            }
        }
    }
}

/// The 16 × 16 transpose: element e of input k becomes element k of output e. Stage 1-2
/// transpose the 4 × 4 blocks inside each 128-bit lane, stages 3-4 move the blocks.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn transpose16(r: [std::arch::x86_64::__m512; 16]) -> [std::arch::x86_64::__m512; 16] {
    use std::arch::x86_64::*;
    let mut t = [_mm512_setzero_ps(); 16];
    for k in 0..8 {
        t[2 * k] = _mm512_unpacklo_ps(r[2 * k], r[2 * k + 1]);
        t[2 * k + 1] = _mm512_unpackhi_ps(r[2 * k], r[2 * k + 1]);
    }
    // u[4g + c], 128-bit block b: column 4b + c of rows 4g..4g+3.
    let mut u = [_mm512_setzero_ps(); 16];
    for g in 0..4 {
        let (a, b, c, d) = (t[4 * g], t[4 * g + 1], t[4 * g + 2], t[4 * g + 3]);
        u[4 * g] = _mm512_shuffle_ps::<0x44>(a, c);
        u[4 * g + 1] = _mm512_shuffle_ps::<0xee>(a, c);
        u[4 * g + 2] = _mm512_shuffle_ps::<0x44>(b, d);
        u[4 * g + 3] = _mm512_shuffle_ps::<0xee>(b, d);
    }
    let mut out = [_mm512_setzero_ps(); 16];
    for c in 0..4 {
        let p = _mm512_shuffle_f32x4::<0x88>(u[c], u[4 + c]);
        let q = _mm512_shuffle_f32x4::<0xdd>(u[c], u[4 + c]);
        let p2 = _mm512_shuffle_f32x4::<0x88>(u[8 + c], u[12 + c]);
        let q2 = _mm512_shuffle_f32x4::<0xdd>(u[8 + c], u[12 + c]);
        out[c] = _mm512_shuffle_f32x4::<0x88>(p, p2);
        out[8 + c] = _mm512_shuffle_f32x4::<0xdd>(p, p2);
        out[4 + c] = _mm512_shuffle_f32x4::<0x88>(q, q2);
        out[12 + c] = _mm512_shuffle_f32x4::<0xdd>(q, q2);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_level_gathers_the_same_rows() {
        let n = 37;
        let count = 50;
        let features: Vec<FeatureLine> = (0..count)
            .map(|s| FeatureLine(std::array::from_fn(|e| (s * 100 + e) as f32)))
            .collect();
        let rest: Vec<RestLine> = (0..count)
            .map(|s| RestLine(std::array::from_fn(|e| -((s * 100 + e) as f32))))
            .collect();
        let indices: Vec<u32> = (0..n).map(|j| ((j * 7) % count) as u32).collect();
        let cap = 64;
        for level in Level::available() {
            let mut rows = vec![f32::NAN; ROWS * cap];
            let mut current = Vec::new();
            gather(level, &indices, (&features, &rest), &mut rows, cap, &mut current);
            for (j, &i) in indices.iter().enumerate() {
                let i = i as usize;
                for e in 0..16 {
                    assert_eq!(rows[e * cap + j], rest[i].0[e], "{level:?}");
                    assert_eq!(rows[(F_ROW + e) * cap + j], features[i].0[e], "{level:?}");
                }
                assert_eq!(current[j], rest[i].current());
            }
        }
    }
}
