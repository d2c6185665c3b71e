//! False-colour error maps: a per-pixel error value → a position t ∈ [0, 1] on a documented,
//! *fixed* scale ([`ErrorScale`]) → an 8-bit sRGB colour from a viridis-like perceptual map
//! ([`colormap`]). Because the scale is an explicit input (not re-normalised per image),
//! maps of different methods drawn with the same [`ErrorScale`] can be compared side by side:
//! the same colour means the same error everywhere.
//!
//! The colour map runs from dark purple (t = 0, small error) through blue and green to
//! yellow (t = 1, large error); its lightness increases monotonically along t (up to 8-bit
//! rounding, < 0.15 L\*), so a bigger error is a lighter colour, also in greyscale print.

use anyhow::{Result, bail, ensure};
use serde::Serialize;

use crate::imaging::colormap;

/// How an error value is placed on the colour map.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum ErrorScale {
    /// Logarithmic between two positive bounds:
    /// t = (log10 e − log10 lo) / (log10 hi − log10 lo), clamped to [0, 1];
    /// so e ≤ lo (including e = 0) is the first colour, e ≥ hi the last.
    Log { lo: f64, hi: f64 },
    /// Linear from 0: t = e / hi, clamped to [0, 1].
    Linear { hi: f64 },
}

impl Default for ErrorScale {
    /// `Log { lo: 1e-2, hi: 1e3 }`: five decades, meant for the per-pixel CIELUV squared error
    /// (mean of ΔL\*², Δu\*², Δv\*²). 1e-2 is a ΔE of about 0.17 (invisible), 1e3 a ΔE of
    /// about 55 (a gross error); the thesis's whole-image MSE values (≈ 10–40) sit mid-scale.
    fn default() -> Self {
        ErrorScale::Log { lo: 1e-2, hi: 1e3 }
    }
}

impl ErrorScale {
    /// A log scale whose top is the `percentile`-th percentile of `errors`
    /// ([`percentile`]) and whose bottom is `decades` decades lower. Compute it once (e.g. from
    /// the noisy input's errors) and reuse it for every map that is to be compared. If that
    /// percentile is 0 (or there are no finite values) the [`Default`] scale is returned.
    pub fn log_from_percentile(errors: &[f64], percentile_: f64, decades: f64) -> ErrorScale {
        let hi = percentile(errors, percentile_);
        if hi.is_finite() && hi > 0.0 && decades.is_finite() && decades > 0.0 {
            ErrorScale::Log {
                lo: hi / 10f64.powf(decades),
                hi,
            }
        } else {
            ErrorScale::default()
        }
    }

    /// Checks that the bounds are finite and ordered (Log: 0 < lo < hi; Linear: hi > 0).
    pub fn validate(&self) -> Result<()> {
        match *self {
            ErrorScale::Log { lo, hi } => ensure!(
                lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo,
                "log error scale needs finite bounds 0 < lo < hi, got lo = {lo}, hi = {hi}"
            ),
            ErrorScale::Linear { hi } => ensure!(
                hi.is_finite() && hi > 0.0,
                "linear error scale needs a finite bound hi > 0, got hi = {hi}"
            ),
        }
        Ok(())
    }

    /// The position t ∈ [0, 1] of error `e` on this scale (see the variants). Non-decreasing
    /// in `e`; NaN maps to 0. The scale must be valid ([`Self::validate`]).
    pub fn position(&self, e: f64) -> f64 {
        let t = match *self {
            ErrorScale::Log { lo, hi } => {
                if e <= lo {
                    0.0
                } else {
                    (e.log10() - lo.log10()) / (hi.log10() - lo.log10())
                }
            }
            ErrorScale::Linear { hi } => e / hi,
        };
        if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) }
    }
}

/// The nearest-rank percentile: the smallest finite value v of `values` such that at least
/// `p` % of the finite values are ≤ v (p clamped to [0, 100]; p = 0 gives the minimum).
/// Non-finite values are ignored; NaN if there are no finite values.
pub fn percentile(values: &[f64], p: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let p = if p.is_nan() {
        100.0
    } else {
        p.clamp(0.0, 100.0)
    };
    let rank = (p / 100.0 * v.len() as f64).ceil() as usize;
    v[rank.saturating_sub(1).min(v.len() - 1)]
}

