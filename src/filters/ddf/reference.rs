//! The plain Rust reference of kernels/filters/ddf.cl: every variant computes this, with the
//! same float operations in the same order.

use anyhow::{Context as _, Result};
use rayon::prelude::*;

use super::{DdfSettings, DirectionTerm};
use crate::imaging::RgbImage;
use crate::layout::outputs::BufferId;
use crate::layout::{FilterVector, SKY_DEPTH, WelfordState, WelfordSums};
use crate::render::Frame;

/// The plain Rust reference of kernels/filters/ddf.cl (all variants compute this).
pub fn reference(frame: &Frame, s: &DdfSettings) -> Result<RgbImage> {
    s.validate()?;
    let fv: &[FilterVector] = frame.filter_vectors()?;
    let sums: &[WelfordSums] = frame
        .host_slice(BufferId::WelfordSums)
        .context("the data-driven filter needs the feature variances")?;
    let state: &[WelfordState] = frame.host_slice(BufferId::WelfordState)?;
    let (w, h) = (frame.width() as i32, frame.height() as i32);
    let p = s.params(
        frame.width(),
        frame.height(),
        frame.variance_factor(),
        crate::stats::depth_scale(frame.info().scene.scene_size),
    );
    let (sky, texture2) = (s.keeps_sky(), s.uses_texture2());
    // The direction term's input of pixel i (kernels/filters/ddf.cl neighbour_direction).
    let dir = |i: usize| match s.direction {
        DirectionTerm::Difference => state[i].direction_mean,
        DirectionTerm::Neighbour => {
            let v = crate::stats::feature_variance_sums(&crate::stats::scaled(
                &sums[i],
                p.variance_factor,
            ))[3];
            let s2 = p.sigma2_f[3] * (1.0 - (v * p.variance_scale[3]).clamp(0.0, 1.0));
            [s2, 0.0, 0.0]
        }
        DirectionTerm::Thesis => [0.0; 3],
    };
    let lanes = FilterVector::lanes;
    let sq = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f32>();
    let pixels = (0..(w * h) as usize)
        .into_par_iter()
        .map(|pixel| {
            let fc = lanes(&fv[pixel]);
            if sky && fc[6] >= SKY_DEPTH {
                return [fc[0] + fc[3], fc[1] + fc[4], fc[2] + fc[5]];
            }
            // The variances as the kernel forms them: every lane of S_n times the factor.
            let g = crate::stats::scaled(&sums[pixel], p.variance_factor);
            let mut sums = crate::stats::feature_variance_sums(&g);
            sums[0] *= p.depth_scale * p.depth_scale;
            let sigma2_f: [f32; 5] = std::array::from_fn(|i| {
                p.sigma2_f[i] * (1.0 - (sums[i] * p.variance_scale[i]).clamp(0.0, 1.0))
            });
            let (mut c_fd, mut c_fi, mut tw_d, mut tw_i) = ([0f32; 3], [0f32; 3], 0f32, 0f32);
            let dc = dir(pixel);
            let mut visit = |n: &[f32; 16], dn: [f32; 3]| {
                let e_dc = p.sigma2_dc * sq(&fc[0..3], &n[0..3]);
                let e_ic = p.sigma2_ic * sq(&fc[3..6], &n[3..6]);
                let dd = (fc[6] - n[6]) * p.depth_scale;
                let e_fd = sigma2_f[0] * dd * dd
                    + sigma2_f[1] * sq(&fc[7..10], &n[7..10])
                    + sigma2_f[2] * sq(&fc[10..13], &n[10..13]);
                let mut e_fi = e_fd;
                if texture2 {
                    e_fi += sigma2_f[4] * sq(&fc[13..16], &n[13..16]);
                }
                e_fi += match s.direction {
                    DirectionTerm::Thesis => sigma2_f[3],
                    DirectionTerm::Difference => sigma2_f[3] * sq(&dc, &dn),
                    DirectionTerm::Neighbour => dn[0],
                };
                let w_d = (-(e_dc + e_fd)).exp();
                let w_i = (-(e_ic + e_fi)).exp();
                for c in 0..3 {
                    c_fd[c] += w_d * n[c];
                    c_fi[c] += w_i * n[3 + c];
                }
                tw_d += w_d;
                tw_i += w_i;
            };
            let (x, y) = (pixel as i32 % w, pixel as i32 / w);
            let mut dy = -p.half_width;
            while dy <= p.half_width {
                let ny = y + dy;
                if (0..h).contains(&ny) {
                    let mut dx = -p.half_width;
                    while dx <= p.half_width {
                        let nx = x + dx;
                        if (0..w).contains(&nx) {
                            let ni = (ny * w + nx) as usize;
                            visit(&lanes(&fv[ni]), dir(ni));
                        }
                        dx += p.step;
                    }
                }
                dy += p.step;
            }
            if p.half_width % p.step != 0 {
                visit(&fc, dc);
            }
            std::array::from_fn(|c| {
                let d = if tw_d > 0.0 { c_fd[c] / tw_d } else { fc[c] };
                let i = if tw_i > 0.0 {
                    c_fi[c] / tw_i
                } else {
                    fc[3 + c]
                };
                d + i
            })
        })
        .collect();
    Ok(RgbImage {
        width: frame.width(),
        height: frame.height(),
        pixels,
    })
}
