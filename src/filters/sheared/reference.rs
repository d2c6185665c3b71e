//! The plain Rust reference of kernels/filters/sheared.cl: the same float operations in the
//! same order, step by step (prepare, 1a, 1b, 2a, 2b, compose), and the 4-D brute force of
//! eq. 9 that the factored steps approximate, and the whole shadows filter over several lights
//! ([`image`]). src/filters/sheared/mod.rs says why.

use anyhow::Result;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::ShearedSettings;
use super::shear::{bin_centre, bin_of, cap_sigma_x, eta, gauss, radius, sigma_x};
use crate::imaging::RgbImage;
use crate::layout::outputs::BufferId;
use crate::layout::{LightFieldPixel, ShadowPixel, ShadowTerms, ShearedParams};
use crate::render::Frame;
use crate::render::shadows::light_field::grid_coordinate;

/// What a pixel is to the filter (kernels/filters/sheared.cl `SHEARED_*`).
pub const NONE: f32 = 0.0;
pub const LIT: f32 = 1.0;
pub const FILTERED: f32 = 2.0;

/// Per pixel: σ_x (world), η, the kind, 0 (kernels/filters/sheared.cl's float4 guide; the
/// kind in the lane where AAF's guide has it, so that AAF's compose pass serves both).
pub type Guide = [f32; 4];
pub const SIGMA: usize = 0;
pub const ETA: usize = 1;
pub const KIND: usize = 2;

/// Floats per pixel of step 1a's output: p and its weight for every (bin, row).
pub fn p_floats(bins: u32) -> usize {
    2 * bins as usize * 4
}

/// Floats per pixel of steps 1b and 2a: g (or q) and its weight per bin.
pub fn g_floats(bins: u32) -> usize {
    2 * bins as usize
}

/// One gather step along a screen direction (the major axis moves one pixel), and the world
/// units of x per step.
pub fn step(dir: [f32; 2], scale: f32) -> (Vec2, f32) {
    let d = Vec2::from(dir);
    let m = d.x.abs().max(d.y.abs());
    if !(m > 0.0) {
        return (Vec2::X, 0.0);
    }
    let s = d / m;
    (s, scale * s.length())
}

/// `sheared_prepare`: the kind, σ_x from eq. 4 (capped) and η from eq. 5 (corrected).
pub fn prepare(p: &ShearedParams, shadow: &[ShadowPixel], field: &[LightFieldPixel]) -> Vec<Guide> {
    shadow
        .par_iter()
        .zip(field)
        .map(|(px, lf)| {
            if !(px.weight > 0.0) || !(lf.count > 0.0) {
                return [0.0, 0.0, NONE, 0.0];
            }
            if px.slope_source == 0.0 {
                return [0.0, 0.0, LIT, 0.0];
            }
            let w1 = step(lf.dir1, lf.scale[0]).1;
            let w2 = step(lf.dir2, lf.scale[1]).1;
            let sx = sigma_x(p.sigma_y, px.slope_min, px.slope_max);
            let sx = cap_sigma_x(sx, [w1, w2], p.max_radius);
            [sx, eta(px.slope_min, px.slope_max, p.shear), FILTERED, 0.0]
        })
        .collect()
}

/// `sheared_1a` (eq. 12): per pixel, for each bin c of the free y1 and each row b of the grid,
/// p = Σ_a f(a, b) w_y(y1(a) − y_c) and its weight Σ_a w_y(y1(a) − y_c).
pub fn step_1a(p: &ShearedParams, field: &[LightFieldPixel], guide: &[Guide]) -> Vec<f32> {
    let (bins, l) = (p.bins as usize, p.side);
    let inv = (1.0 / (2.0 * p.sigma_y * p.sigma_y)).min(f32::MAX);
    let radius_l = p.light.0[3];
    let mut out = vec![0f32; field.len() * p_floats(p.bins)];
    out.par_chunks_mut(p_floats(p.bins))
        .zip(field.par_iter().zip(guide))
        .for_each(|(o, (lf, g))| {
            if g[KIND] == NONE {
                return;
            }
            for c in 0..bins {
                let yc = bin_centre(c as u32, p.bins, p.range);
                // w_y of column a, the same for every row.
                let mut wy = [0f32; 4];
                for a in 0..l {
                    wy[a as usize] = gauss(grid_coordinate(a, lf.jitter[0], l, radius_l) - yc, inv);
                }
                for b in 0..l {
                    let (mut v, mut w) = (0f32, 0f32);
                    for a in 0..l {
                        v += lf.samples[(b * l + a) as usize] * wy[a as usize];
                        w += wy[a as usize];
                    }
                    o[c * 4 + b as usize] = v;
                    o[bins * 4 + c * 4 + b as usize] = w;
                }
            }
        });
    out
}

