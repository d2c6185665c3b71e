//! Stylized shadows (DeCoro 2009, "Rendering Filters for Controlling Detail and Creating
//! Effects", ch. 3 = "Stylized Shadows", NPAR 2007; digest shared/notes/seed-decoro.md §1): a
//! sphere light's hard shadow turned into an art-directed one by four controls, inflation i,
//! softness s, brightness b and abstraction α. Per light (eq. 3.1, §3.3 steps 1-5):
//!
//! 1. the binary matte V of the light at the primary hit (the renderer's shadow output: one
//!    ray to the light's centre, src/render/shadows, kernels/render/shadows.cl
//!    `shadow_centre_visible`), and the contour points between pixels where V changes
//!    ([`contour`]);
//! 2. the signed L8-averaged world-space distance D to the contour, eq. 3.2 ([`distance`]);
//! 3. its Gaussian blur of standard deviation α, two passes of α/√2 ([`blur`]);
//! 4. S = (1 − b)·smoothstep(i − s/2, i + s/2, G * D) + b, eq. 3.3 with (1 − b) for the
//!    printed (1 − b)^-1 ([`transfer`]);
//! 5. S in place of V in the light's direct term: output = F − direct + r·S, with `direct` the
//!    light's direct term the path tracer put into F (ShadowTerms) and r its unshadowed term
//!    at the pixel (ShadowPixel.unshadowed / samples), the digest's option (b) of §1.4.
//!
//! The kernels are kernels/filters/stylized.cl, driven by `device.rs`; each step's file holds
//! its plain Rust reference and says what the seed leaves open and what is done. Steps 1-2
//! depend on the render alone, step 3 on α, step 4 on i, s, b: [`StylizedKernel`] runs them
//! separately, so a change of i, s or b re-runs only the compose, a change of α the blur and
//! the compose (the thesis's "> 100 fps" and "> 50 fps" edits, §3.3.3 "Sampling"). Several
//! lights: see "Several lights" below.
//!
//! Adaptations to a path tracer (digest §1.4):
//! - **Binary V** from one ray to the sphere light's centre: the port's lights are spheres
//!   (soft shadows), the thesis's input is a hard matte; stylizing soft visibility is its
//!   future work (§3.4).
//! - **Sphere lights only**: the lights with a centre and a shadow ray to it. `light = auto`
//!   stylizes every sphere light (at most 8, the shadow output's planes; `light_count` takes
//!   the first n), `light = n` light n alone; other lights' shadows (triangle lights, the
//!   environment, lights left out) stay as rendered.
//! - **b applies to the direct light of the light only**: the path tracer's indirect light is
//!   kept, so b = 0 (the default) is the physical shadow and b adds "ambient" on top (digest
//!   §1.4: b would otherwise double-count indirect light).
//! - **d(x)**, the occluder distance of the quadratic controls, is the shadow ray's hit
//!   distance (§3.3.2 allows "more accurate distances, such as those computed with
//!   raytracing"), spread to both sides of the boundary by the distance step.
//! - Pixels whose centre hit is not diffuse (sky, glass, mirrors) or that have no light
//!   sample keep F as rendered; the matte is the centre ray's (a thin lens is ignored, as in
//!   aaf-shadows).
//! - With the defaults (i = 0, s = 0, b = 0, α = 0) S = V: the hard shadow of the light's
//!   centre replaces the soft one.
//! - **Whole frames**: D at a pixel depends on every contour point of the image, so the
//!   filter has no bounded reach ([`PreparedFilter::reach`] is None) and runs on the merged
//!   film when a frame is split across devices (without a light it passes bands through).
//!
//! # Several lights (eq. 3.1)
//!
//! Eq. 3.1 sums over the lights, each with its own S_l (issue 17, §2). What is built:
//! - **The shadow output per light.** `ShadowTerms` (a light's direct term that the path
//!   tracer put into F) and `ShadowPixel` (V from the centre ray, r, d(x), position, normal)
//!   are per-light planes, `pixels × L` elements, pixel-major (src/layout/outputs.rs
//!   `Per::Light`: pixel p's plane l at p·L + l, so a row of pixels stays contiguous and the
//!   device split and the merge work on them as on per-pixel buffers). The planes are a set
//!   of the scene's sphere lights (`render::LightPlanes`, `ShadowSampling::lights`), only
//!   those a filter asks for: aaf-shadows and sheared ask for their `light` (one plane, the
//!   bytes of before), this filter for the lights it stylizes. The frame records the light of
//!   each plane (`FrameInfo::shadow_lights`), the AOV channels carry it
//!   (`shadow.l1.direct.R`), partial files list it; merging merges every plane.
//! - **The megakernel** (kernels/render/pathtrace.cl) keeps a private float3 per plane
//!   (`SHADOW_PLANES`, a build define, at most 8: beyond that `ShadowSampling::check` refuses
//!   with the cap) and folds a next-event estimate (or a first-bounce hit of the light) into
//!   the plane of the light that was chosen. Next-event estimation picks one light per vertex,
//!   so the planes' terms are disjoint parts of F and can all be subtracted.
//! - **The shadow passes** (src/render/shadows) run once per plane before the first samples,
//!   each writing its plane with the same random numbers as a render of that light alone:
//!   plane l is byte for byte the one-light output (tests/stylized_lights.rs). Their cost is
//!   L times one light's, paid once per render.
//! - **The filter** keeps one pipeline per light (contour, D, blur, controls, matte:
//!   `device.rs`), each reading its light's plane, and composes them a light at a time into
//!   F − Σ_l direct_l + Σ_l r_l·S_l (`st_compose` starts from F, then from the image so far).
//!   [`StylizedKernel::set_light_controls`] changes one light's controls: i, s or b re-run
//!   only the compose, α that light's blur and the compose. In place of the design's single
//!   compose over all lights, the per-light launches keep one kernel and one reference for
//!   any number of lights, and with one light are the one-light filter's kernel (the same
//!   bytes: results/stylized/contact-sheet.png is reproduced exactly).
//! - **Settings**: the four quadratics are every light's default, `[...lights.N]` tables
//!   ([`lights`]) override them for light N or leave its shadow as rendered
//!   (`stylize = false`); `light` chooses one light or, auto, every sphere light (the first
//!   `light_count`).

