//! Image quality metrics: a rendered/filtered *test* image against a *reference* (ground
//! truth), both linear RGB [`RgbImage`]s of the same size. Used by `noisefree compare` and the
//! benchmarks.
//!
//! The thesis (§5.2.2, eq. 5.19) grades images by their mean squared error in CIELUV, measured
//! with the MSU tool on its 8-bit output images. Here the same kind of metric is computed
//! directly on the linear float images ([`mse_luv`]), with every convention fixed below, so
//! the numbers are reproducible; they are *not* numerically the thesis's MSU values (those
//! were taken after tone mapping and 8-bit quantisation).
//!
//! Conventions shared by all metrics:
//!
//! * Pixel values are linear RGB, **linear sRGB / Rec. 709 primaries, no exposure scaling**:
//!   (1, 1, 1) is the reference white (Y = 1). Values above 1 are allowed. See [`color`] for
//!   the XYZ and L\*u\*v\* conversions (D65 white (0.95047, 1, 1.08883), κ/ε form, negatives
//!   clamped to 0 for L\*u\*v\* only, black without NaN).
//! * Every "mean" is over all pixels **and** over the three channels, i.e. divided by
//!   3·W·H; squared differences are not summed over channels.
//! * Inputs must match in size, be non-empty, have `pixels.len() == width * height`, and
//!   hold only finite values; otherwise the functions return an error naming the problem
//!   (and, for non-finite values, the first bad pixel, test image scanned before reference).
//! * Arithmetic is in `f64`, summed sequentially in pixel order, so results are deterministic.
//! * [`psnr`] is `f64::INFINITY` for identical images. `format!("{}")` prints it as `inf`;
//!   [`Metrics`] serialises a non-finite PSNR as the *string* `"inf"` (JSON has no infinity;
//!   `serde_json` would otherwise write `null`), finite values as numbers.

pub mod color;
pub mod error_map;
pub mod ssim;
pub mod worst;

use anyhow::{Result, bail};
use serde::{Serialize, Serializer};

use crate::imaging::RgbImage;

pub use color::{
    CIE_EPSILON, CIE_KAPPA, D65_WHITE, RGB_TO_XYZ, linear_rgb_to_luv, linear_rgb_to_xyz, luminance,
    xyz_to_luv,
};
pub use error_map::{ErrorMap, ErrorScale, error_map_from_values, percentile};
pub use ssim::ssim_gray;

/// The ε in the denominator of [`rel_mse`]: (x − r)² / (r² + 0.01).
pub const REL_MSE_EPSILON: f64 = 0.01;

/// The peak signal value of [`psnr`]: 1.0 (linear RGB white).
pub const PSNR_PEAK: f64 = 1.0;

/// All metrics of one test image against its reference (see the functions of the same names
/// for the exact definitions). Serialises as a flat record; `psnr` as a number, or as the
/// string `"inf"` when the images are identical.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// [`mse_luv`]: mean over pixels of (ΔL\*² + Δu\*² + Δv\*²) / 3 (the thesis's metric).
    pub mse_luv: f64,
    /// [`mse_rgb`]: mean over pixels and channels of (x − r)² in linear RGB.
    pub mse_rgb: f64,
    /// [`rel_mse`]: mean over pixels and channels of (x − r)² / (r² + 0.01).
    pub rel_mse: f64,
    /// [`psnr`]: 10·log10(1 / mse_rgb) dB; +∞ for identical images.
    #[serde(serialize_with = "serialize_f64_or_string")]
    pub psnr: f64,
    /// [`ssim()`]: mean SSIM of the clamped linear luminance, 11×11 Gaussian window σ = 1.5.
    pub ssim: f64,
}

impl std::fmt::Display for Metrics {
    /// One line, e.g. `MSE(Luv) 8.642000  MSE(RGB) 0.001234  relMSE 0.012345  PSNR 29.087 dB
    /// SSIM 0.912345`; an infinite PSNR prints as `inf`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "MSE(Luv) {:.6}  MSE(RGB) {:.6}  relMSE {:.6}  PSNR {:.3} dB  SSIM {:.6}",
            self.mse_luv, self.mse_rgb, self.rel_mse, self.psnr, self.ssim
        )
    }
}

