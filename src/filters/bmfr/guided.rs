//! The selection's fourth candidate (`guided`): a guided filter of the light, with its error
//! estimated by cross-filtering the two half buffers as the non-local means' is (nlm.rs). The
//! plain Rust reference of kernels/filters/bmfr_guided.cl, the same float operations in the
//! same order.
//!
//! Why. The block fit (mod.rs) has one polynomial per 32 × 32 block, so it cannot follow light
//! that changes from one face of a thin object to the next (the inner faces of Grids' bars, a
//! curved shadow's penumbra), and the non-local means finds few patches like such narrow
//! pieces. He, Sun and Tang's guided filter ("Guided Image Filtering", ECCV 2010 / TPAMI 2013)
//! fits a linear model per (2 r + 1)² window instead, here of the albedo-demodulated light on
//! six guides, the mean shading normal and the mean first-hit position (scaled by
//! `guided_scale`, auto 1 / the scene's size), with a ridge ε on the guides' covariance; each
//! pixel then evaluates the average of the models of the windows that cover it, each model
//! weighted by its count of surface pixels. A window holds the surface pixels only (select.rs
//! `surface`, with the open margin as the non-local means count it); the other pixels are left
//! to the other candidates.
//!
//! Every window's sums are box sums, rows first then columns (`bmfr_guided_rows`,
//! `bmfr_guided_solve`, `bmfr_guided_average_rows`, `bmfr_guided_eval`), so the cost does not
//! grow with r²: 91 moments per pixel (1, the six guides, their 21 products, the nine targets
//! and the 54 guide × target products), a 6 × 6 Cholesky solve for nine right-hand sides per
//! window (the light of the frame, of the odd and of the even half, three channels each: the
//! model is linear in the light, so the halves share the frame's guides), then 64 sums of the
//! models.
//!
//! Its error, as the non-local means' (NFOR's cross-filtering): G = ((g(o) − e)² − v_e +
//! (g(e) − o)² − v_o) / 2 per channel, weighed as the other terms with the relative sums; the
//! selection blends it with weight 1 / E_g², E_g = G / 2 over the window's V (the frame's
//! filter has about half the variance of each half's). The blend of the other three
//! candidates is Σ w_k c_k / W; adding a fourth is (W · blend + w_g g) / (W + w_g), so the
//! selection kernels keep the weight W in the output's fourth channel and `bmfr_guided_blend`
//! adds the guided filter after them (the packed selection adds it itself, with the window
//! sums it already has: `bmfr_guided_join`).
//!
//! On CPU devices the packed kernels (kernels/filters/bmfr_guided_packed.cl) take 16 pixels
//! per work-item on float16 lanes, the same bytes: 12x faster than the one-pixel kernels on
//! PoCL, 63-79 ms at 512² against about 200 ms for the rest of bmfr on an AVX2 CPU.
//!
//! Settings chosen with a double-precision prototype of this reference, then the kernels'
//! error on 13 scenes and their cost (off by default: its error is higher on two of them, and
//! it adds 35-45 % to bmfr's time on grids): results/README.md, bmfr, "Stop 57" and "Stop 58".

// Index loops on purpose: each mirrors a loop of the kernel, whose order fixes the bits.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use super::nlm::{RELATIVE_EPSILON, SURFACE, beauty, even};
use super::reference::albedo;
use super::select::window_indices;
use crate::layout::{FilterVector, Float4};

/// Guides per pixel: the mean shading normal and the scaled mean first-hit position.
pub const GUIDES: usize = 6;

/// Right-hand sides: the demodulated light of the frame, the odd half and the even half.
pub const TARGETS: usize = 9;

/// Moments summed over a window: count, guides, their products (upper triangle), targets and
/// guide × target products (bmfr_guided.cl BMFR_GUIDED_MOMENTS).
pub const MOMENTS: usize = 1 + GUIDES + GUIDES * (GUIDES + 1) / 2 + TARGETS + GUIDES * TARGETS;

/// Floats of a window's model, weighted by its count: the slopes, the offsets and the count
/// (bmfr_guided.cl BMFR_GUIDED_MODEL).
pub const MODEL: usize = GUIDES * TARGETS + TARGETS + 1;

// device.rs writes the models' row sums into the moments' planes.
const _: () = assert!(MODEL <= MOMENTS);

/// bmfr_guided.cl `bmfr_guided_guides`.
fn guides(f: &FilterVector, p: &Float4, scale: f32) -> [f32; GUIDES] {
    [
        f.normal[0],
        f.normal[1],
        f.normal[2],
        p.0[0] * scale,
        p.0[1] * scale,
        p.0[2] * scale,
    ]
}

