//! Colour conversions used by the metrics: linear RGB → CIE XYZ → CIE 1976 L\*u\*v\*, and
//! the luminance used by SSIM.
//!
//! Conventions (all of them, in one place):
//!
//! * **Primaries.** A pixel's linear RGB is taken to be *linear* sRGB, i.e. ITU-R BT.709
//!   primaries (x, y) = R (0.64, 0.33), G (0.30, 0.60), B (0.15, 0.06), with no transfer
//!   function applied (the renderer's film is linear radiance).
//! * **White point.** D65 with (Xn, Yn, Zn) = [`D65_WHITE`] = (0.95047, 1.0, 1.08883).
//! * **Matrix.** [`RGB_TO_XYZ`] is the sRGB matrix derived from those primaries *and that
//!   exact white point*, so linear (1, 1, 1) maps to (Xn, Yn, Zn) and therefore to
//!   L\* = 100, u\* = v\* = 0 (to rounding, < 1e-9). Its values agree with the IEC 61966-2-1
//!   four-decimal matrix to 2e-4.
//! * **Scaling.** No exposure scaling: linear RGB (1, 1, 1) *is* the reference white, Y = 1.
//!   Values above 1 are allowed and simply give L\* > 100.
//! * **Negative components** (unphysical, but a denoiser may produce them) are clamped to 0
//!   *before* the L\*u\*v\* conversion, because chromaticity (u′, v′) is undefined for negative
//!   light and would blow up near a zero denominator. (The RGB metrics use the values as
//!   they are.)
//! * **Black.** When X + 15Y + 3Z = 0 (only X = Y = Z = 0 once negatives are clamped),
//!   u′, v′ are taken as the white point's u′n, v′n; since L\* = 0 there, u\* = v\* = 0.
//!   No NaN is ever produced from finite input.
//! * **L\*.** The CIE 1976 form with the exact constants ε = 216/24389 and κ = 24389/27:
//!   L\* = 116·∛(Y/Yn) − 16 if Y/Yn > ε, else κ·Y/Yn.
//! * Arithmetic is in `f64`.

/// CIE D65 reference white (X, Y, Z), normalised to Yn = 1.
pub const D65_WHITE: [f64; 3] = [0.95047, 1.0, 1.08883];

/// ε = 216/24389 ≈ 0.008856: the Y/Yn threshold between the cube-root and linear parts of L\*.
pub const CIE_EPSILON: f64 = 216.0 / 24389.0;

/// κ = 24389/27 ≈ 903.3: the slope of the linear part of L\* (L\* = κ·Y/Yn below ε).
pub const CIE_KAPPA: f64 = 24389.0 / 27.0;

/// Linear sRGB (BT.709 primaries) → CIE XYZ, rows X, Y, Z; white (1, 1, 1) ↦ [`D65_WHITE`].
pub const RGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.412_456_439_1, 0.357_576_077_6, 0.180_437_483_3],
    [0.212_672_851_4, 0.715_152_155_3, 0.072_174_993_3],
    [0.019_333_895_6, 0.119_192_025_9, 0.950_304_078_5],
];

/// Rec. 709 luma coefficients applied to *linear* RGB: the relative luminance Y used by SSIM.
pub const LUMINANCE_709: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Linear RGB → CIE XYZ with [`RGB_TO_XYZ`]; the values are used as given (no clamping).
pub fn linear_rgb_to_xyz(rgb: [f32; 3]) -> [f64; 3] {
    let c = rgb.map(f64::from);
    RGB_TO_XYZ.map(|row| row[0] * c[0] + row[1] * c[1] + row[2] * c[2])
}

/// CIE 1976 L\* of a relative luminance y = Y/Yn (κ/ε form; linear below ε, so also finite
/// for negative y).
pub fn lightness(y: f64) -> f64 {
    if y > CIE_EPSILON {
        116.0 * y.cbrt() - 16.0
    } else {
        CIE_KAPPA * y
    }
}

