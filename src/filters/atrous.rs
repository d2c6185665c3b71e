//! The edge-avoiding à-trous wavelet filter (Dammertz, Sewtz, Hanika, Lensch, "Edge-Avoiding
//! À-Trous Wavelet Transform for fast Global Illumination Filtering", HPG 2010): settings, the
//! OpenCL passes of kernels/filters/atrous.cl and the plain Rust reference of the same equations and
//! the same pass structure.
//!
//! Every pass convolves with the 5 × 5 B3-spline kernel h = (1/16, 1/4, 3/8, 1/4, 1/16)
//! (outer product), its taps `2^i` pixels apart in pass i, each tap weighted by
//! `w_colour · w_normal · w_position`, `w_f = min(1, exp(−‖f_p − f_q‖² / σ_f²))`, and
//! normalised by the sum of the weights. The choices the paper leaves open:
//!
//! - **What is filtered.** By default ([`AtrousSettings::demodulate`]) the light divided by
//!   the first-hit albedo of F (per channel, albedo clamped below at [`ALBEDO_EPSILON`]), and
//!   the albedo is multiplied back after the last pass: the albedo mean is noise-free after a
//!   few samples, so texture detail survives exactly, and the colour weight compares lighting
//!   rather than texture (a textured wall would otherwise either be blurred or, with a small
//!   σ_colour, not filtered at all). `demodulate = false` filters the beauty (direct +
//!   indirect) as the paper does. Emitters have their emission's chromaticity as albedo, so
//!   they demodulate to their (large) emission and the colour weight keeps them apart.
//! - **σ_colour** is halved every pass (σ_colour · 2^−i), as in the paper: each pass leaves
//!   the image smoother, so smaller differences mark real edges. It is in the units of the
//!   filtered colour (linear radiance, or radiance / albedo), so it scales with the exposure
//!   of the scene: lights 10× brighter want a 10× larger σ_colour.
//! - **σ_position** is relative, so the filter does not depend on the scene's scale: the
//!   world-space σ of a pixel is `sigma_position · footprint`, footprint = depth ·
//!   2 tan(fov/2) / height, the world size of one pixel at that pixel's depth (scaling the
//!   scene scales positions and footprints alike; in pixels it is also the same at any
//!   resolution). It is the same in every pass, as the paper's world-space σ_x is: on a plane
//!   facing the camera the taps of pass i lie 2^i footprints apart, so the coarse passes only
//!   reach surfaces whose positions agree better than that, and a depth discontinuity of more
//!   than a few footprints is cut in every pass. A σ that grows with the tap spacing
//!   (`sigma_position · 2^i · footprint`) was measured too, and filtered worse (MSE 5.85 at
//!   its best, 5.45 with √(2^i), against 5.19; see the defaults).
//! - **World positions** are reconstructed from F's depth (distance along the camera ray)
//!   and the ray through the pixel centre, as kernels/render/camera.cl forms it; camera-relative
//!   (the origin cancels in every difference). With a thin lens (DOF) the real rays start
//!   anywhere on the lens, and the pinhole reconstruction is off by about the lens radius ×
//!   (1 + depth / focal distance): fine for the weights while that is below a few footprints.
//! - **Sky** (depth = SKY_DEPTH) has no position or normal: sky pixels keep their input colour
//!   bit for bit and are never a neighbour. A pixel only partly covered by sky has a mean
//!   depth between its surface's and SKY_DEPTH; it is filtered as a surface very far away:
//!   its footprint is huge, so its own position weight accepts every neighbour, while every
//!   other pixel sees it as far off and gives it no weight.
//! - **Image borders.** Taps outside the image are skipped; the normalisation renormalises.
//!   The centre tap always weighs h(0)² = 9/64, so no pixel divides by zero.
//!
//! Limits: σ → ∞ (all three) tends to the plain B3-spline à-trous blur; σ → 0 to the input
//! (only the centre tap keeps a weight). Any σ in (0, ∞) and any finite input (short of float
//! overflow in the sums) give a finite output, never NaN: 1/σ² is clamped to a finite positive
//! number, so 0 · 1/σ² is 0; exponents are ≥ 0; the centre weighs > 0.

use std::sync::Arc;

