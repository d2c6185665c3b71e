//! The plain Rust reference of kernels/filters/bmfr.cl: the same float operations in the same
//! order, the work-group's reductions included (per work-item partial sums over its rows
//! r = t + q·WG, then summed over the work-items in order).

use anyhow::{Context as _, Result, bail};
use rayon::prelude::*;

use super::guided;
use super::prefilter::prefilter;
use super::{emission, nlm, outliers, select};
use super::{
    ALBEDO_EPSILON, BmfrSettings, INFO_FLOATS, PIVOT_MIN, TARGETS, WORK_GROUP, blocks_per_grid,
    grid_blocks, grid_offset,
};
use crate::imaging::RgbImage;
use crate::layout::outputs::BufferId;
use crate::layout::{FilterVector, Float4, SKY_DEPTH};
use crate::render::Frame;
use crate::render::cpu::rng::hash_u32;

/// kernels/filters/bmfr.cl `bmfr_albedo`: the albedo clamped below at [`ALBEDO_EPSILON`].
pub(super) fn albedo(f: &FilterVector) -> [f32; 3] {
    f.albedo.map(|a| a.max(ALBEDO_EPSILON))
}

/// kernels/filters/bmfr.cl `bmfr_kept`: sky, a light seen directly ([`light`]), or a pixel
/// whose samples did not all hit a surface. `split`: the emission was taken out of F
/// (`emission`).
pub fn kept(f: &FilterVector, p: &Float4, spp: f32, split: bool) -> bool {
    f.depth >= SKY_DEPTH || light(f, split) || p.0[3] < spp
}

/// kernels/filters/bmfr.cl `bmfr_light`: a light seen directly, its albedo the emission's
/// chromaticity (largest channel 1), no indirect light (paths end at emitters) and, unless the
/// emission was taken out of F (`split`, emission.rs), some direct light: its emission. Clear
/// glass whose samples all ended black has the same albedo and no light; taken for a light, it
/// was kept black (Outside 512², 8 spp: 29 pixels, MSE-LUV 2.382 → 2.333 filtered;
/// results/README.md, bmfr, "Stop 47"). With the split a light's direct light is 0 too, and
/// such glass is still kept.
pub(super) fn light(f: &FilterVector, split: bool) -> bool {
    f.albedo[0].max(f.albedo[1].max(f.albedo[2])) >= 1.0
        && f.indirect == [0.0; 3]
        && (split || f.direct != [0.0; 3])
}

fn raw(f: &FilterVector, p: &Float4) -> [f32; 4] {
    [p.0[0], p.0[1], p.0[2], f.depth]
}

/// kernels/filters/bmfr.cl `bmfr_features`.
fn features(s: &BmfrSettings, f: &FilterVector, raw: [f32; 4], lo: [f32; 4], scale: [f32; 4]) -> Vec<f32> {
    let v: [f32; 4] = std::array::from_fn(|k| (raw[k] - lo[k]) * scale[k]);
    let mut out = vec![1.0, f.normal[0], f.normal[1], f.normal[2], v[0], v[1], v[2]];
    out.extend([v[0] * v[0], v[1] * v[1], v[2] * v[2]]);
    if s.depth {
        out.push(v[3]);
    }
    if s.texture {
        out.extend(f.albedo);
    }
    if s.texture2 {
        out.extend(f.albedo2);
    }
    out
}

/// kernels/filters/bmfr.cl `bmfr_noise`.
fn noise(s: &BmfrSettings, pixel: u32, column: u32) -> f32 {
    let h = hash_u32(hash_u32(pixel ^ 0x62d3_f1a7) ^ column);
    ((h >> 8) as f32 * (1.0 / 16_777_216.0) - 0.5) * s.noise as f32
}

/// kernels/filters/bmfr.cl `bmfr_tent`.
fn tent(l: i32, block: u32) -> f32 {
    let d = (l as f32 + 0.5 - 0.5 * block as f32).abs();
    1.0 - d / (0.5 * block as f32)
}

