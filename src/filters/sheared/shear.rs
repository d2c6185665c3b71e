//! The frequency analysis of sheared soft shadows (Yan et al. 2015 §4, eqs. 4-5), in Rust;
//! kernels/filters/sheared.cl `sheared_prepare` is the same code.
//!
//! Coordinates: x = (receiver point)·e_i in world units on the plane parallel to the light, y
//! the light's coordinate along the same axis e_i (src/render/shadows/light_field.rs). For one
//! occluder plane at distance d2 from the light over a receiver at d1, the ray from x to y
//! crosses the occluder at (d2/d1)(x + s y), s = d1/d2 − 1 (the slope of AAF,
//! src/render/shadows/bandlimit.rs): f(x, y) = g(x + s y), a spectrum on the line Ω_y = s Ω_x.
//! The light is Gaussian with σ_y = 2/Ω_y^max (eq. 4; Ω_y^max = 4/L with L = R, so σ_y = R/2,
//! the per-axis standard deviation of the sphere's silhouette disk).
//!
//! - **σ_x, eq. 4 as printed**: σ_x = σ_y s_min s_max / (s_max − s_min), +∞ for one slope.
//!   Limited to a 32 px diameter ([`cap_sigma_x`]: the gather's 2σ_x stays within 16 steps).
//! - **η, eq. 5 corrected** (digest §3.2 (i)): sample (x′, y′) has pixel x's value at light
//!   point y = y′ − (x − x′)/s, so it serves x with weight w_y(y′ − η (x − x′)) where η is the
//!   mean of 1/s over the wedge: η = (s_min + s_max) / (2 s_min s_max). The printed
//!   η = −s_min s_max / (2 (s_min + s_max)) is a quarter of the harmonic mean of the slopes
//!   (not of their inverses) and has the wrong sign for our axes; tests/sheared_filter.rs
//!   `one_occluder_plane_decides_the_shear` measures the printed form and both signs of the
//!   corrected one against a 4096-sample reference and keeps this one (+).

/// Slopes below this count as this (an occluder touching the light), as AAF's
/// [`crate::render::shadows::bandlimit::MIN_SLOPE`]; η is then finite (≤ 1e30).
pub const MIN_SLOPE: f32 = 1.0e-30;

/// Largest |η|, so that η (x − x′) is never ∞ · 0.
pub const MAX_ETA: f32 = 1.0e30;

/// Eq. 4: σ_x = σ_y s_min s_max / (s_max − s_min) (+∞ when the slopes are equal).
pub fn sigma_x(sigma_y: f32, s_min: f32, s_max: f32) -> f32 {
    let (a, b) = (s_min.max(MIN_SLOPE), s_max.max(s_min.max(MIN_SLOPE)));
    let spread = b - a;
    if spread > 0.0 {
        sigma_y * (a * b / spread)
    } else {
        f32::INFINITY
    }
}

/// Eq. 5, corrected (module doc): η = (s_min + s_max) / (2 s_min s_max), times `shear`
/// (1: as settled, 0: axis-aligned, −1: the other sign).
pub fn eta(s_min: f32, s_max: f32, shear: f32) -> f32 {
    let (a, b) = (s_min.max(MIN_SLOPE), s_max.max(s_min.max(MIN_SLOPE)));
    let e = ((a + b) / (2.0 * a * b)).min(MAX_ETA);
    shear * e
}

/// Eq. 5 as printed, −s_min s_max / (2 (s_min + s_max)): kept for the single-plane test that
/// rejects it.
pub fn eta_printed(s_min: f32, s_max: f32) -> f32 {
    let (a, b) = (s_min.max(MIN_SLOPE), s_max.max(s_min.max(MIN_SLOPE)));
    -(a * b) / (2.0 * (a + b))
}

