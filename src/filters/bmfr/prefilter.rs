//! Albedo prefiltering (`albedo_prefilter`), for depth of field: the plain Rust reference of
//! kernels/filters/bmfr.cl `bmfr_albedo_prefilter`, the same float operations in the same
//! order.
//!
//! Why. The fit divides each pixel's light by its mean first-hit albedo ā and multiplies the
//! fitted irradiance by ā again. In focus ā is exact after a few samples, so texture comes back
//! sharp. Out of focus each lens sample sees another texel, and ā of 8 samples is itself a
//! noisy estimate of the defocused texture: the fitted irradiance is smooth, and multiplying ā
//! back puts its noise in the output unfiltered. On cornell_diffuse_dof most of bmfr's error
//! sat on the defocused brick wall for this reason (results/README.md, the bmfr section).
//!
//! What. ā is filtered before the fit by per-pixel non-local means with the variance
//! cancellation of Rousselle, Knaus and Zwicker ("Adaptive rendering with non-local means
//! filtering", SIGGRAPH Asia 2012, eq. 4 at patch size 1), the feature prefilter of NFOR
//! (Bitterli et al. 2016 §5.2). For pixels i, j with albedo means a and variances of the mean
//! v (the Welford sums of F's albedo, S / (n − 1) / n):
//!
//! d² = (1/3) Σ_c [(a_i − a_j)² − (v_i + min(v_i, v_j))] / (ε + k² (v_i + v_j)),
//! w = exp(−max(0, d²)),
//!
//! and ā_i ← Σ_j w ā_j / Σ_j w over a (2 r + 1)² window (`albedo_radius`). Where the albedo
//! is noise-free (in focus) v = 0 and only neighbours of exactly the same albedo weigh
//! anything (ε = 1e-10), so the texture is kept; where two means differ by what their noise
//! explains, they are averaged. Kept pixels (sky, lights, partial hits: [`super::reference`]'s
//! `kept`) neither change nor lend their albedo. The filtered ā replaces ā everywhere the
//! filter reads it (the division, the multiplication, the `texture` feature).
//!
//! Geometry (`prefilter_geometry`, with the albedo's). Out of focus the mean first-hit
//! position and normal are as noisy as the albedo, and their noise is the light's: where a
//! defocused light's edge crosses a pixel, the share of its samples that hit the light moves
//! both the mean position (towards the light) and the light (by the emission), so the block's
//! polynomial in the position reproduces each pixel's noise. Its residual against the light is
//! then near 0 and the selection (select.rs, nlm.rs) trusts a fit whose error is the
//! unfiltered light's. NFOR prefilters every feature for this reason (Bitterli et al. 2016
//! §5.2). So the normal, the depth and the position are averaged too, over the same window,
//! with a weight of their own: the same distance over all seven channels with a variance
//! (albedo, normal, depth; their Welford sums), at k = `geometry_k` ([`GEOMETRY_K`]). On one 8-spp 512²
//! frame of cornell_diffuse_dof the pixels within 3 of one whose direct light exceeds 1 (the
//! defocused light's edge, 2 % of the image) held 2.69 of bmfr's MSE-LUV of 4.02, with the
//! fit's mean residual there 0.026 against a variance of the light of 2.95 (a scratch
//! program over these functions, not in the repository; results/README.md has the study's
//! figures). Positions keep their fourth lane (the hits).
//!
//! Cost. `bmfr_albedo_prefilter` loops over its window per work-item, so PoCL runs it on
//! scalar floats: 40-56 ms of bmfr's time at 512² (radius 2, 2 cores) on the depth-of-field
//! scenes. On CPU devices (`packed_nlm`) `bmfr_albedo_prefilter_packed` does the same on
//! float16 lanes: bmfr on Outside DOF (8 spp) took 238 ms before this kernel and 176 ms with
//! it (`noisefree filter a.exr --filter bmfr --repeat 3`, PoCL, 2 cores).

use rayon::prelude::*;

use super::reference::kept;
use crate::layout::{FilterVector, Float4, WelfordSums};

/// k of the distance: how many standard deviations of the difference count as noise (the
/// 2012 paper's k, at patch size 1). Chosen by measurement: bmfr's MSE-LUV at 512², 8 spp,
/// one AOV file per scene (`noisefree render S --spp 8 --filter bmfr --aovs a.exr`, then
/// `noisefree filter a.exr --filter bmfr`, `noisefree compare` against the 2048-spp
/// reference), prefilter off / k = 1 / 2 / 4 at radius 2: cornell_diffuse_dof 9.03 / 5.72 /
/// 5.12 / 5.10, cornell_plane_dof 15.52 / 12.77 / 12.18 / 12.03, outside_dof 10.10 / 8.29 /
/// 7.91 / 7.83, cornell_glossy_dof 10.50 / 9.83 / - / 9.86.
pub const PREFILTER_K: f32 = 4.0;

/// ε of the distance: keeps noise-free albedos (v = 0) apart unless they are equal.
pub const PREFILTER_EPSILON: f32 = 1.0e-10;

/// The default k of the geometry's distance (module docs; `geometry_k`). Measured with the
/// albedo's k at 4 and radius 2, bmfr's MSE-LUV at 512², 8 spp: results/README.md (bmfr,
/// "geometry"). A large k leaves only pairs that are both noise-free and different apart: out
/// of focus the geometry is averaged over the window, in focus it is kept.
pub const GEOMETRY_K: f32 = 32.0;