/// One block's fit: (6 × K weights, block information), as `bmfr_fit` leaves them.
#[allow(clippy::needless_range_loop)] // indices mirror the kernel's
fn fit_block(
    s: &BmfrSettings,
    fv: &[FilterVector],
    pos: &[Float4],
    (w, h): (u32, u32),
    (x0, y0): (i32, i32),
    spp: f32,
) -> (Vec<f32>, [f32; INFO_FLOATS]) {
    let b = s.block_size as i32;
    let n = (b * b) as usize;
    let wg = (WORK_GROUP as usize).min(n);
    let rows = n / wg;
    let k = s.features();
    let cols = k + TARGETS;
    let pixel = |r: usize| -> Option<usize> {
        let (x, y) = (x0 + r as i32 % b, y0 + r as i32 / b);
        if x < 0 || y < 0 || x >= w as i32 || y >= h as i32 {
            return None;
        }
        let i = (y as u32 * w + x as u32) as usize;
        (!kept(&fv[i], &pos[i], spp, s.splits_emission())).then_some(i)
    };
    let mut a = vec![0f32; cols * n];
    // Per work-item minimum, maximum and count, reduced in work-item order.
    let mut lo = [f32::INFINITY; 4];
    let mut hi = [f32::NEG_INFINITY; 4];
    let mut count = 0f32;
    for t in 0..wg {
        let (mut l, mut m, mut c) = ([f32::INFINITY; 4], [f32::NEG_INFINITY; 4], 0f32);
        for q in 0..rows {
            let r = t + q * wg;
            let Some(i) = pixel(r) else { continue };
            let v = raw(&fv[i], &pos[i]);
            for j in 0..4 {
                l[j] = l[j].min(v[j]);
                m[j] = m[j].max(v[j]);
            }
            c += 1.0;
            let al = albedo(&fv[i]);
            for ch in 0..3 {
                a[(k + ch) * n + r] = fv[i].direct[ch] / al[ch];
                a[(k + 3 + ch) * n + r] = fv[i].indirect[ch] / al[ch];
            }
        }
        for j in 0..4 {
            lo[j] = if t == 0 { l[j] } else { lo[j].min(l[j]) };
            hi[j] = if t == 0 { m[j] } else { hi[j].max(m[j]) };
        }
        count += c;
    }
    let mut info = [0f32; INFO_FLOATS];
    for j in 0..4 {
        if lo[j] < hi[j] {
            info[j] = lo[j];
            info[4 + j] = 1.0 / (hi[j] - lo[j]);
        }
    }
    info[8] = count;
    let (blo, bscale) = (
        [info[0], info[1], info[2], info[3]],
        [info[4], info[5], info[6], info[7]],
    );
    for r in 0..n {
        let Some(i) = pixel(r) else { continue };
        let feat = features(s, &fv[i], raw(&fv[i], &pos[i]), blo, bscale);
        a[r] = feat[0];
        for c in 1..k {
            a[c * n + r] = feat[c] + noise(s, i as u32, c as u32);
        }
    }
    // Householder QR (kernels/filters/bmfr.cl, the same reductions).
    let mut dots = vec![0f32; cols];
    let mut factor = vec![0f32; cols];
    for j in 0..k {
        for c in j..cols {
            let mut sum = 0f32;
            for t in 0..wg {
                let mut p = 0f32;
                for q in 0..rows {
                    let r = t + q * wg;
                    if r >= j {
                        p += a[j * n + r] * a[c * n + r];
                    }
                }
                sum += p;
            }
            dots[c] = sum;
        }
        let norm2 = dots[j];
        let xj = a[j * n + j];
        let norm = norm2.sqrt();
        let alpha = if xj > 0.0 { -norm } else { norm };
        let vj = xj - alpha;
        let vnorm2 = norm2 - xj * xj + vj * vj;
        factor[j] = vj;
        for c in j + 1..cols {
            factor[c] = if vnorm2 > 0.0 {
                2.0 * (dots[c] - alpha * a[c * n + j]) / vnorm2
            } else {
                0.0
            };
        }
        for r in j..n {
            let v = if r == j { vj } else { a[j * n + r] };
            for c in j + 1..cols {
                a[c * n + r] -= factor[c] * v;
            }
        }
        a[j * n + j] = alpha;
    }
    let mut weights = vec![0f32; TARGETS * k];
    for t in 0..TARGETS {
        let wt = &mut weights[t * k..(t + 1) * k];
        for j in (0..k).rev() {
            let mut sum = a[(k + t) * n + j];
            for i in j + 1..k {
                sum -= a[i * n + j] * wt[i];
            }
            let rjj = a[j * n + j];
            wt[j] = if rjj.abs() > PIVOT_MIN { sum / rjj } else { 0.0 };
        }
    }
    (weights, info)
}

