//! The instruction-set paths of the mutual-information workspace ([`super::mi::MiWorkspace`]):
//! bucket bitsets from bucket codes, the fused quantise-into-bitsets of AVX-512, and the joint
//! counts by population count. Every path gives the same integer counts.
//!
//! A bitset may have more words than its values need (the workspace pads them to a multiple
//! of 8, one AVX-512 register); the extra words are 0 and count nothing.

use super::cpu::Level;
use super::mi::MAX_BUCKETS;

// `joint_counts` keeps a variable's populated buckets in a u32 mask.
const _: () = assert!(MAX_BUCKETS <= 32);

/// Two variables' bitsets and bucket counts.
pub(super) struct JointInput<'a> {
    pub mx: &'a [u64],
    pub my: &'a [u64],
    pub cx: &'a [u32],
    pub cy: &'a [u32],
    pub buckets: usize,
    pub words: usize,
}

impl Level {
    /// Bitsets of `codes` (one per bucket, `words` words each) into `masks`.
    pub(super) fn bitsets(self, codes: &[u8], buckets: usize, words: usize, masks: &mut [u64]) {
        for b in 0..buckets {
            masks[b * words + codes.len().div_ceil(64)..(b + 1) * words].fill(0);
        }
        #[cfg(target_arch = "x86_64")]
        if self == Level::Avx512 {
            // SAFETY: the CPU has AVX-512 F and BW (`Level::detect`).
            return unsafe { bitsets_avx512(codes, buckets, words, masks) };
        }
        bitsets_sse2_or_scalar(codes, buckets, words, masks)
    }

    /// The `B × B` joint counts of two variables into `out`.
    pub(super) fn joint_counts(self, input: JointInput<'_>, out: &mut [u32]) {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "popcnt")]
            fn popcnt(input: JointInput<'_>, out: &mut [u32]) {
                joint_counts(input, out)
            }
            #[target_feature(enable = "popcnt,avx512f,avx512vpopcntdq")]
            fn avx512(input: JointInput<'_>, out: &mut [u32]) {
                // A closure inside a function with these features may call another such
                // function safely.
                joint_counts_with(input, out, |a, b| and_count_avx512(a, b))
            }
            match self {
                // SAFETY: `Level::detect` only returns a level whose features the CPU has.
                Level::Avx512 => return unsafe { avx512(input, out) },
                Level::Popcnt => return unsafe { popcnt(input, out) },
                Level::Generic => {}
            }
        }
        joint_counts(input, out)
    }
}

/// Population count of `a & b`, summed over the words.
#[inline(always)]
fn and_count(a: &[u64], b: &[u64]) -> u32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x & y).count_ones())
        .sum()
}

/// [`and_count`] eight words at a time with `vpopcntq`, summed in one register and reduced
/// once (the workspace pads the bitsets to a multiple of 8 words, so the scalar tail is
/// usually empty). Sweeping up to four columns at once, the row loaded once per eight words,
/// measured slower (joint counts 9.6 -> 14.2 % of RPF's profile at 256²).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt,avx512f,avx512vpopcntdq")]
fn and_count_avx512(a: &[u64], b: &[u64]) -> u32 {
    use std::arch::x86_64::*;
    let n = a.len().min(b.len());
    let full = n / 8 * 8;
    let mut acc = _mm512_setzero_si512();
    for w in (0..full).step_by(8) {
        // SAFETY: 8 words at w + 7 < full ≤ both lengths; the loads are unaligned.
        let (x, y) = unsafe {
            (
                _mm512_loadu_si512(a.as_ptr().add(w) as *const __m512i),
                _mm512_loadu_si512(b.as_ptr().add(w) as *const __m512i),
            )
        };
        acc = _mm512_add_epi64(acc, _mm512_popcnt_epi64(_mm512_and_si512(x, y)));
    }
    _mm512_reduce_add_epi64(acc) as u32 + and_count(&a[full..n], &b[full..n])
}

/// The set bits of `m`, lowest first.
#[inline(always)]
fn bits(mut m: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            i
        })
    })
}

/// The joint counts of two variables from their bitsets: the bucket pairs both populated, by
/// population count, except the last populated bucket of each variable, whose counts are what
/// the marginal counts leave. Unpopulated pairs are 0.
#[inline(always)]
fn joint_counts(input: JointInput<'_>, out: &mut [u32]) {
    joint_counts_with(input, out, and_count)
}

