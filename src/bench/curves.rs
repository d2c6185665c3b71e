//! Log-log curve maths of the accuracy-time study: reading a curve of error against spp or
//! time at a given x, and the x at which it reaches a given error.

/// Interpolates y at x on a curve given as (x, y) pairs, in log-log; outside the curve, a
/// straight log-log extension with `slope` from the nearest end. Returns (y, extrapolated).
pub(super) fn loglog_at(points: &[(f64, f64)], x: f64, slope: f64) -> Option<(f64, bool)> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|p| p.0 > 0.0 && p.1 > 0.0)
        .collect();
    let (first, last) = (pts.first()?, pts.last()?);
    let lx = x.ln();
    if x < first.0 {
        return Some(((first.1.ln() + slope * (lx - first.0.ln())).exp(), true));
    }
    if x > last.0 {
        return Some(((last.1.ln() + slope * (lx - last.0.ln())).exp(), true));
    }
    for w in pts.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if x >= x0 && x <= x1 {
            let f = if x1 > x0 {
                (lx - x0.ln()) / (x1.ln() - x0.ln())
            } else {
                0.0
            };
            return Some(((y0.ln() + f * (y1.ln() - y0.ln())).exp(), false));
        }
    }
    None
}

/// The x at which a decreasing curve reaches y (log-log), extending with slope -1 past its
/// ends (MSE falls as 1/spp). Returns (x, extrapolated).
pub(super) fn loglog_where(points: &[(f64, f64)], y: f64) -> Option<(f64, bool)> {
    let inv: Vec<(f64, f64)> = points.iter().map(|p| (p.1, p.0)).rev().collect();
    let mut sorted = inv.clone();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    loglog_at(&sorted, y, -1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loglog_interpolation_and_extension() {
        let curve = [(1.0, 100.0), (4.0, 25.0), (16.0, 6.25)];
        let (y, ex) = loglog_at(&curve, 2.0, -1.0).unwrap();
        assert!((y - 50.0).abs() < 1e-9 && !ex);
        let (y, ex) = loglog_at(&curve, 64.0, -1.0).unwrap();
        assert!((y - 6.25 / 4.0).abs() < 1e-9 && ex);
        let (x, ex) = loglog_where(&curve, 12.5).unwrap();
        assert!((x - 8.0).abs() < 1e-9 && !ex);
        let (x, ex) = loglog_where(&curve, 1.0).unwrap();
        assert!((x - 100.0).abs() < 1e-6 && ex);
    }
}
