//! Axis-aligned filtering of indirect light, diffuse and glossy (B. Wang, "A Fast Filter for
//! Physically-Based Rendering", UCB 2013, ch. 4, after Mehta, Wang, Ramamoorthi, Durand 2013;
//! digest shared/notes/seeds-aaf-sheared.md §2): settings here, the OpenCL kernels of
//! kernels/filters/aaf_indirect.cl in `device.rs`, their plain Rust reference in
//! `reference.rs`. The sampling side (sparse and adaptive indirect passes, z_min, z_max) is the
//! renderer's indirect output, src/render/indirect; β and n are in src/render/indirect/
//! bandlimit.rs; the two 1-D passes are the soft-shadow filter's (src/filters/aaf_pass).
//!
//! The filter (eqs. 4.2-4.4, "does not change from section 3.3"): the demodulated indirect
//! light L = Σ L_i / n of each receiver is filtered by two normalised Gaussian 1-D passes
//! (rows, then columns) with β(x) of eq. 4.4, multiplied by the receiver's mean albedo, and
//! added to the path tracer's direct light: final = F.direct + albedo · filtered L. What the
//! seed leaves open, and what is done:
//!
//! - **Demodulation.** The seed filters L_on (BRDF included); we filter irradiance / π and
//!   multiply the albedo back (the digest's ADAPT), so textures stay sharp.
//! - **Distances** are world distances in the receiver's tangent plane (as the authors' code
//!   projects them; the seed says "world space"), with the shadow filter's rejections: normals
//!   within `normal_angle`, offsets along the normal at most `depth_tolerance` · β, and
//!   |β − β′| ≤ `beta_tolerance` · max(β, β′) (inf by default: eq. 4.4's β follows z_min,
//!   which jumps between neighbours near contacts, and no value is given in the seed).
//! - **β's floor**: eq. 4.4's d / 0.15 forces β ≥ 6.7 pixel footprints everywhere, so that
//!   near contacts (small z_min) the filter is wider than the bandlimit asks. It is the
//!   `footprints` setting, 1 by default (measured: see the setting). Where z_min is large,
//!   2 z_min / Ω exceeds the window (radius 20 px at 256² is about 0.2 m in the Cornell box,
//!   2 z_min / 2.8 is 0.36 m at z_min = 0.5 m): the window truncates the Gaussian there, as
//!   the authors' code truncates at 2 z_min / (μ Ω d) pixels; radius 40 measured the same
//!   relMSE (0.00378 against 0.00374) at twice the time.
//! - **Glossy indirect light** (§4.3: "separate buffers for the diffuse and specular
//!   components ... filtered separately"; `glossy`): a metal receiver (a normalised Phong
//!   lobe of exponent m) has its own estimate, its lobe's samples demodulated by the metal's
//!   colour (src/render/indirect), filtered with its own Ω = 3.6 + 0.084 m (eq. 4.5) in β
//!   and n, and multiplied by the colour: final = F.direct + colour · filtered glossy L. A
//!   pixel's centre receiver is one or the other, so the two "buffers" are one per-pixel
//!   record with a lobe; one run of the two 1-D passes filters both, a neighbour of the other
//!   lobe being rejected (the pass's `group`): exactly the two separate runs, each with the
//!   other lobe's pixels lending nothing (tests/aaf_indirect_glossy.rs), at the cost of one.
//!   The glossy integrand depends on the outgoing direction; like the seed we filter it in
//!   image space with the wider bandlimit (src/render/indirect says why that holds for
//!   moderate exponents). Off: a metal receiver's indirect light stays as the path tracer
//!   rendered it, bit for bit today's filter.
//! - **Pixels**: no receiver (sky, a mirror or glass surface, a metal without `glossy`, an
//!   emitter) keeps F as rendered; a receiver whose sparse samples met no reflector (z
//!   undefined) keeps its own L and lends it; the rest are filtered.
//! - **Silhouettes**: the indirect samples lie on the centre's object; a pixel whose other
//!   part shows another surface gets the centre surface's indirect light over all of it.
//! - **A thin lens**: the receiver is the lens-centre ray's hit, as for the shadow filter.

mod device;
mod reference;

use std::sync::Arc;

use anyhow::{Result, bail};