/// [`joint_counts`] with the AND-population count `count` ([`and_count`] or a vector form).
#[inline(always)]
fn joint_counts_with(input: JointInput<'_>, out: &mut [u32], count: impl Fn(&[u64], &[u64]) -> u32) {
    let JointInput {
        mx,
        my,
        cx,
        cy,
        buckets: b,
        words,
    } = input;
    out.fill(0);
    // The populated buckets as bit masks (a list built in memory byte by byte and read back
    // whole stalled on store forwarding).
    let populated = |c: &[u32]| {
        c.iter()
            .enumerate()
            .fold(0u32, |m, (i, &n)| m | (u32::from(n > 0) << i))
    };
    let (px, py) = (populated(cx), populated(cy));
    if px == 0 || py == 0 {
        return;
    }
    let (last_a, last_b) = (31 - px.leading_zeros() as usize, 31 - py.leading_zeros() as usize);
    let (rows, cols) = (px & !(1 << last_a), py & !(1 << last_b));
    for a in bits(rows) {
        let ra = &mx[a * words..(a + 1) * words];
        let row = &mut out[a * b..(a + 1) * b];
        let mut rest = cx[a];
        for c in bits(cols) {
            row[c] = count(ra, &my[c * words..(c + 1) * words]);
            rest -= row[c];
        }
        row[last_b] = rest;
    }
    for c in bits(py) {
        let above: u32 = bits(rows).map(|a| out[a * b + c]).sum();
        out[last_a * b + c] = cy[c] - above;
    }
}

/// [`Level::bitsets`] with SSE2 byte compares (x86-64) or one bit at a time.
fn bitsets_sse2_or_scalar(codes: &[u8], buckets: usize, words: usize, masks: &mut [u64]) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of x86-64.
    unsafe {
        bitsets_sse2(codes, buckets, words, masks)
    }
    #[cfg(not(target_arch = "x86_64"))]
    for (w, chunk) in codes.chunks(64).enumerate() {
        for b in 0..buckets {
            masks[b * words + w] = chunk
                .iter()
                .enumerate()
                .fold(0u64, |m, (i, &c)| m | ((c as usize == b) as u64) << i);
        }
    }
}

/// [`Level::bitsets`] with SSE2 compares of 16 bytes into a 16-bit mask.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
fn bitsets_sse2(codes: &[u8], buckets: usize, words: usize, masks: &mut [u64]) {
    use std::arch::x86_64::*;
    for (w, chunk) in codes.chunks(64).enumerate() {
        let full = chunk.len() / 16 * 16;
        for b in 0..buckets {
            let key = _mm_set1_epi8(b as i8);
            let mut m = 0u64;
            for (k, sixteen) in chunk[..full].chunks_exact(16).enumerate() {
                // SAFETY: `sixteen` holds 16 bytes; the load is unaligned.
                let v = unsafe { _mm_loadu_si128(sixteen.as_ptr() as *const __m128i) };
                let bits = _mm_movemask_epi8(_mm_cmpeq_epi8(v, key)) as u16;
                m |= (bits as u64) << (16 * k);
            }
            for (i, &c) in chunk.iter().enumerate().skip(full) {
                m |= ((c as usize == b) as u64) << i;
            }
            masks[b * words + w] = m;
        }
    }
}

/// [`Level::bitsets`] with AVX-512 BW compares of 64 bytes into a 64-bit mask.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
fn bitsets_avx512(codes: &[u8], buckets: usize, words: usize, masks: &mut [u64]) {
    use std::arch::x86_64::*;
    for (w, chunk) in codes.chunks(64).enumerate() {
        // A partial last chunk is read with a mask (the other bytes are 0 and their bits cleared).
        let valid = if chunk.len() == 64 {
            u64::MAX
        } else {
            (1u64 << chunk.len()) - 1
        };
        // SAFETY: the mask only reads the `chunk.len()` bytes that exist.
        let v = unsafe { _mm512_maskz_loadu_epi8(valid, chunk.as_ptr() as *const i8) };
        for b in 0..buckets {
            masks[b * words + w] = _mm512_cmpeq_epi8_mask(v, _mm512_set1_epi8(b as i8)) & valid;
        }
    }
}


impl Level {
    /// Quantises `values` ([`super::mi::quantize`]) straight into bucket bitsets (`masks`,
    /// `words` per bucket) and counts; returns the number of populated buckets, or None where
    /// this level has no fused path or the values' range overflows f32 (the caller then
    /// quantises in two steps).
    pub(super) fn quantize_bitsets(
        self,
        values: &[f32],
        buckets: usize,
        words: usize,
        masks: &mut [u64],
        counts: &mut [u32],
    ) -> Option<usize> {
        #[cfg(target_arch = "x86_64")]
        if self == Level::Avx512 {
            // SAFETY: the CPU has AVX-512 F and VPOPCNTDQ (`Level::detect`).
            return unsafe { quantize_bitsets_avx512(values, buckets, words, masks, counts) };
        }
        let _ = (values, buckets, words, masks, counts);
        None
    }
}

