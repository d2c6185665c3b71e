//! The plain Rust reference of kernels/filters/aaf_shadows.cl: the same float operations in the
//! same order, pass by pass.

use anyhow::Result;
use glam::Vec3;
use rayon::prelude::*;

use super::AafShadowSettings;
use crate::imaging::RgbImage;
use crate::layout::outputs::BufferId;
use crate::layout::{AafShadowParams, FilterVector, ShadowPixel, ShadowTerms};
use crate::render::Frame;
use crate::render::shadows::bandlimit::beta;

/// What a pixel is to the filter (kernels/filters/aaf_shadows.cl `AAF_*`).
pub const NONE: f32 = 0.0;
pub const LIT: f32 = 1.0;
pub const FILTERED: f32 = 2.0;

/// Per pixel: the noisy visibility h_n, β (0 without slopes) and the kind.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Guide {
    pub visibility: f32,
    pub beta: f32,
    pub kind: f32,
}

/// `aaf_prepare`.
pub fn prepare(p: &AafShadowParams, pixels: &[ShadowPixel]) -> Vec<Guide> {
    pixels
        .par_iter()
        .map(|px| {
            let mut g = Guide::default();
            if px.weight > 0.0 {
                g.visibility = px.visible / px.weight;
                if px.slope_source > 0.0 {
                    g.beta = beta(p.sigma, px.pixel_size, px.slope_min);
                    g.kind = FILTERED;
                } else {
                    g.kind = LIT;
                }
            }
            g
        })
        .collect()
}

/// `aaf_pass`: one 1-D pass along `p.axis` over `input`.
pub fn pass(
    p: &AafShadowParams,
    pixels: &[ShadowPixel],
    guide: &[Guide],
    input: &[f32],
) -> Vec<f32> {
    let (w, h) = (p.width as i32, p.height as i32);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let g = guide[i as usize];
            if g.kind != FILTERED {
                return input[i as usize];
            }
            let px = &pixels[i as usize];
            let pos = Vec3::from(px.position);
            let normal = Vec3::from(px.normal);
            let to_light = (p.light.xyz() - pos).normalize();
            let b = g.beta;
            let inv_two_beta2 = (1.0 / (2.0 * b * b)).min(f32::MAX);
            let (c, n, stride) = if p.axis == 0 { (x, w, 1) } else { (y, h, w) };
            let (mut sum, mut sum_w) = (input[i as usize], 1.0f32);
            for k in (c - p.radius).max(0)..=(c + p.radius).min(n - 1) {
                if k == c {
                    continue;
                }
                let j = (i + (k - c) * stride) as usize;
                let gj = guide[j];
                if gj.kind == NONE {
                    continue;
                }
                let q = &pixels[j];
                if normal.dot(Vec3::from(q.normal)) < p.normal_cos {
                    continue;
                }
                let delta = Vec3::from(q.position) - pos;
                let along = delta.dot(to_light);
                if along.abs() > p.depth_tolerance * b {
                    continue;
                }
                if gj.kind == FILTERED && (b - gj.beta).abs() > p.beta_tolerance * b.max(gj.beta)
                {
                    continue;
                }
                let r2 = (delta.dot(delta) - along * along).max(0.0);
                let wgt = (-r2 * inv_two_beta2).exp();
                sum += wgt * input[j];
                sum_w += wgt;
            }
            sum / sum_w
        })
        .collect()
}

/// `aaf_compose`: F − the replaced light + r · visibility (F as is for no receiver).
pub fn compose(
    fv: &[FilterVector],
    terms: &[ShadowTerms],
    pixels: &[ShadowPixel],
    guide: &[Guide],
    visibility: &[f32],
    width: u32,
    height: u32,
) -> RgbImage {
    let pixels = (0..fv.len())
        .into_par_iter()
        .map(|i| {
            let f = &fv[i];
            let beauty: [f32; 3] = std::array::from_fn(|c| f.direct[c] + f.indirect[c]);
            if guide[i].kind == NONE {
                return beauty;
            }
            let (t, p) = (&terms[i], &pixels[i]);
            std::array::from_fn(|c| {
                (beauty[c] - t.direct[c]) + p.unshadowed[c] / p.samples * visibility[i]
            })
        })
        .collect();
    RgbImage {
        width,
        height,
        pixels,
    }
}

/// The whole filter on `frame` for the light `light` (centre, radius); None: the beauty.
pub fn reference(
    frame: &Frame,
    s: &AafShadowSettings,
    light: Option<[f32; 4]>,
) -> Result<RgbImage> {
    s.validate()?;
    let Some(light) = light else {
        return frame.beauty();
    };
    let (w, h) = (frame.width(), frame.height());
    let pixels: &[ShadowPixel] = frame.host_slice(BufferId::ShadowPixels)?;
    let terms: &[ShadowTerms] = frame.host_slice(BufferId::ShadowTerms)?;
    let p0 = s.params(light, w, h, 0);
    let p1 = s.params(light, w, h, 1);
    let guide = prepare(&p0, pixels);
    let v0: Vec<f32> = guide.iter().map(|g| g.visibility).collect();
    let v1 = pass(&p0, pixels, &guide, &v0);
    let v2 = pass(&p1, pixels, &guide, &v1);
    Ok(compose(frame.filter_vectors()?, terms, pixels, &guide, &v2, w, h))
}
