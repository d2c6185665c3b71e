//! The pixels that hold most of an image's error (`noisefree compare --worst N`).
//!
//! Where one filter loses to another is often a few hundred pixels: a light's rim, a firefly
//! the filter spread, dark texels. A pixel's error here is its term of the image metric, so
//! the terms of all pixels sum to the metric times the pixel count, and each pixel's share of
//! the image's error is exact: in CIELUV (ΔL\*² + Δu\*² + Δv\*²) / 3, the term of
//! [`super::mse_luv`]; in relative MSE the mean over the channels of (x − r)² / (r² + 0.01),
//! the term of [`super::rel_mse`].

use anyhow::Result;
use serde::Serialize;

use super::{check_pair, luv_errors, rel_term};
use crate::imaging::RgbImage;

/// The per-pixel error the pixels are ranked by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PixelMetric {
    /// The pixel's term of MSE in CIELUV (the thesis's metric).
    Luv,
    /// The pixel's term of relative MSE (dark pixels weigh most).
    RelMse,
}

/// One pixel of the ranking.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PixelError {
    pub x: u32,
    pub y: u32,
    pub test: [f32; 3],
    pub reference: [f32; 3],
    /// The pixel's term of the metric.
    pub error: f64,
    /// Its share of the image's whole error (all pixels' terms sum to 1).
    pub share: f64,
}

/// The per-pixel terms of `metric`, row-major; their mean is the image metric.
pub fn pixel_errors(
    test: &RgbImage,
    reference: &RgbImage,
    metric: PixelMetric,
) -> Result<Vec<f64>> {
    check_pair(test, reference)?;
    Ok(match metric {
        PixelMetric::Luv => luv_errors(test, reference).collect(),
        PixelMetric::RelMse => test
            .pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(t, r)| {
                (0..3)
                    .map(|c| rel_term(f64::from(t[c]), f64::from(r[c])))
                    .sum::<f64>()
                    / 3.0
            })
            .collect(),
    })
}

/// The `n` pixels with the largest terms of `metric`, largest first (ties: the first in
/// row-major order first).
pub fn worst_pixels(
    test: &RgbImage,
    reference: &RgbImage,
    metric: PixelMetric,
    n: usize,
) -> Result<Vec<PixelError>> {
    let errors = pixel_errors(test, reference, metric)?;
    let total: f64 = errors.iter().sum();
    let mut order: Vec<usize> = (0..errors.len()).collect();
    // Largest first; a NaN term (check_pair refuses non-finite images) cannot occur.
    order.sort_by(|&a, &b| errors[b].total_cmp(&errors[a]).then(a.cmp(&b)));
    let w = test.width as usize;
    Ok(order
        .into_iter()
        .take(n)
        .map(|i| PixelError {
            x: (i % w) as u32,
            y: (i / w) as u32,
            test: test.pixels[i],
            reference: reference.pixels[i],
            error: errors[i],
            share: if total > 0.0 { errors[i] / total } else { 0.0 },
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::{mse_luv, rel_mse};

    fn image(pixels: Vec<[f32; 3]>) -> RgbImage {
        RgbImage {
            width: 3,
            height: 2,
            pixels,
        }
    }

    #[test]
    fn ranks_the_pixels_by_their_share_of_the_metric() {
        let reference = image(vec![[0.5; 3]; 6]);
        let mut pixels = vec![[0.5; 3]; 6];
        pixels[4] = [0.9, 0.5, 0.5]; // (1, 1): the largest error
        pixels[2] = [0.5, 0.6, 0.5]; // (2, 0)
        pixels[0] = [0.5, 0.5, 0.45]; // (0, 0)
        let test = image(pixels);
        for metric in [PixelMetric::Luv, PixelMetric::RelMse] {
            let all = pixel_errors(&test, &reference, metric).unwrap();
            let mean = all.iter().sum::<f64>() / 6.0;
            let whole = match metric {
                PixelMetric::Luv => mse_luv(&test, &reference).unwrap(),
                PixelMetric::RelMse => rel_mse(&test, &reference).unwrap(),
            };
            assert!(
                (mean - whole).abs() <= 1e-12 * whole,
                "{metric:?}: {mean} vs {whole}"
            );
            let worst = worst_pixels(&test, &reference, metric, 4).unwrap();
            let at: Vec<(u32, u32)> = worst.iter().map(|p| (p.x, p.y)).collect();
            // The fourth is the first error-free pixel in row-major order.
            assert_eq!(at, [(1, 1), (2, 0), (0, 0), (1, 0)], "{metric:?}");
            let shares: f64 = worst.iter().map(|p| p.share).sum();
            assert!((shares - 1.0).abs() < 1e-12, "{metric:?}: shares {shares}");
            assert_eq!(worst[0].test, [0.9, 0.5, 0.5]);
            assert_eq!(worst[3].error, 0.0);
        }
    }

    #[test]
    fn identical_images_have_no_share() {
        let a = image(vec![[0.25; 3]; 6]);
        let worst = worst_pixels(&a, &a, PixelMetric::RelMse, 10).unwrap();
        assert_eq!(worst.len(), 6);
        assert!(worst.iter().all(|p| p.error == 0.0 && p.share == 0.0));
    }
}
