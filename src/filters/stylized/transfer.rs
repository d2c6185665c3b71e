//! Step 4 (DeCoro 2009 §3.3.1, eq. 3.3): the transfer function and the compose, the plain
//! Rust reference of `st_transfer` / `st_compose` in kernels/filters/stylized.cl.
//!
//! Eq. 3.3 is printed `f(D) = (1 − b)^-1 smoothstep(D, i − s/2, i + s/2) + b`; as printed,
//! f(+∞) = 1/(1 − b) + b exceeds 1 and b = 1 divides by zero, while the text says the range
//! is [b, 1] ("the maximum value of f ... is always 1"). We use (1 − b) (digest §1.2 item 1).
//! smoothstep is the shader one, 3t² − 2t³ with OpenCL's argument order (edge0, edge1, x);
//! s = 0 is a hard step D ≥ i (the smoothstep would divide by zero, digest item 3).

use rayon::prelude::*;

use crate::imaging::RgbImage;
use crate::layout::{ShadowPixel, ShadowTerms};

/// The four controls, each a quadratic c0 + c1 d + c2 d² of the occluder distance d(x)
/// (§3.3.2 "Non-constant Stylization Parameters": "quadratic functions of d(x) allow suitable
/// control"); constants have c1 = c2 = 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Controls {
    /// i: the isocontour D = i is the new shadow boundary; world units of D (the L8-averaged
    /// distance, which is not a Euclidean distance: see `distance.rs`).
    pub inflation: [f32; 3],
    /// s: width of the b → 1 ramp, same units as i; clamped at 0.
    pub softness: [f32; 3],
    /// b: the darkest the shadow gets; clamped to [0, 1].
    pub brightness: [f32; 3],
    /// α: the standard deviation of the Gaussian blur of D, pixels; ≤ 0 is no blur.
    pub abstraction: [f32; 3],
}

/// Lanes of the kernels' controls buffer (`ST_INFLATION`, ... in kernels/filters/stylized.cl).
pub const LANES: usize = 16;

impl Controls {
    /// The controls buffer: four quadratics, each padded to four floats.
    pub fn lanes(&self) -> [f32; LANES] {
        let mut l = [0.0; LANES];
        for (k, q) in [
            self.inflation,
            self.softness,
            self.brightness,
            self.abstraction,
        ]
        .iter()
        .enumerate()
        {
            l[4 * k..4 * k + 3].copy_from_slice(q);
        }
        l
    }

    /// i, s, b at occluder distance d, clamped as the kernel clamps them.
    pub fn at(&self, d: f32) -> (f32, f32, f32) {
        (
            quadratic(&self.inflation, d),
            quadratic(&self.softness, d).max(0.0),
            quadratic(&self.brightness, d).clamp(0.0, 1.0),
        )
    }

    /// α at occluder distance d (pixels).
    pub fn abstraction_at(&self, d: f32) -> f32 {
        quadratic(&self.abstraction, d)
    }
}

/// c0 + (c1 + c2 d) d (kernels/filters/stylized.cl `st_quadratic`).
pub fn quadratic(c: &[f32; 3], d: f32) -> f32 {
    c[0] + (c[1] + c[2] * d) * d
}

/// Eq. 3.3 with (1 − b): S = (1 − b) smoothstep(i − s/2, i + s/2, D) + b. D = ±∞ (no contour
/// point) gives 1 or b; never NaN for finite i, s, b.
pub fn transfer(d: f32, i: f32, s: f32, b: f32) -> f32 {
    let t = if s > 0.0 {
        let t = ((d - (i - 0.5 * s)) / s).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    } else if d >= i {
        1.0
    } else {
        0.0
    };
    (1.0 - b) * t + b
}

/// `st_compose` of one light: the matte S per pixel and the image `base` − direct + r·S
/// (`base` as is where the pixel has no light sample on its receiver, as the AAF filter
/// does). The first light's `base` is F; each next light's is the image so far (eq. 3.1).
pub fn compose(
    base: &RgbImage,
    terms: &[ShadowTerms],
    pixels: &[ShadowPixel],
    controls: &Controls,
    occluder: &[f32],
    dist: &[f32],
) -> (Vec<f32>, RgbImage) {
    let out: Vec<(f32, [f32; 3])> = (0..base.pixels.len())
        .into_par_iter()
        .map(|k| {
            let beauty = base.pixels[k];
            let (i, s, b) = controls.at(occluder[k]);
            let matte = transfer(dist[k], i, s, b);
            let p = &pixels[k];
            if !(p.weight > 0.0) {
                return (matte, beauty);
            }
            let t = &terms[k];
            let rgb = std::array::from_fn(|c| {
                (beauty[c] - t.direct[c]) + p.unshadowed[c] / p.samples * matte
            });
            (matte, rgb)
        })
        .collect();
    let matte = out.iter().map(|o| o.0).collect();
    let image = RgbImage {
        width: base.width,
        height: base.height,
        pixels: out.into_iter().map(|o| o.1).collect(),
    };
    (matte, image)
}
