//! The frequency analysis of AAF soft shadows (Wang 2013 §3.2, after Mehta et al. 2012): the
//! filter width β of eq. 3.4 and the sample count n of eq. 3.5, in Rust; kernels/render/
//! bandlimit.cl is the same code for the sampling pass and the filter.
//!
//! Quantities, all in scene units ("metres") or ratios of them:
//! - d1: receiver-to-light distance (to the sphere's centre).
//! - d2: occluder-to-light distance along a shadow ray, d1 − t_occluder; the slope of that
//!   occluder is s = d1/d2 − 1 = t/d2 (dimensionless). s1 is the largest slope over a pixel's
//!   occluded samples (its farthest occluder from the receiver, d2min), s2 the smallest
//!   (nearest occluder, d2max).
//! - d: the world size of one pixel at the receiver (t_hit · 2 tan(fov/2) / height, as the
//!   authors' code computes it); A_p = d².
//! - The light: the seed assumes a planar light with Gaussian intensity of standard deviation
//!   σ. Our lights are spheres of uniform radiance; the filter works on the sphere's silhouette
//!   disk, perpendicular to the receiver-to-centre direction, radius R: A_l = πR², and
//!   σ = R/2, the standard deviation per axis of a uniform disk of radius R (E[x²] = R²/4), so
//!   the Gaussian the analysis assumes has the disk's second moment. (The digest's other
//!   reading, √A_l / 2 ≈ 0.886 R, is the released code's for square lights.)
//!
//! **Eq. 3.4 as printed mixes units**: β = (1/3) max(σ (d1/d2max − 1), d1 / (d2max d)) has a
//! first term in metres and a second in 1/metres. The second term is the pixel-limited width:
//! the shadow of an occluder at slope s2 has no frequency above the pixel's, 1 / (d (1 + s2)),
//! so its width is d (1 + s2) = d · d1 / d2max. The authors' code confirms it (`computeWxf` =
//! min(μ/(σ s2), 1/(d (1 + s2))), β = 1/(3 Ω)). Here β = (1/3) max(σ s2, d (1 + s2)), in
//! metres; tests/aaf_shadows.rs checks the units by scaling a scene.
//!
//! Eq. 3.5 is used as printed: n = 4 (1 + s1/s2)² ((2/s2) √(A_p/A_l) + (1 + s2)⁻¹)², every
//! factor dimensionless. It is the light-limited case of the released code's general form.

use std::f32::consts::PI;

/// Slopes below this count as this (an occluder touching the light): s1/s2 stays finite or
/// +∞, never NaN (kernels/render/bandlimit.cl `AAF_MIN_SLOPE`).
pub const MIN_SLOPE: f32 = 1.0e-30;

/// σ of the light for a sphere of radius `radius`: the per-axis standard deviation of its
/// uniform silhouette disk.
pub fn light_sigma(radius: f32) -> f32 {
    0.5 * radius
}

/// Eq. 3.4, corrected: β = (1/3) max(σ s2, d (1 + s2)), in the units of σ and d.
pub fn beta(sigma: f32, pixel_size: f32, s2: f32) -> f32 {
    (sigma * s2).max(pixel_size * (1.0 + s2)) * (1.0 / 3.0)
}

/// Eq. 3.5: the samples per pixel the shadow at slopes s1 ≥ s2 needs, for a pixel of size
/// `pixel_size` and a sphere light of radius `light_radius` (A_l = πR²).
pub fn sample_count(s1: f32, s2: f32, pixel_size: f32, light_radius: f32) -> f32 {
    let s = s2.max(MIN_SLOPE);
    let ratio = pixel_size / (light_radius * PI.sqrt());
    let a = 1.0 + s1 / s;
    let b = 2.0 / s * ratio + 1.0 / (1.0 + s);
    4.0 * a * a * b * b
}

/// The largest k with k² ≤ n (kernels/render/shadows.cl `shadow_isqrt_floor`).
pub fn isqrt_floor(n: u32) -> u32 {
    let mut k = 0u32;
    while (k + 1) * (k + 1) <= n {
        k += 1;
    }
    k
}

/// The smallest k with k² ≥ n.
pub fn isqrt_ceil(n: u32) -> u32 {
    let k = isqrt_floor(n);
    if k * k < n { k + 1 } else { k }
}

/// The adaptive pass's plan for a pixel whose eq. 3.5 count is `n`: the count clamped to
/// [sparse, max] and the side k of the square of strata it adds (k² more samples), the
/// smallest square that covers the count beyond the sparse samples and no larger than
/// max − sparse allows (kernels/render/shadows.cl `shadow_adaptive`).
pub fn adaptive_plan(n: f32, sparse_spp: u32, max_spp: u32) -> (f32, u32) {
    let target = n.max(sparse_spp as f32).min(max_spp as f32);
    let extra = (target - sparse_spp as f32).ceil() as u32;
    let k = isqrt_ceil(extra).min(isqrt_floor(max_spp - sparse_spp));
    (target, k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_roots_of_counts() {
        for n in 0..2000u32 {
            let (f, c) = (isqrt_floor(n), isqrt_ceil(n));
            assert!(f * f <= n && (f + 1) * (f + 1) > n, "{n}");
            assert!(c * c >= n && (c == 0 || (c - 1) * (c - 1) < n), "{n}");
        }
    }

    #[test]
    fn plans_stay_in_whole_strata_within_the_bounds() {
        for n in [0.0f32, 5.0, 9.0, 9.5, 10.0, 25.0, 60.0, 1e9, f32::INFINITY] {
            let (target, k) = adaptive_plan(n, 9, 100);
            assert!((9.0..=100.0).contains(&target), "{n}: {target}");
            assert!(9 + k * k <= 100, "{n}: {k}");
            // The square covers the target unless max_spp stops it.
            assert!(9 + k * k >= target.ceil() as u32 || 9 + (k + 1) * (k + 1) > 100);
        }
        assert_eq!(adaptive_plan(9.5, 9, 100), (9.5, 1));
        assert_eq!(adaptive_plan(14.0, 9, 100), (14.0, 3));
        assert_eq!(adaptive_plan(1e9, 9, 100), (100.0, 9));
        assert_eq!(adaptive_plan(1e9, 9, 9), (9.0, 0));
    }
}