/// Finite values as numbers; ±∞ and NaN as the strings `"inf"`, `"-inf"`, `"NaN"` (Rust's
/// `Display` spelling), since JSON has no representation for them.
fn serialize_f64_or_string<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_str(&v.to_string())
    }
}

/// Checks one image: non-empty, buffer length = width × height, all values finite.
fn check_image(img: &RgbImage, role: &str) -> Result<()> {
    let n = img.width as usize * img.height as usize;
    if img.pixels.len() != n {
        bail!(
            "{role} image: the pixel buffer holds {} pixels, but {}×{} needs {n}",
            img.pixels.len(),
            img.width,
            img.height
        );
    }
    if n == 0 {
        bail!(
            "{role} image is empty ({}×{}); metrics need at least one pixel",
            img.width,
            img.height
        );
    }
    if let Some(i) = img
        .pixels
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        let w = img.width as usize;
        let p = img.pixels[i];
        let c = p.iter().position(|c| !c.is_finite()).unwrap_or(0);
        bail!(
            "{role} image has a non-finite value at pixel (x, y) = ({}, {}), channel {}: {} \
             (pixel = [{}, {}, {}]); metrics need finite pixels",
            i % w,
            i / w,
            ["R", "G", "B"][c],
            p[c],
            p[0],
            p[1],
            p[2]
        );
    }
    Ok(())
}

/// Checks a test/reference pair: same size, then [`check_image`] on each (test first).
fn check_pair(test: &RgbImage, reference: &RgbImage) -> Result<()> {
    if (test.width, test.height) != (reference.width, reference.height) {
        bail!(
            "image size mismatch: test is {}×{}, reference is {}×{}",
            test.width,
            test.height,
            reference.width,
            reference.height
        );
    }
    check_image(test, "test")?;
    check_image(reference, "reference")
}

/// Per-pixel CIELUV squared error, row-major: (ΔL\*² + Δu\*² + Δv\*²) / 3 with
/// [`linear_rgb_to_luv`] (the mean over the three channels, so its image mean is
/// [`mse_luv`]). The natural input for [`error_map_from_values`].
pub fn luv_error_image(test: &RgbImage, reference: &RgbImage) -> Result<Vec<f64>> {
    check_pair(test, reference)?;
    Ok(luv_errors(test, reference).collect())
}

fn luv_errors<'a>(test: &'a RgbImage, reference: &'a RgbImage) -> impl Iterator<Item = f64> + 'a {
    test.pixels.iter().zip(&reference.pixels).map(|(t, r)| {
        let (a, b) = (linear_rgb_to_luv(*t), linear_rgb_to_luv(*r));
        (0..3).map(|c| (a[c] - b[c]) * (a[c] - b[c])).sum::<f64>() / 3.0
    })
}

/// The per-channel CIELUV MSE [MSE(L\*), MSE(u\*), MSE(v\*)], each a mean over pixels; their
/// mean is [`mse_luv`].
pub fn mse_luv_channels(test: &RgbImage, reference: &RgbImage) -> Result<[f64; 3]> {
    check_pair(test, reference)?;
    let mut sum = [0.0f64; 3];
    for (t, r) in test.pixels.iter().zip(&reference.pixels) {
        let (a, b) = (linear_rgb_to_luv(*t), linear_rgb_to_luv(*r));
        for c in 0..3 {
            sum[c] += (a[c] - b[c]) * (a[c] - b[c]);
        }
    }
    let n = test.pixels.len() as f64;
    Ok(sum.map(|s| s / n))
}

/// MSE in CIELUV, the thesis's metric (§5.2.2, eq. 5.19 applied in CIE 1976 L\*u\*v\*):
/// MSE_Luv = (1 / (W·H)) Σ_pixels (ΔL\*² + Δu\*² + Δv\*²) / 3, i.e. the mean over pixels *and*
/// the three L\*u\*v\* channels. Conversion: [`linear_rgb_to_luv`] (linear Rec. 709 RGB, white
/// (1, 1, 1) ↦ L\* = 100, D65 (0.95047, 1, 1.08883), negatives clamped to 0).
/// Units: (L\*u\*v\* units)²; a uniform ΔE of d gives d²/3.
pub fn mse_luv(test: &RgbImage, reference: &RgbImage) -> Result<f64> {
    check_pair(test, reference)?;
    Ok(mean(luv_errors(test, reference), test.pixels.len()))
}

