//! The frequency analysis of AAF diffuse indirect light (Wang 2013 §4.2, after Mehta et al.
//! 2013): the filter width β of eq. 4.4, the bandlimit Ω_h^max of eq. 4.5 and the sample count
//! n of eq. 4.6, in Rust; kernels/render/indirect.cl is the same code for the sampling pass
//! and the filter.
//!
//! Quantities, in scene units ("metres") or ratios of them:
//! - z_min, z_max: the nearest and farthest first-bounce hit over a pixel's sparse samples.
//!   The seed uses z_max in eq. 4.6 but never defines it; it is taken as the maximum reflector
//!   distance (the digest's reading).
//! - d: the world size of one pixel at the receiver (t_hit · 2 tan(fov/2) / height); A_p = d².
//! - Ω_h^max: the bandlimit of the BRDF-weighted incident light, 2.8 for a diffuse receiver,
//!   3.6 + 0.084 m for a Phong lobe of exponent m (eq. 4.5: a metal receiver's glossy lobe;
//!   kernels/render/bandlimit.cl `aaf_glossy_bandlimit`).
//!
//! Eq. 4.4 as printed: β = max(2 z_min / Ω_h^max, d / 0.15). Both terms are in metres. The
//! second is a floor of 1/0.15 ≈ 6.7 pixel footprints; `footprints` here is that factor, a
//! setting of the filter (1 by default, chosen by measurement: src/filters/aaf_indirect). Eq. 4.6 is used as printed, every factor dimensionless.

/// Ω_h^max of a diffuse receiver (eq. 4.5).
pub const DIFFUSE_BANDLIMIT: f32 = 2.8;

/// Ω_h^max of a Phong lobe of exponent `m` (eq. 4.5).
pub fn glossy_bandlimit(m: f32) -> f32 {
    3.6 + 0.084 * m
}

/// The seed's β floor in pixel footprints: d / 0.15 (eq. 4.4).
pub const SEED_FOOTPRINTS: f32 = 1.0 / 0.15;

/// z below this counts as this (a reflector touching the receiver), so n is finite or +∞,
/// never NaN (kernels/render/indirect.cl `AAF_MIN_Z`).
pub const MIN_Z: f32 = 1.0e-30;

/// Eq. 4.4: β = max(2 z_min / Ω, footprints · d).
pub fn beta(z_min: f32, pixel_size: f32, bandlimit: f32, footprints: f32) -> f32 {
    (2.0 * z_min / bandlimit).max(footprints * pixel_size)
}

/// Eq. 4.6: n = 0.4 (0.9 Ω √A_p / z_min + 0.3)² Ω² (1 + 0.9 z_max / z_min)², A_p = d².
pub fn sample_count(z_min: f32, z_max: f32, pixel_size: f32, bandlimit: f32) -> f32 {
    let z = z_min.max(MIN_Z);
    let a = 0.9 * bandlimit * pixel_size / z + 0.3;
    let b = 1.0 + 0.9 * z_max / z;
    0.4 * a * a * bandlimit * bandlimit * b * b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_formulas_by_hand() {
        // z_min = 0.5 m, d = 0.01 m: 2 · 0.5 / 2.8 = 0.357 m against 0.0667 m.
        assert!((beta(0.5, 0.01, 2.8, SEED_FOOTPRINTS) - 0.357_142_87).abs() < 1e-6);
        // z_min = 0.01 m: the floor, 0.01 / 0.15.
        assert!((beta(0.01, 0.01, 2.8, SEED_FOOTPRINTS) - 0.066_666_67).abs() < 1e-6);
        // z_min = 0.5, z_max = 1, d = 0.01: 0.4 (0.9·2.8·0.01/0.5 + 0.3)² 2.8² (1 + 1.8)²
        // = 0.4 · 0.3504² · 7.84 · 7.84 = 3.0183...
        let n = sample_count(0.5, 1.0, 0.01, 2.8);
        assert!(
            (n - 0.4 * 0.3504f32.powi(2) * 7.84 * 7.84).abs() < 1e-4,
            "{n}"
        );
        assert!(sample_count(0.0, 0.0, 0.01, 2.8).is_infinite());
        assert!((glossy_bandlimit(10.0) - 4.44).abs() < 1e-6);
    }
}