/// A false-colour error image: `rgb8` holds `width * height` pixels, 3 bytes each (R, G, B,
/// sRGB-encoded), rows top to bottom, ready for an 8-bit RGB PNG. `scale` is the scale used,
/// to print in a legend.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorMap {
    pub width: u32,
    pub height: u32,
    pub rgb8: Vec<u8>,
    pub scale: ErrorScale,
}

/// Colours per-pixel error values (row-major, `width * height` of them, each finite and ≥ 0)
/// with `scale` and [`colormap`].
pub fn error_map_from_values(
    errors: &[f64],
    width: u32,
    height: u32,
    scale: ErrorScale,
) -> Result<ErrorMap> {
    scale.validate()?;
    ensure!(
        errors.len() == width as usize * height as usize,
        "error map: {} values for a {width}×{height} image",
        errors.len()
    );
    if let Some(i) = errors.iter().position(|e| !(e.is_finite() && *e >= 0.0)) {
        let w = width.max(1) as usize;
        bail!(
            "error map: pixel ({}, {}) has error {}, expected a finite value ≥ 0",
            i % w,
            i / w,
            errors[i]
        );
    }
    let rgb8 = errors
        .iter()
        .flat_map(|&e| colormap(scale.position(e)))
        .collect();
    Ok(ErrorMap {
        width,
        height,
        rgb8,
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn log_scale_positions() {
        let s = ErrorScale::Log { lo: 1e-2, hi: 1e2 };
        assert_eq!(s.position(0.0), 0.0);
        assert_eq!(s.position(1e-3), 0.0);
        assert!((s.position(1e-1) - 0.25).abs() < 1e-12);
        assert!((s.position(1.0) - 0.5).abs() < 1e-12);
        assert!((s.position(1e2) - 1.0).abs() < 1e-12);
        assert_eq!(s.position(1e9), 1.0);
        let lin = ErrorScale::Linear { hi: 4.0 };
        assert_eq!(lin.position(1.0), 0.25);
        assert_eq!(lin.position(8.0), 1.0);
    }

    #[test]
    fn invalid_scales_are_rejected() {
        for s in [
            ErrorScale::Log { lo: 0.0, hi: 1.0 },
            ErrorScale::Log { lo: 2.0, hi: 1.0 },
            ErrorScale::Log {
                lo: 1.0,
                hi: f64::INFINITY,
            },
            ErrorScale::Linear { hi: 0.0 },
            ErrorScale::Linear { hi: f64::NAN },
        ] {
            assert!(s.validate().is_err(), "{s:?}");
            assert!(error_map_from_values(&[0.0], 1, 1, s).is_err());
        }
        assert!(ErrorScale::default().validate().is_ok());
    }

    #[test]
    fn percentile_nearest_rank() {
        let v = [5.0, 1.0, 3.0, 2.0, 4.0, f64::NAN];
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&v, 20.0), 1.0);
        assert_eq!(percentile(&v, 21.0), 2.0);
        assert_eq!(percentile(&v, 50.0), 3.0);
        assert_eq!(percentile(&v, 100.0), 5.0);
        assert!(percentile(&[], 50.0).is_nan());
        let s = ErrorScale::log_from_percentile(&v, 100.0, 3.0);
        assert_eq!(s, ErrorScale::Log { lo: 5e-3, hi: 5.0 });
        assert_eq!(
            ErrorScale::log_from_percentile(&[0.0, 0.0], 99.0, 3.0),
            ErrorScale::default()
        );
    }

    #[test]
    fn map_dimensions_and_rejections() {
        let m = error_map_from_values(&[0.0; 12], 4, 3, ErrorScale::default()).unwrap();
        assert_eq!((m.width, m.height, m.rgb8.len()), (4, 3, 36));
        assert!(error_map_from_values(&[0.0; 11], 4, 3, ErrorScale::default()).is_err());
        let err = error_map_from_values(&[0.0, -1.0, 0.0, 0.0], 2, 2, ErrorScale::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("(1, 0)"), "{err}");
    }
}
