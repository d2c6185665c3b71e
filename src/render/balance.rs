//! How a frame's rows are shared among devices (thesis §4.2: "Each render device is assigned
//! to a specific part of the screen depending on the speed of the device"). The first split
//! comes from what the devices say of themselves (compute units × clock); after that each
//! device's speed is measured on the band it rendered (rows per second of kernel time, from
//! OpenCL profiling events) and the rows are shared in proportion to those speeds.
//!
//! Proportional sharing has equal kernel times as its fixed point even when rows differ in
//! cost (sky against geometry): a device that took longer than the other gets fewer rows next
//! time. Two guards keep it from chasing noise: nothing moves while the devices' times are
//! within [`Balancer::tolerance`] of each other, and each step goes half way to the
//! proportional split (the measured speed of a band says little about rows it did not hold).

use std::ops::Range;

/// Shares `height` rows among devices, on multiples of `granularity` rows.
#[derive(Clone, Debug)]
pub struct Balancer {
    pub height: u32,
    pub granularity: u32,
    /// Relative difference of the slowest and fastest device's kernel time below which the
    /// split stays as it is.
    pub tolerance: f64,
    /// Fraction of the way to the proportional split taken per frame (1: all the way).
    pub step: f64,
    /// Re-balance at all (false: the first split is kept, for comparison).
    pub enabled: bool,
}

impl Balancer {
    pub fn new(height: u32, granularity: u32) -> Balancer {
        Balancer {
            height,
            granularity: granularity.max(1),
            tolerance: 0.05,
            step: 0.5,
            enabled: true,
        }
    }

    /// Contiguous bands, top to bottom, with sizes in proportion to `weights`; every device
    /// keeps at least one granule while the image has enough rows, so its speed stays measured.
    pub fn split(&self, weights: &[f64]) -> Vec<Range<u32>> {
        let n = weights.len().max(1);
        // A weight that says nothing (zero, negative, NaN: a device that reports no clock)
        // counts as the mean of the others.
        let valid = |w: f64| w.is_finite() && w > 0.0;
        let known: Vec<f64> = weights.iter().copied().filter(|w| valid(*w)).collect();
        let mean = if known.is_empty() {
            1.0
        } else {
            known.iter().sum::<f64>() / known.len() as f64
        };
        let weight = |i: usize| {
            weights
                .get(i)
                .copied()
                .filter(|w| valid(*w))
                .unwrap_or(mean)
        };
        let total: f64 = (0..n).map(weight).sum();
        let share = |i: usize| weight(i) / total;
        let g = self.granularity;
        let granules = self.height.div_ceil(g);
        let min = if granules >= n as u32 { 1 } else { 0 };
        // Cumulative boundaries: the row each share ends at, rounded to the nearest granule
        // boundary (in rows, since the last granule may be short), then pushed apart to keep
        // the minimum.
        let mut bounds = vec![0u32; n + 1];
        let mut acc = 0.0;
        for i in 0..n {
            acc += share(i);
            let row = acc * self.height as f64;
            bounds[i + 1] = ((row / g as f64).round() as u32).min(granules);
        }
        bounds[n] = granules;
        for i in 1..n {
            bounds[i] = bounds[i].max(bounds[i - 1] + min);
        }
        for i in (1..n).rev() {
            bounds[i] = bounds[i].min(bounds[i + 1].saturating_sub(min));
        }
        (0..n)
            .map(|i| (bounds[i] * g).min(self.height)..(bounds[i + 1] * g).min(self.height))
            .collect()
    }

