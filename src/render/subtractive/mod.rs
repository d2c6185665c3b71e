//! Subtractive shadows (DeCoro 2009 ch. 4; digest shared/notes/seed-decoro.md §2): a real-time
//! preview of environment-lit scenes, not a Monte Carlo estimator. Eq. 4.1:
//! `L = f L_e − f L_e (1 − V)`: the unshadowed direct light C minus a low-resolution estimate S
//! of the light the shadows block, joint-bilaterally upsampled to S′ (§2.3 steps 1-5):
//! 1. [`environment_lights`]: E, |E| directional lights importance-sampled from the map;
//! 2. [`shadow_visibility`] + the shadow kernel: S at 1/f² of the pixels, one ray per light;
//! 3. C, unshadowed, from a dense light set (the "prefiltered" map, see [`Settings`]);
//! 4. S → S′ with the weight `G(‖S′_p − S_p‖)(S′_n · S_n)` (§2.2);
//! 5. max(C − S′, 0) (the clamp is the digest's §2.4 stability rule, not in the thesis).
//!
//! The plain Rust reference of every kernel in kernels/render/subtractive.cl is here
//! ([`reference`]); [`device`] runs the kernels. Rays are traced on the host (rayon) with the
//! BVH the path tracer's reference uses; the kernels are steps 2(c-d), 3, 4 and 5.
//!
//! Choices where the seed is open (digest §2.2, §2.4):
//! - E: stratified inverse-CDF sampling of luminance × solid angle on a 256×128 lat-long grid,
//!   equal luminance per light (the thesis: structured importance sampling [2]).
//! - C: a 64×32 prefiltered irradiance map of 1024 importance-sampled unshadowed lights from an
//!   independent seed (the thesis: SH irradiance / prefiltered maps); the diffuse BRDF only.
//! - Direct light only; glass, mirror and chrome first hits shaded as diffuse of their albedo
//!   (§2.4: "no GI, glass or mirror paths"); the sky is C where the camera ray escapes.
//! - S at the centre pixel of each f×f block, f = 1…64 (1/1 … 1/4096; the seed's range 1/16 …
//!   1/1024 is f = 4 … 32); one ray per light facing the surface, rays on the host.
//! - Upsampling: the 2×2 nearest samples, weight = bilinear × G(‖Δp‖, σ) × max(n′·n, 0),
//!   σ = `sigma_position` (1) × f × the pixel's world footprint (scale-invariant);
//!   normalised by the weight sum; the nearest sample when the sum is 0 (§2.4).
//! - max(C − S′, 0) per channel (§2.4, not in the thesis).

pub mod device;
pub mod reference;

use std::f32::consts::PI;

use anyhow::{Result, bail};
use glam::Vec3;
use rayon::prelude::*;

use crate::arrays::SceneArrays;
use crate::arrays::trace::{intersect_closest, occluded};
use crate::geometry::offset_ray_origin;
use crate::render::cpu::pathtrace::{environment_radiance, surface_albedo, surface_at};
use crate::render::cpu::rng::{hash_u32, rng_sample_key};
use crate::render::cpu::sampling::camera_ray;
use crate::scene::Scene;

/// The level-of-detail knobs (§2.2: illumination detail |E|, sampling detail 1/f²) and the
/// choices the thesis leaves open.
#[derive(Clone, Debug)]
pub struct Settings {
    /// |E|: shadow-casting directional lights (illumination detail).
    pub lights: u32,
    /// f: S has one sample per f×f block, 1/f² of the pixels (4 → 1/16 … 32 → 1/1024).
    pub block: u32,
    /// Lights of the dense, unshadowed set C is summed from. The thesis uses SH irradiance or
    /// a prefiltered map (§2.1); a sum over this many importance-sampled lights is the same
    /// integral of the same map up to sampling error, needs no second code path for a
    /// different BRDF and, at `Some(lights)`-equal counts, gives the identity test of §2.7.1.
    /// None: C uses E itself (then block = 1 must equal the additive form).
    pub unshadowed_lights: Option<u32>,
    /// C from the prefiltered irradiance map of the `unshadowed_lights` set ([`irradiance_map`],
    /// one lookup per pixel, as the thesis's SH irradiance) rather than the direct sum.
    pub prefiltered: bool,
    /// σ of G(‖S′_p − S_p‖), relative to the world-space footprint of one block at the
    /// pixel's distance (§2.2 leaves σ open; measured on Outside: 1 keeps contact shadows).
    pub sigma_position: f32,
    /// Seed of the light sets (C's set uses seed + 1 so it is independent of E).
    pub seed: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            lights: 32,
            block: 4,
            unshadowed_lights: Some(1024),
            prefiltered: true,
            sigma_position: 1.0,
            seed: 1,
        }
    }
}