/// σ_x limited so that 2σ_x spans at most `max_radius` gather steps along either axis
/// (`world_per_step`: world x per step along axis 1 and 2; 0 where undefined).
pub fn cap_sigma_x(sigma_x: f32, world_per_step: [f32; 2], max_radius: i32) -> f32 {
    let step = match world_per_step {
        [a, b] if a > 0.0 && b > 0.0 => a.min(b),
        [a, b] => a.max(b),
    };
    if step > 0.0 {
        sigma_x.min(0.5 * max_radius as f32 * step)
    } else {
        sigma_x
    }
}

/// Gather steps on either side for σ_x (2σ_x, rounded up, within `max_radius`); 0 when the
/// axis is undefined.
pub fn radius(sigma_x: f32, world_per_step: f32, max_radius: i32) -> i32 {
    if !(world_per_step > 0.0) || !(sigma_x > 0.0) {
        return 0;
    }
    let r = (2.0 * sigma_x / world_per_step).ceil();
    if r < max_radius as f32 {
        r as i32
    } else {
        max_radius
    }
}

/// The centre of bin `c` of `bins` covering [−range, range] (odd counts put one at 0).
pub fn bin_centre(c: u32, bins: u32, range: f32) -> f32 {
    -range + c as f32 * (2.0 * range / (bins - 1) as f32)
}

/// The nearest bin of `y`, or None beyond the bins.
pub fn bin_of(y: f32, bins: u32, range: f32) -> Option<u32> {
    let c = ((y + range) * ((bins - 1) as f32 / (2.0 * range))).round();
    (c >= 0.0 && c < bins as f32).then_some(c as u32)
}

/// The Gaussian light w_y (unnormalised: every step divides by its weight channel).
pub fn gauss(t: f32, inv_two_sigma2: f32) -> f32 {
    (-(t * t) * inv_two_sigma2).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_values() {
        // s = 1 and 3, σ_y = 0.5: σ_x = 0.5 · 3 / 2 = 0.75; η = 4 / 6.
        assert!((sigma_x(0.5, 1.0, 3.0) - 0.75).abs() < 1e-6);
        assert!((eta(1.0, 3.0, 1.0) - 4.0 / 6.0).abs() < 1e-6);
        // One slope: η = 1/s, σ_x unbounded until capped.
        assert!((eta(2.0, 2.0, 1.0) - 0.5).abs() < 1e-6);
        assert_eq!(sigma_x(0.5, 2.0, 2.0), f32::INFINITY);
        assert_eq!(cap_sigma_x(f32::INFINITY, [0.1, 0.2], 16), 0.8);
        assert_eq!(radius(0.8, 0.1, 16), 16);
        assert_eq!(radius(0.8, 0.0, 16), 0);
        // The printed form is a quarter of the harmonic mean of the slopes.
        assert!((eta_printed(1.0, 3.0) + 0.25 * 2.0 * 3.0 / 4.0).abs() < 1e-6);
        // No slope: finite, never NaN.
        assert!(eta(0.0, 0.0, 1.0).is_finite() && (eta(0.0, 0.0, 1.0) * 0.0) == 0.0);
        assert_eq!(eta(1.0, 3.0, 0.0), 0.0);
    }

    #[test]
    fn bins_round_to_the_nearest_centre_with_one_at_zero() {
        assert_eq!(bin_of(0.0, 17, 2.0), Some(8));
        assert_eq!(bin_centre(8, 17, 2.0), 0.0);
        assert_eq!(bin_of(-2.0, 17, 2.0), Some(0));
        assert_eq!(bin_of(2.0, 17, 2.0), Some(16));
        assert_eq!(bin_of(2.2, 17, 2.0), None);
        assert_eq!(bin_of(f32::INFINITY, 17, 2.0), None);
        assert_eq!(bin_of(f32::NAN, 17, 2.0), None);
        for c in 0..17 {
            assert_eq!(bin_of(bin_centre(c, 17, 2.0), 17, 2.0), Some(c));
        }
    }
}
