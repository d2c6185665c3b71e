//! Sheared filtering of soft shadows, depth of field or diffuse indirect light (L.-Q. Yan, S. U. Mehta, R. Ramamoorthi, F. Durand,
//! "Fast 4D Sheared Filtering for Interactive Rendering of Distribution Effects", ACM TOG 2015;
//! seed 002, digest /work/shared/notes/seeds-aaf-sheared.md §3; issue 16), for each sphere
//! light in turn: the eq. 4-5 analysis in `shear.rs`, the OpenCL steps of kernels/filters/sheared.cl
//! in `device.rs`, their plain Rust reference (and eq. 9's brute force) in `reference.rs`. The
//! sampling side is the renderer's light-field output (src/render/shadows/light_field.rs),
//! gathered with AAF's shadow output (receiver, d1, r(x), slopes, slope fill).
//!
//! **The effect is the scene's** (`effect = auto`): a thin lens (lens_radius > 0) gets depth of
//! field (`dof.rs`, `dof_device.rs`, kernels/filters/sheared_dof.cl over the lens field of
//! kernels/render/lens_field.cl); a pinhole camera with sphere lights gets their soft
//! shadows; a pinhole camera without one gets diffuse indirect light (`gi.rs`,
//! kernels/filters/sheared_gi.cl over the GI field of kernels/render/gi_field.cl; the same
//! launches as depth of field, `DofKernel::gi`). A thin lens with sphere lights gets both
//! (`effect = "dof-shadows"`, the seed's appendix, eqs. 16-17, `lens_shadows.rs`): the
//! shadows filtered over the light, put back on each lens sample, then the lens filtered.
//! Refused, with a message naming the alternative: depth of field alone with a chosen light,
//! "dof-shadows" with light = -1, GI with a chosen light (GI filters indirect light only; the
//! shadows stay as path traced) and GI through a thin lens (its receivers are the lens-centre
//! hits; with "dof-shadows" the indirect light rides in the lens samples and is filtered over
//! the lens).
//!
//! What the seed leaves open, and what is done:
//! - **The light** (§3.2: a Gaussian of σ_y over a square of side 4σ_y): our sphere is sampled
//!   on the l × l jittered grid over the square [−R, R]² of one global frame perpendicular to
//!   (scene centre → light centre), every point traced (a neighbour may need it after the
//!   shear), and weighted by a Gaussian w_y. The disk indicator is not separable in (y1, y2),
//!   which steps 1a-2b need; the Gaussian is, so the filtered term is the shadow of a
//!   Gaussian light, not of the uniform disk. σ_y = `light_sigma` · R: 0.5 is the disk's
//!   per-axis standard deviation (digest §3.4, the FAITHFUL option), but over the square the
//!   grid samples, a flatter Gaussian is nearer the uniform disk's penumbra: RMS at l = 3,
//!   256², `bench --study aaf-shadows` (rows `sheared-light-sigma-*`) on Grids / Curved /
//!   two_lights_shadows, 0.02965 /
//!   0.01193 / 0.02253 at 0.5, 0.02818 / 0.01076 / 0.02210 at 0.6, 0.02758 / 0.01071 /
//!   0.02201 at 0.7, 0.02726 / 0.01136 / 0.02204 at 0.8, 0.02715 / 0.01336 / 0.02218 at 1.0:
//!   0.7 is the default. The bins span ±4 σ_y.
//! - **Samples per pixel**: the AAF sparse pass runs with `sparse_spp` (1 by default: the
//!   receiver, d1 and r(x)), no adaptive pass, and the light field adds l² (default l = 3, as
//!   CAMEL's 9 spp, §6); the slopes come from both (§3.1).
//! - **Slope fill**: AAF's ±`fill_radius` separable max s1 / min s2 fill on the same object
//!   with radius 2 (the seed's "5×5 slope smoothing" for pixels without occluder hits).
//! - **Bins** (eq. 12: "~4l bins, 16"): `bins` (odd, default 17, so one bin sits at y = 0 and
//!   η = 0 reads exactly the unsheared light) over [−2R, 2R]: a sheared light centre beyond
//!   2R (4σ_y) is skipped, its weight being at most e^{-2} of the peak at the nearest sample.
//! - **Normalisation** (digest (ii)): every step carries a weight channel, divided at the end.
//! - **σ_x and η of which pixel** (digest (iii)): the pixel being written, in 1b and 2b.
//! - **Walks**: 1b walks the screen image of the receiver's x1 axis (dir1; the major axis
//!   moves one pixel per step) and measures Δx1 = (p′ − p)·e1 in world units; 2b likewise.
//! - **Rejection** (§5: "far in world space" or normals > 20°): normals within `normal_angle`,
//!   offset along the light direction within `depth_tolerance` σ_x (AAF's test with β → σ_x).
//! - **Pixels**: no receiver: F as rendered; a receiver without slopes: its own samples (radius
//!   0), lent to neighbours; with slopes: filtered. Output = F − the light's part the path
//!   samples put there + r · filtered visibility (kernels/filters/aaf_shadows.cl
//!   `aaf_compose_sheared`), r the same path samples' albedo × unoccluded term
//!   (`ShadowTerms::unshadowed`): the sparse pass's r is one receiver point per pixel at
//!   sparse_spp 1, whose albedo aliased textures and whose object stood for the pixel's
//!   others at edges (MSE 1.7-3.4x higher on the shadow scenes, 7x on a textured receiver:
//!   results/README.md). AAF keeps its sparse and adaptive passes' r (its 20-40 receiver
//!   points beat the path samples' r on Grids and Curved).
//! - **Every sphere light, one at a time** (§3: "filter each light separately"; the digest
//!   §3): as aaf-shadows, `light = auto` filters the scene's first `light_count` sphere lights
//!   (all of them, at most 8: the shadow output's planes; src/filters/shadow_lights.rs), a
//!   number that light alone (the others' shadows stay as rendered), -1 none. Each light has
//!   its own plane of the shadow output and of the light field: its sparse pass and slope
//!   fill, its l × l grid in its own frame (perpendicular to scene centre → its centre), its
//!   slopes, so its own σ_x, η and σ_y = R_l/2; the steps run once per light on its planes,
//!   sharing the steps' buffers, and the composes chain in increasing light order:
//!   F − Σ_l direct_l + Σ_l r_l · filtered v_l. A light's samples depend on the pixel alone,
//!   so with one light (or `light = N`) the output is the one-light filter's, byte for byte.
//! - **Memory** O(N² l²) ([`ShearedSettings::memory_bytes`]): the light field 288 B per pixel
//!   and filtered light (its depth-of-field lanes included) plus the filter's 2 · bins · 4
//!   floats of step 1a and 2 · 2 · bins of steps 1b/2a, shared by the lights; refused before
//!   allocation when it does not fit the device. Depth of field and GI: the
//!   light field plus steps 1a-2a of `dof_device.rs`, 1952 B per pixel at 17 bins.

