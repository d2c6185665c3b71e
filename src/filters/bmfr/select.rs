//! Per-pixel selection between the fit and the unfiltered light, so that the filter's error
//! falls with the sample count instead of stopping at the fit's bias (issue 18: "never worse
//! than the unfiltered image, and consistent").
//!
//! A block's polynomial cannot follow what its features do not explain (a mirror's reflection,
//! a caustic, a shadow edge inside a flat wall): there the fit has a bias b that more samples
//! do not reduce, while the unfiltered light y has no bias and a variance v = σ²/n that falls
//! as 1/n. For the blend g = y + λ (f − y), with f's own variance negligible (K ≈ 10 weights
//! from m ≈ 1000 pixels) and independent of y's noise to the same order,
//! E[(g − μ)²] = λ² b² + (1 − λ)² v, smallest at λ = v / (b² + v), where it is
//! b² v / (b² + v) ≤ min(b², v). Both terms are estimated from the render:
//! - the residual r = f − y has E[r²] = b² + v (the same approximations), so b² + v needs no
//!   separate bias estimate — as Stein's unbiased risk estimate uses it;
//! - v from the two half buffers of NFOR (Bitterli, Rousselle, Moon, Iglesias-Guitián, Adler,
//!   Mitchell, Jarosz, Novák, EGSR 2016): the odd-numbered samples' mean o (the halves output)
//!   and the even ones' e are independent, y = (n_o o + n_e e) / n, so
//!   E[(y − o)²] = (n_e / n)² (σ²/n_e + σ²/n_o) = σ² n_e / (n n_o) and
//!   v = σ²/n = E[(y − o)²] n_o / n_e. F has no colour variance of its own (eq. 6.2 holds
//!   the features' only), which is why the halves are a renderer output.
//!
//! Each is one sample per pixel and channel, so both are summed over the three channels and a
//! (2 r + 1)² window (`select_radius`, default 2: 75 terms) before the weight
//! λ = min(1, κ V / R) is formed; a window where R = 0 (only kept pixels, or 1 spp, where one
//! half is empty and there is no estimate) keeps the fit (λ = 1). Kept pixels (sky, lights,
//! partial hits) add nothing to the sums and stay as they are.
//!
//! κ (`select_scale`, default 2) trusts the fit more than the estimate does. Where the fit is
//! unbiased V / R ≈ 1, but V and R are sums of a few heavy-tailed squares, and every window
//! whose ratio falls below 1 by chance lets (1 − λ)² v of the unfiltered noise back in: with
//! κ = 1 the diffuse Cornell box got worse than the fit alone. Where the fit is biased,
//! b² ≫ v, λ = κ v / b² still goes to 0 as v does (the error stays consistent). Measured on
//! one 8-spp 512² AOV file per scene (`noisefree render S --spp 8 --filter bmfr --aovs a.exr`,
//! `noisefree filter a.exr --filter bmfr --bmfr-select-scale K --bmfr-select-radius R`,
//! `noisefree compare` against the 2048-spp reference), MSE-LUV of cornell_diffuse /
//! cornell_glossy / outside_dof / cornell_diffuse_dof, and their sum:
//!
//! | | diffuse | glossy | outside_dof | diffuse_dof | sum |
//! |---|---|---|---|---|---|
//! | the fit alone | 1.534 | 23.50 | 12.33 | 9.111 | 46.47 |
//! | κ 1, r 3 | 2.146 | 8.180 | 10.10 | 9.685 | 30.11 |
//! | κ 1, r 6 | 1.688 | 7.814 | 10.10 | 9.334 | 28.94 |
//! | κ 1.5, r 3 | 1.489 | 7.503 | 10.09 | 9.066 | 28.15 |
//! | κ 2, r 2 (default) | 1.493 | 7.460 | 10.10 | 9.026 | 28.08 |
//! | κ 2, r 3 | 1.454 | 7.825 | 10.17 | 9.003 | 28.45 |
//! | κ 2, r 6 | 1.485 | 8.932 | 10.28 | 9.046 | 29.74 |
//! | κ 3, r 4 | 1.499 | 9.436 | 10.39 | 9.042 | 30.37 |
//! | κ 4, r 3 | 1.496 | 9.578 | 10.43 | 9.040 | 30.54 |
//!
//! Why the residual against y and not NFOR's cross-filtering (fit each half, compare with the
//! other): the fit is linear in the light for fixed features, so the cross-residual carries the
//! same information up to the leverage term, and would cost a second factorisation's
//! right-hand sides; the window pools the variance estimate instead.