/// Whether neighbour `q` may lend to the pixel `px` with guide `g`: a receiver, normals within
/// the angle, offset along the light direction within the tolerance (kernels/filters/
/// sheared.cl `sheared_accepts`).
fn accepts(p: &ShearedParams, px: &ShadowPixel, g: &Guide, q: &ShadowPixel, gq: &Guide) -> bool {
    if gq[KIND] == NONE {
        return false;
    }
    let normal = Vec3::from(px.normal);
    if normal.dot(Vec3::from(q.normal)) < p.normal_cos {
        return false;
    }
    let pos = Vec3::from(px.position);
    let to_light = (p.light.xyz() - pos).normalize();
    let along = (Vec3::from(q.position) - pos).dot(to_light);
    along.abs() <= p.depth_tolerance * g[SIGMA]
}

/// The pixel `k` steps from (x, y) along `s`, if inside the image.
fn neighbour(p: &ShearedParams, x: i32, y: i32, s: Vec2, k: i32) -> Option<usize> {
    let qx = (x as f32 + k as f32 * s.x).round() as i32;
    let qy = (y as f32 + k as f32 * s.y).round() as i32;
    (qx >= 0 && qy >= 0 && qx < p.width as i32 && qy < p.height as i32)
        .then(|| (qy * p.width as i32 + qx) as usize)
}

/// The gather of steps 1b (`axis` 0) and 2b (`axis` 1) around pixel `i` (a receiver): every
/// accepted neighbour j along the screen image of x_axis, with its w_x(x′ − x) and the bin of
/// y = η (x − x′) (skipped beyond the bins), in walk order.
fn gather(
    p: &ShearedParams,
    shadow: &[ShadowPixel],
    field: &[LightFieldPixel],
    guide: &[Guide],
    i: usize,
    axis: usize,
    mut visit: impl FnMut(usize, f32, u32),
) {
    let g = guide[i];
    let (x, y) = ((i as u32 % p.width) as i32, (i as u32 / p.width) as i32);
    let (px, lf) = (&shadow[i], &field[i]);
    let (dir, e) = if axis == 0 {
        (lf.dir1, p.axis1.xyz())
    } else {
        (lf.dir2, p.axis2.xyz())
    };
    let (s, world) = step(dir, lf.scale[axis]);
    let r = radius(g[SIGMA], world, p.max_radius);
    let inv_x = (1.0 / (2.0 * g[SIGMA] * g[SIGMA])).min(f32::MAX);
    let pos = Vec3::from(px.position);
    for k in -r..=r {
        let Some(j) = neighbour(p, x, y, s, k) else {
            continue;
        };
        if k != 0 && !accepts(p, px, &g, &shadow[j], &guide[j]) {
            continue;
        }
        let dx = (Vec3::from(shadow[j].position) - pos).dot(e);
        let wx = gauss(dx, inv_x);
        if let Some(c) = bin_of(g[ETA] * -dx, p.bins, p.range) {
            visit(j, wx, c);
        }
    }
}

/// `sheared_1b` (eq. 13): the gather along x1. Each neighbour x1′ gives the bin of
/// y1 = η (x1 − x1′) of its step-1a output, weighted by w_x(x1′ − x1); its rows land in the
/// bin nearest their own y2′ (its own jitter).
pub fn step_1b(
    p: &ShearedParams,
    shadow: &[ShadowPixel],
    field: &[LightFieldPixel],
    guide: &[Guide],
    p1a: &[f32],
) -> Vec<f32> {
    let (bins, l) = (p.bins as usize, p.side);
    let stride = p_floats(p.bins);
    let radius_l = p.light.0[3];
    let mut out = vec![0f32; field.len() * g_floats(p.bins)];
    out.par_chunks_mut(g_floats(p.bins))
        .enumerate()
        .for_each(|(i, o)| {
            if guide[i][KIND] == NONE {
                return;
            }
            gather(p, shadow, field, guide, i, 0, |j, wx, c1| {
                let src = &p1a[j * stride..(j + 1) * stride];
                for b in 0..l {
                    let y2 = grid_coordinate(b, field[j].jitter[1], l, radius_l);
                    let Some(c2) = bin_of(y2, p.bins, p.range) else {
                        continue;
                    };
                    let at = c1 as usize * 4 + b as usize;
                    o[c2 as usize] += wx * src[at];
                    o[bins + c2 as usize] += wx * src[bins * 4 + at];
                }
            });
        });
    out
}

