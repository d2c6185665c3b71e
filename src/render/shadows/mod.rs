//! AAF soft shadows, the sampling side (Wang 2013 ch. 3 §3.4, passes 1 and 2): the shadow
//! output ([`crate::layout::outputs::Output::Shadows`]) of one sphere light, gathered when a
//! filter asks for it (src/filters/aaf_shadows).
//!
//! The estimator, per pixel. The pixel's receiver is the hit of the ray through its centre
//! (a diffuse surface; its position, normal, object and pixel size d are what the filter's
//! weights use). The passes here trace light samples, each from its own random point x_k of
//! the pixel that lies on the receiver's object, in directions stratified over the light's cone
//! (uniform in solid angle, as the path tracer samples it), each weighted by l = cos θ at x_k:
//! h_n = Σ f·l / Σ l (eq. 3.2) is the cos-weighted visible fraction of the light, and
//! r = Σ_k r(x_k) / n, with r(x) = albedo · L sin²α cos θ_c (eq. 3.1: the light's unshadowed
//! direct term from its centre, exact while the cone lies above the horizon), so that r · h_n
//! is the light's shadowed direct term over the part of the pixel the receiver covers. The
//! megakernel folds into `ShadowTerms` the light its path samples brought straight from this
//! light to their first surface when that is the receiver's object (the next-event estimate,
//! or the light's emission found by the first bounce without light sampling). The filter
//! writes F − that + r · filtered h_n: everything else, including the rest of a pixel at a
//! silhouette, stays as the path tracer rendered it.
//!
//! The passes run once, before the first path samples ([`super::Renderer::render_samples`]):
//! 1. `shadow_sparse`: sparse_spp = k² samples (one per stratum) per pixel, with the nearest and
//!    farthest occluder of every shadow ray, giving the slopes s1, s2.
//! 2. `shadow_fill` (twice): pixels without an occluded sample take the max s1 / min s2 of the
//!    pixels within ±fill_radius along the row, then the column, on the same object (the
//!    authors' code; the seed does not say what a pixel without occluder gets).
//! 3. `shadow_adaptive`: n(x) of eq. 3.5 clamped to [sparse_spp, max_spp]; the samples beyond
//!    the sparse ones as one more square of strata ([`bandlimit::adaptive_plan`]).
//!
//! One point per pixel: the ray through the pixel centre from the lens centre. With a thin
//! lens the path tracer's rays start anywhere on the lens and a pixel has no single world
//! point, which the world-space weights need; the lens-centre ray is the documented
//! approximation (the shadowed term is then sharp where the rest is out of focus).

pub mod bandlimit;
pub mod light_field;

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel, Program};

use super::DeviceScene;
use crate::gpu::{Gpu, enqueue, event_duration};
use crate::layout::outputs::MAX_SHADOW_PLANES;
use crate::layout::{Float4, ShadowPixel};

/// The sphere lights of the shadow output, one plane each, by their place among the scene's
/// sphere lights (which lead the light list, so it is also their light index): a set, held as
/// a bit mask, whose planes are in increasing light order (plane p holds the p-th light of the
/// set). Simulate only what the scene calls for: each shadow filter asks for the lights it
/// filters (src/filters/shadow_lights.rs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LightPlanes(pub u32);

impl LightPlanes {
    /// The one light `l` (l < 32).
    pub fn one(l: u32) -> LightPlanes {
        LightPlanes(1u32.checked_shl(l).unwrap_or(0))
    }

    /// These lights (each < 32).
    pub fn of(lights: &[u32]) -> LightPlanes {
        LightPlanes(lights.iter().fold(0, |m, &l| m | LightPlanes::one(l).0))
    }

    /// The lights, in plane order.
    pub fn lights(self) -> Vec<u32> {
        (0..32).filter(|l| self.0 >> l & 1 == 1).collect()
    }

    pub fn count(self) -> u32 {
        self.0.count_ones()
    }

    /// The first plane's light.
    pub fn first(self) -> u32 {
        self.0.trailing_zeros().min(31)
    }