impl Settings {
    pub fn validate(&self) -> Result<()> {
        if self.lights == 0 {
            bail!("--preview subtractive needs at least one light (got lights = 0)");
        }
        if !(1..=64).contains(&self.block) {
            bail!(
                "the shadow block must be 1..=64 pixels on a side (1/1 … 1/4096 of the pixels), got {}",
                self.block
            );
        }
        if !(self.sigma_position > 0.0 && self.sigma_position.is_finite()) {
            bail!(
                "sigma_position must be positive, got {}",
                self.sigma_position
            );
        }
        Ok(())
    }
}

/// One directional light of E: unit direction towards the sky and the irradiance it carries
/// at normal incidence (the map's radiance integrated over its share of the sphere).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirLight {
    pub dir: Vec3,
    pub irradiance: Vec3,
}

/// Resolution of the lat-long grid the environment is importance-sampled on.
const ENV_W: usize = 256;
const ENV_H: usize = 128;

fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The direction of lat-long coordinates (u, v), the inverse of `environment_radiance`'s map.
fn latlong_dir(u: f32, v: f32) -> Vec3 {
    let phi = (u - 0.5) * 2.0 * PI;
    let lat = (v - 0.5) * PI;
    Vec3::new(lat.cos() * phi.sin(), lat.sin(), -lat.cos() * phi.cos())
}

/// A clear error for scenes the preview cannot show (§2.4: it is an environment-light mode).
pub fn check_scene(scene: &Scene) -> Result<()> {
    if scene.environment.is_none() {
        bail!(
            "--preview subtractive needs a scene lit by an environment (an `[[light]] type = \"infinite\"`, e.g. scenes/outside.toml); this scene has none"
        );
    }
    Ok(())
}

/// Step 1: `count` lights importance-sampled from the environment (the thesis uses structured
/// importance sampling [2]; here stratified inverse-CDF sampling of luminance × solid angle on
/// a 256×128 lat-long grid, one jittered direction per stratum). Each light carries
/// L·Ω / (count·p) = L / lum(L) · Σw / count: equal luminance per light, so Σ_l f cos E_l is an
/// unbiased estimate of ∫ f L cos dω for the piecewise-constant map.
pub fn environment_lights(s: &SceneArrays, count: u32, seed: u32) -> Vec<DirLight> {
    let d_phi = 2.0 * PI / ENV_W as f32;
    let d_lat = PI / ENV_H as f32;
    let cells: Vec<(Vec3, f32)> = (0..ENV_W * ENV_H)
        .map(|k| {
            let (i, j) = (k % ENV_W, k / ENV_W);
            let (u, v) = (
                (i as f32 + 0.5) / ENV_W as f32,
                (j as f32 + 0.5) / ENV_H as f32,
            );
            let radiance = environment_radiance(s, latlong_dir(u, v));
            let omega = ((v - 0.5) * PI).cos() * d_phi * d_lat;
            (radiance, luminance(radiance).max(0.0) * omega)
        })
        .collect();
    let mut cdf = Vec::with_capacity(cells.len());
    let mut total = 0.0f64;
    for c in &cells {
        total += c.1 as f64;
        cdf.push(total);
    }
    if !(total > 0.0) {
        return Vec::new();
    }
    let rand = |i: u32, dim: u32| {
        hash_u32(seed.wrapping_mul(0x9E37_79B9) ^ hash_u32(i.wrapping_mul(4) + dim)) as f32
            / 4_294_967_296.0
    };
    (0..count)
        .map(|i| {
            let target = (i as f64 + rand(i, 0) as f64) / count as f64 * total;
            let k = cdf.partition_point(|&c| c <= target).min(cells.len() - 1);
            let (i_u, j_v) = (k % ENV_W, k / ENV_W);
            let u = (i_u as f32 + rand(i, 1)) / ENV_W as f32;
            let v = (j_v as f32 + rand(i, 2)) / ENV_H as f32;
            let (radiance, _) = cells[k];
            let irradiance = radiance / luminance(radiance) * (total / count as f64) as f32;
            DirLight {
                dir: latlong_dir(u, v).normalize(),
                irradiance,
            }
        })
        .collect()
}

/// The full-resolution G-buffer (§2.1) of one camera ray per pixel (sample 0's jitter, so the
/// preview lines up with the path tracer's pixels).
#[derive(Clone, Debug)]
pub struct GBuffer {
    pub width: u32,
    pub height: u32,
    /// Hit position; w = 1 for a hit, 0 where the ray sees the sky.
    pub position: Vec<[f32; 4]>,
    /// Shading normal; w = world-space width of one pixel at the hit (for σ of G).
    pub normal: Vec<[f32; 4]>,
    /// Diffuse albedo at a hit; the sky's radiance where the ray escapes.
    pub albedo: Vec<[f32; 4]>,
}