/// MSE in linear RGB: (1 / (3·W·H)) Σ_pixels Σ_channels (x − r)², values as given (negative
/// and > 1 included).
pub fn mse_rgb(test: &RgbImage, reference: &RgbImage) -> Result<f64> {
    check_pair(test, reference)?;
    Ok(mse_rgb_unchecked(test, reference))
}

fn mse_rgb_unchecked(test: &RgbImage, reference: &RgbImage) -> f64 {
    let terms = channel_pairs(test, reference).map(|(x, r)| (x - r) * (x - r));
    mean(terms, 3 * test.pixels.len())
}

/// Relative MSE: (1 / (3·W·H)) Σ_pixels Σ_channels (x − r)² / (r² + 0.01), r the reference
/// channel value, ε = [`REL_MSE_EPSILON`] = 0.01 (avoids division by zero in dark pixels).
pub fn rel_mse(test: &RgbImage, reference: &RgbImage) -> Result<f64> {
    check_pair(test, reference)?;
    Ok(rel_mse_unchecked(test, reference))
}

fn rel_mse_unchecked(test: &RgbImage, reference: &RgbImage) -> f64 {
    let terms = channel_pairs(test, reference).map(|(x, r)| rel_term(x, r));
    mean(terms, 3 * test.pixels.len())
}

/// One channel's term of [`rel_mse`]: (x − r)² / (r² + [`REL_MSE_EPSILON`]).
fn rel_term(x: f64, r: f64) -> f64 {
    (x - r) * (x - r) / (r * r + REL_MSE_EPSILON)
}

/// PSNR in dB with peak [`PSNR_PEAK`] = 1.0 and the linear-RGB [`mse_rgb`] (mean over
/// channels): 10·log10(1² / MSE). `f64::INFINITY` when MSE = 0 (identical images); it can be
/// negative when MSE > 1 (HDR values). See [`psnr_from_mse`].
pub fn psnr(test: &RgbImage, reference: &RgbImage) -> Result<f64> {
    Ok(psnr_from_mse(mse_rgb(test, reference)?))
}

/// 10·log10([`PSNR_PEAK`]² / mse); `f64::INFINITY` for mse = 0 (and for mse ≤ 0).
pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse <= 0.0 {
        f64::INFINITY
    } else {
        10.0 * (PSNR_PEAK * PSNR_PEAK / mse).log10()
    }
}

/// Mean SSIM (Wang et al. 2004) of the luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of the
/// linear RGB, clamped to [0, 1]; 11×11 Gaussian window σ = 1.5, K1 = 0.01, K2 = 0.03, L = 1,
/// mean over the valid window positions; images smaller than 11 in either dimension are one
/// uniformly weighted window. Symmetric; 1 for identical images. See [`ssim`](mod@ssim).
pub fn ssim(test: &RgbImage, reference: &RgbImage) -> Result<f64> {
    check_pair(test, reference)?;
    Ok(ssim_unchecked(test, reference))
}

fn ssim_unchecked(test: &RgbImage, reference: &RgbImage) -> f64 {
    let luma = |img: &RgbImage| -> Vec<f64> {
        img.pixels
            .iter()
            .map(|p| luminance(*p).clamp(0.0, 1.0))
            .collect()
    };
    ssim_gray(
        &luma(test),
        &luma(reference),
        test.width as usize,
        test.height as usize,
    )
}

/// The false-colour map of [`luv_error_image`] drawn with `scale` (see [`ErrorScale`]; use
/// the same scale for every method shown side by side). Returns `width * height * 3` RGB8
/// bytes in [`ErrorMap::rgb8`]; writing files is the caller's business.
pub fn error_map(test: &RgbImage, reference: &RgbImage, scale: ErrorScale) -> Result<ErrorMap> {
    let errors = luv_error_image(test, reference)?;
    error_map_from_values(&errors, test.width, test.height, scale)
}

