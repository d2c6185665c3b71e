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

/// Lines per image row of the packed prefilter's input (kernels/filters/
/// bmfr_prefilter_packed.cl BMFR_PREFILTER_LINES).
pub const PREFILTER_PACKED_LINES: u32 = 7;

/// The largest window half width (a 15 × 15 window).
pub const MAX_ALBEDO_RADIUS: u32 = 7;

/// kernels/filters/bmfr.cl `bmfr_albedo_variance`: the variance of pixel `i`'s albedo mean.
fn variance(s: &WelfordSums, factor: f32, spp: f32) -> [f32; 3] {
    std::array::from_fn(|c| s.albedo[c] * factor / spp)
}

/// F with each surface pixel's albedo replaced by its prefiltered value (module docs).
/// `factor` turns the Welford sums into variances ([`crate::render::Frame::variance_factor`]).
pub fn prefilter(
    fv: &[FilterVector],
    sums: &[WelfordSums],
    pos: &[Float4],
    (w, h): (u32, u32),
    spp: f32,
    factor: f32,
    radius: u32,
) -> Vec<FilterVector> {
    let k2 = PREFILTER_K * PREFILTER_K;
    let r = radius as i32;
    (0..fv.len())
        .into_par_iter()
        .map(|i| {
            let mut out = fv[i];
            if kept(&fv[i], &pos[i], spp) {
                return out;
            }
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let vi = variance(&sums[i], factor, spp);
            let ai = fv[i].albedo;
            let mut sum = [0f32; 3];
            let mut wsum = 0f32;
            for yy in (y - r).max(0)..=(y + r).min(h as i32 - 1) {
                for xx in (x - r).max(0)..=(x + r).min(w as i32 - 1) {
                    let j = (yy as u32 * w + xx as u32) as usize;
                    if kept(&fv[j], &pos[j], spp) {
                        continue;
                    }
                    let vj = variance(&sums[j], factor, spp);
                    let aj = fv[j].albedo;
                    let mut d2 = 0f32;
                    for c in 0..3 {
                        let diff = ai[c] - aj[c];
                        d2 += (diff * diff - (vi[c] + vi[c].min(vj[c])))
                            / (PREFILTER_EPSILON + k2 * (vi[c] + vj[c]));
                    }
                    let wt = (-(d2 / 3.0).max(0.0)).exp();
                    for c in 0..3 {
                        sum[c] += wt * aj[c];
                    }
                    wsum += wt;
                }
            }
            // The pixel itself is in its window with weight 1, so wsum ≥ 1.
            out.albedo = std::array::from_fn(|c| sum[c] / wsum);
            out
        })
        .collect()
}