pub mod blur;
pub mod contour;
mod device;
pub mod distance;
pub mod lights;
pub mod transfer;

use std::sync::Arc;

use anyhow::{Result, bail};

use super::shadow_lights::{
    check_lights, chosen_lights, light_needs, light_planes, lights_of, specialise_lights,
};
use super::{Auto, FilterKind, PreparedFilter, Purpose};
use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::layout::outputs::{BufferId, OutputSet};
use crate::layout::{ShadowPixel, ShadowTerms};
use crate::render::{Frame, FrameInfo, RenderOptions, SceneInfo, ShadowSampling};
pub use device::{DeviceStages, StylizedKernel};
pub use lights::{LightControls, LightTable};
pub use transfer::Controls;

crate::filter_settings! {
    /// The stylized-shadows filter's settings: the four controls, each a quadratic
    /// [c0, c1, c2] of the occluder distance d (c0 + c1 d + c2 d²; [c, 0, 0] is a constant),
    /// and how the distance and the blur are sampled.
    pub struct StylizedSettings, flags "stylized-" {
        /// The sphere light whose shadows are stylized, counting from 0 in the scene's order;
        /// auto: every sphere light (the first `light_count`), or none when the scene has no
        /// sphere light (the image passes through); -1: none.
        pub light: Auto<i32> = Auto::Auto,
        /// With light = auto: how many sphere lights are stylized, the scene's first ones
        /// (0: all of them; at most 8, the shadow output's planes).
        pub light_count: u32 = 0,
        /// Per-light tables overriding the four controls for one light, or leaving its shadow
        /// as rendered (`[filter.stylized-shadows.lights.1]` with `inflation = [...]`,
        /// `softness`, `brightness`, `abstraction` or `stylize = false`); the controls above
        /// are every light's default.
        pub lights: LightTable = LightTable::new(),
        /// Inflation i: the shadow's new boundary is the isocontour D = i of the signed
        /// L8-averaged distance (world units; negative deflates).
        pub inflation: [f32; 3] = [0.0, 0.0, 0.0],
        /// Softness s: width of the ramp from b to 1 around D = i (world units; 0: hard).
        pub softness: [f32; 3] = [0.0, 0.0, 0.0],
        /// Brightness b: the darkest the shadow gets, in [0, 1] (added to the light's direct
        /// term only).
        pub brightness: [f32; 3] = [0.0, 0.0, 0.0],
        /// Abstraction α: standard deviation of the blur of D, pixels (0: none).
        pub abstraction: [f32; 3] = [0.0, 0.0, 0.0],
        /// Contour points drawn per pixel for eq. 3.2 (all of them when the contour has
        /// fewer).
        pub contour_samples: u32 = 1024,
        /// Halton points per blur pass.
        pub blur_samples: u32 = 64,
        /// The normal rule: contour points and blur neighbours whose normal is further from
        /// the pixel's are ignored, degrees (§3.3.2: 45).
        pub normal_angle: f32 = 45.0,
        /// Two pixels are of one surface (a contour pair, a blur neighbour) when they are at
        /// most this many pixel footprints apart along the normal: not across silhouettes.
        pub surface_gap: f32 = 4.0,
        /// Light samples per pixel for r, the unshadowed term (a square; r is anti-aliased
        /// over them; their visibility is not used).
        pub unshadowed_spp: u32 = 4,
        /// The distance kernel: "scalar" (one contour sample at a time), "lanes" (ours:
        /// sixteen samples at a time on float16 lanes, the same bits) or "auto" (lanes on a
        /// CPU, scalar on other devices).
        pub variant: Variant = Variant::Auto,
    }
}

