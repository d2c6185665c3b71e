//! Axis-aligned filtering of soft shadows (B. Wang, "A Fast Filter for Physically-Based
//! Rendering", UCB 2013, ch. 3, after Mehta, Wang, Ramamoorthi 2012): settings here, the
//! OpenCL passes of kernels/filters/aaf_shadows.cl in `device.rs`, their plain Rust reference
//! in `reference.rs`. The sampling side (sparse pass, slope fill, adaptive pass) is the
//! renderer's shadow output, src/render/shadows; the formulas of β and n are in
//! src/render/shadows/bandlimit.rs.
//!
//! The filter (eqs. 3.2, 3.3, 3.7): h(x) = r(x) Σ w h_n / Σ w, w = exp(−‖x − x′‖² / (2β(x)²)),
//! as two 1-D passes (rows, then columns of the first pass's result), each with β of the pixel
//! being written (the per-pass lines of eq. 3.7, not its first line's β(x′)). Normalised
//! means, so the Gaussian's prefactor cancels. What the seed leaves open, and what is done:
//!
//! - **Distances** are in world space, "along the plane parallel to the light": for a sphere
//!   light, the plane of its silhouette disk, perpendicular to the direction ℓ̂ from the
//!   centre pixel's hit to the light's centre: ‖Δ‖² − (Δ·ℓ̂)².
//! - **Rejection** ("a threshold on the acceptable difference in β values", no value given):
//!   a neighbour counts when it is a receiver, its normal is within `normal_angle` of the
//!   pixel's, its offset along ℓ̂ is at most `depth_tolerance` · β (the weight ignores that
//!   offset, so without it a wall's pixels along the light direction would all weigh 1), and,
//!   when it has slopes, |β − β′| ≤ `beta_tolerance` · max(β, β′). Relative forms, so that the
//!   filter does not depend on the scene's scale (the authors' code uses scene-unit constants).
//!   The defaults were chosen by measurement (tests/aaf_quality.rs `measure_rejection_
//!   thresholds`, run by hand): on Grids and on spheres under a grid, 320 × 240, against 1024
//!   spp, the 80 combinations of 10°/20°/45°/180°, 0.5/1/2/3/∞ and 0.25/0.5/1/∞ span RMS
//!   0.01476-0.01571 and 0.00690-0.00710; the defaults (20°, 2, 0.5) give 0.01485 and
//!   0.00690, within 0.6% of the best on each; no offset test is the worst on both.
//! - **Pixels** are of three kinds: no receiver (sky, a non-diffuse surface, the light below
//!   the horizon) keep F as rendered; a receiver without slopes (no occluded sample, none
//!   filled in) keeps its own visibility, which is 1 (every sample reached the light), and
//!   lends it to its neighbours; a receiver with slopes is filtered.
//! - **Output** = F − (the light the path samples on the centre's surface brought to it
//!   straight from this light) + r · filtered h_n, where r is the mean of the unshadowed term
//!   over the light samples' points in the pixel (src/render/shadows): silhouettes and
//!   textures stay anti-aliased. Everything that is not the filtered term (other lights,
//!   indirect light, emission, glossy surfaces, another surface in the same pixel) stays as
//!   rendered.
//! - **Every sphere light, one at a time** (§3.4 filters one light; our scenes have several):
//!   `light = auto` filters the scene's first `light_count` sphere lights (all of them, at
//!   most [`crate::layout::outputs::MAX_SHADOW_PLANES`]), a number filters that light alone (the others' shadows stay
//!   as rendered), -1 none. Each light has its own plane of the shadow output
//!   (src/render/shadows: its own sparse pass, slope fill, slopes s1/s2 and adaptive pass, so
//!   n_l(x) is eq. 3.5 for that light's slopes and size, clamped to [sparse_spp, max_spp]
//!   alone; a pixel spends Σ_l n_l) and its own β (its σ), prepare, two 1-D passes and
//!   compose: the output is F − Σ_l direct_l + Σ_l r_l · filtered h_l, composed a light at a
//!   time in increasing light order. With one sphere light this is the one-light filter, byte
//!   for byte.
//! - **A thin lens**: the shadow samples use the ray through the pixel centre from the lens
//!   centre (src/render/shadows), so the filtered term is in focus everywhere: out of focus
//!   that is wrong (toasters_dof, 512², 8 spp: MSE-LUV 59.1 against 21.9 unfiltered), and
//!   `render`/`filter` print a warning naming the sheared filter's "dof-shadows", which
//!   filters the lens too.

