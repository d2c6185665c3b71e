//! Sheared filtering of depth of field (Yan et al. 2015 §3.2 "DoF", eqs. 3-15; digest
//! /work/shared/notes/seeds-aaf-sheared.md §3.4 "Thin lens"; issue 16): the plain Rust
//! reference of kernels/filters/sheared_dof.cl, step by step, over the lens field of
//! kernels/render/lens_field.cl.
//!
//! What the seed leaves open, and what is done:
//! - **The aperture**: the square [−A, A]² (A = lens_radius) on the camera's (right, down) axes,
//!   sampled on the l × l jittered grid and weighted by the Gaussian w_y of σ_y = A/2 (the
//!   disk's per-axis standard deviation; digest §3.4, the FAITHFUL option): the thesis's disk
//!   indicator is not separable in (u1, u2), which steps 1a-2b need. The filtered image is the
//!   Gaussian-aperture image (Gaussian bokeh of the disk's second moment), not the disk's.
//! - **x and s**: x is the pixel's column (1b) and row (2b), in pixels; s = W (F/z − 1) / S
//!   (pixels per metre of lens) per sample, z its first hit's depth along the view axis. A
//!   point at depth z seen through lens point u lands at pixel x_P − s u, so f(x, u) =
//!   g(x + s u): the shadow case's form (src/filters/sheared/shear.rs) with signed slopes.
//! - **σ_x** (eq. 4): σ_y |s_min s_max| / (s_max − s_min), pixels, capped at a 32 px diameter.
//! - **η** (eq. 5 corrected, digest §3.2 (i)): the mean of 1/s over the wedge,
//!   (s_min + s_max) / (2 s_min s_max), lens metres per pixel; its sign follows the slopes'.
//!   The factor `shear` = +1 was settled by tests/sheared_dof.rs: on a synthetic plane at one
//!   depth (s = ±40 px/m, l = 3, against 4096 Gaussian-aperture samples) RMS 0.0103 / 0.0099
//!   with +, 0.0274 / 0.0268 with −, 0.0259 unsheared, 0.053 with eq. 5 as printed; on the
//!   renderer's lens field of an out-of-focus wall (s ≈ −18 px/m, against 1024 samples)
//!   0.0090 with +, 0.0193 with −, 0.0221 unsheared, 0.0590 for the pixel's own 9 samples.
//! - **In focus** (s = 0 exactly): |s| is taken as 1e-30, η = ±1e30: every neighbour's shift
//!   falls beyond the bins, so the pixel keeps its own samples (Ω_x is unbounded there).
//! - **Fallback** (§3.1: s_min s_max < 0, both sides of the focal plane): the pass added 36
//!   samples; the pixel's value is the Gaussian-weighted mean of its own l² + 36 samples. That
//!   is the axis-aligned filter at its bandlimit: for a wedge containing s = 0 the axis-aligned
//!   bound Ω_x ≤ Ω_u^max / min|s| is unbounded, so the axis-aligned filter's width is the
//!   pixel's own. Fallback pixels lend their grid samples to neighbours in 1b.
//! - **Rejection** (§3.3 K1b): normals of the lens-centre hits within `normal_angle`; a pixel
//!   whose centre ray leaves the scene shares only with such pixels. No world-distance test:
//!   a blurred edge mixes depths by design, and eq. 4's σ_x shrinks with the slope spread.
//! - **Sphere lights in a lens scene**: with this effect alone their shadows stay as path
//!   traced inside the radiance samples; `effect = "dof-shadows"` filters both (the
//!   appendix's eqs. 16-17, lens_shadows.rs), over a lens field whose samples carry the
//!   shadow filter's result.

use glam::Vec3;
use rayon::prelude::*;

use super::shear::{MAX_ETA, MIN_SLOPE, bin_centre, bin_of, gauss, radius};
use crate::layout::{LightFieldPixel, ShearedParams};
use crate::render::shadows::light_field::grid_coordinate;

/// What a pixel is to the filter (kernels/filters/sheared_dof.cl `DOF_*`).
pub const NONE: f32 = 0.0;
pub const FILTERED: f32 = 2.0;
pub const FALLBACK: f32 = 3.0;

/// Per pixel: σ_x (pixels), η, the kind, 0.
pub type Guide = [f32; 4];

/// Floats per pixel of step 1a: rgb + weight per (bin, row).
pub fn p_floats(bins: u32) -> usize {
    bins as usize * 16
}

/// Floats per pixel of steps 1b and 2a: rgb + weight per bin.
pub fn g_floats(bins: u32) -> usize {
    bins as usize * 4
}