//!
//! **Measured, and what is wrong with it** (issue 16; `bench --study aaf-shadows`): on Grids
//! at 256² the filter does not reach adaptive AAF (results/pocl-cpu/aaf-shadows.md). Two
//! causes were measured (by hand, 96-128² renders against 1024 spp):
//! - the light field on the plane disk through the light's centre, perpendicular to the
//!   global e3, is not the sphere's cone where the light is large and near (Grids: R = 0.8 at
//!   1.5-4.5 from the receivers): over the pixels with slopes its mean visibility is 0.382
//!   against 0.416 for AAF's cone samples (64 spp); on a floor under a small light
//!   (R/d ≈ 0.13) the two agree to 0.03%. The Gaussian weighting adds less (its visibility
//!   differs from the uniform disk's by 0.0116 RMS over the image);
//!   Weighting the samples by cos θ / cos θ_c (the integrand's light term) brought that mean
//!   to 0.398 but made the study's RMS worse (0.072 against 0.045 at l = 3), so the samples
//!   stay binary; why is open (a guess: neighbours lend samples normalised by their own
//!   cos θ_c to pixels whose r has another);
//! - receivers whose 1 + l² samples all reach the light count as lit (visibility 1, not
//!   filtered) though many lie in penumbrae; AAF's fill of radius 10 and 9 sparse samples find
//!   slopes for more of them (sparse 9 + fill 10 took the 128² RMS from 0.0635 to 0.0506).

mod device;
pub mod dof;
mod dof_device;
pub mod gi;
pub mod lens_shadows;
pub mod reference;
pub mod shear;

use std::sync::Arc;

use anyhow::{Result, bail};

