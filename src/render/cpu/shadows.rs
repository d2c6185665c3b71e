//! kernels/render/shadows.cl in Rust: AAF's shadow passes (sparse, slope fill, adaptive) for
//! one sphere light, with the same float operations in the same order (src/render/shadows
//! explains the estimator).

use glam::Vec3;
use rayon::prelude::*;

use super::pathtrace::{
    ReferenceOptions, SHADOW_RAY_SHORTEN, ShadowTarget, Surface, surface_albedo, surface_at,
    trace_path,
};
use super::rng::{DIM_LIGHT_U, DIM_LIGHT_V, DIM_PIXEL_X, DIM_PIXEL_Y, rng_sample_key, rng_uniform};
use super::sampling::{pinhole_direction, sample_cone};
use crate::arrays::SceneArrays;
use crate::arrays::trace::{Hit, Prim, intersect_closest, occluder_range};
use crate::geometry::{offset_ray_origin, ray_sphere};
use crate::layout::{Light, MATERIAL_DIFFUSE, MATERIAL_METAL, ShadowPixel};
use crate::render::shadows::ShadowSampling;
use crate::render::shadows::bandlimit::{adaptive_plan, isqrt_floor, sample_count};

/// kernels/render/shadows.cl `SHADOW_SAMPLE_BASE`.
pub const SHADOW_SAMPLE_BASE: u32 = 0xFFFF_FF00;

/// r(x) / albedo (kernels/render/shadows.cl `shadow_unshadowed`).
pub fn shadow_unshadowed(light: &Light, p: Vec3, ns: Vec3) -> Vec3 {
    let to_c = light.p0.xyz() - p;
    let d2 = to_c.dot(to_c);
    let r2 = light.p0.0[3] * light.p0.0[3];
    if d2 <= r2 {
        return Vec3::ZERO;
    }
    let cos_c = ns.dot(to_c) / d2.sqrt();
    light.emission.xyz() * (r2 / d2 * cos_c.max(0.0))
}

/// The object a hit belongs to (kernels/render/shadows.cl `hit_object`).
pub fn hit_object(s: &SceneArrays, hit: &Hit) -> f32 {
    match hit.prim {
        Prim::Triangle(k) => s.tri_shading[k as usize].object as f32,
        Prim::Sphere(i) => -1.0 - i as f32,
    }
}

/// A receiver (kernels/render/shadows.cl `ShadowReceiver`); `d` is the camera ray's direction.
pub struct Receiver {
    pub sf: Surface,
    pub albedo: Vec3,
    pub d: Vec3,
    pub t: f32,
    pub object: f32,
}

/// The first hit through the point (x + jx, y + jy) of the image from the lens centre, when
/// it is a receiver: a diffuse surface.
pub fn receiver(
    s: &SceneArrays,
    x: u32,
    y: u32,
    jx: f32,
    jy: f32,
    rays: &mut u32,
) -> Option<Receiver> {
    aaf_receiver(s, x, y, jx, jy, false, rays)
}

/// [`receiver`], with `glossy` a metal surface too (kernels/render/shadows.cl `aaf_receiver`).
pub fn aaf_receiver(
    s: &SceneArrays,
    x: u32,
    y: u32,
    jx: f32,
    jy: f32,
    glossy: bool,
    rays: &mut u32,
) -> Option<Receiver> {
    let o = s.params.camera_origin.xyz();
    let d = pinhole_direction(&s.params, x, y, jx, jy);
    *rays += 1;
    let hit = intersect_closest(s, o, d, f32::INFINITY)?;
    let sf = surface_at(s, &hit, o, d);
    let kind = s.materials[sf.material as usize].kind;
    if kind != MATERIAL_DIFFUSE && !(glossy && kind == MATERIAL_METAL) {
        return None;
    }
    Some(Receiver {
        albedo: surface_albedo(s, &sf),
        sf,
        d,
        t: hit.t,
        object: hit_object(s, &hit),
    })
}