/// |s| at least [`MIN_SLOPE`], the sign kept (0 counts as +).
pub fn signed(s: f32) -> f32 {
    if s >= 0.0 {
        s.max(MIN_SLOPE)
    } else {
        s.min(-MIN_SLOPE)
    }
}

/// Eq. 4 with signed slopes of one sign: σ_y |s_min s_max| / (s_max − s_min), +∞ for one.
pub fn sigma_x(sigma_y: f32, s_min: f32, s_max: f32) -> f32 {
    let (a, b) = (signed(s_min), signed(s_max.max(s_min)));
    let spread = b - a;
    if spread > 0.0 {
        sigma_y * ((a * b).abs() / spread)
    } else {
        f32::INFINITY
    }
}

/// Eq. 5 corrected: η = (s_min + s_max) / (2 s_min s_max), within ±1e30, times `shear`.
pub fn eta(s_min: f32, s_max: f32, shear: f32) -> f32 {
    let (a, b) = (signed(s_min), signed(s_max.max(s_min)));
    let e = ((a + b) / (2.0 * a * b)).clamp(-MAX_ETA, MAX_ETA);
    shear * e
}

/// `dof_prepare`.
pub fn prepare(p: &ShearedParams, field: &[LightFieldPixel]) -> Vec<Guide> {
    field
        .par_iter()
        .map(|lf| {
            if !(lf.count > 0.0) {
                return [0.0, 0.0, NONE, 0.0];
            }
            if lf.extra_samples > 0.0 {
                return [0.0, 0.0, FALLBACK, 0.0];
            }
            let sx = sigma_x(p.sigma_y, lf.slopes[0], lf.slopes[1]);
            let sx = sx.min(0.5 * p.max_radius as f32);
            [sx, eta(lf.slopes[0], lf.slopes[1], p.shear), FILTERED, 0.0]
        })
        .collect()
}

/// Sample k's rgb (`sheared_rgb_lane`; depth of field and GI).
pub(super) fn rgb(lf: &LightFieldPixel, k: usize) -> [f32; 3] {
    [lf.samples[k], lf.green[k], lf.blue[k]]
}

/// `dof_1a` (eq. 12).
pub fn step_1a(p: &ShearedParams, field: &[LightFieldPixel], guide: &[Guide]) -> Vec<f32> {
    let (l, radius) = (p.side, p.light.0[3]);
    let inv = (1.0 / (2.0 * p.sigma_y * p.sigma_y)).min(f32::MAX);
    bin_rows(
        p,
        field,
        guide,
        |a, j| grid_coordinate(a, j, l, radius),
        |t| gauss(t, inv),
    )
}

/// Step 1a for the lens (depth of field) and the v-plane (GI, src/filters/sheared/gi.rs):
/// p[bin][row] = Σ_a f(a, row) w(y(a) − y_bin), rgb + weight, for every pixel with a field
/// (kind ≠ 0); `coord` is the grid coordinate y of point a under jitter j, `w` the weight.
pub(super) fn bin_rows(
    p: &ShearedParams,
    field: &[LightFieldPixel],
    guide: &[Guide],
    coord: impl Fn(u32, f32) -> f32 + Sync,
    w: impl Fn(f32) -> f32 + Sync,
) -> Vec<f32> {
    let (bins, l) = (p.bins as usize, p.side);
    let mut out = vec![0f32; field.len() * p_floats(p.bins)];
    out.par_chunks_mut(p_floats(p.bins))
        .zip(field.par_iter().zip(guide))
        .for_each(|(o, (lf, g))| {
            if g[2] == NONE {
                return;
            }
            for c in 0..bins {
                let yc = bin_centre(c as u32, p.bins, p.range);
                let mut wy = [0f32; 4];
                for a in 0..l {
                    wy[a as usize] = w(coord(a, lf.jitter[0]) - yc);
                }
                for b in 0..l {
                    let mut v = [0f32; 4];
                    for a in 0..l {
                        let f = rgb(lf, (b * l + a) as usize);
                        for ch in 0..3 {
                            v[ch] += f[ch] * wy[a as usize];
                        }
                        v[3] += wy[a as usize];
                    }
                    let at = (c * 4 + b as usize) * 4;
                    o[at..at + 4].copy_from_slice(&v);
                }
            }
        });
    out
}