use super::shadow_lights::{
    check_lights, chosen_lights, light_index, light_needs, light_planes, lights_of,
    specialise_lights,
};
use super::{Auto, FilterKind, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::{FieldKind, Output, OutputSet};
use crate::layout::{Float4, LightFieldPixel, ShearedParams};
use crate::render::shadows::light_field::{MAX_SIDE, sphere_frame};
use crate::render::{FrameInfo, RenderOptions, SceneInfo, ShadowSampling};
pub use device::{Intermediates, STEPS, ShearedKernel};
pub use dof_device::{DOF_STEPS, DofIntermediates, DofKernel};

/// The effect the sheared filter works on (setting `effect`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Effect {
    /// The sphere lights' soft shadows (a light field over each light, filtered one light at
    /// a time).
    Shadows,
    /// Depth of field through a thin lens (the lens field).
    Dof,
    /// Diffuse indirect light (the GI field over the v-plane).
    Gi,
    /// The sphere lights' soft shadows and depth of field together (the seed's appendix, eqs.
    /// 16-17; `lens_shadows.rs`).
    #[serde(rename = "dof-shadows")]
    DofShadows,
}

crate::filter_settings! {
    /// The sheared soft-shadow filter's settings: the light-field grid and the filter.
    pub struct ShearedSettings, flags "sheared-" {
        /// The sphere light whose shadows are filtered, counting from 0 in the scene's order;
        /// auto: every sphere light (the first `light_count`), each filtered on its own, or
        /// none when the scene has none (the image passes through); -1: none.
        pub light: Auto<i32> = Auto::Auto,
        /// With light = auto: how many sphere lights are filtered, the scene's first ones
        /// (0: all of them; at most 8, the shadow output's planes).
        pub light_count: u32 = 0,
        /// Side l of the light-field grid (l² samples per pixel, l <= 4).
        pub side: u32 = 3,
        /// Samples per pixel of AAF's sparse pass (a square): receiver, d1, r(x), slopes.
        pub sparse_spp: u32 = 1,
        /// Half width of the slope fill, pixels (2: the seed's 5x5).
        pub fill_radius: u32 = 2,
        /// Bins of the free light coordinate in steps 1a and 2a (odd, 3..=33).
        pub bins: u32 = 17,
        /// Most steps of a 1-D gather on either side (16: the seed's 32 px diameter).
        pub max_radius: u32 = 16,
        /// Largest angle between the normals of two pixels that share samples, degrees;
        /// 180 or more: no normal test.
        pub normal_angle: f32 = 20.0,
        /// Largest offset between two pixels along the direction to the light, in units of
        /// the written pixel's sigma_x; inf: no test.
        pub depth_tolerance: f32 = 2.0,
        /// Factor on eq. 5's shear eta (1: as settled; 0: axis-aligned; -1: the other sign).
        pub shear: f32 = 1.0,
        /// Soft shadows: sigma_y of the light's Gaussian weight, in light radii (0.5: the
        /// disk's per-axis standard deviation). 0.7 gave the lowest error on Grids, Curved
        /// and two_lights_shadows (results/README.md).
        pub light_sigma: f32 = 0.7,
        /// What is filtered: "shadows" (the sphere lights'), "dof" (depth of field, needs a
        /// thin lens), "dof-shadows" (both, Yan et al.'s appendix) or "gi" (diffuse indirect
        /// light, a pinhole camera); auto: with a thin lens (lens_radius > 0) "dof-shadows"
        /// when the scene has a sphere light, else "dof"; with a pinhole "shadows" with a
        /// sphere light, else "gi".
        pub effect: Auto<Effect> = Auto::Auto,
    }
}

