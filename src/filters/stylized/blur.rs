//! Step 3 (DeCoro 2009 §3.3.1 "Abstraction", §3.3.3 "Gaussian Blur"): G * D, the plain Rust
//! reference of `st_blur` in kernels/filters/stylized.cl, and the Halton stencil both use.
//!
//! "Each pixel x will randomly sample a disk of pixels of radius 3α around x ... both
//! importance sampling the Gaussian kernel, and using a quasi-random Halton distribution";
//! "two 2-d convolutions of √(1/2) the width" (the kernel is not separable: the 45° rule cuts
//! it). So: two passes, σ = α/√2 each; per pass n Halton points (bases 2, 3) mapped to a 2-D
//! Gaussian truncated at radius 3 (inverse of the radial CDF renormalised to the disk), scaled
//! by the pixel's σ and rounded to the nearest pixel; the result is the plain mean of the kept
//! neighbours (importance sampling: the Gaussian weight is in the density).
//!
//! Choices where the seed is open:
//! - **One stencil for every pixel**, the same Halton points (no per-pixel rotation): the pass
//!   is then an exact convolution with a sparse kernel, without noise, and a constant D stays
//!   constant. The second pass takes the next n points of the sequence, so the two stencils
//!   differ and their composition is denser than either.
//! - **Skipped neighbours**: outside the image, not in the matte, failing the 45° rule
//!   (§3.3.2: "in both the distance transform and blur"), off the pixel's surface (further
//!   than `gap` pixel footprints from its tangent plane: the seed's blur has the normal rule
//!   only, so a lit object in front of a shadow would take the shadow's D across its
//!   silhouette, against §3.3.2's "an unshadowed foreground object may cross a shadowed
//!   background without artifact"), or with D = ±∞ (no contour point on
//!   that side: an infinity would swamp the mean or give ∞ − ∞ = NaN). A pixel whose own D is
//!   ±∞ keeps it; a pixel with no neighbour kept keeps its D; α ≤ 0 copies D (α = 0 is a no-op).
//! - α is in **pixels** (the 3α disk is "of pixels"), so abstraction does not scale with the
//!   scene; the thesis's d units in Fig. 3.11 are not stated.

use glam::Vec3;
use rayon::prelude::*;

use super::contour::in_matte;
use super::transfer::Controls;
use crate::layout::{Float2, ShadowPixel};

/// The radical inverse of k in base b (Halton's sequence, the seed's ref. [77]).
pub fn halton(mut k: u32, b: u32) -> f64 {
    let (mut f, mut r) = (1.0f64, 0.0f64);
    let inv = 1.0 / b as f64;
    while k > 0 {
        f *= inv;
        r += f * (k % b) as f64;
        k /= b;
    }
    r
}

/// Offsets of a unit 2-D Gaussian truncated at radius 3: Halton points `first + 1 ..= first
/// + n` (index 0 is the origin), radius from the inverse radial CDF over [0, 3].
pub fn stencil(first: u32, n: u32) -> Vec<Float2> {
    // 1 − exp(−9/2): the radial CDF of the unit Gaussian at 3.
    let tail = 1.0 - (-4.5f64).exp();
    (0..n)
        .map(|k| {
            let (u, v) = (halton(first + k + 1, 2), halton(first + k + 1, 3));
            let r = (-2.0 * (1.0 - u * tail).ln()).sqrt();
            let a = std::f64::consts::TAU * v;
            Float2([(r * a.cos()) as f32, (r * a.sin()) as f32])
        })
        .collect()
}

/// One pass (`st_blur`) of `input` with `stencil`, α from `controls` at each pixel's d(x).
#[allow(clippy::too_many_arguments)]
pub fn pass(
    pixels: &[ShadowPixel],
    controls: &Controls,
    occluder: &[f32],
    stencil: &[Float2],
    input: &[f32],
    width: u32,
    height: u32,
    normal_cos: f32,
    gap: f32,
) -> Vec<f32> {
    let (w, h) = (width as i32, height as i32);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let own = input[i as usize];
            let px = &pixels[i as usize];
            let alpha = controls.abstraction_at(occluder[i as usize]);
            if !(alpha > 0.0) || !own.is_finite() || !in_matte(px) {
                return own;
            }
            let sigma = alpha * std::f32::consts::FRAC_1_SQRT_2;
            let n = Vec3::from(px.normal);
            let pos = Vec3::from(px.position);
            let plane = gap * px.pixel_size;
            let (mut sum, mut kept) = (0f32, 0u32);
            for o in stencil {
                let qx = x + (sigma * o.0[0]).round_ties_even() as i32;
                let qy = y + (sigma * o.0[1]).round_ties_even() as i32;
                if qx < 0 || qy < 0 || qx >= w || qy >= h {
                    continue;
                }
                let j = (qy * w + qx) as usize;
                let q = &pixels[j];
                let dj = input[j];
                if !in_matte(q) || !dj.is_finite() || n.dot(Vec3::from(q.normal)) < normal_cos {
                    continue;
                }
                if n.dot(Vec3::from(q.position) - pos).abs() > plane {
                    continue;
                }
                sum += dj;
                kept += 1;
            }
            if kept > 0 { sum / kept as f32 } else { own }
        })
        .collect()
}