/// d1 of a receiver (kernels/render/shadows.cl `shadow_light_distance`).
fn light_distance(s: &SceneArrays, light: &Light, sf: &Surface) -> f32 {
    let p = offset_ray_origin(sf.p, sf.ng, s.params.scene_size);
    let to_c = light.p0.xyz() - p;
    let d2 = to_c.dot(to_c);
    if d2 <= light.p0.0[3] * light.p0.0[3] {
        0.0
    } else {
        d2.sqrt()
    }
}

/// The binary visibility of the light's centre and the occluder distance d(x)
/// (kernels/render/shadows.cl `shadow_centre_visible`, the stylized-shadows matte).
pub fn centre_visible(s: &SceneArrays, light: &Light, sf: &Surface, rays: &mut u32) -> (f32, f32) {
    let p = offset_ray_origin(sf.p, sf.ng, s.params.scene_size);
    let to_c = light.p0.xyz() - p;
    let d2 = to_c.dot(to_c);
    let radius = light.p0.0[3];
    if d2 <= radius * radius {
        return (1.0, 0.0);
    }
    let dc = d2.sqrt();
    let dir = to_c / dc;
    if sf.ng.dot(dir) <= 0.0 {
        return (0.0, 0.0);
    }
    *rays += 1;
    match occluder_range(s, p, dir, (dc - radius) * SHADOW_RAY_SHORTEN) {
        Some((near, _)) => (0.0, near),
        None => (1.0, 0.0),
    }
}

/// Running sums of one pixel's light samples.
#[derive(Clone, Copy, Debug)]
struct Sums {
    visible: f32,
    weight: f32,
    occluded: f32,
    s1: f32,
    s2: f32,
    unshadowed: Vec3,
}

/// One light sample (kernels/render/shadows.cl `shadow_sample`).
fn sample(
    s: &SceneArrays,
    light: &Light,
    r: &Receiver,
    u: f32,
    v: f32,
    acc: &mut Sums,
    rays: &mut u32,
) {
    let sf = &r.sf;
    let p = offset_ray_origin(sf.p, sf.ng, s.params.scene_size);
    acc.unshadowed += r.albedo * shadow_unshadowed(light, p, sf.ns);
    let c = light.p0.xyz();
    let radius = light.p0.0[3];
    let to_c = c - p;
    let d2 = to_c.dot(to_c);
    let r2 = radius * radius;
    if d2 <= r2 {
        return;
    }
    let dc = d2.sqrt();
    let sin2_max = r2 / d2;
    let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
    let one_minus_cos_max = sin2_max / (1.0 + cos_max);
    let dir = sample_cone(u, v, to_c / dc, one_minus_cos_max);
    let cos_s = sf.ns.dot(dir);
    if cos_s <= 0.0 || sf.ng.dot(dir) <= 0.0 {
        return;
    }
    let dist = ray_sphere(p, dir, c, radius, 0.0, f32::INFINITY)
        .filter(|&t| t > 0.0)
        .unwrap_or(dc);
    acc.weight += cos_s;
    *rays += 1;
    match occluder_range(s, p, dir, dist * SHADOW_RAY_SHORTEN) {
        Some((near, far)) => {
            acc.occluded += 1.0;
            acc.s2 = acc.s2.min(dc / (dc - near) - 1.0);
            acc.s1 = acc.s1.max(dc / (dc - far) - 1.0);
        }
        None => acc.visible += cos_s,
    }
}

/// k × k light samples of pixel (x, y) on the receiver `object`
/// (kernels/render/shadows.cl `shadow_samples`).
#[allow(clippy::too_many_arguments)]
fn samples(
    s: &SceneArrays,
    light: &Light,
    x: u32,
    y: u32,
    object: f32,
    key: u32,
    k: u32,
    acc: &mut Sums,
    rays: &mut u32,
) {
    let inv_k = 1.0 / k as f32;
    for i in 0..k {
        for j in 0..k {
            let n = i * k + j;
            let (jx, jy) = (
                rng_uniform(key, n, DIM_PIXEL_X),
                rng_uniform(key, n, DIM_PIXEL_Y),
            );
            let Some(q) = receiver(s, x, y, jx, jy, rays) else {
                continue;
            };
            if q.object != object {
                continue;
            }
            let u = (i as f32 + rng_uniform(key, n, DIM_LIGHT_U)) * inv_k;
            let v = (j as f32 + rng_uniform(key, n, DIM_LIGHT_V)) * inv_k;
            sample(s, light, &q, u, v, acc, rays);
        }
    }
}