impl ShearedSettings {
    pub fn validate(&self) -> Result<()> {
        check_lights(self.light, self.light_count, "filtered")?;
        if self.side == 0 || self.side > MAX_SIDE {
            bail!(
                "side is the light-field grid's l, 1..={MAX_SIDE} (Yan et al. 2015: l <= 4), \
                 got {}",
                self.side
            );
        }
        if self.bins < 3 || self.bins > 33 || self.bins.is_multiple_of(2) {
            bail!("bins must be odd, 3..=33 (one bin at y = 0), got {}", self.bins);
        }
        if self.max_radius > 1024 || self.fill_radius > 1024 {
            bail!("max_radius and fill_radius are at most 1024 pixels");
        }
        for (v, name) in [
            (self.normal_angle, "normal_angle"),
            (self.depth_tolerance, "depth_tolerance"),
        ] {
            if !(v >= 0.0) {
                bail!("{name} must be >= 0 (inf: no test), got {v}");
            }
        }
        if !(self.light_sigma > 0.0 && self.light_sigma <= 4.0) {
            bail!("light_sigma is sigma_y in light radii, (0, 4], got {}", self.light_sigma);
        }
        if !self.shear.is_finite() {
            bail!("shear must be finite, got {}", self.shear);
        }
        let chosen_light = light_index(self.light).is_some() && !self.light.is_auto();
        if self.effect == Auto::Set(Effect::Dof) && chosen_light {
            bail!(
                "the sheared filter's effect = \"dof\" filters depth of field alone: for a \
                 sphere light's soft shadows as well set effect = \"dof-shadows\" (Yan et \
                 al.'s appendix), or light = -1 (the shadows stay as path traced)"
            );
        }
        if self.effect == Auto::Set(Effect::Gi) && chosen_light {
            bail!(
                "the sheared filter's GI (effect = \"gi\") filters diffuse indirect light only, \
                 not a sphere light's soft shadows as well: set light = -1 (the shadows stay as \
                 path traced), or effect = \"shadows\""
            );
        }
        if self.effect == Auto::Set(Effect::DofShadows) && self.light == Auto::Set(-1) {
            bail!(
                "effect = \"dof-shadows\" filters sphere lights' shadows with depth of field, \
                 but light = -1 filters none: choose a light (or auto), or effect = \"dof\""
            );
        }
        self.sampling().check()
    }

    /// The sphere lights filtered, in increasing order: `light` alone when set (none for -1),
    /// else the first `light_count` (after specialisation the scene's count; before it, the
    /// first light alone); src/filters/shadow_lights.rs.
    pub fn filtered_lights(&self) -> Vec<u32> {
        chosen_lights(self.light, self.light_count)
    }

    /// The filtered lights with their centre and radius in `scene`; an error naming the
    /// light when the scene lacks one.
    pub fn lights_of(&self, scene: &SceneInfo) -> Result<Vec<(u32, [f32; 4])>> {
        lights_of(Sheared::NAME, &self.filtered_lights(), scene)
    }

    /// How the renderer samples: per filtered light (a plane each), AAF's sparse pass and
    /// fill, no adaptive pass, the grid.
    pub fn sampling(&self) -> ShadowSampling {
        ShadowSampling {
            lights: light_planes(&self.filtered_lights()),
            sparse_spp: self.sparse_spp,
            max_spp: self.sparse_spp,
            fill_radius: self.fill_radius,
            light_field: self.side,
            light_field_gi: self.is_gi(),
        }
    }

    /// Whether the filter does depth of field alone (after `specialise`; `auto` counts as
    /// no).
    pub fn is_dof(&self) -> bool {
        self.effect == Auto::Set(Effect::Dof)
    }

    /// Whether the filter does soft shadows and depth of field together (after
    /// `specialise`; `auto`: no).
    pub fn is_dof_shadows(&self) -> bool {
        self.effect == Auto::Set(Effect::DofShadows)
    }

    /// Whether the filter does diffuse indirect light (after `specialise`; `auto`: no).
    pub fn is_gi(&self) -> bool {
        self.effect == Auto::Set(Effect::Gi)
    }

    /// The GI filter's parameters on a w × h image: σ_v = 2/Ω_v^max (eq. 4, Ω_v^max = 2.8),
    /// the box and the bins over the v-square [−V, V] (src/filters/sheared/gi.rs).
    pub fn gi_params(&self, width: u32, height: u32) -> ShearedParams {
        let v = crate::render::gi_field::V_MAX;
        let mut p = self.params([0.0, 0.0, 0.0, v], [0.0, 1.0, 0.0], width, height);
        p.sigma_y = 2.0 / gi::OMEGA_V_MAX;
        p.range = v;
        p
    }

    /// The depth-of-field filter's parameters for a lens of radius `lens_radius` (A): the
    /// Gaussian aperture σ_y = A/2 (σ_y = 2/Ω_u^max, Ω_u^max = 4/A, §3.2), bins over [−2A, 2A].
    pub fn dof_params(&self, lens_radius: f32, width: u32, height: u32) -> ShearedParams {
        let mut p = self.params([0.0, 0.0, 0.0, lens_radius], [0.0, 1.0, 0.0], width, height);
        p.axis1 = Float4([1.0, 0.0, 0.0, 0.0]);
        p.axis2 = Float4([0.0, 1.0, 0.0, 0.0]);
        // The aperture's Gaussian is the lens pass's (kernels/render/lens_field.cl
        // `lens_weight`, σ = A/2), whatever `light_sigma` says of lights.
        p.sigma_y = 0.5 * lens_radius;
        p.range = 2.0 * lens_radius;
        p
    }