/// Builds the G-buffer. Direct light only (§2.4): every first hit is shaded as a diffuse
/// surface of its albedo (mirror and glass included: the preview has no specular paths).
pub fn gbuffer(s: &SceneArrays) -> GBuffer {
    let p = &s.params;
    let (w, h) = (p.image_width, p.image_height);
    let cam = p.camera_origin.xyz();
    // World-space width of a pixel per unit distance: angle between neighbouring pixel rays.
    let (_, d0) = camera_ray(p, w / 2, h / 2, rng_sample_key(p.seed, 0, 0));
    let (_, d1) = camera_ray(p, w / 2 + 1, h / 2, rng_sample_key(p.seed, 0, 0));
    let pixel_angle = d0.angle_between(d1).max(1e-6);
    let rows: Vec<_> = (0..w * h)
        .into_par_iter()
        .map(|pixel| {
            let (x, y) = (pixel % w, pixel / w);
            let (o, d) = camera_ray(p, x, y, rng_sample_key(p.seed, pixel, 0));
            match intersect_closest(s, o, d, f32::INFINITY) {
                None => {
                    let sky = environment_radiance(s, d);
                    ([0.0; 4], [0.0; 4], [sky.x, sky.y, sky.z, 0.0])
                }
                Some(hit) => {
                    let sf = surface_at(s, &hit, o, d);
                    let a = surface_albedo(s, &sf);
                    let footprint = (sf.p - cam).length() * pixel_angle;
                    let pos = offset_ray_origin(sf.p, sf.ng, p.scene_size);
                    (
                        [pos.x, pos.y, pos.z, 1.0],
                        [sf.ns.x, sf.ns.y, sf.ns.z, footprint],
                        [a.x, a.y, a.z, 0.0],
                    )
                }
            }
        })
        .collect();
    GBuffer {
        width: w,
        height: h,
        position: rows.iter().map(|r| r.0).collect(),
        normal: rows.iter().map(|r| r.1).collect(),
        albedo: rows.iter().map(|r| r.2).collect(),
    }
}

/// The low-resolution grid of S: one sample per f×f block, at the block's centre pixel (the
/// pixel a 1/f² rendering's ray would hit), clamped into the image.
pub fn low_res(width: u32, height: u32, block: u32) -> (u32, u32, Vec<u32>) {
    let (lw, lh) = (width.div_ceil(block), height.div_ceil(block));
    let index = (0..lw * lh)
        .map(|k| {
            let x = ((k % lw) * block + block / 2).min(width - 1);
            let y = ((k / lw) * block + block / 2).min(height - 1);
            y * width + x
        })
        .collect();
    (lw, lh, index)
}

/// Words of visibility bits per sample.
pub fn vis_words(lights: usize) -> usize {
    lights.div_ceil(32)
}

/// Step 2(b): bit l of sample k is set when light l is *visible* from pixel `pixels[k]`
/// (one shadow ray per light facing the surface; lights behind it stay 0, they add nothing).
pub fn shadow_visibility(
    s: &SceneArrays,
    g: &GBuffer,
    pixels: &[u32],
    lights: &[DirLight],
) -> Vec<u32> {
    let words = vis_words(lights.len());
    let mut bits = vec![0u32; pixels.len() * words];
    bits.par_chunks_mut(words.max(1))
        .zip(pixels.par_iter())
        .for_each(|(out, &px)| {
            let pos = g.position[px as usize];
            if pos[3] == 0.0 {
                return;
            }
            let o = Vec3::new(pos[0], pos[1], pos[2]);
            let n = Vec3::from_slice(&g.normal[px as usize][..3]);
            for (l, light) in lights.iter().enumerate() {
                if n.dot(light.dir) > 0.0 && !occluded(s, o, light.dir, f32::INFINITY) {
                    out[l / 32] |= 1 << (l % 32);
                }
            }
        });
    bits
}

/// Shadow rays a frame traces: |E| × the samples that hit (the cost model of §2.3).
pub fn rays(g: &GBuffer, pixels: &[u32], lights: usize) -> u64 {
    pixels
        .iter()
        .filter(|&&p| g.position[p as usize][3] != 0.0)
        .count() as u64
        * lights as u64
}

/// One preview frame and what it cost.
pub struct Preview {
    pub width: u32,
    pub height: u32,
    /// max(C − S′, 0) (or the additive image), RGBA with A = 0.
    pub image: Vec<[f32; 4]>,
    /// Kernel time (profiling events) of the image kernels.
    pub kernel_time: std::time::Duration,
    /// Host time of the shadow rays (rayon), measured on a loaded machine.
    pub ray_time: std::time::Duration,
    pub rays: u64,
}

