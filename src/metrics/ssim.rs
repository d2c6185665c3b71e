//! Structural similarity (Wang, Bovik, Sheikh & Simoncelli, *Image quality assessment: from
//! error visibility to structural similarity*, IEEE TIP 13(4), 2004) on luminance.
//!
//! Conventions:
//!
//! * **Channel.** SSIM is computed on one channel: the relative luminance
//!   Y = 0.2126 R + 0.7152 G + 0.0722 B of the *linear* RGB ([`super::color::luminance`]),
//!   clamped to [0, 1]. No sRGB encoding is applied; HDR values above 1 saturate at 1.
//! * **Constants.** Dynamic range L = 1, K1 = 0.01, K2 = 0.03, so C1 = (K1·L)² = 1e-4 and
//!   C2 = (K2·L)² = 9e-4. The full three-term product with C3 = C2/2, i.e.
//!   SSIM = (2μxμy + C1)(2σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2)).
//! * **Window.** An 11×11 circularly symmetric Gaussian, σ = 1.5 pixels, weights normalised to
//!   sum to 1 (separable: the outer product of a normalised 11-tap 1-D Gaussian). μ, σ² and
//!   σxy are weighted moments over the window: σx² = Σw·x² − μx², σxy = Σw·xy − μxμy
//!   (biased, as in the reference implementation).
//! * **Positions.** Only windows that lie entirely inside the image ("valid" positions, no
//!   padding): (W − 10)·(H − 10) of them. The result is their unweighted mean (MSSIM).
//! * **Small images.** If W < 11 or H < 11 there is no valid position; the whole image is then
//!   one window with *uniform* weights, and its single SSIM value is returned.
//! * The value is symmetric in its two arguments (bit for bit: every product of an x and a y
//!   term is formed as x·y before weighting), is 1 for identical images and lies in
//!   [−1, 1]. Arithmetic is in `f64`.

/// Side of the square Gaussian window.
pub const SSIM_WINDOW: usize = 11;
/// Standard deviation of the Gaussian window, pixels.
pub const SSIM_SIGMA: f64 = 1.5;
/// K1 of Wang et al.
pub const SSIM_K1: f64 = 0.01;
/// K2 of Wang et al.
pub const SSIM_K2: f64 = 0.03;
/// Dynamic range L of the (clamped) luminance.
pub const SSIM_L: f64 = 1.0;

const C1: f64 = (SSIM_K1 * SSIM_L) * (SSIM_K1 * SSIM_L);
const C2: f64 = (SSIM_K2 * SSIM_L) * (SSIM_K2 * SSIM_L);