use super::aaf_pass::PassParams;
use super::settings::Auto;
use super::{FilterKind, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::AafIndirectParams;
use crate::layout::outputs::{Output, OutputSet};
use crate::render::indirect::bandlimit::DIFFUSE_BANDLIMIT;
use crate::render::{FrameInfo, IndirectSampling, RenderOptions, SceneInfo};
pub use device::AafIndirectKernel;
pub use reference::{compose, prepare, reference};

crate::filter_settings! {
    /// The AAF indirect filter's settings: how the indirect output is sampled, and how it is
    /// filtered.
    pub struct AafIndirectSettings, flags "aafi-" {
        /// Indirect samples per pixel of the sparse pass: a square (whole strata).
        pub sparse_spp: u32 = 16,
        /// Most indirect samples per pixel after the adaptive pass (eq. 4.6 is clamped to
        /// it); equal to sparse_spp: no adaptive sampling.
        pub max_spp: u32 = 100,
        /// Half width of each 1-D filter pass, pixels.
        pub radius: u32 = 20,
        /// β's floor in pixel footprints (eq. 4.4's d / 0.15 is 6.67). Chosen by measurement
        /// (scripts/aaf-indirect-study.sh, cornell_diffuse at 256², 16 path spp, against 2048
        /// spp): relMSE 0.00374 at 1, 0.00390 at 3, 0.00420 at the seed's 6.67 (MSE
        /// 0.002576, 0.002579, 0.002583; the floor acts where z_min is small).
        pub footprints: f32 = 1.0,
        /// Largest angle between the normals of two pixels that share samples, degrees;
        /// 180 or more: no normal test.
        pub normal_angle: f32 = 20.0,
        /// Largest offset between two pixels along the written pixel's normal, in units of
        /// its β; inf: no test.
        pub depth_tolerance: f32 = 0.5,
        /// Largest |β − β′| / max(β, β′) between two filtered pixels; inf: no test.
        pub beta_tolerance: f32 = f32::INFINITY,
        /// Metal receivers' glossy indirect light, sampled and filtered with its own bandlimit
        /// 3.6 + 0.084 m (eq. 4.5); off: it stays as rendered. auto: on when the scene has a
        /// metal surface.
        pub glossy: Auto<bool> = Auto::Auto,
    }
}

impl AafIndirectSettings {
    pub fn validate(&self) -> Result<()> {
        self.sampling().check()?;
        if self.radius > super::aaf_shadows::MAX_RADIUS {
            bail!(
                "radius is at most {} pixels, got {}",
                super::aaf_shadows::MAX_RADIUS,
                self.radius
            );
        }
        for (v, name) in [
            (self.footprints, "footprints"),
            (self.normal_angle, "normal_angle"),
            (self.depth_tolerance, "depth_tolerance"),
            (self.beta_tolerance, "beta_tolerance"),
        ] {
            if !(v >= 0.0) {
                bail!("{name} must be >= 0 (inf: no test), got {v}");
            }
        }
        if !self.footprints.is_finite() {
            bail!("footprints must be finite, got {}", self.footprints);
        }
        Ok(())
    }

    /// Whether metal receivers are sampled and filtered. `auto` left as is counts as on: in a
    /// scene without metal that is exactly off (no pixel has a glossy receiver).
    pub fn glossy(&self) -> bool {
        self.glossy.or(true)
    }

    /// How the renderer samples the indirect output for these settings.
    pub fn sampling(&self) -> IndirectSampling {
        IndirectSampling {
            sparse_spp: self.sparse_spp,
            max_spp: self.max_spp,
            bandlimit: DIFFUSE_BANDLIMIT,
            glossy: self.glossy(),
        }
    }

    fn normal_cos(&self) -> f32 {
        if self.normal_angle >= 180.0 {
            -2.0
        } else {
            self.normal_angle.to_radians().cos()
        }
    }

    /// The prepare and compose kernels' parameters for a w × h image.
    pub fn params(&self, width: u32, height: u32) -> AafIndirectParams {
        AafIndirectParams {
            width,
            height,
            radius: self.radius as i32,
            axis: 0,
            glossy: self.glossy() as u32,
            footprints: self.footprints,
            normal_cos: self.normal_cos(),
            depth_tolerance: self.depth_tolerance,
        }
    }

    /// The shared 1-D passes' parameters.
    pub fn pass_params(&self, width: u32, height: u32) -> PassParams {
        PassParams {
            width,
            height,
            radius: self.radius as i32,
            axis: 0,
            normal_cos: self.normal_cos(),
            depth_tolerance: self.depth_tolerance,
            beta_tolerance: self.beta_tolerance,
        }
    }
}

/// The AAF indirect filter in the registry.
pub struct AafIndirect;

impl FilterKind for AafIndirect {
    type Settings = AafIndirectSettings;
    const NAME: &'static str = "aaf-indirect";
    const SUMMARY: &'static str = "axis-aligned filtering of diffuse and glossy indirect light, \
         with adaptive indirect sampling (Wang 2013 ch. 4; on the device)";

    fn check(s: &AafIndirectSettings) -> Result<()> {
        s.validate()
    }

    /// `glossy = auto` becomes on when the scene has a metal surface.
    fn specialise(s: &mut AafIndirectSettings, scene: &SceneInfo) -> Vec<String> {
        let mut notes = Vec::new();
        if s.glossy.is_auto() {
            let metal = scene.has("HAS_METAL");
            s.glossy = Auto::Set(metal);
            notes.push(format!(
                "glossy = {metal}: {}",
                if metal {
                    "the scene has metal surfaces, whose glossy indirect light is filtered \
                     with Ω = 3.6 + 0.084 m"
                } else {
                    "no metal surface, no glossy receiver"
                }
            ));
        }
        notes
    }

    /// Wherever paths go past their first surface (a direct-light-only scene has no indirect
    /// light to filter).
    fn applies(_: &AafIndirectSettings, scene: &SceneInfo) -> bool {
        scene.indirect
    }

    fn needs(_: &AafIndirectSettings) -> OutputSet {
        OutputSet::of(&[Output::Colour, Output::Indirect])
    }

    fn render_options(s: &AafIndirectSettings, options: &mut RenderOptions) {
        options.indirect = s.sampling();
    }

    fn prepare(
        s: &AafIndirectSettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        Ok(Box::new(AafIndirectKernel::new(
            gpu.clone(),
            s,
            frame.width,
            frame.height,
        )?))
    }
}