use anyhow::{Context as _, Result, bail};
use glam::Vec3;
use ocl::{Buffer, Event, Kernel};
use rayon::prelude::*;

use super::{DeviceBuffers, Filtered};
use crate::gpu::{Gpu, event_duration};
use crate::imaging::RgbImage;
use crate::layout::{AtrousParams, FilterVector, Float4, SKY_DEPTH, SceneParams};
use crate::scene::Scene;
use crate::stats::PixelBuffers;

/// The B3-spline taps, offsets −2..2.
pub const B3: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Albedo channels are clamped below at this before the light is divided by them, so black
/// texels do not blow up the demodulated colour (and the same clamp is multiplied back).
pub const ALBEDO_EPSILON: f32 = 1.0e-3;

/// More passes than this would space the taps 2^15 = 32768 pixels apart, wider than any image.
pub const MAX_ITERATIONS: u32 = 15;

/// The camera the depths were rendered with: enough to turn a depth into a position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtrousCamera {
    pub origin: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit right vector of the image plane.
    pub right: Vec3,
    /// Unit up vector of the image plane.
    pub up: Vec3,
    /// tan(vertical fov / 2).
    pub tan_half_fov: f32,
}

impl From<&SceneParams> for AtrousCamera {
    fn from(p: &SceneParams) -> Self {
        AtrousCamera {
            origin: p.camera_origin.xyz(),
            forward: p.camera_forward.xyz(),
            right: p.camera_right.xyz(),
            up: p.camera_up.xyz(),
            tan_half_fov: p.tan_half_fov,
        }
    }
}

impl AtrousCamera {
    /// The camera of a scene file, with the basis the renderer builds (src/render/arrays.rs).
    pub fn from_scene(scene: &Scene) -> Self {
        let cam = &scene.camera;
        let forward = (cam.target - cam.origin).normalize();
        let right = forward.cross(cam.up).normalize();
        let up = right.cross(forward);
        AtrousCamera {
            origin: cam.origin,
            forward,
            right,
            up,
            tan_half_fov: (cam.fov_degrees.to_radians() * 0.5).tan(),
        }
    }
}

/// The filter's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct AtrousSettings {
    /// Number of passes; pass i spaces its taps 2^i pixels apart, so 5 passes reach 2·(1 + 2 +
    /// 4 + 8 + 16) = 62 pixels either side.
    pub iterations: u32,
    /// σ of the colour weight in the first pass, halved every pass; in units of the filtered
    /// colour (linear radiance, or radiance / albedo with `demodulate`).
    pub sigma_color: f32,
    /// σ of the normal weight, on the difference of the mean shading normals (unitless; unit
    /// normals differ by at most 2).
    pub sigma_normal: f32,
    /// σ of the position weight in pixel footprints (the world size of one pixel at the
    /// centre pixel's depth; see the module docs): dimensionless, so the same at any scene
    /// scale and resolution.
    pub sigma_position: f32,
    /// Filter light / albedo and multiply the albedo back (see the module docs); `false`
    /// filters the beauty as the paper does.
    pub demodulate: bool,
}

impl Default for AtrousSettings {
    /// The defaults: 5 passes, σ_colour 0.6 (radiance / albedo), σ_normal 0.5, σ_position 5
    /// footprints, demodulated. Chosen by the sweep of tests/atrous.rs (`sweep`, ignored by
    /// default) on scenes/cornell_diffuse.toml at 128 × 128, 8 spp, against 1024 spp: MSE in
    /// CIELUV 30.9 unfiltered, 5.19 filtered. The optimum is flat: σ_colour 0.5-0.7,
    /// σ_normal 0.3-1, σ_position 4-6 all give 5.18-5.58; σ_colour 0.25 or 2 give 7.0 and
    /// 5.6 at their best.
    fn default() -> Self {
        AtrousSettings {
            iterations: 5,
            sigma_color: 0.6,
            sigma_normal: 0.5,
            sigma_position: 5.0,
            demodulate: true,
        }
    }
}