/// The normalised 1-D Gaussian taps; the 2-D window is their outer product.
pub fn gaussian_taps() -> [f64; SSIM_WINDOW] {
    let half = (SSIM_WINDOW / 2) as f64;
    let mut taps: [f64; SSIM_WINDOW] = std::array::from_fn(|i| {
        let d = i as f64 - half;
        (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()
    });
    let sum: f64 = taps.iter().sum();
    taps.iter_mut().for_each(|t| *t /= sum);
    taps
}

/// SSIM of one window from its weighted moments.
pub(crate) fn ssim_from_moments(mx: f64, my: f64, vx: f64, vy: f64, cxy: f64) -> f64 {
    ((2.0 * (mx * my) + C1) * (2.0 * cxy + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2))
}

/// Mean SSIM of two single-channel `width × height` images (row-major), with the conventions
/// of the module docs (the values are used as given; the caller clamps). Both slices must
/// hold `width * height > 0` values.
pub fn ssim_gray(x: &[f64], y: &[f64], width: usize, height: usize) -> f64 {
    assert_eq!(x.len(), width * height);
    assert_eq!(y.len(), width * height);
    assert!(!x.is_empty());
    if width < SSIM_WINDOW || height < SSIM_WINDOW {
        return ssim_whole(x, y);
    }
    let g = gaussian_taps();
    let ow = width - (SSIM_WINDOW - 1);
    // Ring of the last 11 horizontally filtered rows: [Σx, Σy, Σx², Σy², Σxy] per column.
    let mut ring = vec![[0.0f64; 5]; SSIM_WINDOW * ow];
    let mut total = 0.0;
    for row in 0..height {
        let slot = row % SSIM_WINDOW;
        let xr = &x[row * width..(row + 1) * width];
        let yr = &y[row * width..(row + 1) * width];
        for (col, out) in ring[slot * ow..(slot + 1) * ow].iter_mut().enumerate() {
            let mut acc = [0.0; 5];
            for (k, w) in g.iter().enumerate() {
                let (a, b) = (xr[col + k], yr[col + k]);
                acc[0] += w * a;
                acc[1] += w * b;
                acc[2] += w * a * a;
                acc[3] += w * b * b;
                acc[4] += w * (a * b);
            }
            *out = acc;
        }
        if row + 1 < SSIM_WINDOW {
            continue;
        }
        let top = row + 1 - SSIM_WINDOW;
        for col in 0..ow {
            let mut m = [0.0; 5];
            for (k, w) in g.iter().enumerate() {
                let h = &ring[((top + k) % SSIM_WINDOW) * ow + col];
                for q in 0..5 {
                    m[q] += w * h[q];
                }
            }
            let (mx, my) = (m[0], m[1]);
            total += ssim_from_moments(mx, my, m[2] - mx * mx, m[3] - my * my, m[4] - mx * my);
        }
    }
    total / (ow * (height - (SSIM_WINDOW - 1))) as f64
}

/// SSIM with the whole image as one uniformly weighted window.
fn ssim_whole(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let mut m = [0.0; 3];
    for (a, b) in x.iter().zip(y) {
        m[0] += (a - mx) * (a - mx);
        m[1] += (b - my) * (b - my);
        m[2] += (a - mx) * (b - my);
    }
    ssim_from_moments(mx, my, m[0] / n, m[1] / n, m[2] / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Straightforward 2-D evaluation of every valid window, for checking the separable code.
    fn ssim_brute(x: &[f64], y: &[f64], w: usize, h: usize) -> f64 {
        let g = gaussian_taps();
        let mut total = 0.0;
        let mut count = 0;
        for oy in 0..=h - SSIM_WINDOW {
            for ox in 0..=w - SSIM_WINDOW {
                let mut m = [0.0; 5];
                for j in 0..SSIM_WINDOW {
                    for i in 0..SSIM_WINDOW {
                        let wt = g[i] * g[j];
                        let a = x[(oy + j) * w + ox + i];
                        let b = y[(oy + j) * w + ox + i];
                        m[0] += wt * a;
                        m[1] += wt * b;
                        m[2] += wt * a * a;
                        m[3] += wt * b * b;
                        m[4] += wt * (a * b);
                    }
                }
                total += ssim_from_moments(
                    m[0],
                    m[1],
                    m[2] - m[0] * m[0],
                    m[3] - m[1] * m[1],
                    m[4] - m[0] * m[1],
                );
                count += 1;
            }
        }
        total / count as f64
    }

    /// A deterministic pseudo-random texture in [lo, lo + span).
    fn texture(w: usize, h: usize, seed: u32, lo: f64, span: f64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
        (0..w * h)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                lo + span * (s as f64 / u32::MAX as f64)
            })
            .collect()
    }

    #[test]
    fn taps_are_normalised_symmetric_gaussian() {
        let g = gaussian_taps();
        assert!((g.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        for i in 0..SSIM_WINDOW {
            assert_eq!(g[i], g[SSIM_WINDOW - 1 - i]);
        }
        // Ratio of neighbouring taps follows exp(-(d² - (d-1)²) / (2σ²)).
        assert!((g[4] / g[5] - (-1.0f64 / 4.5).exp()).abs() < 1e-12);
    }

    #[test]
    fn separable_matches_brute_force() {
        let (w, h) = (23, 17);
        let x = texture(w, h, 1, 0.0, 1.0);
        let y = texture(w, h, 2, 0.2, 0.7);
        let fast = ssim_gray(&x, &y, w, h);
        let slow = ssim_brute(&x, &y, w, h);
        assert!((fast - slow).abs() < 1e-12, "{fast} vs {slow}");
        // Exactly 11 wide: one column of windows.
        let x = texture(11, 14, 3, 0.0, 1.0);
        let y = texture(11, 14, 4, 0.0, 1.0);
        let fast = ssim_gray(&x, &y, 11, 14);
        assert!((fast - ssim_brute(&x, &y, 11, 14)).abs() < 1e-12);
    }

    #[test]
    fn identical_is_one_and_symmetric() {
        let x = texture(20, 30, 5, 0.0, 1.0);
        let y = texture(20, 30, 6, 0.1, 0.5);
        assert!((ssim_gray(&x, &x, 20, 30) - 1.0).abs() < 1e-12);
        assert_eq!(ssim_gray(&x, &y, 20, 30), ssim_gray(&y, &x, 20, 30));
        let s = ssim_gray(&x, &y, 20, 30);
        assert!(s > -1.0 && s < 1.0);
    }

    #[test]
    fn constant_images_give_the_luminance_term() {
        // σ = 0 everywhere: SSIM = (2pq + C1) / (p² + q² + C1) · C2 / C2.
        let (p, q) = (0.5f64, 0.6f64);
        let want = (2.0 * p * q + 1e-4) / (p * p + q * q + 1e-4);
        assert!((want - 0.6001 / 0.6101).abs() < 1e-15);
        for (w, h) in [(16, 12), (5, 3)] {
            let s = ssim_gray(&vec![p; w * h], &vec![q; w * h], w, h);
            assert!((s - want).abs() < 1e-12, "{w}×{h}: {s} vs {want}");
        }
        // Black vs white: C1 / (1 + C1).
        let s = ssim_gray(&[0.0; 144], &[1.0; 144], 12, 12);
        assert!((s - 1e-4 / (1.0 + 1e-4)).abs() < 1e-12);
    }

    #[test]
    fn textured_offset_gives_only_the_luminance_term() {
        // y = x + c: σy = σx and σxy = σx², so contrast·structure = 1 and each window's
        // SSIM is its luminance term with μy = μx + c.
        let (w, h, c) = (19, 15, 0.25);
        let x = texture(w, h, 7, 0.0, 0.7);
        let y: Vec<f64> = x.iter().map(|v| v + c).collect();
        let g = gaussian_taps();
        let mut want = 0.0;
        let mut n = 0;
        for oy in 0..=h - 11 {
            for ox in 0..=w - 11 {
                let mut mx = 0.0;
                for j in 0..11 {
                    for i in 0..11 {
                        mx += g[i] * g[j] * x[(oy + j) * w + ox + i];
                    }
                }
                let my = mx + c;
                want += (2.0 * mx * my + 1e-4) / (mx * mx + my * my + 1e-4);
                n += 1;
            }
        }
        want /= n as f64;
        let got = ssim_gray(&x, &y, w, h);
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        assert!(got < 1.0);
    }

    #[test]
    fn small_image_is_one_uniform_window() {
        // 2×1: x = (0, 1), y = (1, 0): μ = 0.5 each, σ² = 0.25 each, σxy = −0.25.
        let s = ssim_gray(&[0.0, 1.0], &[1.0, 0.0], 2, 1);
        let want = (0.5 + 1e-4) * (-0.5 + 9e-4) / ((0.5 + 1e-4) * (0.5 + 9e-4));
        assert!((s - want).abs() < 1e-12);
        // A 1×1 image is fine too.
        assert!((ssim_gray(&[0.3], &[0.3], 1, 1) - 1.0).abs() < 1e-12);
    }
}