/// The plain Rust reference of kernels/filters/bmfr.cl: every block of every grid fitted, then
/// each pixel's fits blended, then (with `select`) each pixel blended with its unfiltered
/// light.
pub fn reference(frame: &Frame, s: &BmfrSettings) -> Result<RgbImage> {
    s.validate()?;
    let (w, h) = (frame.width(), frame.height());
    if w == 0 || h == 0 {
        bail!("the image must be at least 1x1 pixels, got {w}x{h}");
    }
    let pos: &[Float4] = frame.host_slice(BufferId::Positions)?;
    let spp = frame.info().spp as f32;
    // With `emission`: F and the odd half less the light of lights seen directly (emission.rs).
    let split = match s.splits_emission() {
        true => Some(emission::split(frame, s)?),
        false => None,
    };
    let emission_split = split.is_some();
    let fv_frame = match &split {
        Some(sp) => &sp.fv[..],
        None => frame.filter_vectors()?,
    };
    // The odd half where the filter reads it (`needs`); with `emission` its reflected copy.
    let mut odd: Option<&[Float4]> = match &split {
        Some(sp) => Some(&sp.odd),
        None if s.select || s.outliers => Some(frame.host_slice(BufferId::OddHalves)?),
        None => None,
    };
    // With `outliers`: each outlier's light replaced by its darker half's (outliers.rs).
    let replaced;
    let mut fv_frame = fv_frame;
    if let (true, Some(odd_in)) = (s.outliers, odd) {
        let ratio = s.outlier_ratio as f32;
        replaced = outliers::replace(fv_frame, pos, odd_in, (w, h), spp, emission_split, ratio);
        fv_frame = &replaced.0;
        odd = Some(&replaced.1);
    }
    let odd_frame = || odd.context("the bmfr selection reads the odd half buffer");
    let prefiltered;
    let (fv, pos): (&[FilterVector], &[Float4]) = if s.prefilters_albedo() {
        let sums = frame.host_slice(BufferId::WelfordSums)?;
        let factor = frame.variance_factor();
        prefiltered = prefilter(
            fv_frame,
            sums,
            pos,
            (w, h),
            spp,
            emission_split,
            factor,
            s.albedo_radius,
            s.prefilter_geometry.then_some(s.geometry_k as f32),
        );
        (&prefiltered.0, &prefiltered.1)
    } else {
        (fv_frame, pos)
    };
    let b = s.block_size;
    let k = s.features();
    let stride = blocks_per_grid(w, h, b) as usize;
    // (grid, block) -> fit, for every block of every grid.
    let fits: Vec<Vec<(Vec<f32>, [f32; INFO_FLOATS])>> = (0..s.grids)
        .map(|g| {
            let off = grid_offset(g, s.grids, b);
            let (across, down) = grid_blocks(w, h, b, off);
            (0..across * down)
                .into_par_iter()
                .map(|blk| {
                    let x0 = (blk % across * b) as i32 - off.0;
                    let y0 = (blk / across * b) as i32 - off.1;
                    fit_block(s, fv, pos, (w, h), (x0, y0), spp)
                })
                .collect()
        })
        .collect();
    debug_assert!(fits.iter().all(|f| f.len() <= stride));
    let pixels = (0..(w * h) as usize)
        .into_par_iter()
        .map(|i| {
            let f = &fv[i];
            let beauty: [f32; 3] = std::array::from_fn(|c| f.direct[c] + f.indirect[c]);
            if kept(f, &pos[i], spp, emission_split) {
                return beauty;
            }
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let rw = raw(f, &pos[i]);
            let al = albedo(f);
            let mut sum = [0f32; 3];
            let mut wsum = 0f32;
            for g in 0..s.grids {
                let off = grid_offset(g, s.grids, b);
                let (across, _) = grid_blocks(w, h, b, off);
                let (bx, by) = ((x + off.0) / b as i32, (y + off.1) / b as i32);
                let (wt, info) = &fits[g as usize][(by * across as i32 + bx) as usize];
                let feat = features(
                    s,
                    f,
                    rw,
                    [info[0], info[1], info[2], info[3]],
                    [info[4], info[5], info[6], info[7]],
                );
                let fit: [f32; TARGETS] = std::array::from_fn(|c| {
                    let mut v = 0f32;
                    for j in 0..k {
                        v += wt[c * k + j] * feat[j];
                    }
                    v.max(0.0)
                });
                let light: [f32; 3] = std::array::from_fn(|c| (fit[c] + fit[c + 3]) * al[c]);
                let wg = tent(x + off.0 - bx * b as i32, b)
                    * tent(y + off.1 - by * b as i32, b)
                    * 1f32.min(info[8] / (4.0 * k as f32));
                for c in 0..3 {
                    sum[c] += wg * light[c];
                }
                wsum += wg;
            }
            sum.map(|v| v / wsum)
        })
        .collect::<Vec<[f32; 3]>>();
    let pixels = if s.uses_nlm() {
        let odd = odd_frame()?;
        let r = (s.nlm_radius, s.estimate_radius(), s.nlm_patch);
        let k = s.nlm_k() as f32;
        let classes = nlm::classes(fv, pos, odd, (w, h), spp, s.open_margin(), emission_split);
        let smooth = nlm::nlm(fv, odd, (w, h), spp, r, k, &classes);
        let residuals: Vec<[f32; 4]> = (0..pixels.len())
            .into_par_iter()
            .map(|i| {
                let (fit, smooth) = (pixels[i], &smooth[i]);
                let relative = s.select_relative;
                nlm::residual(&fv[i], &odd[i], spp, fit, smooth, relative, classes[i])
            })
            .collect();
        let fourth = s.guided.then(|| {
            let frame_smooth: Vec<[f32; 3]> = smooth.iter().map(|m| m[0]).collect();
            let settings = (s.guided_radius, s.guided_ridge as f32, s.guided_scale() as f32);
            let (relative, dims) = (s.select_relative, (w, h));
            guided::guided(fv, pos, odd, dims, spp, settings, &classes, &pixels, &frame_smooth, relative)
        });
        (0..pixels.len())
            .into_par_iter()
            .map(|i| {
                let xy = ((i as u32 % w) as i32, (i as u32 / w) as i32);
                let r = s.select_radius as i32;
                let trust = (s.select_scale as f32, s.select_floor());
                let (fit, smooth) = (pixels[i], smooth[i][0]);
                let blend = nlm::select(&fv[i], &residuals, (w, h), xy, r, trust, fit, smooth);
                match &fourth {
                    Some(g) => guided::blend(&residuals, g, (w, h), xy, r, blend),
                    None => blend.0,
                }
            })
            .collect()
    } else if s.select {
        let odd = odd_frame()?;
        let residuals: Vec<[f32; 2]> = (0..pixels.len())
            .into_par_iter()
            .map(|i| select::residual(&fv[i], &pos[i], &odd[i], spp, emission_split, pixels[i]))
            .collect();
        (0..pixels.len())
            .into_par_iter()
            .map(|i| {
                let xy = ((i as u32 % w) as i32, (i as u32 / w) as i32);
                let r = s.select_radius as i32;
                let scale = s.select_scale as f32;
                select::select(&fv[i], &residuals, (w, h), xy, r, scale, pixels[i])
            })
            .collect()
    } else {
        pixels
    };
    let pixels = match &split {
        Some(sp) => pixels
            .iter()
            .zip(&sp.emitted)
            .map(|(p, e)| std::array::from_fn(|c| p[c] + e[c]))
            .collect(),
        None => pixels,
    };
    Ok(RgbImage {
        width: w,
        height: h,
        pixels,
    })
}