    /// The next split after a frame in which device i rendered `bands[i]` in `seconds[i]` of
    /// kernel time; None when it should stay.
    pub fn next(&self, bands: &[Range<u32>], seconds: &[f64]) -> Option<Vec<Range<u32>>> {
        if !self.enabled || bands.len() < 2 {
            return None;
        }
        let busy: Vec<f64> = bands
            .iter()
            .zip(seconds)
            .filter(|(b, _)| !b.is_empty())
            .map(|(_, t)| *t)
            .collect();
        let (lo, hi) = busy.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), t| {
            (lo.min(*t), hi.max(*t))
        });
        if !(hi > 0.0) || (hi - lo) / hi <= self.tolerance {
            return None;
        }
        // Rows per second; a device without rows (or time) keeps an equal share's estimate.
        let speeds: Vec<f64> = bands
            .iter()
            .zip(seconds)
            .map(|(b, t)| {
                if b.is_empty() || !(*t > 0.0) {
                    f64::NAN
                } else {
                    b.len() as f64 / t
                }
            })
            .collect();
        let known: Vec<f64> = speeds.iter().copied().filter(|s| s.is_finite()).collect();
        let mean = known.iter().sum::<f64>() / known.len().max(1) as f64;
        let total_speed: f64 = speeds
            .iter()
            .map(|s| if s.is_finite() { *s } else { mean })
            .sum();
        let weights: Vec<f64> = bands
            .iter()
            .zip(&speeds)
            .map(|(b, s)| {
                let target =
                    self.height as f64 * if s.is_finite() { *s } else { mean } / total_speed;
                b.len() as f64 + self.step * (target - b.len() as f64)
            })
            .collect();
        let next = self.split(&weights);
        (next != bands).then_some(next)
    }
}

/// Which device held each row under `bands`.
pub fn owners(bands: &[Range<u32>], height: u32) -> Vec<usize> {
    let mut owner = vec![0; height as usize];
    for (i, b) in bands.iter().enumerate() {
        for y in b.clone() {
            owner[y as usize] = i;
        }
    }
    owner
}

#[cfg(test)]
mod tests {
    use super::*;

    fn covers(bands: &[Range<u32>], height: u32) -> bool {
        bands.first().is_some_and(|b| b.start == 0)
            && bands.last().is_some_and(|b| b.end == height)
            && bands.windows(2).all(|w| w[0].end == w[1].start)
    }

    #[test]
    fn splits_cover_the_image_on_granules_in_proportion() {
        let b = Balancer::new(100, 1);
        assert_eq!(b.split(&[1.0, 1.0]), vec![0..50, 50..100]);
        assert_eq!(b.split(&[1.0, 3.0]), vec![0..25, 25..100]);
        let g = Balancer::new(100, 8);
        let s = g.split(&[2.0, 1.0]);
        assert!(covers(&s, 100), "{s:?}");
        assert_eq!(s[0].end % 8, 0);
        // The last granule is short: boundaries are rounded in rows (66.7 → 64, not 72).
        assert_eq!(s, vec![0..64, 64..100]);
        // Every device keeps a granule; a zero or NaN weight counts as the mean of the others.
        assert_eq!(b.split(&[1.0, 0.0]), vec![0..50, 50..100]);
        assert_eq!(b.split(&[1.0, 1e-9]), vec![0..99, 99..100]);
        // Fewer rows than devices: each row to one device, one device without rows.
        let tiny = Balancer::new(2, 1).split(&[1.0, 1.0, 1.0]);
        assert!(covers(&tiny, 2), "{tiny:?}");
        assert_eq!(tiny.iter().filter(|b| b.is_empty()).count(), 1, "{tiny:?}");
    }

    #[test]
    fn rebalancing_converges_to_equal_times_and_then_stays() {
        // Device 1 is three times as fast; rows 0-49 cost twice as much as rows 50-99.
        let cost = |r: &Range<u32>| {
            r.clone()
                .map(|y| if y < 50 { 2.0 } else { 1.0 })
                .sum::<f64>()
        };
        let speed = [1.0, 3.0];
        let b = Balancer::new(100, 1);
        let mut bands = b.split(&[1.0, 1.0]);
        let mut moves = 0;
        for _ in 0..20 {
            let t: Vec<f64> = bands.iter().zip(speed).map(|(r, s)| cost(r) / s).collect();
            match b.next(&bands, &t) {
                Some(n) => {
                    assert!(covers(&n, 100));
                    bands = n;
                    moves += 1;
                }
                None => break,
            }
        }
        let t: Vec<f64> = bands.iter().zip(speed).map(|(r, s)| cost(r) / s).collect();
        assert!(
            (t[0] - t[1]).abs() / t[0].max(t[1]) <= b.tolerance,
            "{bands:?} {t:?}"
        );
        assert!(moves >= 2, "{moves}");
        assert!(b.next(&bands, &t).is_none());
        let off = Balancer {
            enabled: false,
            ..b.clone()
        };
        assert!(off.next(&[0..50, 50..100], &[1.0, 3.0]).is_none());
    }

    #[test]
    fn owners_follow_the_bands() {
        assert_eq!(owners(&[0..2, 2..3, 3..5], 5), vec![0, 0, 1, 2, 2]);
    }
}