/// Which loop of `st_distance` (kernels/filters/stylized.cl) runs eq. 3.2. Both give the
/// same bits (tests/stylized.rs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Variant {
    /// `lanes` on CPU devices, `scalar` on the others: on PoCL the lanes' st_distance took
    /// 0.15-0.24x the scalar loop's time at 512², 8 spp (two lights, curved, grids;
    /// results/README.md, "Stylized shadows below OIDN fast on the wall clock"). A GPU's SIMD
    /// lanes are its work-items already; not measured (no GPU was lent), so GPUs keep the
    /// scalar loop, as the à-trous and data-driven filters' `auto` do.
    Auto,
    /// One contour sample at a time per work-item.
    Scalar,
    /// Ours, for CPUs: sixteen samples at a time on float16 lanes, pass 1's distances kept
    /// for pass 2, drawn points read from a window of the planes (AVX-512) or gathered; two
    /// pixels a work-item, their sums added together, each in sample order.
    Lanes,
}

impl Variant {
    /// The variant this one stands for on a device of `kind` (`DeviceSummary::kind`: "CPU",
    /// "GPU", ...): [`Variant::Auto`] chosen, the others as they are.
    pub fn for_device(self, kind: &str) -> Variant {
        match self {
            Variant::Auto if kind == "CPU" => Variant::Lanes,
            Variant::Auto => Variant::Scalar,
            v => v,
        }
    }
}

/// Most points drawn per pixel, and most blur points per pass.
pub const MAX_SAMPLES: u32 = 1 << 16;

/// The seed of the distance step's strata (a fixed one: the filter is deterministic).
pub const DISTANCE_SEED: u32 = 0x5717_12ed;

impl StylizedSettings {
    pub fn validate(&self) -> Result<()> {
        check_lights(self.light, self.light_count, "stylized")?;
        lights::check(&self.lights)?;
        let k = (self.unshadowed_spp as f64).sqrt().round() as u32;
        if self.unshadowed_spp == 0 || k * k != self.unshadowed_spp || k > 64 {
            bail!(
                "unshadowed_spp is a square of whole strata (1, 4, 9, ..., 4096), got {}",
                self.unshadowed_spp
            );
        }
        self.sampling().check()?;
        for (v, name) in [
            (self.contour_samples, "contour_samples"),
            (self.blur_samples, "blur_samples"),
        ] {
            if v == 0 || v > MAX_SAMPLES {
                bail!("{name} must be in 1..={MAX_SAMPLES}, got {v}");
            }
        }
        let every = std::iter::once((String::new(), self.controls())).chain(
            self.lights
                .iter()
                .map(|(k, e)| (format!("lights.{k}."), e.over(&self.controls()))),
        );
        for (at, c) in every {
            for (q, name) in [
                (c.inflation, "inflation"),
                (c.softness, "softness"),
                (c.brightness, "brightness"),
                (c.abstraction, "abstraction"),
            ] {
                if q.iter().any(|v| !v.is_finite()) {
                    bail!("{at}{name} takes three finite coefficients [c0, c1, c2], got {q:?}");
                }
            }
        }
        if !(self.normal_angle >= 0.0) || !(self.surface_gap > 0.0) {
            bail!(
                "normal_angle must be >= 0 degrees and surface_gap > 0, got {} and {}",
                self.normal_angle,
                self.surface_gap
            );
        }
        Ok(())
    }

