//! kernels/render/indirect.cl in Rust: AAF's indirect passes (sparse, adaptive) for diffuse
//! and glossy (metal) receivers, with the same float operations in the same order
//! (src/render/indirect explains the estimator).

use std::f32::consts::PI;

use glam::Vec3;
use rayon::prelude::*;

use super::pathtrace::{
    ReferenceOptions, environment_radiance, reflect_dir, sample_direct_light, scatter,
    surface_albedo, surface_at, survives,
};
use super::rng::{DIM_BSDF_U, DIM_BSDF_V, DIM_PIXEL_X, DIM_PIXEL_Y, rng_sample_key, rng_uniform};
use super::sampling::{sample_diffuse, sample_phong_lobe};
use super::shadows::{Receiver, aaf_receiver};
use crate::arrays::SceneArrays;
use crate::arrays::trace::intersect_closest;
use crate::geometry::offset_ray_origin;
use crate::layout::{IndirectPixel, MATERIAL_DIFFUSE, MATERIAL_EMITTER, MATERIAL_METAL};
use crate::render::IndirectSampling;
use crate::render::indirect::bandlimit::{glossy_bandlimit, sample_count};
use crate::render::shadows::bandlimit::{adaptive_plan, isqrt_floor};

/// kernels/render/indirect.cl `INDIRECT_SAMPLE_BASE`.
pub const INDIRECT_SAMPLE_BASE: u32 = 0xF000_0000;

/// The light a path sample counts as indirect, arriving at a receiver from `d`
/// (kernels/render/indirect.cl `indirect_radiance`), and the first bounce's hit distance
/// (inf: none).
pub fn indirect_radiance(
    s: &SceneArrays,
    opt: ReferenceOptions,
    o: Vec3,
    d: Vec3,
    key: u32,
    rays: &mut u32,
) -> (Vec3, f32) {
    let params = &s.params;
    let (mut o, mut d) = (o, d);
    let mut throughput = Vec3::ONE;
    let mut l = Vec3::ZERO;
    let mut count_emission = false;
    let mut z = f32::INFINITY;
    for bounce in 1..params.max_vertices {
        if !survives(s, opt, &mut throughput, key, bounce) {
            break;
        }
        *rays += 1;
        let Some(hit) = intersect_closest(s, o, d, f32::INFINITY) else {
            if bounce >= 2 {
                l += throughput * environment_radiance(s, d);
            }
            break;
        };
        if bounce == 1 {
            z = hit.t;
        }
        let sf = surface_at(s, &hit, o, d);
        let m = &s.materials[sf.material as usize];
        if m.kind == MATERIAL_EMITTER {
            if bounce >= 2 && count_emission && sf.entering {
                l += throughput * m.emission.xyz();
            }
            break;
        }
        let albedo = surface_albedo(s, &sf);
        if opt.next_event_estimation && m.kind == MATERIAL_DIFFUSE && params.light_count > 0 {
            let (li, _) = sample_direct_light(s, sf.p, sf.ng, sf.ns, key, bounce, rays);
            l += throughput * albedo * (1.0 / PI) * li;
        }
        let sc = scatter(s, &sf, d, albedo, key, bounce);
        if sc.absorbed {
            break;
        }
        throughput *= sc.weight;
        count_emission = if opt.next_event_estimation {
            sc.specular
        } else {
            true
        };
        o = offset_ray_origin(sf.p, sc.offset_normal, params.scene_size);
        d = sc.direction;
    }
    (l, z)
}

/// Running sums of one pixel's indirect samples.
#[derive(Clone, Copy, Debug)]
struct Sums {
    irradiance: Vec3,
    albedo: Vec3,
    weight: f32,
    z_min: f32,
    z_max: f32,
    reflectors: f32,
}

/// The lobe of a receiver: 1 glossy (a metal), 0 diffuse.
fn lobe(s: &SceneArrays, r: &Receiver) -> f32 {
    if s.materials[r.sf.material as usize].kind == MATERIAL_METAL {
        1.0
    } else {
        0.0
    }
}

/// k × k indirect samples of pixel (x, y) numbered from `first`, on the receiver `object`
/// of lobe `lobe` (kernels/render/indirect.cl `indirect_samples`).
#[allow(clippy::too_many_arguments)]
fn samples(
    s: &SceneArrays,
    opt: ReferenceOptions,
    (x, y, pixel): (u32, u32, u32),
    object: f32,
    centre_lobe: f32,
    first: u32,
    k: u32,
    acc: &mut Sums,
    rays: &mut u32,
) {
    let inv_k = 1.0 / k as f32;
    let glossy = centre_lobe > 0.0;
    for i in 0..k {
        for j in 0..k {
            let key = rng_sample_key(
                s.params.seed,
                pixel,
                INDIRECT_SAMPLE_BASE + first + i * k + j,
            );
            let (jx, jy) = (
                rng_uniform(key, 0, DIM_PIXEL_X),
                rng_uniform(key, 0, DIM_PIXEL_Y),
            );
            let Some(q) = aaf_receiver(s, x, y, jx, jy, glossy, rays) else {
                continue;
            };
            if q.object != object || lobe(s, &q) != centre_lobe {
                continue;
            }
            let u = (i as f32 + rng_uniform(key, 0, DIM_BSDF_U)) * inv_k;
            let v = (j as f32 + rng_uniform(key, 0, DIM_BSDF_V)) * inv_k;
            let d = if glossy {
                let m = &s.materials[q.sf.material as usize];
                sample_phong_lobe(u, v, reflect_dir(q.d, q.sf.ns), m.exponent)
            } else {
                sample_diffuse(u, v, q.sf.ns)
            };
            acc.weight += 1.0;
            acc.albedo += q.albedo;
            if d.dot(q.sf.ng) <= 0.0 {
                continue;
            }
            let o = offset_ray_origin(q.sf.p, q.sf.ng, s.params.scene_size);
            let (l, z) = indirect_radiance(s, opt, o, d, key, rays);
            acc.irradiance += l;
            if z < f32::INFINITY {
                acc.z_min = acc.z_min.min(z);
                acc.z_max = acc.z_max.max(z);
                acc.reflectors += 1.0;
            }
        }
    }
}