/// `sheared_2a` (eq. 14): q(y2) = Σ_{y2′ bins} g(y2′) w_y(y2′ − y2), and its weight.
pub fn step_2a(p: &ShearedParams, guide: &[Guide], g1b: &[f32]) -> Vec<f32> {
    let bins = p.bins as usize;
    let inv = (1.0 / (2.0 * p.sigma_y * p.sigma_y)).min(f32::MAX);
    let mut out = vec![0f32; guide.len() * g_floats(p.bins)];
    out.par_chunks_mut(g_floats(p.bins))
        .enumerate()
        .for_each(|(i, o)| {
            if guide[i][KIND] == NONE {
                return;
            }
            let src = &g1b[i * 2 * bins..(i + 1) * 2 * bins];
            // w_y between two bins depends on their offset only: 2 bins - 1 values.
            let spacing = 2.0 * p.range / (bins - 1) as f32;
            let table: Vec<f32> = (0..2 * bins as i32 - 1)
                .map(|d| gauss((d - (bins as i32 - 1)) as f32 * spacing, inv))
                .collect();
            for c in 0..bins {
                let (mut v, mut w) = (0f32, 0f32);
                for c2 in 0..bins {
                    let wy = table[c2 + bins - 1 - c];
                    v += src[c2] * wy;
                    w += src[bins + c2] * wy;
                }
                o[c] = v;
                o[bins + c] = w;
            }
        });
    out
}

/// `sheared_2b` (eq. 15): the gather along x2 reading each neighbour's bin of
/// y2 = η (x2 − x2′), weighted by w_x; the visibility is the value over the weight channel
/// (the mean of the pixel's own samples where no weight arrived).
pub fn step_2b(
    p: &ShearedParams,
    shadow: &[ShadowPixel],
    field: &[LightFieldPixel],
    guide: &[Guide],
    q2a: &[f32],
) -> Vec<f32> {
    let bins = p.bins as usize;
    (0..guide.len())
        .into_par_iter()
        .map(|i| {
            if guide[i][KIND] == NONE {
                return 0.0;
            }
            let (mut v, mut w) = (0f32, 0f32);
            gather(p, shadow, field, guide, i, 1, |j, wx, c| {
                v += wx * q2a[j * 2 * bins + c as usize];
                w += wx * q2a[j * 2 * bins + bins + c as usize];
            });
            if w > 0.0 { v / w } else { own_mean(p, &field[i]) }
        })
        .collect()
}

/// The unweighted mean of a pixel's own samples.
pub fn own_mean(p: &ShearedParams, lf: &LightFieldPixel) -> f32 {
    let n = p.side * p.side;
    let mut sum = 0f32;
    for k in 0..n {
        sum += lf.samples[k as usize];
    }
    sum / n as f32
}