/// Lines per image row of the packed prefilter's input, passed to the kernels as
/// `-D BMFR_PREFILTER_LINES` (kernels/filters/bmfr_prefilter_packed.cl has their layout): the
/// albedo's 7, and with the geometry its 11 more (normal, depth, their variances, position).
pub fn prefilter_packed_lines(geometry: bool) -> u32 {
    if geometry { 18 } else { 7 }
}

/// The largest window half width (a 15 × 15 window).
pub const MAX_ALBEDO_RADIUS: u32 = 7;

/// kernels/filters/bmfr.cl `bmfr_albedo_variance`: the variance of pixel `i`'s albedo mean.
fn variance(s: &WelfordSums, factor: f32, spp: f32) -> [f32; 3] {
    std::array::from_fn(|c| s.albedo[c] * factor / spp)
}

/// The seven channels of the geometry's distance, and the variances of their means
/// (kernels/filters/bmfr.cl `bmfr_geometry`): albedo, normal, depth.
fn geometry(f: &FilterVector, s: &WelfordSums, factor: f32, spp: f32) -> ([f32; 7], [f32; 7]) {
    let a = f.albedo;
    let n = f.normal;
    let v = [s.albedo[0], s.albedo[1], s.albedo[2], s.normal[0], s.normal[1], s.normal[2], s.depth];
    (
        [a[0], a[1], a[2], n[0], n[1], n[2], f.depth],
        v.map(|x| x * factor / spp),
    )
}

/// The distance term of one channel (module docs).
fn term(a: f32, b: f32, va: f32, vb: f32, k2: f32) -> f32 {
    let diff = a - b;
    (diff * diff - (va + va.min(vb))) / (PREFILTER_EPSILON + k2 * (va + vb))
}

/// F with each surface pixel's albedo replaced by its prefiltered value, and with
/// `geometry_k` (`Some(k)`) its normal and depth, and the positions' xyz, too (module docs);
/// the positions are returned as given without it. `factor` turns the Welford sums into variances
/// ([`crate::render::Frame::variance_factor`]).
#[allow(clippy::too_many_arguments)]
pub fn prefilter(
    fv: &[FilterVector],
    sums: &[WelfordSums],
    pos: &[Float4],
    (w, h): (u32, u32),
    spp: f32,
    split: bool,
    factor: f32,
    radius: u32,
    geometry_k: Option<f32>,
) -> (Vec<FilterVector>, Vec<Float4>) {
    let k2 = PREFILTER_K * PREFILTER_K;
    let kg2 = geometry_k.map(|k| k * k);
    let r = radius as i32;
    (0..fv.len())
        .into_par_iter()
        .map(|i| {
            let (mut out, mut p) = (fv[i], pos[i]);
            if kept(&fv[i], &pos[i], spp, split) {
                return (out, p);
            }
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let vi = variance(&sums[i], factor, spp);
            let ai = fv[i].albedo;
            let (gi, gvi) = geometry(&fv[i], &sums[i], factor, spp);
            let mut sum = [0f32; 3];
            let mut wsum = 0f32;
            // Normal, depth, position xyz: their differences from the pixel's own are averaged
            // (below).
            let q = pos[i].0;
            let own = [gi[3], gi[4], gi[5], gi[6], q[0], q[1], q[2]];
            let mut gsum = [0f32; 7];
            let mut gwsum = 0f32;
            for yy in (y - r).max(0)..=(y + r).min(h as i32 - 1) {
                for xx in (x - r).max(0)..=(x + r).min(w as i32 - 1) {
                    let j = (yy as u32 * w + xx as u32) as usize;
                    if kept(&fv[j], &pos[j], spp, split) {
                        continue;
                    }
                    let vj = variance(&sums[j], factor, spp);
                    let aj = fv[j].albedo;
                    let mut d2 = 0f32;
                    for c in 0..3 {
                        d2 += term(ai[c], aj[c], vi[c], vj[c], k2);
                    }
                    let wt = (-(d2 / 3.0).max(0.0)).exp();
                    for c in 0..3 {
                        sum[c] += wt * aj[c];
                    }
                    wsum += wt;
                    if let Some(kg2) = kg2 {
                        let (gj, gvj) = geometry(&fv[j], &sums[j], factor, spp);
                        let mut dg = 0f32;
                        for c in 0..7 {
                            dg += term(gi[c], gj[c], gvi[c], gvj[c], kg2);
                        }
                        let wg = (-(dg / 7.0).max(0.0)).exp();
                        let q = pos[j].0;
                        let values = [gj[3], gj[4], gj[5], gj[6], q[0], q[1], q[2]];
                        for c in 0..7 {
                            gsum[c] += wg * (values[c] - own[c]);
                        }
                        gwsum += wg;
                    }
                }
            }
            // The pixel itself is in its window with weights 1, so the sums of weights are ≥ 1.
            out.albedo = std::array::from_fn(|c| sum[c] / wsum);
            if kg2.is_some() {
                // The pixel's value plus the mean difference: a feature that is the same over
                // the window (a flat wall's z) stays exactly so. Averaging the values themselves
                // rounds them apart by an ulp, and the fit, which rescales each block's
                // positions to [0, 1] by their range, would make a feature of that rounding.
                let m: [f32; 7] = std::array::from_fn(|c| own[c] + gsum[c] / gwsum);
                out.normal = [m[0], m[1], m[2]];
                out.depth = m[3];
                p.0[0] = m[4];
                p.0[1] = m[5];
                p.0[2] = m[6];
            }
            (out, p)
        })
        .unzip()
}