    pub fn controls(&self) -> Controls {
        Controls {
            inflation: self.inflation,
            softness: self.softness,
            brightness: self.brightness,
            abstraction: self.abstraction,
        }
    }

    /// cos of the normal rule's angle (-2: no test at 180° or more).
    pub fn normal_cos(&self) -> f32 {
        if self.normal_angle >= 180.0 {
            -2.0
        } else {
            self.normal_angle.to_radians().cos()
        }
    }

    /// The controls of sphere light `l`: the filter's, with its table's overrides.
    pub fn controls_of(&self, l: u32) -> Controls {
        lights::controls_of(&self.lights, &self.controls(), l)
    }

    /// The sphere lights stylized: `light` alone when set, else the first `light_count`
    /// (after specialisation the scene's count; before it, 0 counts as the first light);
    /// less those whose table says `stylize = false`.
    pub fn stylized_lights(&self) -> Vec<u32> {
        chosen_lights(self.light, self.light_count)
            .into_iter()
            .filter(|&l| lights::stylized(&self.lights, l))
            .collect()
    }

    /// The shadow output this filter needs: a plane per stylized light, `unshadowed_spp`
    /// light samples for r and no adaptive pass (the centre ray gives V).
    pub fn sampling(&self) -> ShadowSampling {
        ShadowSampling {
            lights: light_planes(&self.stylized_lights()),
            sparse_spp: self.unshadowed_spp,
            max_spp: self.unshadowed_spp,
            fill_radius: 0,
            ..ShadowSampling::default()
        }
    }
}

/// The stylized-shadows filter in the registry.
pub struct StylizedShadows;

impl FilterKind for StylizedShadows {
    type Settings = StylizedSettings;
    const NAME: &'static str = "stylized-shadows";
    const SUMMARY: &'static str = "art-directed shadows of one sphere light: inflation, \
         softness, brightness, abstraction (DeCoro 2009 ch. 3; on the device)";
    /// Art direction, not an estimate of the converged image: out of the error studies.
    const PURPOSE: Purpose = Purpose::Stylize;

    fn check(s: &StylizedSettings) -> Result<()> {
        s.validate()
    }

    /// `light = auto` becomes the scene's first `light_count` sphere lights (all by default,
    /// at most the shadow output's 8 planes), or none when the scene has none; a set `light`
    /// is checked against the scene (src/filters/shadow_lights.rs).
    fn specialise(s: &mut StylizedSettings, scene: &SceneInfo) -> Vec<String> {
        specialise_lights(
            &mut s.light,
            &mut s.light_count,
            scene,
            "stylized (less any with stylize = false)",
            "each with its own contour, distance and blur",
        )
    }

    fn needs(s: &StylizedSettings) -> OutputSet {
        if s.stylized_lights().is_empty() {
            OutputSet::colour()
        } else {
            light_needs(Auto::Set(0))
        }
    }

    fn render_options(s: &StylizedSettings, options: &mut RenderOptions) {
        options.shadows = s.sampling();
    }

    fn prepare(
        s: &StylizedSettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        let lights = s.stylized_lights();
        lights_of(StylizedShadows::NAME, &lights, &frame.scene)?;
        Ok(Box::new(StylizedKernel::new(
            gpu.clone(),
            s,
            &lights,
            frame.width,
            frame.height,
        )?))
    }
}

