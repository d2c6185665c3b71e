//! Eq. 5.18 for the samples of one pixel: the weights of eq. 5.2 from the scaled, standardised
//! coordinates and the weighted mean of the neighbours' current colours (the readings are in
//! `filter.rs`). [`weigh_plain`] is the reference; [`weigh`] picks the AVX-512 path where the
//! CPU has it, which gives the same bytes:
//!
//! * lanes are the pixel's own samples i (eight f64 lanes), so each lane's sums over the
//!   neighbours j run in the reference's order, with separate multiplications and additions
//!   (no fused multiply-add where the reference has none);
//! * `exp` is glibc's `expf` (the algorithm of Szabolcs Nagy in ARM's optimized-routines, used
//!   by glibc since 2.28 and by musl) as glibc's x86-64 FMA variant computes it: a 32-entry
//!   table of 2^(i/32), a degree-3 polynomial in f64 with the same fused operations, rounded
//!   to f32. On a CPU with AVX-512 glibc runs that variant for `f32::exp`, so the weights are
//!   bit for bit those of the reference; the unit tests compare the two over the inputs that
//!   occur (−105 < x ≤ 0).

use super::cpu::Level;

/// Most coordinates per sample: 3 colours and 15 features (eq. 5.2).
pub(super) const MAX_DIMS: usize = 18;

/// exp(−d) is 0 in f32 from here on; such neighbours are skipped.
pub(super) const EXP_CUTOFF: f32 = 105.0;

/// What [`weigh`] reads: `active` rows of `cap` coordinates (N's samples in columns, the
/// pixel's own samples first) and the current colour of every sample of N.
pub(super) struct Neighbourhood<'a> {
    pub dims: &'a [f32],
    pub cap: usize,
    pub active: usize,
    pub current: &'a [[f32; 3]],
}

/// Reusable buffers of [`weigh`].
#[derive(Default)]
pub(super) struct WeighScratch {
    /// The plain path's distances to every neighbour.
    dist: Vec<f32>,
    /// The AVX-512 path's neighbour colours in f64.
    colours: Vec<f64>,
}

/// Filters the first `out.len()` samples of N (eq. 5.18) into `out`.
pub(super) fn weigh(
    level: Level,
    nb: &Neighbourhood<'_>,
    out: &mut [[f32; 3]],
    scratch: &mut WeighScratch,
) {
    assert!(nb.active <= MAX_DIMS && nb.current.len() <= nb.cap && out.len() <= nb.current.len());
    #[cfg(target_arch = "x86_64")]
    if level == Level::Avx512 {
        // SAFETY: the CPU has AVX-512 F, VL and FMA (`Level::detect`).
        return unsafe { weigh_avx512(nb, out, &mut scratch.colours) };
    }
    let _ = level;
    weigh_plain(nb, out, &mut scratch.dist)
}

/// The reference: one sample i at a time, the squared distances to every j accumulated
/// dimension by dimension, then `c′_i + Σ_j w_ij (c′_j − c′_i) / Σ_j w_ij` in f64.
pub(super) fn weigh_plain(nb: &Neighbourhood<'_>, out: &mut [[f32; 3]], dist: &mut Vec<f32>) {
    let n = nb.current.len();
    dist.resize(n, 0.0);
    for (i, o) in out.iter_mut().enumerate() {
        dist.fill(0.0);
        for a in 0..nb.active {
            let row = &nb.dims[a * nb.cap..a * nb.cap + n];
            let centre = row[i];
            for (d, &v) in dist.iter_mut().zip(row) {
                let t = v - centre;
                *d += t * t;
            }
        }
        let ci = nb.current[i];
        let mut sum_w = 0.0f64;
        let mut acc = [0.0f64; 3];
        for (d, cj) in dist.iter().zip(nb.current) {
            if *d >= EXP_CUTOFF {
                continue;
            }
            let wij = (-*d).exp() as f64;
            sum_w += wij;
            for k in 0..3 {
                acc[k] += wij * (cj[k] as f64 - ci[k] as f64);
            }
        }
        *o = finish(ci, sum_w, acc);
    }
}

/// `c′_i + acc / Σw`, clamped to the f32 range (sum_w ≥ 1: sample i is in N at distance 0).
#[inline]
fn finish(ci: [f32; 3], sum_w: f64, acc: [f64; 3]) -> [f32; 3] {
    std::array::from_fn(|k| {
        let v = ci[k] as f64 + acc[k] / sum_w;
        v.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32
    })
}

