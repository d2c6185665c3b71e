//! kernels/render/lens_field.cl in Rust: the lens-field pass of sheared depth of field (Yan et
//! al. 2015 §3.1, §3.2 "DoF"; src/render/lens_field.rs), with the same float operations in the
//! same order. The first hit's depth comes from one more closest-hit query on the sample's
//! camera ray (the kernel reads it from the path's first vertex: the same hit).

use glam::Vec3;
use rayon::prelude::*;

use super::pathtrace::{ReferenceOptions, ShadowTarget, surface_at, trace_path_from};
use super::rng::{DIM_LENS_U, DIM_LENS_V, DIM_PIXEL_X, DIM_PIXEL_Y, rng_sample_key, rng_uniform};
use super::sampling::pinhole_direction;
use crate::arrays::SceneArrays;
use crate::arrays::trace::intersect_closest;
use crate::layout::LightFieldPixel;

/// kernels/render/lens_field.cl `LENS_SAMPLE_BASE`.
pub const LENS_SAMPLE_BASE: u32 = 0xFFFF_FE00;
const LENS_JITTER_SAMPLE: u32 = LENS_SAMPLE_BASE + 0xF0;
const EXTRA_SIDE: u32 = 6;

/// `lens_sample`: (radiance, slope) of lens point (u1, u2) (right, down) for pixel (x, y).
#[allow(clippy::too_many_arguments)]
fn lens_sample(
    s: &SceneArrays,
    opt: ReferenceOptions,
    x: u32,
    y: u32,
    key: u32,
    u: [f32; 2],
    slope_k: f32,
    rays: &mut u32,
) -> (Vec3, f32) {
    let p = &s.params;
    let (jx, jy) = (
        rng_uniform(key, 0, DIM_PIXEL_X),
        rng_uniform(key, 0, DIM_PIXEL_Y),
    );
    let forward = p.camera_forward.xyz();
    let dir = pinhole_direction(p, x, y, jx, jy);
    let cam = p.camera_origin.xyz();
    let focus = cam + dir * (p.focal_distance / dir.dot(forward));
    let o = cam + u[0] * p.camera_right.xyz() - u[1] * p.camera_up.xyz();
    let d = (focus - o).normalize();
    let ps = trace_path_from(s, opt, o, d, key, rays, ShadowTarget::NONE);
    let z = match intersect_closest(s, o, d, f32::INFINITY) {
        Some(hit) => (surface_at(s, &hit, o, d).p - cam).dot(forward),
        None => f32::INFINITY,
    };
    (
        ps.direct + ps.indirect,
        slope_k * (1.0 / z - 1.0 / p.focal_distance),
    )
}

/// `lens_weight`.
fn lens_weight(u1: f32, u2: f32, radius: f32) -> f32 {
    if !(radius > 0.0) {
        return 1.0;
    }
    let sigma = 0.5 * radius;
    (-(u1 * u1 + u2 * u2) / (2.0 * sigma * sigma)).exp()
}

/// `lens_field_sample` over every pixel: the lens fields and the rays traced (the depth
/// queries not counted, as in the kernel).
pub fn lens_field(
    s: &SceneArrays,
    opt: ReferenceOptions,
    side: u32,
) -> (Vec<LightFieldPixel>, u64) {
    let p = &s.params;
    let (w, h) = (p.image_width, p.image_height);
    let out: Vec<(LightFieldPixel, u32)> = (0..w * h)
        .into_par_iter()
        .map(|pixel| {
            let (x, y) = (pixel % w, pixel / w);
            let mut lf = LightFieldPixel::default();
            let mut rays = 0u32;
            let radius = p.lens_radius;
            let slope_k = h as f32 / (2.0 * p.tan_half_fov);
            let co = p.camera_origin.xyz();
            let cd = pinhole_direction(p, x, y, 0.5, 0.5);
            rays += 1;
            if let Some(hit) = intersect_closest(s, co, cd, f32::INFINITY) {
                let sf = surface_at(s, &hit, co, cd);
                lf.position = sf.p.to_array();
                lf.normal = sf.ns.to_array();
            }
            let jkey = rng_sample_key(p.seed, pixel, LENS_JITTER_SAMPLE);
            let j = [
                rng_uniform(jkey, 0, DIM_LENS_U),
                rng_uniform(jkey, 0, DIM_LENS_V),
            ];
            let inv = 1.0 / side as f32;
            let (mut s_min, mut s_max) = (f32::INFINITY, f32::NEG_INFINITY);
            for b in 0..side {
                for a in 0..side {
                    let k = b * side + a;
                    let u1 = radius * (2.0 * (a as f32 + j[0]) * inv - 1.0);
                    let u2 = radius * (2.0 * (b as f32 + j[1]) * inv - 1.0);
                    let key = rng_sample_key(p.seed, pixel, LENS_SAMPLE_BASE + k);
                    let (l, sl) = lens_sample(s, opt, x, y, key, [u1, u2], slope_k, &mut rays);
                    s_min = s_min.min(sl);
                    s_max = s_max.max(sl);
                    (
                        lf.samples[k as usize],
                        lf.green[k as usize],
                        lf.blue[k as usize],
                    ) = (l.x, l.y, l.z);
                }
            }
            lf.slopes = [s_min, s_max];
            if s_min * s_max < 0.0 {
                let (mut sum, mut wsum) = (Vec3::ZERO, 0f32);
                let inv6 = 1.0 / EXTRA_SIDE as f32;
                for k in 0..EXTRA_SIDE * EXTRA_SIDE {
                    let key = rng_sample_key(p.seed, pixel, LENS_SAMPLE_BASE + 16 + k);
                    let (a, b) = ((k % EXTRA_SIDE) as f32, (k / EXTRA_SIDE) as f32);
                    let u1 = radius * (2.0 * (a + rng_uniform(key, 0, DIM_LENS_U)) * inv6 - 1.0);
                    let u2 = radius * (2.0 * (b + rng_uniform(key, 0, DIM_LENS_V)) * inv6 - 1.0);
                    let (l, _) = lens_sample(s, opt, x, y, key, [u1, u2], slope_k, &mut rays);
                    let wt = lens_weight(u1, u2, radius);
                    sum += wt * l;
                    wsum += wt;
                }
                lf.extra_samples = (EXTRA_SIDE * EXTRA_SIDE) as f32;
                lf.extra = [sum.x, sum.y, sum.z, wsum];
            }
            lf.jitter = j;
            lf.dir1 = [1.0, 0.0];
            lf.dir2 = [0.0, 1.0];
            lf.scale = [1.0, 1.0];
            lf.count = (side * side) as f32;
            (lf, rays)
        })
        .collect();
    let rays = out.iter().map(|(_, r)| *r as u64).sum();
    (out.into_iter().map(|(lf, _)| lf).collect(), rays)
}
