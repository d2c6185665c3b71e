//! AAF indirect light, the sampling side (Wang 2013 ch. 4 with the passes of §3.4): the
//! indirect output ([`crate::layout::outputs::Output::Indirect`]), gathered when a filter asks
//! for it (src/filters/aaf_indirect). kernels/render/indirect.cl runs it on the device,
//! src/render/cpu/indirect.rs is the same code in Rust.
//!
//! The estimator, per pixel. The receiver is the hit of the ray through the pixel centre from
//! the lens centre (a diffuse surface, or with `glossy` a metal; its position, normal, object
//! and pixel size d are what the filter's weights use). Each indirect sample starts at its own
//! random point x_k of the pixel that lies on the receiver's object, leaves in a direction
//! stratified over the receiver's lobe, and follows the path tracer's rules from the first
//! bounce on, counting only what the path tracer counts as indirect (kernels/render/
//! indirect.cl `indirect_radiance`). The first bounce's hit distance gives z_min and z_max
//! (the maximum reflector distance: the seed's z_max is undefined).
//!
//! Two lobes, one output (the seed's §4.3 keeps "separate buffers for the diffuse and specular
//! components"; here a pixel's centre receiver is diffuse or metal, never both, so one
//! per-pixel record with its `lobe` and its Ω_h^max holds either, and the filter keeps the
//! lobes apart):
//! - **Diffuse**: cosine-weighted hemisphere samples, so the Lambertian estimate is
//!   albedo · L_i: Σ L_i / n is the albedo-demodulated indirect light (irradiance / π) and
//!   Σ albedo(x_k) / n the albedo that multiplies it back (§2.3 of the digest: filter
//!   irradiance, not L_on). Ω_h^max = 2.8 (eq. 4.5).
//! - **Glossy** (a metal: the normalised Phong lobe of exponent m around the mirror
//!   direction, kernels/render/materials.cl): the lobe is sampled exactly as the megakernel
//!   samples it, so f cos / pdf is the metal's colour and Σ L_i / n the colour-demodulated
//!   glossy indirect light; Ω_h^max = 3.6 + 0.084 m (eq. 4.5, m taken as the seed's
//!   Blinn-Phong exponent: our lobe is Phong's, around the mirror direction). The mirror
//!   direction is that of the camera ray through each sample's point x_k, so the estimate is
//!   for the view through the pixel. The glossy integrand depends on the outgoing direction;
//!   the seed still filters it in image space (over the receiver's tangent plane) with the
//!   wider bandlimit, i.e. a narrower β = 2 z_min / Ω, and so do we. Across β the view
//!   direction turns by about β / t (t the camera distance) and the mirror direction by up to
//!   twice that, 4 z_min / (Ω t); the lobe's half width is about 1.18 / √m. On
//!   cornell_glossy (t ≈ 3.4 m, z_min up to about 1 m, and the filter's window of 20 pixels
//!   at 256² is about 0.2 m, turning the mirror by at most 0.12 rad) that is below the gold's
//!   half width (m = 400: 0.03 against 0.06 rad) and about the aluminium's (m = 50: 0.12
//!   against 0.17 rad): moderately specular receivers, as the seed assumes, are where this
//!   holds; a near-mirror metal far from its reflectors would be blurred across views.
//!
//! The passes run once, before the first path samples ([`super::Renderer::render_samples`]):
//! 1. `indirect_sparse`: sparse_spp = k² samples per pixel, one per stratum, with z_min, z_max.
//! 2. `indirect_adaptive`: n(x) of eq. 4.6 with the pixel's Ω, clamped to [sparse_spp,
//!    max_spp]; the samples beyond the sparse ones as one more square of strata (the shadow
//!    passes' plan, [`super::shadows::bandlimit::adaptive_plan`]). A receiver whose sparse
//!    samples met no reflector (every ray left to the sky) has no z and keeps its sparse
//!    samples.
//!
//! Without `glossy` a metal receiver is no receiver: its indirect light stays as the path
//! tracer rendered it. Other non-diffuse surfaces (mirrors, glass) are never receivers. The
//! firefly clamp (`sample_clamp`) does not apply to these samples.

pub mod bandlimit;

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel, Program};

use super::DeviceScene;
use crate::gpu::{Gpu, enqueue, event_duration};
use crate::layout::IndirectPixel;

/// How the indirect output is sampled (the `aaf-indirect` filter's settings choose it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndirectSampling {
    /// Indirect samples per pixel of the sparse pass: a square, k × k strata.
    pub sparse_spp: u32,
    /// Most samples per pixel after the adaptive pass (eq. 4.6 is clamped to it).
    pub max_spp: u32,
    /// Ω_h^max of a diffuse receiver (eq. 4.5: 2.8); a metal's is 3.6 + 0.084 m.
    pub bandlimit: f32,
    /// Metal receivers are sampled too (their glossy lobe); off: only diffuse receivers.
    pub glossy: bool,
}