    /// The plane holding light `l`, if the set has it.
    pub fn plane_of(self, l: u32) -> Option<u32> {
        (l < 32 && self.0 >> l & 1 == 1).then(|| (self.0 & ((1u32 << l) - 1)).count_ones())
    }
}

/// How the shadow output is sampled (the shadow filters' settings choose it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadowSampling {
    /// The sphere lights, one plane each (kernels/render/shadows.cl runs the passes once per
    /// plane; the megakernel folds each light's direct term into its plane).
    pub lights: LightPlanes,
    /// Samples per pixel of the sparse pass: a square, k × k strata.
    pub sparse_spp: u32,
    /// Largest samples per pixel after the adaptive pass (eq. 3.5 is clamped to it).
    pub max_spp: u32,
    /// Half width of the slope fill, pixels.
    pub fill_radius: u32,
    /// Side l of the light-field grid of sheared filtering (with
    /// [`crate::layout::outputs::Output::LightField`]; 1..=4; 3 by default, Yan et al.'s
    /// 9 spp, so that a render gathering every filter's outputs without their sampling
    /// choices still has one).
    pub light_field: u32,
    /// With the light-field output and no shadow output: sample diffuse indirect light over
    /// the v-plane (kernels/render/gi_field.cl, the sheared filter's GI) instead of the lens
    /// (kernels/render/lens_field.cl, its depth of field).
    pub light_field_gi: bool,
}

impl Default for ShadowSampling {
    fn default() -> Self {
        ShadowSampling {
            lights: LightPlanes::one(0),
            sparse_spp: 9,
            max_spp: 100,
            fill_radius: 10,
            light_field: 3,
            light_field_gi: false,
        }
    }
}

impl ShadowSampling {
    /// Checks the counts: the sparse count is a positive square, the maximum at least it;
    /// one to [`MAX_SHADOW_PLANES`] light planes.
    pub fn check(&self) -> Result<()> {
        let planes = self.lights.count();
        if planes == 0 || planes > MAX_SHADOW_PLANES {
            bail!(
                "the shadow output holds 1 to {MAX_SHADOW_PLANES} sphere lights (one plane each, \
                 a private term of every path sample), got {planes}: stylize fewer lights"
            );
        }
        let k = bandlimit::isqrt_floor(self.sparse_spp);
        if self.sparse_spp == 0 || k * k != self.sparse_spp {
            bail!(
                "the sparse shadow pass takes whole strata: sparse_spp must be a square \
                 (1, 4, 9, 16, ...), got {}",
                self.sparse_spp
            );
        }
        if self.max_spp < self.sparse_spp {
            bail!(
                "max_spp ({}) must be at least sparse_spp ({})",
                self.max_spp,
                self.sparse_spp
            );
        }
        if self.light_field > light_field::MAX_SIDE {
            bail!(
                "the light-field grid of sheared filtering is l x l with l <= {} (Yan et al. \
                 2015 §3.1; l² samples per pixel are kept), got l = {}",
                light_field::MAX_SIDE,
                self.light_field
            );
        }
        if self.max_spp > 1 << 20 {
            bail!("max_spp is at most 2^20, got {}", self.max_spp);
        }
        Ok(())
    }
}

/// The lights the shadow output samples, checked against the scene (sphere lights lead the
/// light list) and the render: the passes work on the whole image (the slope fill reaches
/// `fill_radius` pixels across), so a tile is refused rather than filtered differently from
/// the whole render. Sample ranges are fine: the passes depend on the pixel alone, so every
/// range's part holds the same shadow pixels ([`crate::layout::outputs::Merge::Identical`]).
pub(super) fn shadow_light(
    arrays: &crate::arrays::SceneArrays,
    sampling: &ShadowSampling,
    tile: super::Tile,
    frame: &crate::arrays::FrameSettings,
) -> Result<LightPlanes> {
    sampling.check()?;
    if tile != super::Tile::whole(frame.width, frame.height) {
        bail!(
            "the shadow output (the aaf-shadows filter) needs the whole image, not a tile: its \
             slope fill reaches across tile borders; render sample ranges (--samples A..B) \
             instead of tiles"
        );
    }
    let spheres = arrays
        .lights
        .iter()
        .take_while(|l| l.kind == crate::layout::LIGHT_SPHERE)
        .count() as u32;
    if let Some(&l) = sampling.lights.lights().iter().find(|&&l| l >= spheres) {
        bail!(
            "the shadow output samples sphere light {l} (counting from 0), but the scene has \
             {spheres} sphere light(s)"
        );
    }
    Ok(sampling.lights)
}