/// Pass 1 for every pixel: the shadow pixels and the rays traced.
pub fn sparse(s: &SceneArrays, light: u32, sqrt_spp: u32) -> (Vec<ShadowPixel>, u64) {
    let w = s.params.image_width;
    let n = w as usize * s.params.image_height as usize;
    let out: Vec<(ShadowPixel, u32)> = (0..n)
        .into_par_iter()
        .map(|pixel| {
            let (x, y) = (pixel as u32 % w, pixel as u32 / w);
            let mut px = ShadowPixel::default();
            let mut rays = 0u32;
            if light >= s.params.light_count {
                return (px, rays);
            }
            let Some(centre) = receiver(s, x, y, 0.5, 0.5, &mut rays) else {
                return (px, rays);
            };
            let (sf, t, object) = (&centre.sf, centre.t, centre.object);
            let mut acc = Sums {
                visible: 0.0,
                weight: 0.0,
                occluded: 0.0,
                s1: 0.0,
                s2: f32::INFINITY,
                unshadowed: Vec3::ZERO,
            };
            let key = rng_sample_key(s.params.seed, pixel as u32, SHADOW_SAMPLE_BASE);
            let l = &s.lights[light as usize];
            samples(s, l, x, y, object, key, sqrt_spp, &mut acc, &mut rays);
            let d1 = light_distance(s, l, sf);
            let slopes = acc.occluded > 0.0;
            px.visible = acc.visible;
            px.weight = acc.weight;
            px.samples = if acc.weight > 0.0 {
                (sqrt_spp * sqrt_spp) as f32
            } else {
                0.0
            };
            px.occluded = acc.occluded;
            px.light_distance = d1;
            px.slope_max = if slopes { acc.s1 } else { 0.0 };
            px.slope_min = if slopes { acc.s2 } else { 0.0 };
            px.slope_source = if slopes { 1.0 } else { 0.0 };
            px.pixel_size = t * 2.0 * s.params.tan_half_fov / s.params.image_height as f32;
            px.target = px.samples;
            px.object = object;
            (px.centre_visible, px.occluder_distance) = centre_visible(s, l, sf, &mut rays);
            px.position = sf.p.to_array();
            px.normal = sf.ns.to_array();
            px.unshadowed = acc.unshadowed.to_array();
            (px, rays)
        })
        .collect();
    let rays = out.iter().map(|(_, r)| *r as u64).sum();
    (out.into_iter().map(|(p, _)| p).collect(), rays)
}

fn has_own_slopes(q: &ShadowPixel) -> bool {
    q.weight > 0.0 && q.occluded > 0.0
}

/// The slope fill's two passes (kernels/render/shadows.cl `shadow_fill`), in place.
pub fn fill(pixels: &mut [ShadowPixel], width: u32, height: u32, radius: u32) {
    let (w, h, r) = (width as i64, height as i64, radius as i64);
    let rows: Vec<[f32; 3]> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let object = pixels[i as usize].object;
            let mut acc = [0.0f32, f32::INFINITY, 0.0];
            for nx in (x - r).max(0)..=(x + r).min(w - 1) {
                let q = &pixels[(y * w + nx) as usize];
                if has_own_slopes(q) && q.object == object {
                    acc = [acc[0].max(q.slope_max), acc[1].min(q.slope_min), 1.0];
                }
            }
            acc
        })
        .collect();
    let filled: Vec<Option<[f32; 2]>> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let px = &pixels[i as usize];
            if !(px.weight > 0.0) || px.slope_source != 0.0 {
                return None;
            }
            let mut acc = [0.0f32, f32::INFINITY, 0.0];
            for ny in (y - r).max(0)..=(y + r).min(h - 1) {
                let q = (ny * w + x) as usize;
                let f = rows[q];
                if f[2] > 0.0 && pixels[q].object == px.object {
                    acc = [acc[0].max(f[0]), acc[1].min(f[1]), 1.0];
                }
            }
            (acc[2] > 0.0).then_some([acc[0], acc[1]])
        })
        .collect();
    for (px, f) in pixels.iter_mut().zip(filled) {
        if let Some([s1, s2]) = f {
            px.slope_max = s1;
            px.slope_min = s2;
            px.slope_source = 2.0;
        }
    }
}