/// Pass 1 for every pixel (kernels/render/indirect.cl `indirect_sparse`): the indirect pixels
/// and the rays traced.
pub fn sparse(
    s: &SceneArrays,
    opt: ReferenceOptions,
    sampling: &IndirectSampling,
) -> (Vec<IndirectPixel>, u64) {
    let w = s.params.image_width;
    let n = w as usize * s.params.image_height as usize;
    let sqrt_spp = isqrt_floor(sampling.sparse_spp);
    let out: Vec<(IndirectPixel, u32)> = (0..n)
        .into_par_iter()
        .map(|pixel| {
            let (x, y) = (pixel as u32 % w, pixel as u32 / w);
            let mut px = IndirectPixel::default();
            let mut rays = 0u32;
            let Some(r) = aaf_receiver(s, x, y, 0.5, 0.5, sampling.glossy, &mut rays) else {
                return (px, rays);
            };
            let centre_lobe = lobe(s, &r);
            let mut acc = Sums {
                irradiance: Vec3::ZERO,
                albedo: Vec3::ZERO,
                weight: 0.0,
                z_min: f32::INFINITY,
                z_max: 0.0,
                reflectors: 0.0,
            };
            let at = (x, y, pixel as u32);
            samples(
                s,
                opt,
                at,
                r.object,
                centre_lobe,
                0,
                sqrt_spp,
                &mut acc,
                &mut rays,
            );
            let z = acc.reflectors > 0.0;
            px.samples = if acc.weight > 0.0 {
                (sqrt_spp * sqrt_spp) as f32
            } else {
                0.0
            };
            px.weight = acc.weight;
            px.z_min = if z { acc.z_min } else { 0.0 };
            px.z_max = if z { acc.z_max } else { 0.0 };
            px.reflectors = acc.reflectors;
            px.pixel_size = r.t * 2.0 * s.params.tan_half_fov / s.params.image_height as f32;
            px.target = px.samples;
            px.object = r.object;
            px.bandlimit = if centre_lobe > 0.0 {
                glossy_bandlimit(s.materials[r.sf.material as usize].exponent)
            } else {
                sampling.bandlimit
            };
            px.lobe = centre_lobe;
            px.irradiance = acc.irradiance.to_array();
            px.albedo = acc.albedo.to_array();
            px.position = r.sf.p.to_array();
            px.normal = r.sf.ns.to_array();
            (px, rays)
        })
        .collect();
    let rays = out.iter().map(|(_, r)| *r as u64).sum();
    (out.into_iter().map(|(p, _)| p).collect(), rays)
}

/// Pass 2 (kernels/render/indirect.cl `indirect_adaptive`), in place; returns the rays traced.
pub fn adaptive(
    s: &SceneArrays,
    opt: ReferenceOptions,
    pixels: &mut [IndirectPixel],
    sampling: &IndirectSampling,
) -> u64 {
    let w = s.params.image_width;
    pixels
        .par_iter_mut()
        .enumerate()
        .map(|(pixel, px)| {
            if !(px.weight > 0.0) || !(px.reflectors > 0.0) {
                return 0u64;
            }
            let n = sample_count(px.z_min, px.z_max, px.pixel_size, px.bandlimit);
            let (target, k) = adaptive_plan(n, sampling.sparse_spp, sampling.max_spp);
            px.target = target;
            if k == 0 {
                return 0;
            }
            let mut rays = 0u32;
            let mut acc = Sums {
                irradiance: Vec3::from(px.irradiance),
                albedo: Vec3::from(px.albedo),
                weight: px.weight,
                z_min: px.z_min,
                z_max: px.z_max,
                reflectors: px.reflectors,
            };
            let at = (pixel as u32 % w, pixel as u32 / w, pixel as u32);
            let first = sampling.sparse_spp;
            samples(
                s, opt, at, px.object, px.lobe, first, k, &mut acc, &mut rays,
            );
            px.irradiance = acc.irradiance.to_array();
            px.albedo = acc.albedo.to_array();
            px.weight = acc.weight;
            px.samples += (k * k) as f32;
            rays as u64
        })
        .sum()
}

/// Both passes, as the renderer runs them: the indirect pixels and the rays traced.
pub fn passes(
    s: &SceneArrays,
    opt: ReferenceOptions,
    sampling: &IndirectSampling,
) -> (Vec<IndirectPixel>, u64) {
    let (mut pixels, rays) = sparse(s, opt, sampling);
    let more = adaptive(s, opt, &mut pixels, sampling);
    (pixels, rays + more)
}