mod device;
mod reference;

use std::sync::Arc;

use anyhow::{Result, bail};

use super::aaf_pass::PassParams;
use super::shadow_lights::{
    check_lights, chosen_lights, light_needs, light_planes, lights_of, specialise_lights,
};
use super::{Auto, FilterKind, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::OutputSet;
use crate::layout::{AafShadowParams, Float4};
use crate::render::shadows::bandlimit::light_sigma;
use crate::render::{FrameInfo, RenderOptions, SceneInfo, ShadowSampling};
pub use device::AafShadowKernel;
pub(crate) use device::compose_kernel;
pub use reference::{compose, compose_over, prepare, reference};

crate::filter_settings! {
    /// The AAF soft-shadow filter's settings: how the shadow output is sampled, and how it is
    /// filtered.
    pub struct AafShadowSettings, flags "aaf-" {
        /// The sphere light whose shadows are filtered, counting from 0 in the scene's order;
        /// auto: every sphere light (the first `light_count`), each filtered on its own, or
        /// none when the scene has no sphere light (the image passes through); -1: none.
        pub light: Auto<i32> = Auto::Auto,
        /// With light = auto: how many sphere lights are filtered, the scene's first ones
        /// (0: all of them; at most 8, the shadow output's planes).
        pub light_count: u32 = 0,
        /// Light samples per pixel of the sparse pass: a square (whole strata).
        pub sparse_spp: u32 = 9,
        /// Most light samples per pixel after the adaptive pass (eq. 3.5 is clamped to it);
        /// equal to sparse_spp: no adaptive sampling.
        pub max_spp: u32 = 100,
        /// Half width of each 1-D filter pass, pixels.
        pub radius: u32 = 10,
        /// Half width of the slope fill, pixels.
        pub fill_radius: u32 = 10,
        /// Largest angle between the normals of two pixels that share samples, degrees;
        /// 180 or more: no normal test.
        pub normal_angle: f32 = 20.0,
        /// Largest offset between two pixels along the direction to the light, in units of
        /// the written pixel's β; inf: no test.
        pub depth_tolerance: f32 = 2.0,
        /// Largest |β − β′| / max(β, β′) between two pixels with slopes; inf: no test.
        pub beta_tolerance: f32 = 0.5,
    }
}

/// Most pixels a 1-D pass reaches on either side.
pub const MAX_RADIUS: u32 = 1024;

impl AafShadowSettings {
    pub fn validate(&self) -> Result<()> {
        check_lights(self.light, self.light_count, "filtered")?;
        self.sampling().check()?;
        for (v, name) in [(self.radius, "radius"), (self.fill_radius, "fill_radius")] {
            if v > MAX_RADIUS {
                bail!("{name} is at most {MAX_RADIUS} pixels, got {v}");
            }
        }
        for (v, name) in [
            (self.normal_angle, "normal_angle"),
            (self.depth_tolerance, "depth_tolerance"),
            (self.beta_tolerance, "beta_tolerance"),
        ] {
            if !(v >= 0.0) {
                bail!("{name} must be >= 0 (inf: no test), got {v}");
            }
        }
        Ok(())
    }

    /// The sphere lights filtered, in increasing order: `light` alone when set (none for -1),
    /// else the first `light_count` (after specialisation the scene's count; before it, 0
    /// counts as the first light alone).
    pub fn filtered_lights(&self) -> Vec<u32> {
        chosen_lights(self.light, self.light_count)
    }

    /// The filtered lights with their centre and radius in `scene`; an error naming the
    /// light when the scene lacks one.
    pub fn lights_of(&self, scene: &SceneInfo) -> Result<Vec<(u32, [f32; 4])>> {
        lights_of(AafShadows::NAME, &self.filtered_lights(), scene)
    }

    /// How the renderer samples the shadow output for these settings: a plane per filtered
    /// light, each with its own sparse and adaptive passes.
    pub fn sampling(&self) -> ShadowSampling {
        ShadowSampling {
            lights: light_planes(&self.filtered_lights()),
            sparse_spp: self.sparse_spp,
            max_spp: self.max_spp,
            fill_radius: self.fill_radius,
            ..ShadowSampling::default()
        }
    }

    /// The shared 1-D passes' parameters (src/filters/aaf_pass) for a w × h image.
    pub fn pass_params(&self, width: u32, height: u32) -> PassParams {
        let p = self.params([0.0; 4], width, height, 0);
        PassParams {
            width,
            height,
            radius: p.radius,
            axis: 0,
            normal_cos: p.normal_cos,
            depth_tolerance: p.depth_tolerance,
            beta_tolerance: p.beta_tolerance,
        }
    }

    /// The parameters of pass `axis` (0 rows, 1 columns; also prepare and compose) for the
    /// light `light` (centre, radius) and a w × h image.
    pub fn params(&self, light: [f32; 4], width: u32, height: u32, axis: u32) -> AafShadowParams {
        let normal_cos = if self.normal_angle >= 180.0 {
            -2.0
        } else {
            self.normal_angle.to_radians().cos()
        };
        AafShadowParams {
            light: Float4(light),
            width,
            height,
            radius: self.radius as i32,
            axis,
            sigma: light_sigma(light[3]),
            normal_cos,
            depth_tolerance: self.depth_tolerance,
            beta_tolerance: self.beta_tolerance,
        }
    }
}

/// The AAF soft-shadow filter in the registry.
pub struct AafShadows;

impl FilterKind for AafShadows {
    type Settings = AafShadowSettings;
    const NAME: &'static str = "aaf-shadows";
    const SUMMARY: &'static str = "axis-aligned filtering of every sphere light's soft \
         shadows, a light at a time, with adaptive light sampling (Wang 2013 ch. 3; on the \
         device)";

    fn check(s: &AafShadowSettings) -> Result<()> {
        s.validate()
    }

    /// `light = auto` becomes the scene's first `light_count` sphere lights (all of them, at
    /// most [`crate::layout::outputs::MAX_SHADOW_PLANES`]), or none when the scene has none; a set `light` is
    /// checked against the scene.
    fn specialise(s: &mut AafShadowSettings, scene: &SceneInfo) -> Vec<String> {
        let mut notes = specialise_lights(
            &mut s.light,
            &mut s.light_count,
            scene,
            "filtered",
            "each with its own sparse and adaptive passes, slopes and 1-D passes",
        );
        let lens = scene.camera.lens_radius;
        if lens > 0.0 && !s.filtered_lights().is_empty() {
            // Measured on toasters_dof (512², 8 spp, the quality study): MSE-LUV 59.1 against
            // 21.9 unfiltered; the sheared filter's "dof-shadows" 4.59.
            notes.push(format!(
                "warning: aaf-shadows on a thin lens (radius {lens}): the filtered shadow is                  the lens-centre receiver's, in focus everywhere (Wang 2013 has no depth of                  field), so defocused pixels get a sharp shadow; --filter sheared filters the                  shadows and the lens together (effect \"dof-shadows\")"
            ));
        }
        notes
    }

    fn applies(s: &AafShadowSettings, _scene: &SceneInfo) -> bool {
        !s.filtered_lights().is_empty()
    }

    /// The shadow output, when there is a light to filter.
    fn needs(s: &AafShadowSettings) -> OutputSet {
        light_needs(s.light)
    }

    fn render_options(s: &AafShadowSettings, options: &mut RenderOptions) {
        options.shadows = s.sampling();
    }

    fn prepare(
        s: &AafShadowSettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        Ok(Box::new(AafShadowKernel::new(
            gpu.clone(),
            s,
            &s.lights_of(&frame.scene)?,
            frame.width,
            frame.height,
        )?))
    }
}