impl AtrousSettings {
    /// Filtering the beauty (`demodulate = false`, the paper's input), from the same sweep:
    /// σ_colour 0.1 (linear radiance), σ_normal 1, σ_position 6; MSE 13.0 on the same image.
    /// Here the colour weight alone has to stop at texture edges, so σ_colour must be small,
    /// and then the noise is filtered less: hence the demodulated default.
    pub fn for_beauty() -> Self {
        AtrousSettings {
            iterations: 5,
            sigma_color: 0.1,
            sigma_normal: 1.0,
            sigma_position: 6.0,
            demodulate: false,
        }
    }

    pub fn validate(&self) -> Result<()> {
        if self.iterations > MAX_ITERATIONS {
            bail!(
                "the a-trous filter runs at most {MAX_ITERATIONS} iterations (taps 2^i pixels \
                 apart), got {}",
                self.iterations
            );
        }
        for (v, name) in [
            (self.sigma_color, "sigma_color"),
            (self.sigma_normal, "sigma_normal"),
            (self.sigma_position, "sigma_position"),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                bail!("the a-trous {name} must be a positive number, got {v}");
            }
        }
        Ok(())
    }

    /// The parameters of pass `iteration` for a w × h image.
    pub fn params(
        &self,
        camera: &AtrousCamera,
        width: u32,
        height: u32,
        iteration: u32,
    ) -> AtrousParams {
        AtrousParams {
            camera_origin: Float4::from_vec3(camera.origin, 0.0),
            camera_forward: Float4::from_vec3(camera.forward, 0.0),
            camera_right: Float4::from_vec3(camera.right, 0.0),
            camera_up: Float4::from_vec3(camera.up, 0.0),
            width,
            height,
            step: 1 << iteration,
            iteration,
            sigma_color: self.sigma_color,
            sigma_normal: self.sigma_normal,
            sigma_position: self.sigma_position,
            tan_half_fov: camera.tan_half_fov,
        }
    }
}

/// The à-trous filter on the device: an init kernel, `iterations` pass kernels ping-ponging
/// between two colour buffers, and a finish kernel, built once for a camera and image size.
pub struct AtrousFilter {
    _gpu: Arc<Gpu>,
    /// Stand-in for the FilterVectors until the first run sets them.
    _placeholder: Buffer<FilterVector>,
    init: Kernel,
    passes: Vec<Kernel>,
    finish: Kernel,
    /// One parameter block per pass (pass 0's also serves init and finish).
    _params: Vec<Buffer<AtrousParams>>,
    /// Ping-pong colour buffers; the result ends in `colour[iterations % 2]`.
    colour: [Buffer<Float4>; 2],
    _position: Buffer<Float4>,
    _normal: Buffer<Float4>,
    width: u32,
    height: u32,
}