/// bmfr_guided.cl `bmfr_guided_moments`: the pixel's terms of the window sums.
fn moments(f: &FilterVector, p: &Float4, odd: &Float4, spp: f32, scale: f32) -> [f32; MOMENTS] {
    let x = guides(f, p, scale);
    let b = beauty(f);
    let e = even(b, odd, spp);
    let al = albedo(f);
    let t: [f32; TARGETS] = std::array::from_fn(|k| {
        let v = match k / 3 {
            0 => b[k % 3],
            1 => odd.0[k % 3],
            _ => e[k % 3],
        };
        v / al[k % 3]
    });
    let mut q = [0f32; MOMENTS];
    q[0] = 1.0;
    q[1..1 + GUIDES].copy_from_slice(&x);
    let mut n = 1 + GUIDES;
    for a in 0..GUIDES {
        for bb in a..GUIDES {
            q[n] = x[a] * x[bb];
            n += 1;
        }
    }
    q[n..n + TARGETS].copy_from_slice(&t);
    n += TARGETS;
    for d in 0..GUIDES {
        for k in 0..TARGETS {
            q[n] = x[d] * t[k];
            n += 1;
        }
    }
    q
}

/// bmfr_guided.cl `bmfr_guided_solve` for one window's sums: the model times the count.
fn solve(s: &[f32; MOMENTS], ridge: f32) -> [f32; MODEL] {
    let mut out = [0f32; MODEL];
    let m = s[0];
    if !(m >= 1.0) {
        return out;
    }
    let xm: [f32; GUIDES] = std::array::from_fn(|d| s[1 + d] / m);
    let base_t = 1 + GUIDES + GUIDES * (GUIDES + 1) / 2;
    let tm: [f32; TARGETS] = std::array::from_fn(|k| s[base_t + k] / m);
    let mut c = [[0f32; GUIDES]; GUIDES];
    let mut n = 1 + GUIDES;
    for a in 0..GUIDES {
        for b in a..GUIDES {
            let v = s[n] / m - xm[a] * xm[b];
            c[a][b] = if a == b { v + ridge } else { v };
            c[b][a] = c[a][b];
            n += 1;
        }
    }
    let base_xt = base_t + TARGETS;
    // Cholesky, lower triangle; a pivot that rounding took below the ridge is the ridge.
    let mut l = [[0f32; GUIDES]; GUIDES];
    for i in 0..GUIDES {
        for j in 0..=i {
            let mut v = c[i][j];
            for k in 0..j {
                v -= l[i][k] * l[j][k];
            }
            l[i][j] = if i == j { v.max(ridge).sqrt() } else { v / l[j][j] };
        }
    }
    for k in 0..TARGETS {
        let mut y = [0f32; GUIDES];
        for i in 0..GUIDES {
            let mut v = s[base_xt + i * TARGETS + k] / m - xm[i] * tm[k];
            for j in 0..i {
                v -= l[i][j] * y[j];
            }
            y[i] = v / l[i][i];
        }
        let mut a = [0f32; GUIDES];
        for i in (0..GUIDES).rev() {
            let mut v = y[i];
            for j in i + 1..GUIDES {
                v -= l[j][i] * a[j];
            }
            a[i] = v / l[i][i];
        }
        let mut b = tm[k];
        for d in 0..GUIDES {
            b -= a[d] * xm[d];
            out[d * TARGETS + k] = m * a[d];
        }
        out[GUIDES * TARGETS + k] = m * b;
    }
    out[MODEL - 1] = m;
    out
}

/// Sums of `values` (`N` per pixel) over each pixel's window, rows first (the pixels x − r ..
/// x + r of its row inside the image, left to right), then columns (the row sums of y − r ..
/// y + r, top to bottom), as bmfr_guided.cl's row and column passes add them.
fn box_sums<const N: usize>(values: &[[f32; N]], dims: (u32, u32), r: i32) -> Vec<[f32; N]> {
    line_sums(&line_sums(values, dims, r, true), dims, r, false)
}