/// CIE 1976 uniform chromaticity (u′, v′) = (4X, 9Y) / (X + 15Y + 3Z); the white point's
/// (u′n, v′n) when the denominator is not positive (black).
fn uv_prime(xyz: [f64; 3]) -> (f64, f64) {
    let d = xyz[0] + 15.0 * xyz[1] + 3.0 * xyz[2];
    if d > 0.0 {
        (4.0 * xyz[0] / d, 9.0 * xyz[1] / d)
    } else {
        let w = D65_WHITE;
        let dn = w[0] + 15.0 * w[1] + 3.0 * w[2];
        (4.0 * w[0] / dn, 9.0 * w[1] / dn)
    }
}

/// CIE XYZ → CIE 1976 (L\*, u\*, v\*) relative to [`D65_WHITE`]:
/// L\* = [`lightness`]\(Y/Yn), u\* = 13·L\*·(u′ − u′n), v\* = 13·L\*·(v′ − v′n).
/// XYZ is used as given; black (X + 15Y + 3Z ≤ 0) gets u′ = u′n, v′ = v′n.
pub fn xyz_to_luv(xyz: [f64; 3]) -> [f64; 3] {
    let l = lightness(xyz[1] / D65_WHITE[1]);
    let (u, v) = uv_prime(xyz);
    let (un, vn) = uv_prime(D65_WHITE);
    [l, 13.0 * l * (u - un), 13.0 * l * (v - vn)]
}

/// Linear RGB → CIE L\*u\*v\*: negative components clamped to 0, then [`linear_rgb_to_xyz`]
/// and [`xyz_to_luv`]. Finite for every finite input.
pub fn linear_rgb_to_luv(rgb: [f32; 3]) -> [f64; 3] {
    xyz_to_luv(linear_rgb_to_xyz(rgb.map(|c| c.max(0.0))))
}

