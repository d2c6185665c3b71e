//! Partial renders merged against one-machine renders (tests/partial.rs, tests/merge_cli.rs):
//! every lane of every output buffer, and filtered images.

use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::BufferId;
use noisefree::layout::{SKY_DEPTH, WelfordState};
use noisefree::render::Frame;

/// Merged against one-machine renders: every lane of every output buffer agrees within this,
/// relative to the larger magnitude (absolute below 1e-3). Both sides round: the one-machine
/// render its float running means and Kahan-summed S_n over all samples, the merge the parts'
/// float running means, combined in double precision. Measured (PoCL): 1.5e-5 on the mean
/// first-bounce direction (a component near 0, so absolute: 1.5e-8), at most 5.0e-6 on every
/// other lane (F's normal, S_n of the direction), on cornell_plane_dof (DOF, textures), 40 x
/// 30, 24 spp, ranges 0..5, 5..11 in four tiles, 11..24; 1.05e-5 and 1.6e-6 on
/// cornell_diffuse 24 x 20 through the command line. Bound 3e-5 (2x).
pub const MERGE_BOUND: f64 = 3e-5;

/// The lanes of a buffer as values: S_n as s − c (its Kahan compensation taken out, film.cl),
/// the compensations themselves as 0 (they are compared inside S_n), everything else as stored.
pub fn values(f: &Frame, id: BufferId) -> Vec<f64> {
    let floats = f.host(id).unwrap().floats();
    let state: &[WelfordState] = match id {
        BufferId::WelfordSums | BufferId::WelfordState => {
            f.host_slice(BufferId::WelfordState).unwrap()
        }
        _ => return floats.iter().map(|&v| v as f64).collect(),
    };
    if id == BufferId::WelfordState {
        return state
            .iter()
            .flat_map(|c| {
                let mut v = [0f64; 20];
                for (i, d) in c.direction_mean.iter().enumerate() {
                    v[i] = *d as f64;
                }
                v
            })
            .collect();
    }
    floats
        .chunks(16)
        .zip(state)
        .flat_map(|(s, c)| (0..16).map(move |i| s[i] as f64 - c.s_compensation[i] as f64))
        .collect()
}

/// The largest difference of two buffers relative to the larger magnitude (absolute below
/// 1e-3), with where it is: (difference, element, lane).
pub fn worst(a: &[f64], b: &[f64], floats: usize) -> (f64, usize, usize) {
    assert_eq!(a.len(), b.len());
    let mut w = (0.0, 0, 0);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        let d = (x - y).abs() / x.abs().max(y.abs()).max(1e-3);
        if d > w.0 {
            w = (d, i / floats, i % floats);
        }
    }
    w
}

/// Every buffer of `one`'s outputs in `merged` within [`MERGE_BOUND`] (printing each one's
/// largest difference).
pub fn assert_outputs_within_bound(one: &Frame, merged: &Frame) {
    assert_eq!(merged.outputs(), one.outputs());
    for id in one.outputs().buffers().map(|b| b.id) {
        let floats = id.decl().element_bytes / 4;
        let (w, element, lane) = worst(&values(one, id), &values(merged, id), floats);
        eprintln!(
            "{}: merged within {w:.2e} of the one-machine render (pixel {element}, lane {lane})",
            id.decl().name
        );
        assert!(
            w <= MERGE_BOUND,
            "{}: pixel {element} lane {lane} differs by {w:e}",
            id.decl().name
        );
    }
}

/// The largest difference of two filtered images of `one` relative to the larger magnitude
/// (absolute below 1e-3), leaving out the pixels whose samples hit both surfaces and the sky:
/// the data-driven filter is not continuous there (F.depth is a mean of SKY_DEPTH, 1e9, and
/// surface depths, ~1e8, whose float rounding flips its depth weight: measured 0.47 there, tests/partial.rs). Also
/// how many pixels it compared, at least 85% of them.
pub fn filtered_difference(one: &Frame, a: &RgbImage, b: &RgbImage) -> (f32, usize) {
    let f = one.filter_vectors().unwrap();
    let mut d = 0f32;
    let mut compared = 0;
    for (p, (x, y)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if f[p].depth > 1e6 && f[p].depth != SKY_DEPTH {
            continue;
        }
        compared += 1;
        for c in 0..3 {
            d = d.max((x[c] - y[c]).abs() / x[c].abs().max(y[c].abs()).max(1e-3));
        }
    }
    assert!(compared * 100 >= a.pixels.len() * 85, "{compared} pixels");
    (d, compared)
}
