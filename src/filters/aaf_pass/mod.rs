//! The 1-D pass of axis-aligned filtering (Wang 2013 eq. 3.7, per-pass lines: β of the pixel
//! being written), shared by the soft-shadow filter (src/filters/aaf_shadows) and the
//! diffuse-indirect filter (src/filters/aaf_indirect): ch. 4's filter "does not change from
//! section 3.3". kernels/filters/aaf_pass.cl is the device code; [`pass`] is its plain Rust
//! reference, the same float operations in the same order.
//!
//! Each filter's prepare step writes, per pixel, a [`PassPixel`] (the guide) and a value
//! (four lanes: the shadow filter's visibility in lane 0, the indirect filter's irradiance in
//! rgb). A pass is the normalised Gaussian mean Σ w v / Σ w over the pixels within `radius`
//! along one image axis, w = exp(−r² / (2β²)) with β of the pixel written (eqs. 3.3, 4.3: the
//! prefactors cancel in a normalised mean). r is the world distance in the plane perpendicular
//! to the pixel's `axis` (shadows: the direction to the light; indirect light: the normal, as
//! the authors' released code projects onto the tangent plane). A neighbour is rejected when it
//! is [`NONE`], when its `group` differs (the indirect filter's lobes, diffuse and glossy: the
//! seed's separate buffers; the shadow filter's pixels are all group 0), when its normal is more than `normal_cos` away, when its offset along `axis`
//! exceeds `depth_tolerance` · β (the weight ignores that offset), and, when it is
//! [`FILTERED`] too, when |β − β′| > `beta_tolerance` · max(β, β′).

mod device;

use glam::Vec3;
use rayon::prelude::*;

pub use device::DevicePasses;

/// Nothing to filter (kernels/filters/aaf_pass.cl `AAF_NONE`): keeps its value, lends none.
pub const NONE: f32 = 0.0;
/// Its value stands and is lent to its neighbours (`AAF_LIT`).
pub const LIT: f32 = 1.0;
/// Filtered with its β (`AAF_FILTERED`).
pub const FILTERED: f32 = 2.0;

/// What the pass knows of one pixel (three float4 on the device: (position, kind),
/// (normal, β), (axis, group)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassPixel {
    pub position: Vec3,
    pub kind: f32,
    pub normal: Vec3,
    pub beta: f32,
    /// Unit direction whose component of an offset is dropped from the distance.
    pub axis: Vec3,
    /// Pixels share values only within one group.
    pub group: f32,
}

impl PassPixel {
    /// The device's three float4.
    pub fn lanes(&self) -> [[f32; 4]; 3] {
        [
            self.position.extend(self.kind).to_array(),
            self.normal.extend(self.beta).to_array(),
            self.axis.extend(self.group).to_array(),
        ]
    }
}

/// The pass's scalar arguments (the same for both filters' passes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassParams {
    pub width: u32,
    pub height: u32,
    /// Half width of the window, pixels.
    pub radius: i32,
    /// 0: along rows (x), 1: along columns (y).
    pub axis: u32,
    /// cos of the largest angle between normals (−2: no test).
    pub normal_cos: f32,
    /// Largest offset along the written pixel's axis, in units of its β (inf: no test).
    pub depth_tolerance: f32,
    /// Largest |β − β′| / max(β, β′) between filtered pixels (inf: no test).
    pub beta_tolerance: f32,
}

impl PassParams {
    /// The same parameters for the pass along `axis`.
    pub fn along(&self, axis: u32) -> PassParams {
        PassParams { axis, ..*self }
    }
}

/// `aaf_pass`: one 1-D pass along `p.axis` over `input`.
pub fn pass(p: &PassParams, guide: &[PassPixel], input: &[[f32; 4]]) -> Vec<[f32; 4]> {
    let (w, h) = (p.width as i32, p.height as i32);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let g = &guide[i as usize];
            if g.kind != FILTERED {
                return input[i as usize];
            }
            let b = g.beta;
            let inv_two_beta2 = (1.0 / (2.0 * b * b)).min(f32::MAX);
            let (c, n, stride) = if p.axis == 0 { (x, w, 1) } else { (y, h, w) };
            let mut sum = input[i as usize];
            let mut sum_w = 1.0f32;
            for k in (c - p.radius).max(0)..=(c + p.radius).min(n - 1) {
                if k == c {
                    continue;
                }
                let j = (i + (k - c) * stride) as usize;
                let q = &guide[j];
                if q.kind == NONE || q.group != g.group || g.normal.dot(q.normal) < p.normal_cos {
                    continue;
                }
                let delta = q.position - g.position;
                let along = delta.dot(g.axis);
                if along.abs() > p.depth_tolerance * b {
                    continue;
                }
                if q.kind == FILTERED && (b - q.beta).abs() > p.beta_tolerance * b.max(q.beta) {
                    continue;
                }
                let r2 = (delta.dot(delta) - along * along).max(0.0);
                let wgt = (-r2 * inv_two_beta2).exp();
                for (s, v) in sum.iter_mut().zip(input[j]) {
                    *s += wgt * v;
                }
                sum_w += wgt;
            }
            sum.map(|s| s / sum_w)
        })
        .collect()
}

/// Both passes: rows, then the columns of the rows' result.
pub fn both(p: &PassParams, guide: &[PassPixel], input: &[[f32; 4]]) -> Vec<[f32; 4]> {
    let rows = pass(&p.along(0), guide, input);
    pass(&p.along(1), guide, &rows)
}
