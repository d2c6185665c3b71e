//! The perceptual colour map of every false-colour picture (error maps, variance AOVs): dark
//! purple (t = 0) through blue and green to yellow (t = 1), lightness rising along t, so a larger
//! value is a lighter colour, also in greyscale print.

/// Anchors of the colour map at t = 0, 1/8, …, 1 (8-bit sRGB). They follow the published
/// viridis colours (van der Walt & Smith, 2015) sampled at nine points; between anchors the
/// map interpolates linearly in sRGB-encoded values.
pub const COLORMAP_ANCHORS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [40, 174, 128],
    [94, 201, 98],
    [173, 220, 48],
    [253, 231, 37],
];

/// The 8-bit sRGB colour at position `t` (clamped to [0, 1]; NaN → 0) of the viridis-like map:
/// [`colormap_exact`] rounded to the nearest integer per channel.
pub fn colormap(t: f64) -> [u8; 3] {
    colormap_exact(t).map(|v| v.round().clamp(0.0, 255.0) as u8)
}

/// The colour map before 8-bit rounding: sRGB-encoded values in [0, 255], linearly interpolated
/// between [`COLORMAP_ANCHORS`]. Its CIE L\* rises strictly with `t` (from about 14.9 to 90.9,
/// nearly linearly); after rounding ([`colormap`]) it may dip by at most ≈ 0.1 L\*.
pub fn colormap_exact(t: f64) -> [f64; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let segments = (COLORMAP_ANCHORS.len() - 1) as f64;
    let s = t * segments;
    let i = (s.floor() as usize).min(COLORMAP_ANCHORS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (COLORMAP_ANCHORS[i], COLORMAP_ANCHORS[i + 1]);
    std::array::from_fn(|c| f64::from(a[c]) + f * (f64::from(b[c]) - f64::from(a[c])))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::srgb_to_linear;

    /// CIE L* of an sRGB colour given in [0, 255] (CIE 1976: 116 f(Y) - 16).
    fn l_star(c: [f64; 3]) -> f64 {
        let lin = c.map(|v| f64::from(srgb_to_linear((v / 255.0) as f32)));
        let y = 0.2126729 * lin[0] + 0.7151522 * lin[1] + 0.0721750 * lin[2];
        let d: f64 = 6.0 / 29.0;
        let f = if y > d * d * d {
            y.cbrt()
        } else {
            y / (3.0 * d * d) + 4.0 / 29.0
        };
        116.0 * f - 16.0
    }

    #[test]
    fn colormap_ends_and_anchors() {
        assert_eq!(colormap(0.0), COLORMAP_ANCHORS[0]);
        assert_eq!(colormap(1.0), COLORMAP_ANCHORS[8]);
        assert_eq!(colormap(0.5), COLORMAP_ANCHORS[4]);
        assert_eq!(colormap(-3.0), COLORMAP_ANCHORS[0]);
        assert_eq!(colormap(7.0), COLORMAP_ANCHORS[8]);
        assert_eq!(colormap(f64::NAN), COLORMAP_ANCHORS[0]);
    }

    #[test]
    fn colormap_lightness_is_monotonic() {
        let (mut prev_exact, mut prev_8bit) = (-1.0, -1.0);
        for i in 0..=4096 {
            let t = i as f64 / 4096.0;
            let exact = l_star(colormap_exact(t));
            let quantised = l_star(colormap(t).map(f64::from));
            assert!(
                exact > prev_exact,
                "L* not rising at t = {t}: {prev_exact} → {exact}"
            );
            assert!(quantised > prev_8bit - 0.15, "8-bit L* dips at t = {t}");
            (prev_exact, prev_8bit) = (exact, quantised);
        }
        let ends = [0.0, 1.0].map(|t| l_star(colormap_exact(t)));
        assert!(
            (ends[0] - 14.9).abs() < 0.1 && (ends[1] - 90.9).abs() < 0.1,
            "{ends:?}"
        );
    }
}