/// Eq. 9, the 4-D brute force the factored steps approximate, O(n² l²) per pixel: every
/// neighbour q = x + k1·step1 + k2·step2 of the window and every sample (a, b), weighted by
/// w_x(Δx1) w_x(Δx2) w_y(y1(a) − η(x1 − x1′)) w_y(y2(b) − η(x2 − x2′)) with the written
/// pixel's σ_x and η, the same rejection, and the same rule for shifts beyond the bins
/// (skipped); light coordinates exact (no bins).
pub fn brute_force(
    p: &ShearedParams,
    shadow: &[ShadowPixel],
    field: &[LightFieldPixel],
    guide: &[Guide],
) -> Vec<f32> {
    let l = p.side;
    let inv_y = (1.0 / (2.0 * p.sigma_y * p.sigma_y)).min(f32::MAX);
    let radius_l = p.light.0[3];
    (0..guide.len())
        .into_par_iter()
        .map(|i| {
            let g = guide[i];
            if g[KIND] == NONE {
                return 0.0;
            }
            let (x, y) = ((i as u32 % p.width) as i32, (i as u32 / p.width) as i32);
            let (px, lf) = (&shadow[i], &field[i]);
            let (s1, w1) = step(lf.dir1, lf.scale[0]);
            let (s2, w2) = step(lf.dir2, lf.scale[1]);
            let (r1, r2) = (
                radius(g[SIGMA], w1, p.max_radius),
                radius(g[SIGMA], w2, p.max_radius),
            );
            let inv_x = (1.0 / (2.0 * g[SIGMA] * g[SIGMA])).min(f32::MAX);
            let pos = Vec3::from(px.position);
            let (mut v, mut w) = (0f64, 0f64);
            for k2 in -r2..=r2 {
                for k1 in -r1..=r1 {
                    let qx = (x as f32 + k1 as f32 * s1.x + k2 as f32 * s2.x).round() as i32;
                    let qy = (y as f32 + k1 as f32 * s1.y + k2 as f32 * s2.y).round() as i32;
                    if qx < 0 || qy < 0 || qx >= p.width as i32 || qy >= p.height as i32 {
                        continue;
                    }
                    let j = (qy * p.width as i32 + qx) as usize;
                    if j != i && !accepts(p, px, &g, &shadow[j], &guide[j]) {
                        continue;
                    }
                    let d = Vec3::from(shadow[j].position) - pos;
                    let (dx1, dx2) = (d.dot(p.axis1.xyz()), d.dot(p.axis2.xyz()));
                    let (t1, t2) = (g[ETA] * -dx1, g[ETA] * -dx2);
                    if bin_of(t1, p.bins, p.range).is_none()
                        || bin_of(t2, p.bins, p.range).is_none()
                    {
                        continue;
                    }
                    let wx = gauss(dx1, inv_x) as f64 * gauss(dx2, inv_x) as f64;
                    let q = &field[j];
                    for b in 0..l {
                        let wy2 = gauss(grid_coordinate(b, q.jitter[1], l, radius_l) - t2, inv_y);
                        for a in 0..l {
                            let y1 = grid_coordinate(a, q.jitter[0], l, radius_l);
                            let wt = wx * gauss(y1 - t1, inv_y) as f64 * wy2 as f64;
                            v += wt * q.samples[(b * l + a) as usize] as f64;
                            w += wt;
                        }
                    }
                }
            }
            if w > 0.0 {
                (v / w) as f32
            } else {
                own_mean(p, lf)
            }
        })
        .collect()
}

/// The four steps in order: the filtered visibility of every pixel.
pub fn factored(
    p: &ShearedParams,
    shadow: &[ShadowPixel],
    field: &[LightFieldPixel],
    guide: &[Guide],
) -> Vec<f32> {
    let a = step_1a(p, field, guide);
    let b = step_1b(p, shadow, field, guide, &a);
    let c = step_2a(p, guide, &b);
    step_2b(p, shadow, field, guide, &c)
}

/// The whole shadows filter on `frame` (which holds the shadow output and the light field of
/// every light of `s`), in the kernels' order: per filtered light (their centres and radii from
/// the frame's scene), in increasing order, prepare and the four steps on that light's planes
/// with its parameters, then AAF's compose onto the image of the lights before (F for the
/// first); without a light, the beauty.
pub fn image(frame: &Frame, s: &ShearedSettings) -> Result<RgbImage> {
    s.validate()?;
    let scene = &frame.info().scene;
    let (w, h) = (frame.width(), frame.height());
    let mut image = frame.beauty()?;
    for (light, sphere) in s.lights_of(scene)? {
        let own = frame.light_plane(light, "the sheared filter")?;
        let plane = own.as_ref().unwrap_or(frame);
        let shadow: &[ShadowPixel] = plane.host_slice(BufferId::ShadowPixels)?;
        let field: &[LightFieldPixel] = plane.host_slice(BufferId::LightFieldPixels)?;
        let terms: &[ShadowTerms] = plane.host_slice(BufferId::ShadowTerms)?;
        let p = s.params(sphere, scene.scene_centre, w, h);
        let guide = prepare(&p, shadow, field);
        let visibility = factored(&p, shadow, field, &guide);
        image = compose(&image, terms, &guide, &visibility);
    }
    Ok(image)
}

/// `aaf_compose_sheared`: onto `base`, base − the light's replaced term + r · visibility, r
/// the path samples' own (`ShadowTerms::unshadowed`, over the samples `direct` is over; base
/// as is for no receiver).
pub fn compose(
    base: &RgbImage,
    terms: &[ShadowTerms],
    guide: &[Guide],
    visibility: &[f32],
) -> RgbImage {
    let out = (0..base.pixels.len())
        .into_par_iter()
        .map(|i| {
            let b = base.pixels[i];
            if guide[i][KIND] == NONE {
                return b;
            }
            let t = &terms[i];
            std::array::from_fn(|c| (b[c] - t.direct[c]) + t.unshadowed[c] * visibility[i])
        })
        .collect();
    RgbImage {
        width: base.width,
        height: base.height,
        pixels: out,
    }
}