/// Pass 2 (kernels/render/shadows.cl `shadow_adaptive`), in place; returns the rays traced.
pub fn adaptive(
    s: &SceneArrays,
    pixels: &mut [ShadowPixel],
    light: u32,
    sparse_spp: u32,
    max_spp: u32,
) -> u64 {
    let w = s.params.image_width;
    let l = &s.lights[light as usize];
    pixels
        .par_iter_mut()
        .enumerate()
        .map(|(pixel, px)| {
            if !(px.weight > 0.0) || px.slope_source == 0.0 {
                return 0u64;
            }
            let n = sample_count(px.slope_max, px.slope_min, px.pixel_size, l.p0.0[3]);
            let (target, k) = adaptive_plan(n, sparse_spp, max_spp);
            px.target = target;
            if k == 0 {
                return 0;
            }
            let (x, y) = (pixel as u32 % w, pixel as u32 / w);
            let mut rays = 0u32;
            let mut acc = Sums {
                visible: px.visible,
                weight: px.weight,
                occluded: px.occluded,
                s1: px.slope_max,
                s2: px.slope_min,
                unshadowed: Vec3::from(px.unshadowed),
            };
            let key = rng_sample_key(s.params.seed, pixel as u32, SHADOW_SAMPLE_BASE + 1);
            samples(s, l, x, y, px.object, key, k, &mut acc, &mut rays);
            px.visible = acc.visible;
            px.weight = acc.weight;
            px.occluded = acc.occluded;
            px.samples += (k * k) as f32;
            px.slope_max = acc.s1;
            px.slope_min = acc.s2;
            px.unshadowed = acc.unshadowed.to_array();
            if acc.occluded > 0.0 {
                px.slope_source = 1.0;
            }
            rays as u64
        })
        .sum()
}

/// All three passes, as the renderer runs them for the first plane's light (the renderer
/// runs them once per plane, each exactly so): the shadow pixels and the rays traced.
pub fn passes(s: &SceneArrays, sampling: &ShadowSampling) -> (Vec<ShadowPixel>, u64) {
    let (mut pixels, mut rays) =
        sparse(s, sampling.lights.first(), isqrt_floor(sampling.sparse_spp));
    fill(
        &mut pixels,
        s.params.image_width,
        s.params.image_height,
        sampling.fill_radius,
    );
    rays += adaptive(
        s,
        &mut pixels,
        sampling.lights.first(),
        sampling.sparse_spp,
        sampling.max_spp,
    );
    (pixels, rays)
}

/// The shadow terms (ShadowTerms lanes: the replaced light, pad, r, pad) of samples
/// [sample_base, sample_base + count) of every pixel for light `shadow_light`, whose shadow
/// pixels (the passes' output: the centre's receiver) are `pixels`, folded as
/// kernels/render/film.cl folds them (eq. 6.5), into `terms`.
pub fn render_shadow_terms(
    s: &SceneArrays,
    opt: ReferenceOptions,
    shadow_light: u32,
    pixels: &[ShadowPixel],
    terms: &mut [[f32; 8]],
    sample_base: u32,
    count: u32,
) {
    let w = s.params.image_width;
    terms.par_iter_mut().enumerate().for_each(|(pixel, t)| {
        let (x, y) = (pixel as u32 % w, pixel as u32 / w);
        let centre = &pixels[pixel];
        let target = ShadowTarget {
            light: shadow_light,
            object: if centre.weight > 0.0 {
                centre.object
            } else {
                f32::NAN
            },
        };
        let mut rays = 0u32;
        for k in 0..count {
            let sample = sample_base + k;
            let key = rng_sample_key(s.params.seed, pixel as u32, sample);
            let ps = trace_path(s, opt, x, y, key, &mut rays, target);
            let n = (sample + 1) as f32;
            for c in 0..3 {
                t[c] += (ps.shadow_direct[c] - t[c]) / n;
                t[4 + c] += (ps.shadow_unshadowed[c] - t[4 + c]) / n;
            }
        }
    });
}