/// 2^(i/32) as bits, minus i << 47 (glibc's `__exp2f_data.tab`; the test checks each entry
/// against 2^(i/32)).
const EXP2_TABLE: [u64; 32] = [
    0x3ff0000000000000, 0x3fefd9b0d3158574, 0x3fefb5586cf9890f, 0x3fef9301d0125b51,
    0x3fef72b83c7d517b, 0x3fef54873168b9aa, 0x3fef387a6e756238, 0x3fef1e9df51fdee1,
    0x3fef06fe0a31b715, 0x3feef1a7373aa9cb, 0x3feedea64c123422, 0x3feece086061892d,
    0x3feebfdad5362a27, 0x3feeb42b569d4f82, 0x3feeab07dd485429, 0x3feea47eb03a5585,
    0x3feea09e667f3bcd, 0x3fee9f75e8ec5f74, 0x3feea11473eb0187, 0x3feea589994cce13,
    0x3feeace5422aa0db, 0x3feeb737b0cdc5e5, 0x3feec49182a3f090, 0x3feed503b23e255d,
    0x3feee89f995ad3ad, 0x3feeff76f2fb5e47, 0x3fef199bdd85529c, 0x3fef3720dcef9069,
    0x3fef5818dcfba487, 0x3fef7c97337b9b5f, 0x3fefa4afa2a490da, 0x3fefd0765b6e4540,
];
/// 32 / ln 2.
const INV_LN2_N: f64 = f64::from_bits(0x40471547652b82fe);
/// 1.5 · 2^52: adding it rounds to an integer in the low bits.
const SHIFT: f64 = f64::from_bits(0x4338000000000000);
/// The polynomial: 2^(r/32) ≈ 1 + C2 r + C1 r² + C0 r³.
const C0: f64 = f64::from_bits(0x3ebc6af84b912394);
const C1: f64 = f64::from_bits(0x3f2ebfce50fac4f3);
const C2: f64 = f64::from_bits(0x3f962e42ff0c52d6);
/// Below log(2^−150) glibc returns 0 without the polynomial (`__math_uflowf`) ...
const UNDERFLOW: f32 = f32::from_bits(0xc2cff1b4);
/// ... and below log(2^−149) the smallest subnormal, 2^−149 (`__math_may_uflowf`).
const MAY_UNDERFLOW: f32 = f32::from_bits(0xc2ce8ecf);

/// glibc's `expf` as its FMA variant computes it, for finite x ≤ 0 (scalar; the tests use it
/// to check the algorithm, the filter calls `f32::exp` or the vector form).
pub fn expf_glibc_fma(x: f32) -> f32 {
    if x < UNDERFLOW {
        return 0.0;
    }
    if x < MAY_UNDERFLOW {
        return f32::from_bits(1);
    }
    let xd = x as f64;
    let kd = INV_LN2_N.mul_add(xd, SHIFT);
    let ki = kd.to_bits();
    let kd = kd - SHIFT;
    let r = INV_LN2_N.mul_add(xd, -kd);
    let t = EXP2_TABLE[(ki % 32) as usize].wrapping_add(ki << 47);
    let s = f64::from_bits(t);
    let z = C0.mul_add(r, C1);
    let r2 = r * r;
    let y = r.mul_add(C2, 1.0);
    let y = z.mul_add(r2, y);
    (y * s) as f32
}

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// [`expf_glibc_fma`] on eight lanes of finite x ≤ 0.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,fma")]
fn expf8(x: __m256) -> __m512d {
    let xd = _mm512_cvtps_pd(x);
    let inv = _mm512_set1_pd(INV_LN2_N);
    let shift = _mm512_set1_pd(SHIFT);
    let kd = _mm512_fmadd_pd(inv, xd, shift);
    let ki = _mm512_castpd_si512(kd);
    let kd = _mm512_sub_pd(kd, shift);
    let r = _mm512_fmsub_pd(inv, xd, kd);
    // The table in two halves of 16 entries: bits 0-3 of ki pick the entry, bit 4 the half.
    // SAFETY: 8 entries per load, from a 32-entry table.
    let t = unsafe {
        let p = EXP2_TABLE.as_ptr() as *const __m512i;
        let (t0, t1, t2, t3) = (
            _mm512_loadu_si512(p),
            _mm512_loadu_si512(p.add(1)),
            _mm512_loadu_si512(p.add(2)),
            _mm512_loadu_si512(p.add(3)),
        );
        let low = _mm512_permutex2var_epi64(t0, ki, t1);
        let high = _mm512_permutex2var_epi64(t2, ki, t3);
        let upper = _mm512_test_epi64_mask(ki, _mm512_set1_epi64(16));
        _mm512_mask_blend_epi64(upper, low, high)
    };
    let s = _mm512_castsi512_pd(_mm512_add_epi64(t, _mm512_slli_epi64::<47>(ki)));
    let z = _mm512_fmadd_pd(_mm512_set1_pd(C0), r, _mm512_set1_pd(C1));
    let r2 = _mm512_mul_pd(r, r);
    let y = _mm512_fmadd_pd(r, _mm512_set1_pd(C2), _mm512_set1_pd(1.0));
    let y = _mm512_fmadd_pd(z, r2, y);
    let e = _mm512_cvtpd_ps(_mm512_mul_pd(y, s));
    let tiny = _mm256_cmp_ps_mask::<_CMP_LT_OQ>(x, _mm256_set1_ps(MAY_UNDERFLOW));
    let zero = _mm256_cmp_ps_mask::<_CMP_LT_OQ>(x, _mm256_set1_ps(UNDERFLOW));
    let e = _mm256_mask_mov_ps(e, tiny, _mm256_set1_ps(f32::from_bits(1)));
    _mm512_cvtps_pd(_mm256_mask_mov_ps(e, zero, _mm256_setzero_ps()))
}