impl AtrousFilter {
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &AtrousSettings,
        camera: &AtrousCamera,
        width: u32,
        height: u32,
    ) -> Result<AtrousFilter> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let defines = vec![
            (
                "ATROUS_DEMODULATE".to_string(),
                (settings.demodulate as u32).to_string(),
            ),
            (
                "ATROUS_ALBEDO_EPSILON".to_string(),
                format!("{ALBEDO_EPSILON:e}f"),
            ),
        ];
        let program = gpu.program("filters/atrous.cl", &defines, "")?;
        let pixels = width as usize * height as usize;
        let params = (0..settings.iterations.max(1))
            .map(|i| gpu.upload(&[settings.params(camera, width, height, i)]))
            .collect::<Result<Vec<_>>>()?;
        let colour = [
            gpu.zeroed::<Float4>(pixels, "a-trous colour")?,
            gpu.zeroed::<Float4>(pixels, "a-trous colour")?,
        ];
        let position = gpu.zeroed::<Float4>(pixels, "a-trous position")?;
        let normal = gpu.zeroed::<Float4>(pixels, "a-trous normal")?;
        let placeholder = gpu.zeroed::<FilterVector>(1, "placeholder")?;
        let size = [width as usize, height as usize];
        let init = Kernel::builder()
            .program(&program)
            .name("atrous_init")
            .queue(gpu.queue.clone())
            .global_work_size(size)
            .arg(&params[0])
            .arg(&placeholder)
            .arg(&colour[0])
            .arg(&position)
            .arg(&normal)
            .build()
            .context("creating the a-trous init kernel")?;
        let passes = (0..settings.iterations as usize)
            .map(|i| {
                Kernel::builder()
                    .program(&program)
                    .name("atrous_pass")
                    .queue(gpu.queue.clone())
                    .global_work_size(size)
                    .arg(&params[i])
                    .arg(&colour[i % 2])
                    .arg(&position)
                    .arg(&normal)
                    .arg(&colour[(i + 1) % 2])
                    .build()
                    .context("creating an a-trous pass kernel")
            })
            .collect::<Result<Vec<_>>>()?;
        let finish = Kernel::builder()
            .program(&program)
            .name("atrous_finish")
            .queue(gpu.queue.clone())
            .global_work_size(size)
            .arg(&params[0])
            .arg(&placeholder)
            .arg(&colour[settings.iterations as usize % 2])
            .build()
            .context("creating the a-trous finish kernel")?;
        Ok(AtrousFilter {
            _gpu: gpu,
            _placeholder: placeholder,
            init,
            passes,
            finish,
            _params: params,
            colour,
            _position: position,
            _normal: normal,
            width,
            height,
        })
    }

    /// Filters `buffers` (which must be width × height) and reads the image back. The kernel
    /// time is the sum over init, every pass and finish, from their profiling events.
    pub fn run(&mut self, buffers: &DeviceBuffers) -> Result<Filtered> {
        if buffers.width != self.width || buffers.height != self.height {
            bail!(
                "the filter was built for {}x{}, the buffers are {}x{}",
                self.width,
                self.height,
                buffers.width,
                buffers.height
            );
        }
        self.init.set_arg(1, buffers.filter_vectors)?;
        self.finish.set_arg(1, buffers.filter_vectors)?;
        let mut events = Vec::with_capacity(self.passes.len() + 2);
        // SAFETY: every buffer outlives its launch (we wait for all of them below) and holds
        // width x height pixels; the in-order queue runs the passes one after the other.
        unsafe {
            for k in std::iter::once(&self.init)
                .chain(&self.passes)
                .chain(std::iter::once(&self.finish))
            {
                let mut event = Event::empty();
                k.cmd()
                    .enew(&mut event)
                    .enq()
                    .context("launching an a-trous filter pass")?;
                events.push(event);
            }
        }
        let mut kernel_time = std::time::Duration::ZERO;
        for e in &events {
            kernel_time += event_duration(e)?;
        }
        let result = &self.colour[self.passes.len() % 2];
        let mut out = vec![Float4::default(); result.len()];
        result.read(&mut out).enq()?;
        out.truncate(self.width as usize * self.height as usize);
        Ok(Filtered {
            image: RgbImage {
                width: self.width,
                height: self.height,
                pixels: out.iter().map(|p| [p.0[0], p.0[1], p.0[2]]).collect(),
            },
            kernel_time,
        })
    }
}

// ---- The plain Rust reference: the same float operations in the same order. ----