    /// The filter's parameters for light `light` (centre, radius) in a scene centred at
    /// `scene_centre`, on a w × h image.
    pub fn params(
        &self,
        light: [f32; 4],
        scene_centre: [f32; 3],
        width: u32,
        height: u32,
    ) -> ShearedParams {
        let [e1, e2] = sphere_frame(light, scene_centre);
        let normal_cos = if self.normal_angle >= 180.0 {
            -2.0
        } else {
            self.normal_angle.to_radians().cos()
        };
        ShearedParams {
            light: Float4(light),
            axis1: Float4::from_vec3(e1, 0.0),
            axis2: Float4::from_vec3(e2, 0.0),
            width,
            height,
            side: self.side,
            bins: self.bins,
            sigma_y: self.light_sigma * light[3],
            range: 4.0 * self.light_sigma * light[3],
            normal_cos,
            depth_tolerance: self.depth_tolerance,
            max_radius: self.max_radius as i32,
            shear: self.shear,
            pad0: 0.0,
            pad1: 0.0,
        }
    }

    /// Device bytes of the light fields and the filter's buffers for a w × h image: O(N² l²)
    /// (the light field's lanes are fixed at 16 samples; steps 1a-2a grow with the bins), a
    /// light field per filtered light.
    pub fn memory_bytes(&self, width: u32, height: u32) -> u64 {
        let n = width as u64 * height as u64;
        if self.is_dof() || self.is_gi() {
            return n * dof_device::bytes_per_pixel(self.bins);
        }
        let shadows = n * self.shadow_bytes_per_pixel(self.filtered_lights().len().max(1) as u32);
        if self.is_dof_shadows() {
            // The lens field twice (as rendered, and combined), each sample's albedo and the
            // lights' terms, and the depth-of-field filter's buffers.
            let lens = std::mem::size_of::<LightFieldPixel>()
                + std::mem::size_of::<crate::layout::LensShadowPixel>();
            return shadows + n * (lens as u64 + dof_device::bytes_per_pixel(self.bins));
        }
        shadows
    }

    /// Soft shadows of `lights` sphere lights: bytes per pixel of their light fields (one per
    /// light) and of the steps' buffers, which the lights share (they run one after another).
    pub fn shadow_bytes_per_pixel(&self, lights: u32) -> u64 {
        lights as u64 * std::mem::size_of::<LightFieldPixel>() as u64
            + 4 * (reference::p_floats(self.bins) + 2 * reference::g_floats(self.bins)) as u64
            + 16 // guide
            + 4 // visibility
            + 16 // image
    }
}

/// The sheared soft-shadow filter in the registry.
pub struct Sheared;

impl FilterKind for Sheared {
    type Settings = ShearedSettings;
    const NAME: &'static str = "sheared";
    const SUMMARY: &'static str = "4-D sheared filtering of every sphere light's soft shadows \
         (a light at a time), of depth of field with a thin lens, of both together, or of \
         diffuse indirect light, from l x l light, lens or v-plane samples per pixel (Yan et \
         al. 2015; on the device)";

    fn check(s: &ShearedSettings) -> Result<()> {
        s.validate()
    }

