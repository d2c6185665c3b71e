//! The other reading of Alg. 7's `CalculateBucket`: Peng's ("[23]", the mutual-information
//! code Sen & Darabi cite; the `estpab` routine of his MutualInfo package). Each value is
//! rounded to the nearest integer, halves away from 0, and every integer between the smallest
//! and the largest is a state. On the standardised samples of N (Alg. 6 lines 15-18) that is
//! a bucket one standard deviation wide, and as many buckets as the values span: a firefly
//! 20σ out lands in a bucket of its own instead of sharing the top one of `B` equal buckets
//! with everything above the mean.
//!
//! Empty states change no entropy, so the states are numbered densely in order
//! ([`quantize_unit`]); a variable with at most [`super::mi::MAX_BUCKETS`] of them uses the
//! bitsets of the range reading, a wider one counts its joint histograms directly.

/// Peng's rounding: `int(x + 0.5)` above 0, `int(x − 0.5)` otherwise (in f64; a NaN is 0).
#[inline]
fn round_half_away(v: f32) -> i64 {
    let d = v as f64;
    if d > 0.0 {
        (d + 0.5) as i64
    } else {
        (d - 0.5) as i64
    }
}

/// The state of every value, numbered densely in increasing order, into `codes`; returns the
/// number of states that occur. `table` is scratch.
pub fn quantize_unit(values: &[f32], codes: &mut [u16], table: &mut Vec<u32>) -> usize {
    assert_eq!(values.len(), codes.len());
    if values.is_empty() {
        return 0;
    }
    let (mut lo, mut hi) = (i64::MAX, i64::MIN);
    for &v in values {
        let r = round_half_away(v);
        lo = lo.min(r);
        hi = hi.max(r);
    }
    let span = (hi - lo) as u64 + 1;
    if span <= 1 << 16 {
        // Mark the integers that occur, then number them in order.
        table.clear();
        table.resize(span as usize, 0);
        for &v in values {
            table[(round_half_away(v) - lo) as usize] = 1;
        }
        let mut next = 0u32;
        for t in table.iter_mut() {
            if *t != 0 {
                *t = next;
                next += 1;
            } else {
                *t = u32::MAX;
            }
        }
        for (c, &v) in codes.iter_mut().zip(values) {
            *c = table[(round_half_away(v) - lo) as usize] as u16;
        }
        return next as usize;
    }
    // Values that are not standardised can span more integers than a table holds: sort the
    // distinct ones instead (at most one state per value, and n ≤ u16::MAX here).
    let mut distinct: Vec<i64> = values.iter().map(|&v| round_half_away(v)).collect();
    distinct.sort_unstable();
    distinct.dedup();
    for (c, &v) in codes.iter_mut().zip(values) {
        let r = round_half_away(v);
        *c = distinct.binary_search(&r).unwrap_or(0) as u16;
    }
    distinct.len()
}

/// The joint counts of two variables' states (`px × py`, row-major) into `joint`.
pub fn joint_counts(cx: &[u16], cy: &[u16], px: usize, py: usize, joint: &mut Vec<u32>) {
    joint.clear();
    joint.resize(px * py, 0);
    for (&a, &b) in cx.iter().zip(cy) {
        joint[a as usize * py + b as usize] += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_are_pengs_rounding_numbered_densely() {
        assert_eq!(
            [-1.5, -0.5, -0.49, 0.0, 0.49, 0.5, 1.49, 2.5].map(round_half_away),
            [-2, -1, 0, 0, 0, 1, 1, 3]
        );
        let v = [0.2f32, -0.7, 20.3, 0.4, 1.6, -0.7];
        let mut codes = [9u16; 6];
        // States -1, 0, 2, 20 occur: numbered 0..4 in order.
        assert_eq!(quantize_unit(&v, &mut codes, &mut Vec::new()), 4);
        assert_eq!(codes, [1, 0, 3, 1, 2, 0]);
        let wide = [0.0f32, 1.0e9, -1.0e9];
        let mut codes = [9u16; 3];
        assert_eq!(quantize_unit(&wide, &mut codes, &mut Vec::new()), 3);
        assert_eq!(codes, [1, 2, 0]);
    }
}