/// What the shadow passes (or AAF's indirect passes, [`super::IndirectStats`]) spent.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShadowStats {
    /// Light samples over every pixel of the image, Σn / N² (pixels that are no receiver
    /// count with 0).
    pub average_spp: f64,
    /// The same over the receivers only.
    pub receiver_spp: f64,
    pub receivers: u64,
    pub max_spp: u32,
    /// Rays of the three passes (camera rays and shadow rays).
    pub rays: u64,
    pub kernel_time: Duration,
}

/// The shadow passes of one renderer, built from its program (kernels/render/shadows.cl):
/// one set per light plane, each writing its plane of the shadow pixels.
pub(super) struct ShadowPasses {
    sampling: ShadowSampling,
    /// Per plane: the sparse pass, the two slope fills, the adaptive pass.
    planes: Vec<[Kernel; 4]>,
    /// Per plane, the light-field pass (sheared filtering, each light in its own frame), when
    /// its output is gathered; else empty.
    light_fields: Vec<Kernel>,
    rays: Buffer<u32>,
    _fill_buffer: Buffer<Float4>,
}

impl ShadowPasses {
    /// The passes over the renderer's scene buffers and its shadow-pixel buffer `pixels`;
    /// with `light_field` (its buffer, and each plane's light's frame e1, e2), the light-field
    /// pass of every plane too.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        gpu: &Arc<Gpu>,
        program: &Program,
        size: [usize; 2],
        sampling: ShadowSampling,
        scene: &DeviceScene,
        debug_counters: &Buffer<u32>,
        pixels: &Buffer<u8>,
        light_field: Option<(&Buffer<u8>, Vec<[Float4; 2]>)>,
    ) -> Result<ShadowPasses> {
        sampling.check()?;
        let n = size[0] * size[1];
        let count = sampling.lights.count();
        let rays = gpu.zeroed::<u32>(n, "shadow ray count")?;
        let fill_buffer = gpu.zeroed::<Float4>(n, "shadow slope fill")?;
        let build = |name: &str, with_scene: bool| -> Result<ocl::builders::KernelBuilder> {
            let mut b = Kernel::builder();
            b.program(program)
                .name(name)
                .queue(gpu.queue.clone())
                .global_work_size(size);
            if with_scene {
                scene.bind(&mut b, debug_counters);
            }
            b.arg_named("shadow_pixels", pixels);
            Ok(b)
        };
        let k = bandlimit::isqrt_floor(sampling.sparse_spp);
        let planes = sampling
            .lights
            .lights()
            .into_iter()
            .enumerate()
            .map(|(plane, light)| -> Result<[Kernel; 4]> {
                let plane = plane as u32;
                let mut b = build("shadow_sparse", true)?;
                b.arg_named("plane", plane)
                    .arg_named("planes", count)
                    .arg_named("shadow_rays", &rays)
                    .arg_named("light", light)
                    .arg_named("sqrt_spp", k);
                let sparse = b.build().context("creating the sparse shadow kernel")?;
                let fill = [0u32, 1].map(|pass| {
                    let mut b = build("shadow_fill", false)?;
                    b.arg_named("plane", plane)
                        .arg_named("planes", count)
                        .arg_named("fill", &fill_buffer)
                        .arg_named("width", size[0] as u32)
                        .arg_named("height", size[1] as u32)
                        .arg_named("radius", sampling.fill_radius as i32)
                        .arg_named("pass", pass);
                    b.build().context("creating the slope fill kernel")
                });
                let [f0, f1] = fill;
                let mut b = build("shadow_adaptive", true)?;
                b.arg_named("plane", plane)
                    .arg_named("planes", count)
                    .arg_named("shadow_rays", &rays)
                    .arg_named("light", light)
                    .arg_named("sparse_spp", sampling.sparse_spp)
                    .arg_named("max_spp", sampling.max_spp);
                let adaptive = b.build().context("creating the adaptive shadow kernel")?;
                Ok([sparse, f0?, f1?, adaptive])
            })
            .collect::<Result<Vec<_>>>()?;
        let light_fields = match light_field {
            Some(_) if sampling.light_field == 0 => bail!(
                "the light-field output needs its grid side (1..={}), got 0",
                light_field::MAX_SIDE
            ),
            Some((buffer, frames)) => sampling
                .lights
                .lights()
                .into_iter()
                .zip(frames)
                .enumerate()
                .map(|(plane, (light, [e1, e2]))| -> Result<Kernel> {
                    let mut b = build("light_field_sample", true)?;
                    b.arg_named("plane", plane as u32)
                        .arg_named("planes", count)
                        .arg_named("light_field", buffer)
                        .arg_named("shadow_rays", &rays)
                        .arg_named("light", light)
                        .arg_named("side", sampling.light_field)
                        .arg_named("frame_u", e1)
                        .arg_named("frame_v", e2);
                    b.build().context("creating the light-field kernel")
                })
                .collect::<Result<Vec<_>>>()?,
            None => Vec::new(),
        };
        Ok(ShadowPasses {
            sampling,
            planes,
            light_fields,
            rays,
            _fill_buffer: fill_buffer,
        })
    }

    pub(super) fn sampling(&self) -> ShadowSampling {
        self.sampling
    }

    /// Runs, per plane, the sparse pass, the light-field pass (if any), the slope fill and the
    /// adaptive pass; returns their rays and kernel time.
    pub(super) fn run(&self) -> Result<(u64, Duration)> {
        let mut rays = 0u64;
        let mut time = Duration::ZERO;
        let mut counts = vec![0u32; self.rays.len()];
        for (plane, [sparse, f0, f1, adaptive]) in self.planes.iter().enumerate() {
            let light_field = self
                .light_fields
                .get(plane)
                .map(|k| (k, "the light-field pass", true));
            for (k, what, traces) in [(sparse, "the sparse shadow pass", true)]
                .into_iter()
                .chain(light_field)
                .chain([
                    (f0, "the slope fill", false),
                    (f1, "the slope fill", false),
                    (adaptive, "the adaptive shadow pass", true),
                ])
            {
                // SAFETY: every buffer argument is owned by the renderer or by self and sized
                // for the image; we wait for the event before the next launch.
                let event = unsafe { enqueue(k, what)? };
                time += event_duration(&event)?;
                if traces {
                    self.rays.read(&mut counts).enq()?;
                    rays += counts.iter().map(|&c| c as u64).sum::<u64>();
                }
            }
        }
        Ok((rays, time))
    }
}

/// Σn / N² and the rest of [`ShadowStats`] from the shadow pixels.
pub fn shadow_stats(pixels: &[ShadowPixel], rays: u64, kernel_time: Duration) -> ShadowStats {
    pass_stats(
        pixels.iter().map(|p| (p.samples, p.weight > 0.0)),
        rays,
        kernel_time,
    )
}

/// The statistics of a sampling pass (this one's, or AAF's indirect passes') from each
/// pixel's (samples, whether it is a receiver).
pub fn pass_stats(
    pixels: impl Iterator<Item = (f32, bool)>,
    rays: u64,
    kernel_time: Duration,
) -> ShadowStats {
    let (mut total, mut count, mut receivers, mut max) = (0f64, 0u64, 0u64, 0u32);
    for (samples, receiver) in pixels {
        total += samples as f64;
        count += 1;
        receivers += receiver as u64;
        max = max.max(samples as u32);
    }
    ShadowStats {
        average_spp: total / count.max(1) as f64,
        receiver_spp: if receivers > 0 {
            total / receivers as f64
        } else {
            0.0
        },
        receivers,
        max_spp: max,
        rays,
        kernel_time,
    }
}