/// What the reference computes, step by step, for one stylized light (tests compare each
/// with the kernels').
pub struct Stages {
    /// The contour list (two float4s per point).
    pub contour: Vec<crate::layout::Float4>,
    /// D of eq. 3.2, signed; ±∞ where no contour point counts.
    pub distance: Vec<f32>,
    /// d(x), the occluder distance of the controls.
    pub occluder: Vec<f32>,
    /// G * D after both passes.
    pub blurred: Vec<f32>,
    /// S per pixel.
    pub matte: Vec<f32>,
    /// The image after this light's compose (the last light's: the filter's output).
    pub image: RgbImage,
}

/// The whole filter in plain Rust on `frame` (which holds the shadow output): the stages of
/// the first stylized light, with the image of them all (see [`reference_lights`]).
pub fn reference(frame: &Frame, s: &StylizedSettings) -> Result<Stages> {
    let controls: Vec<Controls> = s
        .stylized_lights()
        .iter()
        .map(|&l| s.controls_of(l))
        .collect();
    let mut all = reference_lights(frame, s, &controls)?;
    let image = all.last().map(|l| l.image.clone());
    let mut first = all.swap_remove(0);
    first.image = image.expect("one light at least");
    Ok(first)
}

/// The plane `light` of a per-light buffer of `frame` (src/layout/outputs.rs `Per::Light`).
pub fn light_plane<T: ocl::OclPrm>(frame: &Frame, id: BufferId, light: u32) -> Result<Vec<T>> {
    let info = frame.info();
    let Some(plane) = info.shadow_plane(light) else {
        bail!(
            "the frame's shadow output holds sphere light(s) {:?}, not {light}",
            info.shadow_lights
        );
    };
    let planes = info.shadow_lights.len();
    let all: &[T] = frame.host_slice(id)?;
    Ok(all.iter().skip(plane).step_by(planes).copied().collect())
}

/// Every stylized light of `s` in plain Rust, light k with `controls[k]`: each light's stages,
/// the image after each light's compose (eq. 3.1: F − Σ_l direct_l + Σ_l r_l·S_l, a light at a
/// time, as the kernels compose). Without a light: one stage set whose image is F.
pub fn reference_lights(
    frame: &Frame,
    s: &StylizedSettings,
    controls: &[Controls],
) -> Result<Vec<Stages>> {
    s.validate()?;
    let lights = s.stylized_lights();
    if controls.len() != lights.len() {
        bail!("{} controls for {} stylized lights", controls.len(), lights.len());
    }
    let (w, h) = (frame.width(), frame.height());
    let mut image = frame.beauty()?;
    if lights.is_empty() {
        return Ok(vec![Stages {
            contour: Vec::new(),
            distance: Vec::new(),
            occluder: Vec::new(),
            blurred: Vec::new(),
            matte: Vec::new(),
            image,
        }]);
    }
    let mut out = Vec::new();
    for (&light, controls) in lights.iter().zip(controls) {
        let pixels: Vec<ShadowPixel> = light_plane(frame, BufferId::ShadowPixels, light)?;
        let terms: Vec<ShadowTerms> = light_plane(frame, BufferId::ShadowTerms, light)?;
        let normal_cos = s.normal_cos();
        let contour = contour::compact(&contour::slots(&pixels, w, h, normal_cos, s.surface_gap));
        let sampling = distance::Sampling::new(
            (contour.len() / 2) as u32,
            s.contour_samples,
            DISTANCE_SEED,
            normal_cos,
        );
        let (dist, occluder) = distance::distances(&pixels, &contour, &sampling);
        let n = s.blur_samples;
        let mut blurred = dist.clone();
        for pass in 0..2 {
            let stencil = blur::stencil(pass * n, n);
            blurred = blur::pass(
                &pixels,
                controls,
                &occluder,
                &stencil,
                &blurred,
                w,
                h,
                normal_cos,
                s.surface_gap,
            );
        }
        let (matte, next) =
            transfer::compose(&image, &terms, &pixels, controls, &occluder, &blurred);
        image = next;
        out.push(Stages {
            contour,
            distance: dist,
            occluder,
            blurred,
            matte,
            image: image.clone(),
        });
    }
    Ok(out)
}