use super::reference::kept;
use crate::layout::{FilterVector, Float4};

/// kernels/filters/bmfr.cl `bmfr_residuals` for one pixel: (Σ_c (f − y)², Σ_c v).
pub fn residual(
    f: &FilterVector,
    pos: &Float4,
    odd: &Float4,
    spp: f32,
    split: bool,
    fit: [f32; 3],
) -> [f32; 2] {
    if !surface(f, pos, odd, spp, split) {
        return [0.0, 0.0];
    }
    let beauty: [f32; 3] = std::array::from_fn(|c| f.direct[c] + f.indirect[c]);
    let (rr, v) = fit_terms(beauty, fit, odd, spp);
    [rr[0] + rr[1] + rr[2], v[0] + v[1] + v[2]]
}

/// kernels/filters/bmfr.cl `bmfr_fit_terms`: per channel, the fit's squared residual
/// (f − y)² and the variance of the frame's mean y from the half buffers,
/// (y − odd)² n_odd / n_even.
pub(super) fn fit_terms(
    beauty: [f32; 3],
    fit: [f32; 3],
    odd: &Float4,
    spp: f32,
) -> ([f32; 3], [f32; 3]) {
    let (n_odd, n_even) = (odd.0[3], spp - odd.0[3]);
    let rr = std::array::from_fn(|c| (fit[c] - beauty[c]) * (fit[c] - beauty[c]));
    let v = std::array::from_fn(|c| {
        let d = beauty[c] - odd.0[c];
        d * d * (n_odd / n_even)
    });
    (rr, v)
}

/// kernels/filters/bmfr.cl `bmfr_surface`: not kept, and both halves hold samples.
pub fn surface(f: &FilterVector, p: &Float4, odd: &Float4, spp: f32, split: bool) -> bool {
    !kept(f, p, spp, split) && odd.0[3] >= 1.0 && spp - odd.0[3] >= 1.0
}

/// The per-pixel estimates that `take` accepts summed over the (2 radius + 1)² window around
/// (x, y) inside the image, row by row, as the kernels' selection loops do.
pub fn window_sum<const N: usize>(
    estimates: &[[f32; N]],
    dims: (u32, u32),
    xy: (i32, i32),
    radius: i32,
    take: impl Fn(&[f32; N]) -> bool,
) -> [f32; N] {
    let mut sum = [0f32; N];
    window_for_each(estimates, dims, xy, radius, |e| {
        if take(e) {
            for (s, v) in sum.iter_mut().zip(e) {
                *s += v;
            }
        }
    });
    sum
}

/// Calls `visit` with the estimates of the (2 radius + 1)² window around (x, y) inside the
/// image, row by row, as the kernels' selection loops visit them.
pub fn window_for_each<const N: usize>(
    estimates: &[[f32; N]],
    (width, height): (u32, u32),
    (x, y): (i32, i32),
    radius: i32,
    mut visit: impl FnMut(&[f32; N]),
) {
    window_indices((width, height), (x, y), radius, |j| visit(&estimates[j]));
}

/// Calls `visit` with the index of each pixel of the (2 radius + 1)² window around (x, y)
/// inside the image, row by row.
pub fn window_indices(
    (width, height): (u32, u32),
    (x, y): (i32, i32),
    radius: i32,
    mut visit: impl FnMut(usize),
) {
    for yy in (y - radius)..=(y + radius) {
        if yy < 0 || yy >= height as i32 {
            continue;
        }
        for xx in (x - radius)..=(x + radius) {
            if xx < 0 || xx >= width as i32 {
                continue;
            }
            visit((yy as u32 * width + xx as u32) as usize);
        }
    }
}

/// kernels/filters/bmfr.cl `bmfr_select` for pixel (x, y): the window sums, then the blend.
pub fn select(
    f: &FilterVector,
    residuals: &[[f32; 2]],
    (width, height): (u32, u32),
    (x, y): (i32, i32),
    radius: i32,
    scale: f32,
    fit: [f32; 3],
) -> [f32; 3] {
    let [sum_r, sum_v] = window_sum(residuals, (width, height), (x, y), radius, |_| true);
    let lambda = if sum_r > 0.0 {
        1f32.min(scale * sum_v / sum_r)
    } else {
        1.0
    };
    std::array::from_fn(|c| {
        let beauty = f.direct[c] + f.indirect[c];
        beauty + lambda * (fit[c] - beauty)
    })
}