/// Every metric of `test` against `reference`. Errors if the sizes differ, an image is empty
/// or its buffer does not match its size, or any pixel value is not finite (naming the first
/// such pixel, test image first).
pub fn compare(test: &RgbImage, reference: &RgbImage) -> Result<Metrics> {
    check_pair(test, reference)?;
    let mse_rgb = mse_rgb_unchecked(test, reference);
    Ok(Metrics {
        mse_luv: mean(luv_errors(test, reference), test.pixels.len()),
        mse_rgb,
        rel_mse: rel_mse_unchecked(test, reference),
        psnr: psnr_from_mse(mse_rgb),
        ssim: ssim_unchecked(test, reference),
    })
}

/// (test, reference) channel values in f64, pixel by pixel, R G B.
fn channel_pairs<'a>(
    test: &'a RgbImage,
    reference: &'a RgbImage,
) -> impl Iterator<Item = (f64, f64)> + 'a {
    test.pixels
        .iter()
        .zip(&reference.pixels)
        .flat_map(|(t, r)| (0..3).map(move |c| (f64::from(t[c]), f64::from(r[c]))))
}

fn mean(terms: impl Iterator<Item = f64>, n: usize) -> f64 {
    terms.sum::<f64>() / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> RgbImage {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        RgbImage {
            width,
            height,
            pixels,
        }
    }

    /// A deterministic, textured HDR-ish image.
    fn textured(width: u32, height: u32, seed: u32) -> RgbImage {
        image(width, height, |x, y| {
            let mut h = x
                .wrapping_mul(73_856_093)
                .wrapping_add(y.wrapping_mul(19_349_663))
                .wrapping_add(seed.wrapping_mul(83_492_791));
            std::array::from_fn(|_| {
                h ^= h << 13;
                h ^= h >> 17;
                h ^= h << 5;
                (h % 1000) as f32 / 800.0
            })
        })
    }

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs().max(1e-300)
    }

    #[test]
    fn identical_images() {
        let img = textured(32, 24, 1);
        let m = compare(&img, &img).unwrap();
        assert_eq!(m.mse_luv, 0.0);
        assert_eq!(m.mse_rgb, 0.0);
        assert_eq!(m.rel_mse, 0.0);
        assert_eq!(m.psnr, f64::INFINITY);
        assert!((m.ssim - 1.0).abs() < 1e-12, "{}", m.ssim);
        assert!(m.to_string().contains("PSNR inf dB"), "{m}");
        // Also for a small (single-window) and an all-black image.
        let small = textured(3, 2, 2);
        assert!((compare(&small, &small).unwrap().ssim - 1.0).abs() < 1e-12);
        let black = image(12, 12, |_, _| [0.0; 3]);
        let m = compare(&black, &black).unwrap();
        assert_eq!((m.mse_luv, m.ssim), (0.0, 1.0));
    }

    /// 2×2 grey 0.5 reference; the test differs at pixel (1, 0) by (+0.25, 0, −0.25).
    #[test]
    fn single_pixel_difference_by_hand() {
        let reference = image(2, 2, |_, _| [0.5; 3]);
        let test = image(2, 2, |x, y| {
            if (x, y) == (1, 0) {
                [0.75, 0.5, 0.25]
            } else {
                [0.5; 3]
            }
        });
        let m = compare(&test, &reference).unwrap();
        // Σ(x−r)² = 0.0625 + 0 + 0.0625 = 0.125 over 3·4 = 12 values.
        assert!(close(m.mse_rgb, 0.125 / 12.0, 1e-12), "{}", m.mse_rgb);
        // Each term divided by 0.5² + 0.01 = 0.26.
        assert!(
            close(m.rel_mse, 0.125 / 0.26 / 12.0, 1e-12),
            "{}",
            m.rel_mse
        );
        // 10·log10(12 / 0.125) = 10·log10(96) = 19.822712…
        assert!(close(m.psnr, 19.822_712_330_395_684, 1e-12), "{}", m.psnr);
        // The LUV error sits in one pixel: MSE_Luv = that pixel's error / 4.
        let per_pixel = luv_error_image(&test, &reference).unwrap();
        assert_eq!(per_pixel.len(), 4);
        assert_eq!([per_pixel[0], per_pixel[2], per_pixel[3]], [0.0; 3]);
        let (a, b) = (
            linear_rgb_to_luv([0.75, 0.5, 0.25]),
            linear_rgb_to_luv([0.5; 3]),
        );
        let e = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)) / 3.0;
        assert!(close(per_pixel[1], e, 1e-12));
        assert!(close(m.mse_luv, e / 4.0, 1e-12));
        // Agrees with the separate functions.
        assert_eq!(mse_rgb(&test, &reference).unwrap(), m.mse_rgb);
        assert_eq!(rel_mse(&test, &reference).unwrap(), m.rel_mse);
        assert_eq!(psnr(&test, &reference).unwrap(), m.psnr);
        assert_eq!(ssim(&test, &reference).unwrap(), m.ssim);
        assert_eq!(mse_luv(&test, &reference).unwrap(), m.mse_luv);
    }

    #[test]
    fn mse_luv_black_vs_white_by_hand() {
        // One white pixel among four, reference black: ΔL* = 100, Δu* = Δv* = 0 →
        // per-pixel 100² / 3, mean over 4 pixels = 10000 / 12 = 833.33…
        let reference = image(2, 2, |_, _| [0.0; 3]);
        let test = image(
            2,
            2,
            |x, y| if (x, y) == (0, 1) { [1.0; 3] } else { [0.0; 3] },
        );
        let m = mse_luv(&test, &reference).unwrap();
        assert!(close(m, 10000.0 / 12.0, 1e-9), "{m}");
        let ch = mse_luv_channels(&test, &reference).unwrap();
        assert!(close(ch[0], 2500.0, 1e-9));
        assert!(ch[1].abs() < 1e-9 && ch[2].abs() < 1e-9);
        assert!(close((ch[0] + ch[1] + ch[2]) / 3.0, m, 1e-12));
        // Pure red vs black: (53.2408² + 175.0151² + 37.7564²) / 3 for the one pixel.
        let red = image(1, 1, |_, _| [1.0, 0.0, 0.0]);
        let black = image(1, 1, |_, _| [0.0; 3]);
        let want = (53.2408f64.powi(2) + 175.0151f64.powi(2) + 37.7564f64.powi(2)) / 3.0;
        assert!(close(mse_luv(&red, &black).unwrap(), want, 1e-5));
    }

    #[test]
    fn psnr_conventions() {
        assert_eq!(psnr_from_mse(0.0), f64::INFINITY);
        assert!(close(psnr_from_mse(0.01), 20.0, 1e-12));
        assert_eq!(psnr_from_mse(1.0), 0.0);
        assert!(psnr_from_mse(4.0) < 0.0);
    }

    #[test]
    fn ssim_constant_offset_is_luminance_term() {
        // Constant grey 0.5 vs 0.6: σ = 0, so SSIM = (2·0.3 + C1) / (0.25 + 0.36 + C1).
        let a = image(16, 16, |_, _| [0.5; 3]);
        let b = image(16, 16, |_, _| [0.6; 3]);
        let s = ssim(&a, &b).unwrap();
        assert!((s - 0.6001 / 0.6101).abs() < 1e-6, "{s}");
        // Luminance above 1 is clamped: 2.0 and 5.0 both become 1 → identical.
        let c = image(16, 16, |_, _| [2.0; 3]);
        let d = image(16, 16, |_, _| [5.0; 3]);
        assert!((ssim(&c, &d).unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn ssim_is_symmetric_and_below_one() {
        let a = textured(40, 30, 3);
        let b = textured(40, 30, 4);
        let (ab, ba) = (ssim(&a, &b).unwrap(), ssim(&b, &a).unwrap());
        assert_eq!(ab, ba);
        assert!(ab < 1.0 && ab > -1.0);
    }

    #[test]
    fn other_metrics_are_symmetric_where_they_should_be() {
        let a = textured(20, 20, 5);
        let b = textured(20, 20, 6);
        let ab = compare(&a, &b).unwrap();
        let ba = compare(&b, &a).unwrap();
        assert!(close(ab.mse_luv, ba.mse_luv, 1e-12));
        assert!(close(ab.mse_rgb, ba.mse_rgb, 1e-12));
        assert!(close(ab.psnr, ba.psnr, 1e-12));
        // relMSE is not symmetric (normalised by the reference).
        assert!(ab.mse_luv > 0.0 && ab.rel_mse > 0.0 && ab.psnr.is_finite());
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let a = textured(4, 3, 1);
        let b = textured(3, 4, 1);
        let err = compare(&a, &b).unwrap_err().to_string();
        assert!(err.contains("size mismatch") && err.contains("4×3") && err.contains("3×4"));
        let mut bad = textured(4, 3, 1);
        bad.pixels.pop();
        let err = compare(&bad, &a).unwrap_err().to_string();
        assert!(
            err.contains("test image") && err.contains("11 pixels"),
            "{err}"
        );
        let empty = RgbImage {
            width: 0,
            height: 0,
            pixels: vec![],
        };
        assert!(compare(&empty, &empty).is_err());
    }

    #[test]
    fn non_finite_pixels_are_named() {
        let good = textured(5, 4, 1);
        let mut bad = good.clone();
        bad.pixels[2 * 5 + 3][1] = f32::NAN; // (x, y) = (3, 2), G
        bad.pixels[3 * 5 + 1][0] = f32::INFINITY; // a later one, not reported
        let err = compare(&good, &bad).unwrap_err().to_string();
        assert!(err.contains("reference image"), "{err}");
        assert!(err.contains("(3, 2)") && err.contains("channel G"), "{err}");
        let err = compare(&bad, &good).unwrap_err().to_string();
        assert!(err.starts_with("test image"), "{err}");
        for f in [mse_luv, mse_rgb, rel_mse, psnr, ssim] {
            assert!(f(&bad, &good).is_err());
        }
        assert!(error_map(&bad, &good, ErrorScale::default()).is_err());
    }

    #[test]
    fn error_map_dimensions_and_monotonicity() {
        // Reference grey; the test's error grows left to right.
        let w = 64;
        let reference = image(w, 3, |_, _| [0.2; 3]);
        let test = image(w, 3, |x, _| [0.2 + 0.02 * x as f32; 3]);
        let scale = ErrorScale::Log { lo: 1e-3, hi: 1e4 };
        let map = error_map(&test, &reference, scale).unwrap();
        assert_eq!((map.width, map.height), (w, 3));
        assert_eq!(map.rgb8.len(), (w * 3 * 3) as usize);
        assert_eq!(map.scale, scale);
        let errors = luv_error_image(&test, &reference).unwrap();
        assert_eq!(errors[0], 0.0);
        // Zero error is the first colour.
        assert_eq!(map.rgb8[0..3], COLORMAP_FIRST);
        let mut prev_t = -1.0;
        for x in 0..w as usize {
            let e = errors[x];
            let t = scale.position(e);
            assert!(t >= prev_t, "position not monotone at x = {x}");
            if x > 0 {
                assert!(
                    e > errors[x - 1] && t > prev_t,
                    "strictly growing at x = {x}"
                );
            }
            prev_t = t;
            // The pixel's colour is the map's colour at that position…
            assert_eq!(map.rgb8[3 * x..3 * x + 3], crate::imaging::colormap(t));
        }
        // …and colours further along the map are lighter (colormap tests check L* is
        // monotone); here: green+red channels sum grows from first to last pixel.
        let first = &map.rgb8[0..3];
        let last = &map.rgb8[3 * (w as usize - 1)..3 * w as usize];
        assert!(
            u32::from(last[0]) + u32::from(last[1]) > u32::from(first[0]) + u32::from(first[1])
        );
        // Rows are identical (error does not depend on y).
        let row = 3 * w as usize;
        assert_eq!(map.rgb8[0..row], map.rgb8[row..2 * row]);
    }

    const COLORMAP_FIRST: [u8; 3] = crate::imaging::COLORMAP_ANCHORS[0];

    #[test]
    fn metrics_serialise_with_inf_as_string() {
        // Checked through toml (already a dependency); serde_json behaves the same way
        // since the field's serializer itself emits a string for non-finite values.
        let m = Metrics {
            mse_luv: 1.5,
            mse_rgb: 0.0,
            rel_mse: 0.0,
            psnr: f64::INFINITY,
            ssim: 1.0,
        };
        let s = toml::to_string(&m).unwrap();
        assert!(s.contains("psnr = \"inf\""), "{s}");
        assert!(s.contains("mse_luv = 1.5"), "{s}");
        let m = Metrics { psnr: 20.0, ..m };
        let s = toml::to_string(&m).unwrap();
        assert!(s.contains("psnr = 20.0"), "{s}");
    }
}