/// [`Level::quantize_bitsets`] on AVX-512: the same f32 operations as `quantize`, 16 lanes
/// wide (min and max do not depend on the order, and `vminps(x, top)` gives `top` for a NaN
/// as `f32::min` does); the buckets of 64 values packed into 64 bytes and compared with each
/// bucket number into one 64-bit word.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,popcnt")]
fn quantize_bitsets_avx512(
    values: &[f32],
    buckets: usize,
    words: usize,
    masks: &mut [u64],
    counts: &mut [u32],
) -> Option<usize> {
    use std::arch::x86_64::*;
    let n = values.len();
    debug_assert!(words >= n.div_ceil(64) && masks.len() == buckets * words);
    // A partial last chunk of 16 is read with a mask; its missing lanes count nowhere.
    let load = |j: usize| {
        let valid = if j + 16 <= n {
            0xffff
        } else {
            (1u32 << (n - j)) as u16 - 1
        };
        // SAFETY: the mask only reads the lanes that exist.
        let v = unsafe { _mm512_maskz_loadu_ps(valid, values.as_ptr().add(j)) };
        (v, valid)
    };
    // min_max: `vminps(v, acc)` returns acc when v is NaN, as `f32::min` ignores a NaN.
    let mut lo = _mm512_set1_ps(f32::INFINITY);
    let mut hi = _mm512_set1_ps(f32::NEG_INFINITY);
    for j in (0..n).step_by(16) {
        let (v, valid) = load(j);
        lo = _mm512_mask_min_ps(lo, valid, v, lo);
        hi = _mm512_mask_max_ps(hi, valid, v, hi);
    }
    let (lo, hi) = (_mm512_reduce_min_ps(lo), _mm512_reduce_max_ps(hi));
    let range = hi - lo;
    let wide = hi as f64 - lo as f64;
    counts[..buckets].fill(0);
    if wide.is_nan() || wide <= 0.0 || wide.is_infinite() {
        masks.fill(0);
        // Every value in bucket 0.
        for (w, m) in masks[..words].iter_mut().enumerate() {
            let left = n.saturating_sub(64 * w);
            *m = if left >= 64 { u64::MAX } else { (1u64 << left) - 1 };
        }
        counts[0] = n as u32;
        return Some(usize::from(n > 0));
    }
    if !range.is_finite() {
        return None;
    }
    let (lo_v, scale, top) = (
        _mm512_set1_ps(lo),
        _mm512_set1_ps(buckets as f32 / range),
        _mm512_set1_ps((buckets - 1) as f32),
    );
    // The words past n are 0; the loop below writes every other word (zeroing all of them
    // first was 1 % of RPF's profile).
    let used = n.div_ceil(64);
    for b in 0..buckets {
        masks[b * words + used..(b + 1) * words].fill(0);
    }
    for w in 0..used {
        // 64 values' buckets as 64 bytes (a missing lane's byte is 0 and its bit cleared).
        let mut codes = _mm512_setzero_si512();
        let mut valid = 0u64;
        for part in 0..4 {
            let j = 64 * w + 16 * part;
            if j >= n {
                break;
            }
            let (v, lanes) = load(j);
            let x = _mm512_min_ps(_mm512_mul_ps(_mm512_sub_ps(v, lo_v), scale), top);
            let bytes = _mm512_castsi128_si512(_mm512_cvtepi32_epi8(_mm512_cvttps_epi32(x)));
            codes = match part {
                0 => _mm512_inserti32x4::<0>(codes, _mm512_castsi512_si128(bytes)),
                1 => _mm512_inserti32x4::<1>(codes, _mm512_castsi512_si128(bytes)),
                2 => _mm512_inserti32x4::<2>(codes, _mm512_castsi512_si128(bytes)),
                _ => _mm512_inserti32x4::<3>(codes, _mm512_castsi512_si128(bytes)),
            };
            valid |= (lanes as u64) << (16 * part);
        }
        for b in 0..buckets {
            let m = _mm512_cmpeq_epi8_mask(codes, _mm512_set1_epi8(b as i8)) & valid;
            masks[b * words + w] = m;
            counts[b] += m.count_ones();
        }
    }
    Some(counts[..buckets].iter().filter(|&&c| c > 0).count())
}
