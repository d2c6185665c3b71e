//! kernels/render/light_field.cl in Rust: the light-field pass of sheared soft shadows (Yan et
//! al. 2015 §3.1; src/render/shadows/light_field.rs), with the same float operations in the
//! same order, and the shadow passes in the order the renderer runs them with it, per light
//! plane.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::rng::{DIM_LIGHT_U, DIM_LIGHT_V, rng_sample_key, rng_uniform};
use super::shadows::{SHADOW_SAMPLE_BASE, adaptive, fill, receiver, sparse};
use crate::arrays::SceneArrays;
use crate::arrays::trace::occluder_range;
use crate::geometry::{offset_ray_origin, ray_sphere};
use crate::layout::{LightFieldPixel, SceneParams, ShadowPixel};
use crate::render::cpu::pathtrace::SHADOW_RAY_SHORTEN;
use crate::render::shadows::ShadowSampling;
use crate::render::shadows::bandlimit::isqrt_floor;

/// `light_field_project`.
fn project(p: &SceneParams, q: Vec3) -> Option<Vec2> {
    let v = q - p.camera_origin.xyz();
    let z = v.dot(p.camera_forward.xyz());
    if !(z > 0.0) {
        return None;
    }
    let (w, h) = (p.image_width as f32, p.image_height as f32);
    let sx = v.dot(p.camera_right.xyz()) / z / (p.tan_half_fov * (w / h));
    let sy = v.dot(p.camera_up.xyz()) / z / p.tan_half_fov;
    Some(Vec2::new((sx + 1.0) * 0.5 * w, (1.0 - sy) * 0.5 * h))
}

/// `light_field_axis`: (unit screen direction, world units per pixel along it).
fn axis(p: &SceneParams, pos: Vec3, t: Vec3, dx: f32, footprint: f32) -> (Vec2, f32) {
    let none = (Vec2::X, 0.0);
    let (Some(a), Some(b)) = (project(p, pos), project(p, pos + footprint * t)) else {
        return none;
    };
    let v = b - a;
    let len = v.length();
    if !(len > 1.0e-4) || !(dx > 1.0e-6) {
        return none;
    }
    (v / len, footprint * dx / len)
}