/// Relative luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of linear RGB ([`LUMINANCE_709`]),
/// not clamped.
pub fn luminance(rgb: [f32; 3]) -> f64 {
    LUMINANCE_709
        .iter()
        .zip(rgb)
        .map(|(k, c)| k * f64::from(c))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    fn assert_luv(rgb: [f32; 3], want: [f64; 3], tol: f64) {
        let got = linear_rgb_to_luv(rgb);
        for c in 0..3 {
            assert!(
                close(got[c], want[c], tol),
                "Luv of {rgb:?}: got {got:?}, want {want:?}"
            );
        }
    }

    /// Inverts a 3×3 matrix (Cramer's rule); test helper only.
    fn inverse(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
        let [[a, b, c], [d, e, f], [g, h, i]] = m;
        let det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
        [
            [e * i - f * h, c * h - b * i, b * f - c * e],
            [f * g - d * i, a * i - c * g, c * d - a * f],
            [d * h - e * g, b * g - a * h, a * e - b * d],
        ]
        .map(|row| row.map(|v| v / det))
    }

    /// The hard-coded matrix is the one implied by the BT.709 primaries and the D65 white.
    #[test]
    fn matrix_follows_from_primaries_and_white() {
        let prim = [(0.64, 0.33), (0.30, 0.60), (0.15, 0.06)];
        // Columns: XYZ of each primary with Y = 1.
        let p = [
            prim.map(|(x, y)| x / y),
            [1.0; 3],
            prim.map(|(x, y)| (1.0 - x - y) / y),
        ];
        let pi = inverse(p);
        let s: [f64; 3] = std::array::from_fn(|r| (0..3).map(|k| pi[r][k] * D65_WHITE[k]).sum());
        for r in 0..3 {
            for c in 0..3 {
                let want = p[r][c] * s[c];
                assert!(
                    close(RGB_TO_XYZ[r][c], want, 1e-9),
                    "M[{r}][{c}] = {} vs derived {want}",
                    RGB_TO_XYZ[r][c]
                );
            }
            let row_sum: f64 = RGB_TO_XYZ[r].iter().sum();
            assert!(close(row_sum, D65_WHITE[r], 1e-9));
        }
        // And it matches the four-decimal IEC 61966-2-1 matrix.
        let iec = [
            [0.4124, 0.3576, 0.1805],
            [0.2126, 0.7152, 0.0722],
            [0.0193, 0.1192, 0.9505],
        ];
        for r in 0..3 {
            for c in 0..3 {
                assert!(close(RGB_TO_XYZ[r][c], iec[r][c], 2e-4));
            }
        }
    }

    #[test]
    fn constants() {
        assert!(close(CIE_EPSILON, 0.008856, 1e-6));
        assert!(close(CIE_KAPPA, 903.2963, 1e-4));
        // The two branches of L* meet at ε (continuity of the κ/ε form): κε = 8.
        assert!(close(CIE_KAPPA * CIE_EPSILON, 8.0, 1e-12));
        assert!(close(116.0 * CIE_EPSILON.cbrt() - 16.0, 8.0, 1e-12));
    }

    #[test]
    fn white_is_l100_u0_v0() {
        let xyz = linear_rgb_to_xyz([1.0; 3]);
        for c in 0..3 {
            assert!(close(xyz[c], D65_WHITE[c], 1e-9));
        }
        assert_luv([1.0; 3], [100.0, 0.0, 0.0], 1e-6);
    }

    #[test]
    fn greys_are_achromatic_with_hand_computed_lightness() {
        // Linear 0.18 ("18 % grey"): 116·∛0.18 − 16 = 49.4961.
        assert_luv([0.18; 3], [49.4961, 0.0, 0.0], 1e-3);
        // Linear 0.5: 116·∛0.5 − 16 = 76.0693.
        assert_luv([0.5; 3], [76.0693, 0.0, 0.0], 1e-3);
        // sRGB-encoded 128/255 decodes to linear 0.215861; published L* = 53.585.
        let lin = ((128.0f64 / 255.0 + 0.055) / 1.055).powf(2.4) as f32;
        assert_luv([lin; 3], [53.585, 0.0, 0.0], 1e-3);
        // Below ε the linear branch applies: Y = 0.001 → L* = κ·0.001 = 0.903296.
        assert_luv([0.001; 3], [0.903296, 0.0, 0.0], 1e-5);
        // Above 1 is allowed: L* exceeds 100 (Y = 8 → 116·2 − 16 = 216).
        assert_luv([8.0; 3], [216.0, 0.0, 0.0], 1e-6);
    }

    #[test]
    fn primaries_match_published_values() {
        // Published L*u*v* (D65, 2°) of the sRGB primaries.
        assert_luv([1.0, 0.0, 0.0], [53.2408, 175.0151, 37.7564], 1e-3);
        assert_luv([0.0, 1.0, 0.0], [87.7347, -83.0776, 107.3985], 1e-3);
        assert_luv([0.0, 0.0, 1.0], [32.2970, -9.4054, -130.3423], 1e-3);
        // And XYZ of red is the first matrix column.
        let xyz = linear_rgb_to_xyz([1.0, 0.0, 0.0]);
        assert!(close(xyz[0], 0.412456, 1e-6));
        assert!(close(xyz[1], 0.212673, 1e-6));
        assert!(close(xyz[2], 0.019334, 1e-6));
    }

    #[test]
    fn black_and_negative_values_give_no_nan() {
        assert_eq!(linear_rgb_to_luv([0.0; 3]), [0.0; 3]);
        assert_eq!(linear_rgb_to_luv([-1.0, -2.0, -0.5]), [0.0; 3]);
        // Negative components are clamped: same as the clamped colour.
        assert_eq!(
            linear_rgb_to_luv([-1.0, 0.5, 0.25]),
            linear_rgb_to_luv([0.0, 0.5, 0.25])
        );
        // Tiny values stay finite.
        let tiny = linear_rgb_to_luv([f32::MIN_POSITIVE, 0.0, 0.0]);
        assert!(tiny.iter().all(|v| v.is_finite()));
        // Huge values stay finite.
        let huge = linear_rgb_to_luv([f32::MAX; 3]);
        assert!(huge.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn luminance_weights() {
        assert!(close(luminance([1.0; 3]), 1.0, 1e-12));
        assert!(close(luminance([1.0, 0.0, 0.0]), 0.2126, 1e-12));
        assert!(close(luminance([0.0, 2.0, 0.0]), 1.4304, 1e-12));
        assert!(close(luminance([0.0, 0.0, -1.0]), -0.0722, 1e-12));
    }
}