    fn specialise(s: &mut ShearedSettings, scene: &SceneInfo) -> Vec<String> {
        let lens = scene.camera.lens_radius;
        if s.effect.is_auto() {
            let shadows = !scene.sphere_lights.is_empty()
                || light_index(s.light).is_some() && !s.light.is_auto();
            s.effect = Auto::Set(match (lens > 0.0, shadows) {
                (true, true) => Effect::DofShadows,
                (true, false) => Effect::Dof,
                (false, true) => Effect::Shadows,
                (false, false) => Effect::Gi,
            });
        }
        if s.is_gi() {
            let mut notes = vec![format!(
                "diffuse indirect light: {} v-plane samples per pixel, s = z",
                s.side * s.side
            )];
            if s.light.is_auto() {
                s.light = Auto::Set(-1);
            }
            if !scene.sphere_lights.is_empty() {
                notes.push(format!(
                    "the {} sphere light(s)' shadows stay as path traced (direct light is not \
                     filtered by the GI effect)",
                    scene.sphere_lights.len()
                ));
            }
            return notes;
        }
        if s.is_dof_shadows() {
            let mut notes = vec![format!(
                "soft shadows and depth of field together (Yan et al.'s appendix, eqs. \
                 16-17): the lights' shadows filtered over the light, put back on each of the \
                 l x l lens samples, then filtered over the lens (radius {lens}, focal \
                 distance {})",
                scene.camera.focal_distance
            )];
            notes.extend(specialise_lights(
                &mut s.light,
                &mut s.light_count,
                scene,
                "filtered",
                "each with its own light field, sigma_y, shear and steps 1a-2b",
            ));
            return notes;
        }
        if !s.is_dof() {
            return specialise_lights(
                &mut s.light,
                &mut s.light_count,
                scene,
                "filtered",
                "each with its own light field (l x l samples in its own frame), sigma_y, \
                 shear, steps 1a-2b and compose",
            );
        }
        let mut notes = vec![format!(
            "depth of field through the thin lens (radius {lens}, focal distance {}): l x l \
             lens samples, Gaussian aperture sigma = A/2",
            scene.camera.focal_distance
        )];
        if s.light.is_auto() {
            s.light = Auto::Set(-1);
            if !scene.sphere_lights.is_empty() {
                notes.push(format!(
                    "light = -1: the {} sphere light(s)' shadows stay as path traced \
                     (unfiltered); effect = \"dof-shadows\" filters them as well",
                    scene.sphere_lights.len()
                ));
            }
        }
        notes
    }

    /// Depth of field wherever the camera has a lens, the shadows of sphere lights, or
    /// diffuse indirect light where paths go past their first surface.
    fn applies(s: &ShearedSettings, scene: &SceneInfo) -> bool {
        s.is_dof()
            || s.is_dof_shadows()
            || (s.is_gi() && scene.indirect)
            || !s.filtered_lights().is_empty()
    }

    fn needs(s: &ShearedSettings) -> OutputSet {
        // The field each effect reads, recorded so that a frame holding another is refused
        // and the viewer gathers again (src/view/session.rs).
        if s.is_dof() {
            return OutputSet::colour().with_field(FieldKind::Lens);
        }
        if s.is_gi() {
            return OutputSet::colour().with_field(FieldKind::Gi);
        }
        let outputs = light_needs(s.light);
        if s.is_dof_shadows() {
            return outputs.with(Output::LightField).with(Output::LensShadows);
        }
        match light_index(s.light) {
            Some(_) => outputs.with(Output::LightField),
            None => outputs,
        }
    }

    fn render_options(s: &ShearedSettings, options: &mut RenderOptions) {
        options.shadows = s.sampling();
    }

    fn prepare(
        s: &ShearedSettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        if s.is_gi() {
            let lens = frame.scene.camera.lens_radius;
            if lens > 0.0 {
                bail!(
                    "the sheared filter's GI (effect = \"gi\") needs a pinhole camera, but the \
                     scene's has a thin lens (lens_radius {lens}): GI and depth of field together \
                     are not built; set lens_radius = 0 in its [camera], or effect = \"dof\""
                );
            }
            let p = s.gi_params(frame.width, frame.height);
            return Ok(Box::new(DofKernel::gi(gpu.clone(), p)?));
        }
        if s.is_dof_shadows() {
            return Ok(Box::new(lens_shadows::LensShadowKernel::new(s, frame, gpu)?));
        }
        if s.is_dof() {
            let lens = frame.scene.camera.lens_radius;
            if !(lens > 0.0) {
                bail!(
                    "the sheared filter's depth of field needs a thin lens, but the scene's \
                     camera is a pinhole (lens_radius {lens}): set lens_radius > 0 in its \
                     [camera], or effect = \"shadows\" or \"gi\""
                );
            }
            let p = s.dof_params(lens, frame.width, frame.height);
            return Ok(Box::new(DofKernel::new(gpu.clone(), p)?));
        }
        Ok(Box::new(ShearedKernel::new(
            gpu.clone(),
            s,
            &s.lights_of(&frame.scene)?,
            frame.scene.scene_centre,
            frame.width,
            frame.height,
        )?))
    }
}