/// `light_field_sample` over every pixel: the light fields, with the slopes merged into
/// `pixels`; returns them and the rays traced.
pub fn light_field(
    s: &SceneArrays,
    pixels: &mut [ShadowPixel],
    light: u32,
    side: u32,
    frame: [Vec3; 2],
) -> (Vec<LightFieldPixel>, u64) {
    let w = s.params.image_width;
    let out: Vec<(LightFieldPixel, u32)> = pixels
        .par_iter_mut()
        .enumerate()
        .map(|(pixel, px)| {
            let mut lf = LightFieldPixel::default();
            let mut rays = 0u32;
            if !(px.weight > 0.0) || light >= s.params.light_count {
                return (lf, rays);
            }
            let (x, y) = (pixel as u32 % w, pixel as u32 / w);
            let Some(r) = receiver(s, x, y, 0.5, 0.5, &mut rays) else {
                return (lf, rays);
            };
            let l = &s.lights[light as usize];
            let (c, radius) = (l.p0.xyz(), l.p0.0[3]);
            let [e1, e2] = frame;
            let o = offset_ray_origin(r.sf.p, r.sf.ng, s.params.scene_size);
            let dc = (c - o).length();
            let key = rng_sample_key(s.params.seed, pixel as u32, SHADOW_SAMPLE_BASE + 2);
            let (j1, j2) = (
                rng_uniform(key, 0, DIM_LIGHT_U),
                rng_uniform(key, 0, DIM_LIGHT_V),
            );
            let inv = 1.0 / side as f32;
            let (mut occluded, mut s1, mut s2) = (0f32, 0f32, f32::INFINITY);
            for b in 0..side {
                for a in 0..side {
                    let y1 = radius * (2.0 * (a as f32 + j1) * inv - 1.0);
                    let y2 = radius * (2.0 * (b as f32 + j2) * inv - 1.0);
                    let to = c + y1 * e1 + y2 * e2 - o;
                    let mut dist = to.length();
                    let mut f = 0.0;
                    if dist > 0.0 && dc > radius {
                        let dir = to / dist;
                        if let Some(t) = ray_sphere(o, dir, c, radius, 0.0, f32::INFINITY)
                            && t > 0.0
                        {
                            dist = dist.min(t);
                        }
                        if r.sf.ng.dot(dir) <= 0.0 {
                            f = 0.0;
                        } else {
                            rays += 1;
                            match occluder_range(s, o, dir, dist * SHADOW_RAY_SHORTEN) {
                                Some((t_near, t_far)) => {
                                    occluded += 1.0;
                                    s2 = s2.min(dc / (dc - t_near) - 1.0);
                                    s1 = s1.max(dc / (dc - t_far) - 1.0);
                                }
                                None => f = 1.0,
                            }
                        }
                    }
                    lf.samples[(b * side + a) as usize] = f;
                }
            }
            if occluded > 0.0 {
                let own = px.slope_source == 1.0;
                px.slope_max = if own { px.slope_max.max(s1) } else { s1 };
                px.slope_min = if own { px.slope_min.min(s2) } else { s2 };
                px.slope_source = 1.0;
                px.occluded += occluded;
            }
            lf.jitter = [j1, j2];
            let footprint = px.pixel_size;
            let ng = r.sf.ng;
            let (mut t1, mut t2) = (ng.cross(e2), ng.cross(e1));
            let (n1, n2) = (t1.length(), t2.length());
            let (mut d1, mut d2) = (Vec2::X, Vec2::Y);
            let (mut k1, mut k2) = (0.0, 0.0);
            if n1 > 1.0e-6 {
                t1 /= n1;
                if t1.dot(e1) < 0.0 {
                    t1 = -t1;
                }
                (d1, k1) = axis(&s.params, r.sf.p, t1, t1.dot(e1), footprint);
            }
            if n2 > 1.0e-6 {
                t2 /= n2;
                if t2.dot(e2) < 0.0 {
                    t2 = -t2;
                }
                (d2, k2) = axis(&s.params, r.sf.p, t2, t2.dot(e2), footprint);
            }
            lf.dir1 = d1.to_array();
            lf.dir2 = d2.to_array();
            lf.scale = [k1, k2];
            lf.count = (side * side) as f32;
            (lf, rays)
        })
        .collect();
    let rays = out.iter().map(|(_, r)| *r as u64).sum();
    (out.into_iter().map(|(p, _)| p).collect(), rays)
}

/// The shadow passes with the light-field pass, in the renderer's order (sparse, light field,
/// slope fill, adaptive), for each plane of `sampling.lights` with its light's frame
/// (`frames`, in plane order): per plane the shadow pixels and the light fields, and the rays
/// of them all.
#[allow(clippy::type_complexity)]
pub fn passes(
    s: &SceneArrays,
    sampling: &ShadowSampling,
    frames: &[[Vec3; 2]],
) -> (Vec<(Vec<ShadowPixel>, Vec<LightFieldPixel>)>, u64) {
    let mut rays = 0;
    let planes = sampling
        .lights
        .lights()
        .into_iter()
        .zip(frames)
        .map(|(light, &frame)| {
            let (mut pixels, sparse_rays) = sparse(s, light, isqrt_floor(sampling.sparse_spp));
            let (fields, more) = light_field(s, &mut pixels, light, sampling.light_field, frame);
            fill(
                &mut pixels,
                s.params.image_width,
                s.params.image_height,
                sampling.fill_radius,
            );
            rays += sparse_rays
                + more
                + adaptive(s, &mut pixels, light, sampling.sparse_spp, sampling.max_spp);
            (pixels, fields)
        })
        .collect();
    (planes, rays)
}
