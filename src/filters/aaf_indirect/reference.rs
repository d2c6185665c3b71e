//! The plain Rust reference of kernels/filters/aaf_indirect.cl: the same float operations in
//! the same order, pass by pass (the 1-D passes are src/filters/aaf_pass's).

use anyhow::Result;
use glam::Vec3;
use rayon::prelude::*;

use super::AafIndirectSettings;
use crate::filters::aaf_pass::{self, FILTERED, LIT, NONE, PassPixel};
use crate::imaging::RgbImage;
use crate::layout::outputs::BufferId;
use crate::layout::{AafIndirectParams, FilterVector, IndirectPixel};
use crate::render::Frame;
use crate::render::indirect::bandlimit::beta;

/// `aaf_indirect_prepare`: the shared pass's guide (the lobe as its group) and the values
/// (L in rgb); glossy receivers are none unless `p.glossy`.
pub fn prepare(
    p: &AafIndirectParams,
    pixels: &[IndirectPixel],
) -> (Vec<PassPixel>, Vec<[f32; 4]>) {
    pixels
        .par_iter()
        .map(|px| {
            let (mut v, mut b, mut kind) = ([0.0f32; 3], 0.0, NONE);
            if px.weight > 0.0 && (px.lobe == 0.0 || p.glossy != 0) {
                v = px.irradiance.map(|c| c / px.weight);
                if px.reflectors > 0.0 {
                    b = beta(px.z_min, px.pixel_size, px.bandlimit, p.footprints);
                    kind = FILTERED;
                } else {
                    kind = LIT;
                }
            }
            let normal = Vec3::from(px.normal);
            let g = PassPixel {
                position: Vec3::from(px.position),
                kind,
                normal,
                beta: b,
                axis: normal,
                group: px.lobe,
            };
            (g, [v[0], v[1], v[2], 0.0])
        })
        .unzip()
}

/// `aaf_indirect_compose`: F.direct + mean albedo (a metal's colour) · L (F as is for no
/// receiver).
pub fn compose(
    fv: &[FilterVector],
    pixels: &[IndirectPixel],
    guide: &[PassPixel],
    values: &[[f32; 4]],
    width: u32,
    height: u32,
) -> RgbImage {
    let pixels = (0..fv.len())
        .into_par_iter()
        .map(|i| {
            let f = &fv[i];
            if guide[i].kind == NONE {
                return std::array::from_fn(|c| f.direct[c] + f.indirect[c]);
            }
            let px = &pixels[i];
            std::array::from_fn(|c| f.direct[c] + px.albedo[c] / px.weight * values[i][c])
        })
        .collect();
    RgbImage {
        width,
        height,
        pixels,
    }
}

/// The whole filter on `frame` (which must hold the indirect output).
pub fn reference(frame: &Frame, s: &AafIndirectSettings) -> Result<RgbImage> {
    s.validate()?;
    let (w, h) = (frame.width(), frame.height());
    let pixels: &[IndirectPixel] = frame.host_slice(BufferId::IndirectPixels)?;
    let (guide, v0) = prepare(&s.params(w, h), pixels);
    let v2 = aaf_pass::both(&s.pass_params(w, h), &guide, &v0);
    Ok(compose(frame.filter_vectors()?, pixels, &guide, &v2, w, h))
}
