//! kernels/render/rng.cl in Rust: counter-based random numbers, bit for bit.

pub const DIM_PIXEL_X: u32 = 0;
pub const DIM_PIXEL_Y: u32 = 1;
pub const DIM_LENS_U: u32 = 2;
pub const DIM_LENS_V: u32 = 3;
pub const DIM_RUSSIAN_ROULETTE: u32 = 4;
pub const DIM_LIGHT_SELECT: u32 = 5;
pub const DIM_LIGHT_U: u32 = 6;
pub const DIM_LIGHT_V: u32 = 7;
pub const DIM_BSDF_LOBE: u32 = 8;
pub const DIM_BSDF_U: u32 = 9;
pub const DIM_BSDF_V: u32 = 10;

/// Wellons' lowbias32 integer hash.
pub fn hash_u32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

pub fn rng_sample_key(seed: u32, pixel: u32, sample: u32) -> u32 {
    hash_u32(hash_u32(hash_u32(seed ^ 0x9e37_79b9) ^ pixel) ^ sample)
}

/// A uniform float in [0, 1) with 24 random bits.
pub fn rng_uniform(key: u32, bounce: u32, dim: u32) -> f32 {
    let h = hash_u32(key ^ hash_u32((bounce << 8) | dim));
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_in_unit_interval_and_roughly_uniform() {
        let mut buckets = [0u32; 16];
        let n = 160_000;
        for i in 0..n {
            let u = rng_uniform(rng_sample_key(7, i, i / 3), i % 5, i % 11);
            assert!((0.0..1.0).contains(&u));
            buckets[(u * 16.0) as usize] += 1;
        }
        // Chi-square with 15 degrees of freedom: 99.9% quantile is 37.7.
        let e = n as f64 / 16.0;
        let chi2: f64 = buckets.iter().map(|&b| (b as f64 - e).powi(2) / e).sum();
        assert!(chi2 < 37.7, "chi2 = {chi2}");
    }

    #[test]
    fn dimensions_are_uncorrelated() {
        // Pearson correlation between consecutive dimensions of the same sample.
        let n = 100_000;
        let (mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            let key = rng_sample_key(1, i, 0);
            let x = rng_uniform(key, 0, DIM_PIXEL_X) as f64;
            let y = rng_uniform(key, 0, DIM_PIXEL_Y) as f64;
            sx += x;
            sy += y;
            sxx += x * x;
            syy += y * y;
            sxy += x * y;
        }
        let n = n as f64;
        let cov = sxy / n - sx * sy / (n * n);
        let r = cov / ((sxx / n - (sx / n).powi(2)) * (syy / n - (sy / n).powi(2))).sqrt();
        assert!(r.abs() < 0.015, "correlation {r}");
    }
}