impl Default for IndirectSampling {
    fn default() -> Self {
        IndirectSampling {
            sparse_spp: 16,
            max_spp: 100,
            bandlimit: bandlimit::DIFFUSE_BANDLIMIT,
            glossy: true,
        }
    }
}

impl IndirectSampling {
    /// Checks the counts: the sparse count is a positive square, the maximum at least it.
    pub fn check(&self) -> Result<()> {
        let k = super::shadows::bandlimit::isqrt_floor(self.sparse_spp);
        if self.sparse_spp == 0 || k * k != self.sparse_spp {
            bail!(
                "the sparse indirect pass takes whole strata: sparse_spp must be a square \
                 (1, 4, 9, 16, ...), got {}",
                self.sparse_spp
            );
        }
        if self.max_spp < self.sparse_spp || self.max_spp > 1 << 20 {
            bail!(
                "max_spp must be at least sparse_spp ({}) and at most 2^20, got {}",
                self.sparse_spp,
                self.max_spp
            );
        }
        if !(self.bandlimit > 0.0 && self.bandlimit.is_finite()) {
            bail!(
                "the bandlimit must be > 0 and finite, got {}",
                self.bandlimit
            );
        }
        Ok(())
    }
}

/// The indirect output needs the whole image: its passes trace every pixel's centre receiver
/// before the path samples (sample ranges are fine: the passes depend on the pixel alone).
pub(super) fn check_whole(
    sampling: &IndirectSampling,
    tile: super::Tile,
    w: u32,
    h: u32,
) -> Result<()> {
    sampling.check()?;
    if tile != super::Tile::whole(w, h) {
        bail!(
            "the indirect output (the aaf-indirect filter) needs the whole image, not a tile: \
             its filter reaches across tile borders; render sample ranges (--samples A..B) \
             instead of tiles"
        );
    }
    Ok(())
}

/// What the indirect passes spent (the shadow passes' statistics: Σn / N² over the image,
/// pixels that are no receiver counting with 0, and over the receivers).
pub type IndirectStats = super::ShadowStats;

/// Σn / N² and the rest of [`IndirectStats`] from the indirect pixels.
pub fn indirect_stats(pixels: &[IndirectPixel], rays: u64, kernel_time: Duration) -> IndirectStats {
    super::shadows::pass_stats(
        pixels.iter().map(|p| (p.samples, p.weight > 0.0)),
        rays,
        kernel_time,
    )
}

/// The indirect passes of one renderer, built from its program.
pub(super) struct IndirectPasses {
    sampling: IndirectSampling,
    sparse: Kernel,
    adaptive: Kernel,
    rays: Buffer<u32>,
}

impl IndirectPasses {
    pub(super) fn new(
        gpu: &Arc<Gpu>,
        program: &Program,
        size: [usize; 2],
        sampling: IndirectSampling,
        scene: &DeviceScene,
        debug_counters: &Buffer<u32>,
        pixels: &Buffer<u8>,
    ) -> Result<IndirectPasses> {
        sampling.check()?;
        let rays = gpu.zeroed::<u32>(size[0] * size[1], "indirect ray count")?;
        let build = |name: &str| {
            let mut b = Kernel::builder();
            b.program(program)
                .name(name)
                .queue(gpu.queue.clone())
                .global_work_size(size);
            scene.bind(&mut b, debug_counters);
            b.arg_named("indirect_pixels", pixels)
                .arg_named("indirect_rays", &rays);
            b
        };
        let k = super::shadows::bandlimit::isqrt_floor(sampling.sparse_spp);
        let mut b = build("indirect_sparse");
        b.arg_named("sqrt_spp", k)
            .arg_named("glossy", sampling.glossy as u32)
            .arg_named("bandlimit", sampling.bandlimit);
        let sparse = b.build().context("creating the sparse indirect kernel")?;
        let mut b = build("indirect_adaptive");
        b.arg_named("sparse_spp", sampling.sparse_spp)
            .arg_named("max_spp", sampling.max_spp);
        let adaptive = b.build().context("creating the adaptive indirect kernel")?;
        Ok(IndirectPasses {
            sampling,
            sparse,
            adaptive,
            rays,
        })
    }

    pub(super) fn sampling(&self) -> IndirectSampling {
        self.sampling
    }

    /// Runs the sparse and the adaptive pass; returns their rays and kernel time.
    pub(super) fn run(&self) -> Result<(u64, Duration)> {
        let (mut rays, mut time) = (0u64, Duration::ZERO);
        let mut counts = vec![0u32; self.rays.len()];
        for (k, what) in [
            (&self.sparse, "the sparse indirect pass"),
            (&self.adaptive, "the adaptive indirect pass"),
        ] {
            // SAFETY: every buffer argument is owned by the renderer or by self and sized for
            // the image; we wait for the event before the next launch.
            let event = unsafe { enqueue(k, what)? };
            time += event_duration(&event)?;
            self.rays.read(&mut counts).enq()?;
            rays += counts.iter().map(|&c| c as u64).sum::<u64>();
        }
        Ok((rays, time))
    }
}
