//! Per-pixel statistics on the host (thesis §6.1-6.2.2) and the files that carry a render's
//! outputs: the AOV EXR (every per-pixel output, [`aov`]) and the samples file (the per-sample
//! output, [`samples`]), each with a [`RenderRecord`] of how it was made; partial renders of
//! sample ranges and tiles ([`partial`]) and their exact merge ([`merge`]).

pub mod aov;
pub mod merge;
pub mod partial;
pub mod record;
pub mod samples;

use crate::layout::WelfordSums;
pub use record::RenderRecord;

/// The data-driven filter compares depths in hundredths of the scene's size, so that
/// sigma_depth means the same for a scene modelled in millimetres and one in kilometres (the
/// thesis's scenes measure a few hundred units, §4.3.1, Fig. 4.9). Unknown size: raw units.
pub fn depth_scale(scene_size: f32) -> f32 {
    if scene_size > 0.0 && scene_size.is_finite() {
        100.0 / scene_size
    } else {
        1.0
    }
}

/// Every lane of `g` times `factor` (the variances S_n / (n - 1) from Welford's sums, as the
/// kernels form them).
pub fn scaled(g: &WelfordSums, factor: f32) -> WelfordSums {
    WelfordSums {
        depth: g.depth * factor,
        normal: g.normal.map(|v| v * factor),
        albedo: g.albedo.map(|v| v * factor),
        direction: g.direction.map(|v| v * factor),
        albedo2: g.albedo2.map(|v| v * factor),
        pad: [0.0; 3],
    }
}

pub use crate::render::frame::variance_factor;

/// Variances S_n / (n - 1) from Welford's sums (eq. 6.6 and the text after it).
pub fn variances_from_sums(sums: &[WelfordSums], n: u32) -> Vec<WelfordSums> {
    let f = variance_factor(n);
    sums.iter().map(|g| scaled(g, f)).collect()
}

/// Sum of a feature's variance components (the inner sum of eq. 6.10), per feature in GB order:
/// depth, normal, texture, direction, texture2.
pub fn feature_variance_sums(g: &WelfordSums) -> [f32; 5] {
    let s = |v: [f32; 3]| v[0] + v[1] + v[2];
    [
        g.depth,
        s(g.normal),
        s(g.albedo),
        s(g.direction),
        s(g.albedo2),
    ]
}