/// `dof_accepts`.
fn accepts(p: &ShearedParams, li: &LightFieldPixel, lj: &LightFieldPixel, kind_j: f32) -> bool {
    if kind_j == NONE {
        return false;
    }
    let (ni, nj) = (Vec3::from(li.normal), Vec3::from(lj.normal));
    let (si, sj) = (ni.dot(ni) == 0.0, nj.dot(nj) == 0.0);
    if si || sj {
        return si && sj;
    }
    ni.dot(nj) >= p.normal_cos
}

/// The gather of 1b (`axis` 0: along the row) and 2b (1: the column) around FILTERED pixel
/// `i`: (neighbour, w_x, bin of η (x − x′)) in walk order.
fn gather(
    p: &ShearedParams,
    field: &[LightFieldPixel],
    guide: &[Guide],
    i: usize,
    axis: usize,
    mut visit: impl FnMut(usize, f32, u32),
) {
    let g = guide[i];
    // One-pixel steps: the shadow case's radius with one unit of x per step.
    let r = radius(g[0], 1.0, p.max_radius);
    let inv_x = (1.0 / (2.0 * g[0] * g[0])).min(f32::MAX);
    for (k, j) in neighbours(p, i, axis, r) {
        if k != 0 && !accepts(p, &field[i], &field[j], guide[j][2]) {
            continue;
        }
        let dx = k as f32;
        let wx = gauss(dx, inv_x);
        if let Some(c) = bin_of(g[1] * -dx, p.bins, p.range) {
            visit(j, wx, c);
        }
    }
}

/// Steps 1b and 2b of the lens and v-plane filters walk k = −r..=r steps from pixel `i` along
/// `axis` (0: its row, 1: its column): (k, neighbour) inside the image, in walk order
/// (`sheared_walk`).
pub(super) fn neighbours(
    p: &ShearedParams,
    i: usize,
    axis: usize,
    r: i32,
) -> impl Iterator<Item = (i32, usize)> {
    let (w, h) = (p.width as i32, p.height as i32);
    let (x, y) = (i as i32 % w, i as i32 / w);
    (-r..=r).filter_map(move |k| {
        let (qx, qy) = if axis == 0 { (x + k, y) } else { (x, y + k) };
        (qx >= 0 && qy >= 0 && qx < w && qy < h).then_some((k, (qy * w + qx) as usize))
    })
}

/// Step 2b (eq. 15) for the lens and the v-plane: for each FILTERED pixel, Σ w_x × the step-2a
/// bin over the neighbours `walk` visits along its column (j, w_x, bin), over its weight;
/// `finish` makes every pixel with a field from that (None: no weight, or not FILTERED: the
/// fallback and OWN pixels keep their own samples); `beauty` (F) where it has no field.
pub(super) fn gather_columns(
    p: &ShearedParams,
    guide: &[Guide],
    beauty: &[[f32; 3]],
    q2a: &[f32],
    walk: impl Fn(usize, &mut dyn FnMut(usize, f32, u32)) + Sync,
    finish: impl Fn(usize, Option<[f32; 3]>) -> [f32; 3] + Sync,
) -> Vec<[f32; 3]> {
    let bins = p.bins as usize;
    (0..guide.len())
        .into_par_iter()
        .map(|i| {
            if guide[i][2] == NONE {
                return beauty[i];
            }
            let mut v = [0f32; 4];
            if guide[i][2] == FILTERED {
                walk(i, &mut |j, wx, c| {
                    for ch in 0..4 {
                        v[ch] += wx * q2a[j * bins * 4 + c as usize * 4 + ch];
                    }
                });
            }
            finish(i, (v[3] > 0.0).then(|| [v[0] / v[3], v[1] / v[3], v[2] / v[3]]))
        })
        .collect()
}

/// `dof_1b` (eq. 13).
pub fn step_1b(p: &ShearedParams, field: &[LightFieldPixel], guide: &[Guide], p1a: &[f32]) -> Vec<f32> {
    let (l, radius) = (p.side, p.light.0[3]);
    gather_rows(
        p,
        field,
        guide,
        p1a,
        |b, j| grid_coordinate(b, j, l, radius),
        |i, visit| {
            if guide[i][2] == FILTERED {
                gather(p, field, guide, i, 0, visit)
            }
        },
    )
}

