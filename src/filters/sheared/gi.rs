//! Sheared filtering of diffuse indirect light (Yan et al. 2015 §3.1 "Diffuse Indirect
//! Illumination", eqs. 2-15, §5; digest /work/shared/notes/seeds-aaf-sheared.md §3; issue 16):
//! the plain Rust reference of kernels/filters/sheared_gi.cl, step by step, over the GI field
//! of kernels/render/gi_field.cl (src/render/gi_field.rs: the lanes, the v-plane sampler and
//! the truncation).
//!
//! What the seed leaves open, and what is done:
//! - **x and s**: x is the receiver's world position on its tangent plane (§5: "the filtering
//!   directions x1, x2 are orthogonal in world space to the receiver normal, and locally
//!   aligned"), x1 along the tangent t of the shading normal, x2 along n × t (the v-plane's
//!   axes). s = z, the first bounce's hit distance. One reflector plane at z gives
//!   f(x, v) = g(x + z v): the shadow case's form (src/filters/sheared/shear.rs), so σ_x is
//!   eq. 4 with σ_v = 2/Ω_v^max (Ω_v^max = 2.8, eq. 2) and η = (1/z_min + 1/z_max)/2 (eq. 5
//!   corrected, digest §3.2 (i)): neighbour x′'s sample at v′ is pixel x's direction
//!   v′ − η (x − x′).
//! - **The walks**: 1b walks the image row, 2b the column (as depth of field), each step
//!   measured in world units: w_x is the Gaussian of the offset's length on the written
//!   pixel's tangent plane, the shear reads Δ·t (1b) and Δ·(n × t) (2b). σ_x is capped at
//!   `max_radius`/2 pixel sizes d (the seed's 32 px diameter); the gather takes ⌈2σ_x/d⌉ steps.
//! - **The box of steps 1a and 2a** (§5: "we use a box function instead of a Gaussian"; its
//!   width is not given, digest §3.2 (iv)): the truncation square itself, half width V = 5.
//!   The samples are importance-sampled and weighted to be equivalent to cosine sampling
//!   (src/render/gi_field.rs), so the v-integral is their plain mean over the square; a
//!   narrower box would average only the directions near the normal (not the irradiance).
//!   With the box at V the shear moves the window: a neighbour's sample counts for pixel x
//!   when its direction for x, v′ − η (x − x′), stays inside [−V, V]². The γ(v′ − Δ)/γ(v′)
//!   change of weight under the shift is what the box leaves out (the seed's approximation).
//!   Bins: `bins` (odd) over [−V, V], for both the shift (1b/2b) and the neighbour's binned
//!   v2′ (1b), spacing 2V/(bins − 1).
//! - **Pixels**: no receiver (sky, emitter, glossy first hit): F as rendered. A receiver whose
//!   l² samples met no reflector (all left to the sky: z undefined): its own samples, lent to
//!   neighbours. Others filtered. Output = F.direct + albedo × filtered L (the albedo lane: the
//!   mean over the samples' points, as AAF's `indirect` output).
//! - **Rejection** (§5 K1b): normals within `normal_angle`; offset along the written pixel's
//!   normal within `depth_tolerance` σ_x.
//! - **Bounces**: the seed's GI has one bounce. Each sample here is the path tracer's whole
//!   indirect light from that direction (every later bounce included, kernels/render/indirect.cl
//!   `indirect_radiance`) and z is its first bounce's distance: later bounces are filtered with
//!   the first reflector's wedge (smoother than it, so the bound still holds for them).

use glam::Vec3;
use rayon::prelude::*;

use super::shear::{bin_centre, bin_of, eta as shear_eta, gauss, sigma_x as shear_sigma_x};
use crate::layout::{LightFieldPixel, ShearedParams};
use crate::render::cpu::sampling::tangent_frame;
use crate::render::gi_field::{V_MAX, grid_v};

/// What a pixel is to the filter (kernels/filters/sheared_gi.cl `GI_*`).
pub const NONE: f32 = 0.0;
pub const OWN: f32 = 1.0;
pub const FILTERED: f32 = 2.0;

/// Ω_v^max of eq. 2 (Yan et al. §3.1, after Mehta et al. 2013).
pub const OMEGA_V_MAX: f32 = 2.8;

/// Per pixel: σ_x (world), η (per world unit), the kind, the pixel size d.
pub type Guide = [f32; 4];

pub use super::dof::{g_floats, p_floats};
use super::dof::{bin_rows, gather_columns, gather_rows, neighbours, rgb, sum_bins};

/// `gi_prepare`.
pub fn prepare(p: &ShearedParams, field: &[LightFieldPixel]) -> Vec<Guide> {
    field
        .par_iter()
        .map(|lf| {
            if !(lf.count > 0.0) {
                return [0.0, 0.0, NONE, 0.0];
            }
            let d = lf.scale[0];
            // No sample met a reflector (z_max = 0): z is undefined.
            if !(lf.slopes[1] > 0.0) {
                return [0.0, 0.0, OWN, d];
            }
            let [a, b] = lf.slopes;
            let sx = shear_sigma_x(p.sigma_y, a, b).min(0.5 * p.max_radius as f32 * d);
            [sx, shear_eta(a, b, p.shear), FILTERED, d]
        })
        .collect()
}

/// The box of steps 1a and 2a: 1 within half width `range` (= V).
pub fn boxed(t: f32, range: f32) -> f32 {
    if t.abs() <= range { 1.0 } else { 0.0 }
}

