//! Log-log curve maths of the accuracy-time and AAF studies: reading a curve of error against
//! spp or time at a given x, the x at which it reaches a given error, a curve out of a study's
//! table, and the sheared rows against AAF's curve at equal quality.

use super::table::{ResultTable, num};

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

/// One method's curve from a study table: (x, MSE) by `x_column` (the `mse_rgb` column), sorted
/// by x, for the rows of scene `at.0` at size `at.1`.
pub(super) fn curve(
    t: &ResultTable,
    at: (&str, &str),
    method: &str,
    x_column: &str,
) -> Vec<(f64, f64)> {
    curve_of(t, at, method, x_column, "mse_rgb")
}

/// [`curve`] of another error column (`rel_mse`, ...).
pub(super) fn curve_of(
    t: &ResultTable,
    at: (&str, &str),
    method: &str,
    x_column: &str,
    y_column: &str,
) -> Vec<(f64, f64)> {
    let (scene, size) = at;
    let mut v: Vec<(f64, f64)> = t
        .records()
        .iter()
        .filter(|r| r["scene"] == scene && r["size"] == size && r["method"] == method)
        .filter_map(|r| Some((r[x_column].parse().ok()?, r[y_column].parse().ok()?)))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// An error column of a study table and how the tables name it and its square root.
pub(super) struct Metric {
    pub column: &'static str,
    pub name: &'static str,
    pub root: &'static str,
}

/// Squared error in linear RGB; its root is the RMS of Yan et al.'s Fig. 9.
pub(super) const MSE: Metric = Metric {
    column: "mse_rgb",
    name: "MSE",
    root: "RMS",
};

/// Relative squared error; it weighs dark regions as much as bright ones.
pub(super) const REL_MSE: Metric = Metric {
    column: "rel_mse",
    name: "relMSE",
    root: "√relMSE",
};

/// The sheared rows of a study table against AAF's curve `aaf` (Yan et al. 2015's claims, Fig.
/// 9 and §6), by `metric`: AAF's samples (`x_column`, `what` in the header) and seconds at the
/// row's error (log-log interpolation, slope −1 beyond the curve: *), their ratios to the
/// row's, and the root of AAF's error at the row's samples over the root of the row's. A
/// Markdown table.
pub(super) fn sheared_against_aaf(
    t: &ResultTable,
    at: (&str, &str),
    aaf: &str,
    x_column: &str,
    what: &str,
    metric: &Metric,
) -> String {
    let aaf_spp = curve_of(t, at, aaf, x_column, metric.column);
    let aaf_time = curve_of(t, at, aaf, "seconds", metric.column);
    let (name, root) = (metric.name, metric.root);
    let mut md = format!(
        "| method | l | {what} spp | {root} | seconds | {aaf} {what} spp at equal {name} | \
         sample ratio | {aaf} seconds at equal {name} | time ratio | {aaf} {root} at equal \
         {what} spp / {root} |\n|---|---|---|---|---|---|---|---|---|---|\n"
    );
    let star = |ex: bool| if ex { "*" } else { "" };
    for r in t
        .records()
        .iter()
        .filter(|r| r["scene"] == at.0 && r["size"] == at.1 && r["method"].starts_with("sheared"))
    {
        let (Ok(spp), Ok(err), Ok(secs)) = (
            r[x_column].parse::<f64>(),
            r[metric.column].parse::<f64>(),
            r["seconds"].parse::<f64>(),
        ) else {
            continue;
        };
        let equal = loglog_where(&aaf_spp, err)
            .map_or((String::new(), String::new()), |(x, ex)| {
                (format!("{x:.1}{}", star(ex)), format!("{:.2}", x / spp))
            });
        let time = loglog_where(&aaf_time, err)
            .map_or((String::new(), String::new()), |(x, ex)| {
                (format!("{x:.3}{}", star(ex)), format!("{:.2}", x / secs))
            });
        let ratio = loglog_at(&aaf_spp, spp, -1.0).map_or(String::new(), |(m, ex)| {
            format!("{:.2}{}", (m / err).sqrt(), star(ex))
        });
        md.push_str(&format!(
            "| {} | {} | {spp:.1} | {} | {} | {} | {} | {} | {} | {ratio} |\n",
            r["method"],
            r["setting"],
            num(err.sqrt()),
            r["seconds"],
            equal.0,
            equal.1,
            time.0,
            time.1
        ));
    }
    md
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
