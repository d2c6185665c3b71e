//! The plain Rust reference of kernels/filters/aaf_shadows.cl: the same float operations in the
//! same order, pass by pass.

use anyhow::Result;
use glam::Vec3;
use rayon::prelude::*;

use super::AafShadowSettings;
use crate::filters::aaf_pass::{self, FILTERED, LIT, NONE, PassPixel};
use crate::imaging::RgbImage;
use crate::layout::outputs::BufferId;
use crate::layout::{AafShadowParams, FilterVector, ShadowPixel, ShadowTerms};
use crate::render::Frame;
use crate::render::shadows::bandlimit::beta as beta_of;

/// `aaf_prepare`: the shared pass's guide and the values (h_n in lane 0).
pub fn prepare(p: &AafShadowParams, pixels: &[ShadowPixel]) -> (Vec<PassPixel>, Vec<[f32; 4]>) {
    pixels
        .par_iter()
        .map(|px| {
            let (mut v, mut beta, mut kind) = (0.0, 0.0, NONE);
            if px.weight > 0.0 {
                v = px.visible / px.weight;
                if px.slope_source > 0.0 {
                    beta = beta_of(p.sigma, px.pixel_size, px.slope_min);
                    kind = FILTERED;
                } else {
                    kind = LIT;
                }
            }
            let position = Vec3::from(px.position);
            let axis = if kind == FILTERED {
                (p.light.xyz() - position).normalize()
            } else {
                Vec3::ZERO
            };
            let g = PassPixel {
                position,
                kind,
                normal: Vec3::from(px.normal),
                beta,
                axis,
                group: 0.0,
            };
            (g, [v, 0.0, 0.0, 0.0])
        })
        .unzip()
}

/// `aaf_compose` from F: F − the replaced light + r · visibility (F as is for no receiver).
pub fn compose(
    fv: &[FilterVector],
    terms: &[ShadowTerms],
    pixels: &[ShadowPixel],
    guide: &[PassPixel],
    visibility: &[[f32; 4]],
    width: u32,
    height: u32,
) -> RgbImage {
    let beauty = RgbImage::beauty(width, height, fv);
    compose_over(&beauty, terms, pixels, guide, visibility)
}

/// `aaf_compose` from `base` (F for the first light, `chained` the image of the lights before
/// it for the others): base − the replaced light + r · visibility (base as is for no
/// receiver).
pub fn compose_over(
    base: &RgbImage,
    terms: &[ShadowTerms],
    pixels: &[ShadowPixel],
    guide: &[PassPixel],
    visibility: &[[f32; 4]],
) -> RgbImage {
    let out = (0..base.pixels.len())
        .into_par_iter()
        .map(|i| {
            let b = base.pixels[i];
            if guide[i].kind == NONE {
                return b;
            }
            let (t, p) = (&terms[i], &pixels[i]);
            std::array::from_fn(|c| (b[c] - t.direct[c]) + p.unshadowed[c] / p.samples * visibility[i][0])
        })
        .collect();
    RgbImage {
        width: base.width,
        height: base.height,
        pixels: out,
    }
}

/// The whole filter on `frame`, every filtered light of `s` (their centres and radii from the
/// frame's scene) a light at a time, in increasing order; without one: the beauty.
pub fn reference(frame: &Frame, s: &AafShadowSettings) -> Result<RgbImage> {
    s.validate()?;
    let lights = s.lights_of(&frame.info().scene)?;
    let mut image = frame.beauty()?;
    let (w, h) = (frame.width(), frame.height());
    for (light, sphere) in lights {
        let own = frame.light_plane(light, "the aaf-shadows filter")?;
        let plane = own.as_ref().unwrap_or(frame);
        let pixels: &[ShadowPixel] = plane.host_slice(BufferId::ShadowPixels)?;
        let terms: &[ShadowTerms] = plane.host_slice(BufferId::ShadowTerms)?;
        let p0 = s.params(sphere, w, h, 0);
        let (guide, v0) = prepare(&p0, pixels);
        let v2 = aaf_pass::both(&s.pass_params(w, h), &guide, &v0);
        image = compose_over(&image, terms, pixels, &guide, &v2);
    }
    Ok(image)
}
