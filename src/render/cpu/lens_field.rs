//! kernels/render/lens_field.cl in Rust: the lens-field pass of sheared depth of field (Yan et
//! al. 2015 §3.1, §3.2 "DoF"; src/render/lens_field.rs), with the same float operations in the
//! same order. The first hit's depth comes from one more closest-hit query on the sample's
//! camera ray (the kernel reads it from the path's first vertex: the same hit).
//! [`lens_shadow_field`] is `lens_shadow_field_sample` (soft shadows with depth of field) for
//! one filtered light.

use glam::Vec3;
use rayon::prelude::*;

use super::pathtrace::{PathSample, ReferenceOptions, ShadowTarget, surface_at, trace_path_from};
use super::rng::{DIM_LENS_U, DIM_LENS_V, DIM_PIXEL_X, DIM_PIXEL_Y, rng_sample_key, rng_uniform};
use super::sampling::pinhole_direction;
use super::shadows::shadow_unshadowed;
use crate::arrays::SceneArrays;
use crate::arrays::trace::intersect_closest;
use crate::layout::{LensShadowPixel, LightFieldPixel};

/// kernels/render/lens_field.cl `LENS_SAMPLE_BASE`.
pub const LENS_SAMPLE_BASE: u32 = 0xFFFF_FE00;
const LENS_JITTER_SAMPLE: u32 = LENS_SAMPLE_BASE + 0xF0;
const EXTRA_SIDE: u32 = 6;

/// `lens_sample`: the path of lens point (u1, u2) (right, down) for pixel (x, y), its slope
/// and its first hit's point (None: the sky).
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
    target: ShadowTarget,
) -> (PathSample, f32, Option<Vec3>) {
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
    let ps = trace_path_from(s, opt, o, d, key, rays, target);
    let hit = intersect_closest(s, o, d, f32::INFINITY).map(|hit| surface_at(s, &hit, o, d).p);
    let z = match hit {
        Some(q) => (q - cam).dot(forward),
        None => f32::INFINITY,
    };
    (ps, slope_k * (1.0 / z - 1.0 / p.focal_distance), hit)
}

/// `lens_radiance`: all the sample's light but the filtered light's direct term.
fn lens_radiance(ps: &PathSample) -> Vec3 {
    ps.direct + ps.indirect - ps.shadow_direct
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
    let (field, _, rays) = fields(s, opt, side, |_| ShadowTarget::NONE);
    (field, rays)
}

/// `lens_shadow_field_sample` over every pixel for one filtered light (a shadow plane):
/// `target(pixel)` is that light and the object of the pixel centre's receiver (NaN where the
/// shadow output has none). The lens fields, the [`LensShadowPixel`]s (plane 0) and the rays.
pub fn lens_shadow_field(
    s: &SceneArrays,
    opt: ReferenceOptions,
    side: u32,
    target: impl Fn(u32) -> ShadowTarget + Sync,
) -> (Vec<LightFieldPixel>, Vec<LensShadowPixel>, u64) {
    fields(s, opt, side, target)
}

fn fields(
    s: &SceneArrays,
    opt: ReferenceOptions,
    side: u32,
    target: impl Fn(u32) -> ShadowTarget + Sync,
) -> (Vec<LightFieldPixel>, Vec<LensShadowPixel>, u64) {
    let p = &s.params;
    let (w, h) = (p.image_width, p.image_height);
    let out: Vec<(LightFieldPixel, LensShadowPixel, u32)> = (0..w * h)
        .into_par_iter()
        .map(|pixel| {
            let (x, y) = (pixel % w, pixel / w);
            let t = target(pixel);
            let light = (t.light < p.light_count).then(|| &s.lights[t.light as usize]);
            let mut lf = LightFieldPixel::default();
            let mut ls = LensShadowPixel::default();
            let (mut unshadowed, mut on) = (Vec3::ZERO, 0f32);
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
                    let (ps, sl, hit) =
                        lens_sample(s, opt, x, y, key, [u1, u2], slope_k, &mut rays, t);
                    let l = lens_radiance(&ps);
                    s_min = s_min.min(sl);
                    s_max = s_max.max(sl);
                    let k = k as usize;
                    (lf.samples[k], lf.green[k], lf.blue[k]) = (l.x, l.y, l.z);
                    if let (true, Some(light), Some(q)) = (ps.receiver, light, hit) {
                        (ls.albedo[k], ls.albedo_green[k], ls.albedo_blue[k]) =
                            (ps.albedo.x, ps.albedo.y, ps.albedo.z);
                        unshadowed += shadow_unshadowed(light, q, ps.normal);
                        on += 1.0;
                    }
                }
            }
            lf.slopes = [s_min, s_max];
            if s_min * s_max < 0.0 {
                let (mut sum, mut wsum, mut albedo) = (Vec3::ZERO, 0f32, Vec3::ZERO);
                let inv6 = 1.0 / EXTRA_SIDE as f32;
                for k in 0..EXTRA_SIDE * EXTRA_SIDE {
                    let key = rng_sample_key(p.seed, pixel, LENS_SAMPLE_BASE + 16 + k);
                    let (a, b) = ((k % EXTRA_SIDE) as f32, (k / EXTRA_SIDE) as f32);
                    let u1 = radius * (2.0 * (a + rng_uniform(key, 0, DIM_LENS_U)) * inv6 - 1.0);
                    let u2 = radius * (2.0 * (b + rng_uniform(key, 0, DIM_LENS_V)) * inv6 - 1.0);
                    let (ps, _, _) =
                        lens_sample(s, opt, x, y, key, [u1, u2], slope_k, &mut rays, t);
                    let wt = lens_weight(u1, u2, radius);
                    sum += wt * lens_radiance(&ps);
                    wsum += wt;
                    if ps.receiver {
                        albedo += wt * ps.albedo;
                    }
                }
                lf.extra_samples = (EXTRA_SIDE * EXTRA_SIDE) as f32;
                lf.extra = [sum.x, sum.y, sum.z, wsum];
                ls.albedo_extra = [albedo.x, albedo.y, albedo.z, 0.0];
            }
            let mean = if on > 0.0 {
                unshadowed / on
            } else {
                Vec3::ZERO
            };
            ls.unshadowed[0].0 = [mean.x, mean.y, mean.z, on];
            lf.jitter = j;
            lf.dir1 = [1.0, 0.0];
            lf.dir2 = [0.0, 1.0];
            lf.scale = [1.0, 1.0];
            lf.count = (side * side) as f32;
            (lf, ls, rays)
        })
        .collect();
    let rays = out.iter().map(|(_, _, r)| *r as u64).sum();
    let (field, shadow) = out.into_iter().map(|(lf, ls, _)| (lf, ls)).unzip();
    (field, shadow, rays)
}