/// [`weigh_plain`] with the pixel's samples in lanes (module docs).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,fma")]
fn weigh_avx512(nb: &Neighbourhood<'_>, out: &mut [[f32; 3]], wide: &mut Vec<f64>) {
    let n = nb.current.len();
    let (cap, active) = (nb.cap, nb.active);
    // The neighbours' colours in f64 once, not once per lane group and neighbour.
    // (A plain loop over the flat floats: `flat_map` over the triples called a closure per
    // colour, 2 % of RPF's profile.)
    wide.clear();
    wide.resize(3 * n, 0.0);
    for (w, &c) in wide.iter_mut().zip(nb.current.as_flattened()) {
        *w = f64::from(c);
    }
    let wide = &wide[..];
    for first in (0..out.len()).step_by(8) {
        let lanes = (out.len() - first).min(8);
        let valid = ((1u32 << lanes) - 1) as u8;
        let mut centres = [_mm256_setzero_ps(); MAX_DIMS];
        for (a, c) in centres[..active].iter_mut().enumerate() {
            // SAFETY: `lanes` values of row a from `first` (< n ≤ cap), masked.
            *c = unsafe { _mm256_maskz_loadu_ps(valid, nb.dims.as_ptr().add(a * cap + first)) };
        }
        let centres = &centres[..active];
        let ci: [__m512d; 3] = std::array::from_fn(|k| {
            let mut v = [0.0f64; 8];
            for (l, c) in v.iter_mut().zip(&nb.current[first..first + lanes]) {
                *l = c[k] as f64;
            }
            // SAFETY: 8 doubles.
            unsafe { _mm512_loadu_pd(v.as_ptr()) }
        });
        let mut sum_w = _mm512_setzero_pd();
        let mut acc = [_mm512_setzero_pd(); 3];
        // Four neighbours at a time: their distance sums are independent chains (each in the
        // reference's order over the dimensions); the weights then go into the sums one
        // neighbour after another, as in the reference.
        let mut j = 0;
        while j < n {
            let block = (n - j).min(4);
            let mut d = [_mm256_setzero_ps(); 4];
            if block == 4 {
                // A whole block without the per-neighbour loop bound (the general loop below
                // branched on `block` for every dimension).
                for (a, &centre) in centres.iter().enumerate() {
                    let row: &[f32; 4] = nb.dims[a * cap + j..a * cap + j + 4].try_into().unwrap();
                    for u in 0..4 {
                        let t = _mm256_sub_ps(_mm256_set1_ps(row[u]), centre);
                        d[u] = _mm256_add_ps(d[u], _mm256_mul_ps(t, t));
                    }
                }
            } else {
                for (a, &centre) in centres.iter().enumerate() {
                    let row = &nb.dims[a * cap + j..a * cap + j + block];
                    for (du, &v) in d.iter_mut().zip(row) {
                        let t = _mm256_sub_ps(_mm256_set1_ps(v), centre);
                        *du = _mm256_add_ps(*du, _mm256_mul_ps(t, t));
                    }
                }
            }
            // Whether any distance of the block is NaN, tested once (it rarely is).
            let nan = d[..block]
                .iter()
                .fold(0u8, |m, &d| m | _mm256_cmp_ps_mask::<_CMP_UNORD_Q>(d, d));
            for (u, &d) in d[..block].iter().enumerate() {
                // The reference skips d ≥ 105 (a NaN is not skipped).
                let near =
                    _mm256_cmp_ps_mask::<_CMP_NGE_UQ>(d, _mm256_set1_ps(EXP_CUTOFF)) & valid;
                if near == 0 {
                    continue;
                }
                let w = if nan != 0 && _mm256_cmp_ps_mask::<_CMP_UNORD_Q>(d, d) & near != 0 {
                    // A NaN distance: the library's exp, lane by lane.
                    let mut lanes_d = [0.0f32; 8];
                    // SAFETY: 8 floats.
                    unsafe { _mm256_storeu_ps(lanes_d.as_mut_ptr(), d) };
                    let e = lanes_d.map(|d| (-d).exp() as f64);
                    // SAFETY: 8 doubles.
                    unsafe { _mm512_loadu_pd(e.as_ptr()) }
                } else {
                    expf8(_mm256_sub_ps(_mm256_setzero_ps(), d))
                };
                sum_w = _mm512_mask_add_pd(sum_w, near, sum_w, w);
                let cj = &wide[3 * (j + u)..3 * (j + u) + 3];
                for k in 0..3 {
                    let diff = _mm512_sub_pd(_mm512_set1_pd(cj[k]), ci[k]);
                    acc[k] = _mm512_mask_add_pd(acc[k], near, acc[k], _mm512_mul_pd(w, diff));
                }
            }
            j += block;
        }
        let mut sums = [0.0f64; 8];
        let mut accs = [[0.0f64; 8]; 3];
        // SAFETY: 8 doubles each.
        unsafe {
            _mm512_storeu_pd(sums.as_mut_ptr(), sum_w);
            for k in 0..3 {
                _mm512_storeu_pd(accs[k].as_mut_ptr(), acc[k]);
            }
        }
        for l in 0..lanes {
            let i = first + l;
            out[i] = finish(nb.current[i], sums[l], [accs[0][l], accs[1][l], accs[2][l]]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_two_to_the_i_over_32() {
        for (i, &t) in EXP2_TABLE.iter().enumerate() {
            let v = f64::from_bits(t + ((i as u64) << 47));
            let exact = (i as f64 / 32.0).exp2();
            assert!((v - exact).abs() <= exact * f64::EPSILON, "{i}: {v} vs {exact}");
        }
    }

    /// The replica equals the library's `expf` on every 61st f32 in [−105, 0] (the whole range
    /// was compared once: `cargo test --release -- --ignored every_f32`), where the library is
    /// glibc's FMA variant (x86-64 with FMA).
    #[test]
    fn the_replica_is_glibc_expf() {
        if !glibc_fma() {
            return;
        }
        check_range(61);
    }

    #[test]
    #[ignore]
    fn every_f32_in_range() {
        assert!(glibc_fma(), "needs glibc on a CPU with FMA");
        check_range(1);
    }

    fn glibc_fma() -> bool {
        #[cfg(all(target_arch = "x86_64", target_os = "linux", target_env = "gnu"))]
        return std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("avx2");
        #[allow(unreachable_code)]
        false
    }

    fn check_range(stride: usize) {
        let (first, last) = ((-0.0f32).to_bits(), (-EXP_CUTOFF).to_bits());
        let vector = Level::detect() == Level::Avx512;
        let mut batch = Vec::with_capacity(8);
        for bits in (first..=last).step_by(stride) {
            let x = f32::from_bits(bits);
            let e = x.exp();
            assert_eq!(expf_glibc_fma(x).to_bits(), e.to_bits(), "x = {x:e}");
            batch.push((x, e));
            if vector && batch.len() == 8 {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: the CPU has AVX-512 (`Level::detect`).
                unsafe {
                    let xs: [f32; 8] = std::array::from_fn(|l| batch[l].0);
                    let mut got = [0.0f64; 8];
                    _mm512_storeu_pd(got.as_mut_ptr(), expf8(_mm256_loadu_ps(xs.as_ptr())));
                    for (l, &(x, e)) in batch.iter().enumerate() {
                        assert_eq!(got[l].to_bits(), (e as f64).to_bits(), "x = {x:e}");
                    }
                }
                batch.clear();
            }
        }
    }
}