/// The light set C is summed from (E itself when `unshadowed_lights` is None).
pub fn unshadowed_set(s: &SceneArrays, settings: &Settings, e: &[DirLight]) -> Vec<DirLight> {
    match settings.unshadowed_lights {
        Some(n) => environment_lights(s, n, settings.seed.wrapping_add(1)),
        None => e.to_vec(),
    }
}

/// Steps 1-5 on the device for one frame (C computed by the caller once per environment and
/// camera: it does not depend on the knobs).
pub fn subtractive(
    s: &SceneArrays,
    g: &GBuffer,
    dg: &device::DeviceGBuffer,
    k: &device::SubtractiveKernels,
    c: &[[f32; 4]],
    settings: &Settings,
) -> Result<Preview> {
    settings.validate()?;
    let e = environment_lights(s, settings.lights, settings.seed);
    let (lw, lh, pixels) = low_res(g.width, g.height, settings.block);
    let t = std::time::Instant::now();
    let bits = shadow_visibility(s, g, &pixels, &e);
    let ray_time = t.elapsed();
    let s_low = k.shadow(dg, &pixels, &e, &bits, false)?;
    let out = k.compose(
        dg,
        c,
        &s_low.image,
        &pixels,
        lw,
        lh,
        settings.block,
        settings.sigma_position,
    )?;
    Ok(Preview {
        width: g.width,
        height: g.height,
        image: out.image,
        kernel_time: s_low.time + out.time,
        ray_time,
        rays: rays(g, &pixels, e.len()),
    })
}

/// The additive form at the same |E| (§2.5's comparison): the visible lights summed at every
/// pixel, one shadow ray per light and pixel.
pub fn additive(
    s: &SceneArrays,
    g: &GBuffer,
    dg: &device::DeviceGBuffer,
    k: &device::SubtractiveKernels,
    lights: u32,
    seed: u32,
) -> Result<Preview> {
    let e = environment_lights(s, lights, seed);
    let pixels: Vec<u32> = (0..g.width * g.height).collect();
    let t = std::time::Instant::now();
    let bits = shadow_visibility(s, g, &pixels, &e);
    let ray_time = t.elapsed();
    let out = k.shadow(dg, &pixels, &e, &bits, true)?;
    Ok(Preview {
        width: g.width,
        height: g.height,
        image: out.image,
        kernel_time: out.time,
        ray_time,
        rays: rays(g, &pixels, e.len()),
    })
}

/// Resolution of the prefiltered irradiance map (lat-long over normal directions).
pub const MAP_W: u32 = 64;
pub const MAP_H: u32 = 32;

/// Step 3's prefiltered map (§2.1: the thesis uses SH irradiance [78] for diffuse surfaces):
/// irradiance E(n) = Σ_l max(n·ω_l, 0) E_l over a dense unshadowed light set, tabulated on a
/// 64×32 lat-long grid of normals and looked up bilinearly per pixel. It depends on the
/// environment only, so it is built once; a frame then costs one lookup per pixel instead of
/// a sum over the dense set. Irradiance is the map convolved with a cosine lobe, smooth
/// enough that bilinear lookup at 5.6° spacing is close to the direct sum (measured in
/// tests/subtractive.rs).
pub fn irradiance_map(lights: &[DirLight]) -> Vec<[f32; 4]> {
    (0..MAP_W * MAP_H)
        .into_par_iter()
        .map(|k| {
            let u = ((k % MAP_W) as f32 + 0.5) / MAP_W as f32;
            let v = ((k / MAP_W) as f32 + 0.5) / MAP_H as f32;
            let n = latlong_dir(u, v);
            let mut e = Vec3::ZERO;
            for l in lights {
                let c = n.dot(l.dir);
                if c > 0.0 {
                    e += l.irradiance * c;
                }
            }
            [e.x, e.y, e.z, 0.0]
        })
        .collect()
}

/// C for `settings`: the prefiltered map of the dense set, the dense set summed directly
/// (`prefiltered` false), or E itself (`unshadowed_lights` None, for the identity test).
pub fn unshadowed(
    s: &SceneArrays,
    dg: &device::DeviceGBuffer,
    k: &device::SubtractiveKernels,
    settings: &Settings,
    e: &[DirLight],
) -> Result<device::Timed> {
    let set = unshadowed_set(s, settings, e);
    if settings.prefiltered && settings.unshadowed_lights.is_some() {
        k.prefiltered(dg, &irradiance_map(&set))
    } else {
        k.unshadowed(dg, &set)
    }
}

/// An RGBA result of the kernels as an image (A dropped).
pub fn to_rgb(width: u32, height: u32, image: &[[f32; 4]]) -> crate::imaging::RgbImage {
    crate::imaging::RgbImage {
        width,
        height,
        pixels: image.iter().map(|p| [p[0], p[1], p[2]]).collect(),
    }
}