/// Step 1b for the lens and the v-plane: around each pixel, `walk` visits (neighbour j, w_x,
/// bin of the shifted y1); j's rows land in the bins of their own y2′ = `coord`(row, j's
/// jitter).
pub(super) fn gather_rows(
    p: &ShearedParams,
    field: &[LightFieldPixel],
    guide: &[Guide],
    p1a: &[f32],
    coord: impl Fn(u32, f32) -> f32 + Sync,
    walk: impl Fn(usize, &mut dyn FnMut(usize, f32, u32)) + Sync,
) -> Vec<f32> {
    let l = p.side;
    let stride = p_floats(p.bins);
    let mut out = vec![0f32; guide.len() * g_floats(p.bins)];
    out.par_chunks_mut(g_floats(p.bins))
        .enumerate()
        .for_each(|(i, o)| {
            walk(i, &mut |j, wx, c1| {
                let src = &p1a[j * stride..(j + 1) * stride];
                for b in 0..l {
                    let Some(c2) = bin_of(coord(b, field[j].jitter[1]), p.bins, p.range) else {
                        continue;
                    };
                    let at = (c1 as usize * 4 + b as usize) * 4;
                    for ch in 0..4 {
                        o[c2 as usize * 4 + ch] += wx * src[at + ch];
                    }
                }
            });
        });
    out
}

/// `dof_2a` (eq. 14).
pub fn step_2a(p: &ShearedParams, guide: &[Guide], g1b: &[f32]) -> Vec<f32> {
    let bins = p.bins as usize;
    let inv = (1.0 / (2.0 * p.sigma_y * p.sigma_y)).min(f32::MAX);
    let spacing = 2.0 * p.range / (bins - 1) as f32;
    let table: Vec<f32> = (0..2 * bins as i32 - 1)
        .map(|d| gauss((d - (bins as i32 - 1)) as f32 * spacing, inv))
        .collect();
    sum_bins(p, guide, g1b, |c, c2| table[c2 + bins - 1 - c])
}

/// Step 2a for the lens and the v-plane: q[c] = Σ_c′ g[c′] w(c, c′) over every bin c′, for
/// every pixel with a field.
pub(super) fn sum_bins(
    p: &ShearedParams,
    guide: &[Guide],
    g1b: &[f32],
    w: impl Fn(usize, usize) -> f32 + Sync,
) -> Vec<f32> {
    let bins = p.bins as usize;
    let mut out = vec![0f32; guide.len() * g_floats(p.bins)];
    out.par_chunks_mut(g_floats(p.bins))
        .enumerate()
        .for_each(|(i, o)| {
            if guide[i][2] == NONE {
                return;
            }
            let src = &g1b[i * bins * 4..(i + 1) * bins * 4];
            for c in 0..bins {
                let mut v = [0f32; 4];
                for c2 in 0..bins {
                    let wy = w(c, c2);
                    for ch in 0..4 {
                        v[ch] += src[c2 * 4 + ch] * wy;
                    }
                }
                o[c * 4..c * 4 + 4].copy_from_slice(&v);
            }
        });
    out
}

/// `dof_own`: the pixel's own grid samples weighted w_y(u1) w_y(u2), and its extra samples.
pub fn own(p: &ShearedParams, lf: &LightFieldPixel) -> [f32; 3] {
    let l = p.side;
    let inv = (1.0 / (2.0 * p.sigma_y * p.sigma_y)).min(f32::MAX);
    let mut v = [lf.extra[0], lf.extra[1], lf.extra[2]];
    let mut w = lf.extra[3];
    for b in 0..l {
        let wb = gauss(grid_coordinate(b, lf.jitter[1], l, p.light.0[3]), inv);
        for a in 0..l {
            let wt = gauss(grid_coordinate(a, lf.jitter[0], l, p.light.0[3]), inv) * wb;
            let f = rgb(lf, (b * l + a) as usize);
            for ch in 0..3 {
                v[ch] += wt * f[ch];
            }
            w += wt;
        }
    }
    if w > 0.0 {
        v.map(|c| c / w)
    } else {
        [0.0; 3]
    }
}

/// `dof_2b` (eq. 15): the image; `beauty` (F) where the pixel has no field.
pub fn step_2b(
    p: &ShearedParams,
    field: &[LightFieldPixel],
    beauty: &[[f32; 3]],
    guide: &[Guide],
    q2a: &[f32],
) -> Vec<[f32; 3]> {
    let walk = |i, visit: &mut dyn FnMut(usize, f32, u32)| gather(p, field, guide, i, 1, visit);
    gather_columns(p, guide, beauty, q2a, walk, |i, filtered| {
        filtered.unwrap_or_else(|| own(p, &field[i]))
    })
}

/// The whole filter: prepare and the four steps.
pub fn filter(p: &ShearedParams, field: &[LightFieldPixel], beauty: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let guide = prepare(p, field);
    let a = step_1a(p, field, &guide);
    let b = step_1b(p, field, &guide, &a);
    let c = step_2a(p, &guide, &b);
    step_2b(p, field, beauty, &guide, &c)
}
