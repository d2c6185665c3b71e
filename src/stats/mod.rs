//! Per-pixel statistics (thesis §6.1-6.2.2) on the host: the one set of buffers every filter
//! reads, whether it comes straight from the renderer or from an AOV file.

pub mod aovs;

use crate::layout::{FilterVector, GBuffer};

/// The per-pixel buffers shared by all filters: the FilterVector means (eq. 6.1) and, when they
/// were gathered, the feature variances (eq. 6.2, S_n / (n - 1)).
#[derive(Clone, Debug, PartialEq)]
pub struct PixelBuffers {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel behind the means.
    pub spp: u32,
    pub filter_vectors: Vec<FilterVector>,
    /// Feature variances in GBuffer layout.
    pub variances: Option<Vec<GBuffer>>,
    /// Mean first-bounce directions (for the direction-difference variant of the filter).
    pub directions: Option<Vec<[f32; 3]>>,
    /// The scene's size (largest extent of its bounds) in its own units, which gives depth a
    /// unit the filters' sigmas can be stated in; 0 when unknown.
    pub scene_size: f32,
}

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

impl PixelBuffers {
    /// direct + indirect: the unfiltered image.
    pub fn beauty(&self) -> crate::imaging::RgbImage {
        crate::imaging::RgbImage::beauty(self.width, self.height, &self.filter_vectors)
    }
}

/// Variances S_n / (n - 1) from Welford's sums (eq. 6.6 and the text after it). With one
/// sample there is no variance estimate; it is reported as 0.
pub fn variances_from_sums(sums: &[GBuffer], n: u32) -> Vec<GBuffer> {
    let scale = if n > 1 { 1.0 / (n - 1) as f32 } else { 0.0 };
    sums.iter()
        .map(|g| GBuffer {
            depth: g.depth * scale,
            normal: g.normal.map(|v| v * scale),
            albedo: g.albedo.map(|v| v * scale),
            direction: g.direction.map(|v| v * scale),
            albedo2: g.albedo2.map(|v| v * scale),
            pad: [0.0; 3],
        })
        .collect()
}

/// Sum of a feature's variance components (the inner sum of eq. 6.10), per feature in GB order:
/// depth, normal, texture, direction, texture2.
pub fn feature_variance_sums(g: &GBuffer) -> [f32; 5] {
    let s = |v: [f32; 3]| v[0] + v[1] + v[2];
    [
        g.depth,
        s(g.normal),
        s(g.albedo),
        s(g.direction),
        s(g.albedo2),
    ]
}