/// One pass of [`box_sums`]: per pixel, the sum of `values` over the 2 r + 1 pixels of its
/// row (`along_rows`) or its column centred on it, inside the image, in increasing order.
fn line_sums<const N: usize>(
    values: &[[f32; N]],
    (w, h): (u32, u32),
    r: i32,
    along_rows: bool,
) -> Vec<[f32; N]> {
    (0..values.len())
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let (centre, len) = if along_rows { (x, w) } else { (y, h) };
            let mut acc = [0f32; N];
            for t in (centre - r).max(0)..=(centre + r).min(len as i32 - 1) {
                let (xx, yy) = if along_rows { (t, y) } else { (x, t) };
                let v = &values[(yy as u32 * w + xx as u32) as usize];
                for c in 0..N {
                    acc[c] += v[c];
                }
            }
            acc
        })
        .collect()
}

/// Per pixel: the guided filter of the frame's light (modulated back) and its cross-half
/// error term G (module docs), both zero off the surface class. `fit` and `smooth` are the
/// fit's and the frame's non-local means' light (the relative sums' level).
#[allow(clippy::too_many_arguments)]
pub fn guided(
    fv: &[FilterVector],
    pos: &[Float4],
    odd: &[Float4],
    (w, h): (u32, u32),
    spp: f32,
    (radius, ridge, scale): (u32, f32, f32),
    classes: &[f32],
    fit: &[[f32; 3]],
    smooth: &[[f32; 3]],
    relative: bool,
) -> Vec<[f32; 4]> {
    let r = radius as i32;
    let q: Vec<[f32; MOMENTS]> = (0..fv.len())
        .into_par_iter()
        .map(|i| match classes[i] == SURFACE {
            true => moments(&fv[i], &pos[i], &odd[i], spp, scale),
            false => [0.0; MOMENTS],
        })
        .collect();
    let sums = box_sums(&q, (w, h), r);
    drop(q);
    let models: Vec<[f32; MODEL]> = sums.par_iter().map(|s| solve(s, ridge)).collect();
    drop(sums);
    let averaged = box_sums(&models, (w, h), r);
    (0..fv.len())
        .into_par_iter()
        .map(|i| {
            if classes[i] != SURFACE {
                return [0.0; 4];
            }
            let f = &fv[i];
            let s = &averaged[i];
            let x = guides(f, &pos[i], scale);
            let al = albedo(f);
            let count = s[MODEL - 1];
            let g: [f32; TARGETS] = std::array::from_fn(|k| {
                let mut v = s[GUIDES * TARGETS + k] / count;
                for d in 0..GUIDES {
                    v += s[d * TARGETS + k] / count * x[d];
                }
                v.max(0.0) * al[k % 3]
            });
            let b = beauty(f);
            let o = &odd[i];
            let e = even(b, o, spp);
            let (n_odd, n_even) = (o.0[3], spp - o.0[3]);
            let mut term = 0f32;
            for c in 0..3 {
                let oe = o.0[c] - e[c];
                let (v_odd, v_even) = (oe * oe * (n_even / spp), oe * oe * (n_odd / spp));
                let (go, ge) = (g[3 + c] - e[c], g[6 + c] - o.0[c]);
                let mut t = 0.5 * ((go * go - v_even) + (ge * ge - v_odd));
                if relative {
                    let level = fit[i][c].max(smooth[i][c]);
                    t *= 1.0 / (level * level + RELATIVE_EPSILON);
                }
                term += t;
            }
            [g[0], g[1], g[2], term]
        })
        .collect()
}

/// kernels/filters/bmfr_guided.cl `bmfr_guided_blend` (`bmfr_guided_join`) for pixel (x, y):
/// the selection's blend `selected` of weight `weight` (0: the selection made no blend, kept
/// as it is) with the guided filter, weighted by 1 / E_g² (module docs). `residuals`: nlm.rs
/// `residual`'s (V, R, N, class); `guided`: [`guided`]'s.
pub fn blend(
    residuals: &[[f32; 4]],
    guided: &[[f32; 4]],
    (width, height): (u32, u32),
    (x, y): (i32, i32),
    radius: i32,
    (selected, weight): ([f32; 3], f32),
) -> [f32; 3] {
    let i = (y as u32 * width + x as u32) as usize;
    if residuals[i][3] != SURFACE || !(weight > 0.0) {
        return selected;
    }
    let (mut v, mut g) = (0f32, 0f32);
    window_indices((width, height), (x, y), radius, |j| {
        if residuals[j][3] == SURFACE {
            v += residuals[j][0];
            g += guided[j][3];
        }
    });
    let e_g = (0.5 * g / v).max(1.0e-6);
    let w_g = 1.0 / (e_g * e_g);
    let out = guided[i];
    std::array::from_fn(|c| (weight * selected[c] + w_g * out[c]) / (weight + w_g))
}