/// `gi_1a` (eq. 12 with the box).
pub fn step_1a(p: &ShearedParams, field: &[LightFieldPixel], guide: &[Guide]) -> Vec<f32> {
    let (l, range) = (p.side, p.range);
    bin_rows(p, field, guide, |a, j| grid_v(a, j, l), |t| boxed(t, range))
}

/// `gi_accepts`: j has a field, normals within the angle, the offset along i's normal within
/// depth_tolerance σ_x.
fn accepts(p: &ShearedParams, li: &LightFieldPixel, lj: &LightFieldPixel, g: Guide, kind_j: f32) -> bool {
    if kind_j == NONE {
        return false;
    }
    let (ni, nj) = (Vec3::from(li.normal), Vec3::from(lj.normal));
    if ni.dot(nj) < p.normal_cos {
        return false;
    }
    let off = (Vec3::from(lj.position) - Vec3::from(li.position)).dot(ni).abs();
    off <= p.depth_tolerance * g[0]
}

/// Gather steps on either side: ⌈2σ_x/d⌉ within max_radius; 0 for OWN pixels.
fn steps(p: &ShearedParams, g: Guide) -> i32 {
    if g[2] != FILTERED || !(g[3] > 0.0) || !(g[0] > 0.0) {
        return 0;
    }
    let r = (2.0 * g[0] / g[3]).ceil();
    if r < p.max_radius as f32 { r as i32 } else { p.max_radius }
}

/// The gather of 1b (`axis` 0: along the row, shear on t) and 2b (1: the column, on n × t)
/// around pixel `i`: (neighbour, w_x, bin of η (x − x′)) in walk order.
fn gather(
    p: &ShearedParams,
    field: &[LightFieldPixel],
    guide: &[Guide],
    i: usize,
    axis: usize,
    mut visit: impl FnMut(usize, f32, u32),
) {
    let g = guide[i];
    let r = steps(p, g);
    let inv_x = (1.0 / (2.0 * g[0] * g[0])).min(f32::MAX);
    let n = Vec3::from(field[i].normal);
    let (t, b) = tangent_frame(n);
    let e = if axis == 0 { t } else { b };
    let pi = Vec3::from(field[i].position);
    for (k, j) in neighbours(p, i, axis, r) {
        if k != 0 && !accepts(p, &field[i], &field[j], g, guide[j][2]) {
            continue;
        }
        let delta = Vec3::from(field[j].position) - pi;
        let tangential = delta - n * delta.dot(n);
        let wx = gauss(tangential.length(), inv_x);
        if let Some(c) = bin_of(g[1] * -delta.dot(e), p.bins, p.range) {
            visit(j, wx, c);
        }
    }
}

/// `gi_1b` (eq. 13): for FILTERED and OWN pixels (OWN: their own samples, lent in 2b).
pub fn step_1b(p: &ShearedParams, field: &[LightFieldPixel], guide: &[Guide], p1a: &[f32]) -> Vec<f32> {
    let l = p.side;
    gather_rows(
        p,
        field,
        guide,
        p1a,
        |b, j| grid_v(b, j, l),
        |i, visit| {
            if guide[i][2] != NONE {
                gather(p, field, guide, i, 0, visit)
            }
        },
    )
}

/// `gi_2a` (eq. 14 with the box on bin centres: |c − c′| ≤ (bins − 1)/2).
pub fn step_2a(p: &ShearedParams, guide: &[Guide], g1b: &[f32]) -> Vec<f32> {
    let reach = (p.bins as usize - 1) / 2;
    sum_bins(p, guide, g1b, |c, c2| if c.abs_diff(c2) <= reach { 1.0 } else { 0.0 })
}

/// `gi_own`: the mean of the pixel's own l² samples (the unfiltered estimate of L).
pub fn own(p: &ShearedParams, lf: &LightFieldPixel) -> [f32; 3] {
    let n = (p.side * p.side) as usize;
    let mut v = [0f32; 3];
    for k in 0..n {
        let f = rgb(lf, k);
        for ch in 0..3 {
            v[ch] += f[ch];
        }
    }
    v.map(|c| c / n as f32)
}

/// `gi_2b` (eq. 15): F.direct + albedo × L; `direct` and `beauty` (F) per pixel.
pub fn step_2b(
    p: &ShearedParams,
    field: &[LightFieldPixel],
    direct: &[[f32; 3]],
    beauty: &[[f32; 3]],
    guide: &[Guide],
    q2a: &[f32],
) -> Vec<[f32; 3]> {
    let walk = |i, visit: &mut dyn FnMut(usize, f32, u32)| gather(p, field, guide, i, 1, visit);
    gather_columns(p, guide, beauty, q2a, walk, |i, filtered| {
        let l = filtered.unwrap_or_else(|| own(p, &field[i]));
        let a = field[i].extra;
        std::array::from_fn(|ch| direct[i][ch] + a[ch] * l[ch])
    })
}

/// The whole filter: prepare and the four steps.
pub fn filter(
    p: &ShearedParams,
    field: &[LightFieldPixel],
    direct: &[[f32; 3]],
    beauty: &[[f32; 3]],
) -> Vec<[f32; 3]> {
    let guide = prepare(p, field);
    let a = step_1a(p, field, &guide);
    let b = step_1b(p, field, &guide, &a);
    let c = step_2a(p, &guide, &b);
    step_2b(p, field, direct, beauty, &guide, &c)
}

/// The bin grid's v at centre `c` (for tests).
pub fn v_centre(p: &ShearedParams, c: u32) -> f32 {
    bin_centre(c, p.bins, p.range)
}

/// The half side of the v-square the bins cover.
pub const RANGE: f32 = V_MAX;
