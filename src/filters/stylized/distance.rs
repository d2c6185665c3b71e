//! Step 2 (DeCoro 2009 §3.3.1, eq. 3.2): the signed L8-averaged world-space distance to the
//! shadow contour, the plain Rust reference of `st_distance` in kernels/filters/stylized.cl.
//!
//! Eq. 3.2 with p = 8 ("used for the results in this paper"): D = (∫_C |x − y|^-p dy)^(-1/p) /
//! (∫_C dy)^(-1/p) = (mean_{y∈C} |x − y|^-8)^(-1/8), estimated from N contour points (§3.3.3:
//! "sampling a random set of pixels y ∈ C"), distances from the stored world positions
//! (§3.3.2 "World-space Distance Metric"), negated where V = 0 (§3.3.1 Inflation).
//!
//! Choices where the seed is open:
//! - **Which N points**: stratified over the list (point k of N from the k-th N-th of the
//!   list, jittered by the counter-based hash of (seed, pixel)); the list is in pixel order,
//!   so the strata spread the samples along the contour. A list of at most N points is used
//!   whole: D is then exact, with no noise.
//! - **Stability** (digest §1.7 item 6): d^-8 overflows float32 below d ≈ 1.5e-5 and
//!   underflows above ≈ 5e4 (0^(-1/8) = ∞). D is computed as m·(mean (m/d)^8)^(-1/8), m = min
//!   d: every term is in [0, 1] and the nearest point adds 1, so the mean lies in
//!   [1/N, 1] and D in [m, N^(1/8) m]: finite, and scaling the scene scales D.
//! - **The 45° rule** (§3.3.2): points whose normal is more than 45° from the pixel's are
//!   skipped. No point left (no contour at all, or none facing the same way) gives D = ±∞:
//!   S = 1 or b, never NaN (digest §1.7 item 6).
//! - **d(x) for the quadratic controls** (§3.3.2): the thesis uses the distance to a coarse
//!   proxy of the occluder; ours is the occluder distances of the contour points (each the
//!   shadow ray's hit distance at the shadowed side of the boundary) averaged with the same
//!   weights (m/d)^8, so that it is defined on both sides of the boundary and smooth across
//!   it (the controls must not jump where V does). With no point: the pixel's own.

use glam::Vec3;
use rayon::prelude::*;

use super::contour::in_matte;
use crate::layout::{Float4, ShadowPixel};
use crate::render::cpu::rng::{hash_u32, rng_sample_key, rng_uniform};

/// How the distance step samples the contour list.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampling {
    /// Points in the list.
    pub count: u32,
    /// Points drawn per pixel (all of them when count ≤ n).
    pub n: u32,
    /// count / n in float32, computed once by the host for the kernel and the reference.
    pub scale: f32,
    pub seed: u32,
    pub normal_cos: f32,
}

impl Sampling {
    pub fn new(count: u32, n: u32, seed: u32, normal_cos: f32) -> Sampling {
        Sampling {
            count,
            n,
            scale: count as f32 / n.max(1) as f32,
            seed,
            normal_cos,
        }
    }

    /// The list entry of sample k at pixel `key`'s stratum.
    fn entry(&self, key: u32, k: u32) -> u32 {
        if self.count <= self.n {
            return k;
        }
        (((k as f32 + rng_uniform(key, k, 0)) * self.scale) as u32).min(self.count - 1)
    }
}

/// hash_u32(k << 8) for k < n, padded with zeros to a whole number of sixteen: the part of
/// `rng_uniform(key, k, 0)` that is the same at every pixel, hashed once for `st_distance`'s
/// lanes instead of at every pixel.
pub fn draw_hashes(n: u32) -> Vec<u32> {
    let padded = n.div_ceil(16) * 16;
    (0..padded).map(|k| if k < n { hash_u32(k << 8) } else { 0 }).collect()
}

/// D and d(x) of one pixel at `p` with normal `n` and visibility `lit`, from `contour` (two
/// float4s per point, `contour.rs`).
pub fn at(p: Vec3, n: Vec3, lit: bool, own_occluder: f32, contour: &[Float4], s: &Sampling, key: u32) -> (f32, f32) {
    let samples = s.count.min(s.n);
    let point = |k: u32| -> Option<(Vec3, f32)> {
        let j = s.entry(key, k) as usize;
        let (q, qn) = (contour[2 * j].0, contour[2 * j + 1].0);
        if n.dot(Vec3::new(qn[0], qn[1], qn[2])) < s.normal_cos {
            return None;
        }
        Some((Vec3::new(q[0], q[1], q[2]), q[3]))
    };
    let mut m = f32::INFINITY;
    for k in 0..samples {
        if let Some((q, _)) = point(k) {
            let delta = q - p;
            m = m.min(delta.dot(delta).sqrt());
        }
    }
    if m == f32::INFINITY {
        return (if lit { f32::INFINITY } else { f32::NEG_INFINITY }, own_occluder);
    }
    let (mut sum, mut sum_occ, mut kept) = (0f32, 0f32, 0u32);
    for k in 0..samples {
        let Some((q, occ)) = point(k) else { continue };
        let delta = q - p;
        let d = delta.dot(delta).sqrt();
        let mut w = 1.0;
        if d > m {
            let r = m / d;
            let r2 = r * r;
            let r4 = r2 * r2;
            w = r4 * r4;
        }
        sum += w;
        sum_occ += w * occ;
        kept += 1;
    }
    let mean = sum / kept as f32;
    let d = m / mean.sqrt().sqrt().sqrt();
    (if lit { d } else { -d }, sum_occ / sum)
}

/// `st_distance` over the image: (D, d(x)) per pixel; pixels out of the matte get (+∞, 0).
pub fn distances(pixels: &[ShadowPixel], contour: &[Float4], s: &Sampling) -> (Vec<f32>, Vec<f32>) {
    pixels
        .par_iter()
        .enumerate()
        .map(|(i, px)| {
            if !in_matte(px) {
                return (f32::INFINITY, 0.0);
            }
            let key = rng_sample_key(s.seed, i as u32, 0);
            at(
                Vec3::from(px.position),
                Vec3::from(px.normal),
                px.centre_visible != 0.0,
                px.occluder_distance,
                contour,
                s,
                key,
            )
        })
        .unzip()
}

/// The naive estimate (mean d^-8)^(-1/8) in float32, as eq. 3.2 reads: what the stable form
/// replaces (the stability tests show it overflowing).
pub fn naive(distances: &[f32]) -> f32 {
    let mean = distances.iter().map(|d| d.powi(-8)).sum::<f32>() / distances.len() as f32;
    mean.powf(-1.0 / 8.0)
}

/// D of a point at distance r from the middle of a straight contour of length ℓ, for r ≪ ℓ:
/// (16ℓ / (5π))^(1/8) r^(7/8) (digest §1.2 item 4: ∫ (r² + t²)^-4 dt = 5π / (16 r^7)).
pub fn straight_edge(length: f64, r: f64) -> f64 {
    (16.0 * length / (5.0 * std::f64::consts::PI)).powf(1.0 / 8.0) * r.powf(7.0 / 8.0)
}