type V3 = [f32; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn sum_sq(a: V3, b: V3) -> f32 {
    let d = sub(a, b);
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// 1/σ², finite and positive for any σ (kernels/filters/atrous.cl `atrous_inv_sq`).
fn inv_sq(sigma: f32) -> f32 {
    1.0 / (sigma * sigma).clamp(f32::MIN_POSITIVE, f32::MAX)
}

fn albedo_clamped(f: &FilterVector) -> V3 {
    f.albedo.map(|a| a.max(ALBEDO_EPSILON))
}

fn beauty(f: &FilterVector) -> V3 {
    std::array::from_fn(|c| f.direct[c] + f.indirect[c])
}

/// The unit direction of the camera ray through the centre of pixel (x, y)
/// (kernels/filters/atrous.cl `atrous_pixel_direction`).
pub fn pixel_direction(p: &AtrousParams, x: u32, y: u32) -> V3 {
    let (w, h) = (p.width as f32, p.height as f32);
    let sx = (2.0 * (x as f32 + 0.5) / w - 1.0) * p.tan_half_fov * (w / h);
    let sy = (1.0 - 2.0 * (y as f32 + 0.5) / h) * p.tan_half_fov;
    let (f, r, u) = (p.camera_forward.0, p.camera_right.0, p.camera_up.0);
    let d: V3 = std::array::from_fn(|c| f[c] + sx * r[c] + sy * u[c]);
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    d.map(|v| v / len)
}

/// The per-pixel guides of kernels/filters/atrous.cl `atrous_init`.
#[derive(Clone, Copy)]
struct Guide {
    /// depth · dir, camera-relative.
    position: V3,
    /// World size of one pixel at this depth.
    footprint: f32,
    normal: V3,
    surface: bool,
}

/// The plain Rust reference of kernels/filters/atrous.cl: init, `iterations` passes, finish.
pub fn reference(b: &PixelBuffers, camera: &AtrousCamera, s: &AtrousSettings) -> Result<RgbImage> {
    s.validate()?;
    let (w, h) = (b.width, b.height);
    if w == 0 || h == 0 {
        bail!("the image must be at least 1x1 pixels, got {w}x{h}");
    }
    let n = w as usize * h as usize;
    if b.filter_vectors.len() != n {
        bail!(
            "{}x{} pixels but {} FilterVectors",
            w,
            h,
            b.filter_vectors.len()
        );
    }
    let p0 = s.params(camera, w, h, 0);
    let guides: Vec<Guide> = (0..n)
        .into_par_iter()
        .map(|i| {
            let f = &b.filter_vectors[i];
            if f.depth >= SKY_DEPTH {
                return Guide {
                    position: [0.0; 3],
                    footprint: 0.0,
                    normal: [0.0; 3],
                    surface: false,
                };
            }
            let dir = pixel_direction(&p0, i as u32 % w, i as u32 / w);
            Guide {
                position: dir.map(|d| f.depth * d),
                footprint: f.depth * (2.0 * p0.tan_half_fov / h as f32),
                normal: f.normal,
                surface: true,
            }
        })
        .collect();
    let mut colour: Vec<V3> = b
        .filter_vectors
        .par_iter()
        .map(|f| {
            let c = beauty(f);
            if s.demodulate && f.depth < SKY_DEPTH {
                let a = albedo_clamped(f);
                std::array::from_fn(|k| c[k] / a[k])
            } else {
                c
            }
        })
        .collect();
    for iteration in 0..s.iterations {
        let p = s.params(camera, w, h, iteration);
        let input = &colour;
        let next: Vec<V3> = (0..n)
            .into_par_iter()
            .map(|i| {
                let gc = &guides[i];
                let cc = input[i];
                if !gc.surface {
                    return cc;
                }
                let step = p.step;
                let inv_c = inv_sq(p.sigma_color * 2f32.powi(-(iteration as i32)));
                let inv_n = inv_sq(p.sigma_normal);
                let inv_p = inv_sq(p.sigma_position * gc.footprint);
                let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
                let mut sum = [0f32; 3];
                let mut wsum = 0f32;
                for (ky, hy) in B3.iter().enumerate() {
                    let ny = y + (ky as i32 - 2) * step;
                    if ny < 0 || ny >= h as i32 {
                        continue;
                    }
                    for (kx, hx) in B3.iter().enumerate() {
                        let nx = x + (kx as i32 - 2) * step;
                        if nx < 0 || nx >= w as i32 {
                            continue;
                        }
                        let j = (ny as u32 * w + nx as u32) as usize;
                        let gq = &guides[j];
                        if !gq.surface {
                            continue;
                        }
                        let cq = input[j];
                        let e = sum_sq(cc, cq) * inv_c
                            + sum_sq(gc.normal, gq.normal) * inv_n
                            + sum_sq(gc.position, gq.position) * inv_p;
                        let wq = hx * hy * 1f32.min((-e).exp());
                        for c in 0..3 {
                            sum[c] += wq * cq[c];
                        }
                        wsum += wq;
                    }
                }
                sum.map(|v| v / wsum)
            })
            .collect();
        colour = next;
    }
    let pixels = colour
        .par_iter()
        .zip(&b.filter_vectors)
        .map(|(c, f)| {
            if f.depth >= SKY_DEPTH {
                beauty(f)
            } else if s.demodulate {
                let a = albedo_clamped(f);
                std::array::from_fn(|k| c[k] * a[k])
            } else {
                *c
            }
        })
        .collect();
    Ok(RgbImage {
        width: w,
        height: h,
        pixels,
    })
}
