//! The plain Rust reference of kernels/filters/atrous.cl: the same float operations in the same
//! order, and the same pass structure.

use anyhow::{Result, bail};
use rayon::prelude::*;

use super::{ALBEDO_EPSILON, AtrousSettings, B3};
use crate::imaging::RgbImage;
use crate::layout::{AtrousParams, FilterVector, SKY_DEPTH};
use crate::render::Frame;
use crate::scene::CameraBasis;

type V3 = [f32; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn sum_sq(a: V3, b: V3) -> f32 {
    let d = sub(a, b);
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// 1/σ², finite and positive for any σ (kernels/filters/atrous.cl `atrous_inv_sq`).
fn inv_sq(sigma: f32) -> f32 {
    1.0 / (sigma * sigma).clamp(f32::MIN_POSITIVE, f32::MAX)
}

fn albedo_clamped(f: &FilterVector) -> V3 {
    f.albedo.map(|a| a.max(ALBEDO_EPSILON))
}

fn beauty(f: &FilterVector) -> V3 {
    std::array::from_fn(|c| f.direct[c] + f.indirect[c])
}

/// The unit direction of the camera ray through the centre of pixel (x, y)
/// (kernels/filters/atrous.cl `atrous_pixel_direction`).
pub fn pixel_direction(p: &AtrousParams, x: u32, y: u32) -> V3 {
    let (w, h) = (p.width as f32, p.height as f32);
    let sx = (2.0 * (x as f32 + 0.5) / w - 1.0) * p.tan_half_fov * (w / h);
    let sy = (1.0 - 2.0 * (y as f32 + 0.5) / h) * p.tan_half_fov;
    let (f, r, u) = (p.camera_forward.0, p.camera_right.0, p.camera_up.0);
    let d: V3 = std::array::from_fn(|c| f[c] + sx * r[c] + sy * u[c]);
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    d.map(|v| v / len)
}

/// The per-pixel guides of kernels/filters/atrous.cl `atrous_init`.
#[derive(Clone, Copy)]
struct Guide {
    /// depth · dir, camera-relative.
    position: V3,
    /// World size of one pixel at this depth.
    footprint: f32,
    normal: V3,
    surface: bool,
}

/// The plain Rust reference of kernels/filters/atrous.cl: init, `iterations` passes, finish.
pub fn reference(frame: &Frame, camera: &CameraBasis, s: &AtrousSettings) -> Result<RgbImage> {
    s.validate()?;
    let (w, h) = (frame.width(), frame.height());
    let fv: &[FilterVector] = frame.filter_vectors()?;
    if w == 0 || h == 0 {
        bail!("the image must be at least 1x1 pixels, got {w}x{h}");
    }
    let n = w as usize * h as usize;
    if fv.len() != n {
        bail!("{}x{} pixels but {} FilterVectors", w, h, fv.len());
    }
    let p0 = s.params(camera, w, h, 0);
    let guides: Vec<Guide> = (0..n)
        .into_par_iter()
        .map(|i| {
            let f = &fv[i];
            if f.depth >= SKY_DEPTH {
                return Guide {
                    position: [0.0; 3],
                    footprint: 0.0,
                    normal: [0.0; 3],
                    surface: false,
                };
            }
            let dir = pixel_direction(&p0, i as u32 % w, i as u32 / w);
            Guide {
                position: dir.map(|d| f.depth * d),
                footprint: f.depth * (2.0 * p0.tan_half_fov / h as f32),
                normal: f.normal,
                surface: true,
            }
        })
        .collect();
    let mut colour: Vec<V3> = fv
        .par_iter()
        .map(|f| {
            let c = beauty(f);
            if s.demodulate && f.depth < SKY_DEPTH {
                let a = albedo_clamped(f);
                std::array::from_fn(|k| c[k] / a[k])
            } else {
                c
            }
        })
        .collect();
    for iteration in 0..s.iterations {
        let p = s.params(camera, w, h, iteration);
        let input = &colour;
        let next: Vec<V3> = (0..n)
            .into_par_iter()
            .map(|i| {
                let gc = &guides[i];
                let cc = input[i];
                if !gc.surface {
                    return cc;
                }
                let step = p.step;
                let inv_c = inv_sq(p.sigma_color * 2f32.powi(-(iteration as i32)));
                let inv_n = inv_sq(p.sigma_normal);
                let inv_p = inv_sq(p.sigma_position * gc.footprint);
                let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
                let mut sum = [0f32; 3];
                let mut wsum = 0f32;
                for (ky, hy) in B3.iter().enumerate() {
                    let ny = y + (ky as i32 - 2) * step;
                    if ny < 0 || ny >= h as i32 {
                        continue;
                    }
                    for (kx, hx) in B3.iter().enumerate() {
                        let nx = x + (kx as i32 - 2) * step;
                        if nx < 0 || nx >= w as i32 {
                            continue;
                        }
                        let j = (ny as u32 * w + nx as u32) as usize;
                        let gq = &guides[j];
                        if !gq.surface {
                            continue;
                        }
                        let cq = input[j];
                        let e = sum_sq(cc, cq) * inv_c
                            + sum_sq(gc.normal, gq.normal) * inv_n
                            + sum_sq(gc.position, gq.position) * inv_p;
                        let wq = hx * hy * 1f32.min((-e).exp());
                        for c in 0..3 {
                            sum[c] += wq * cq[c];
                        }
                        wsum += wq;
                    }
                }
                sum.map(|v| v / wsum)
            })
            .collect();
        colour = next;
    }
    let pixels = colour
        .par_iter()
        .zip(fv)
        .map(|(c, f)| {
            if f.depth >= SKY_DEPTH {
                beauty(f)
            } else if s.demodulate {
                let a = albedo_clamped(f);
                std::array::from_fn(|k| c[k] * a[k])
            } else {
                *c
            }
        })
        .collect();
    Ok(RgbImage {
        width: w,
        height: h,
        pixels,
    })
}
