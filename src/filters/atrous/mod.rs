//! The edge-avoiding à-trous wavelet filter (Dammertz, Sewtz, Hanika, Lensch, "Edge-Avoiding
//! À-Trous Wavelet Transform for fast Global Illumination Filtering", HPG 2010): settings here,
//! the OpenCL passes of kernels/filters/atrous.cl (one pixel per work-item) and
//! kernels/filters/atrous_packed.cl (ours, for CPUs: 16 pixels per work-item on float16 lanes,
//! [`Variant`]) in `device.rs`, and the plain Rust reference of the same equations and the same
//! pass structure in `reference.rs`.
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

mod device;
mod reference;

use std::sync::Arc;

use anyhow::{Result, bail};
use serde::{Deserialize, Serialize};

use super::{Auto, FilterKind, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::{Output, OutputSet};
use crate::layout::{AtrousParams, Float4};
use crate::render::{FrameInfo, SceneInfo};
use crate::scene::CameraBasis;
pub use device::{AtrousKernel, PACK, PACKED_GROUP};
pub use reference::{pixel_direction, reference};

/// The B3-spline taps, offsets −2..2.
pub const B3: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Albedo channels are clamped below at this before the light is divided by them, so black
/// texels do not blow up the demodulated colour (and the same clamp is multiplied back).
pub const ALBEDO_EPSILON: f32 = 1.0e-3;

/// More passes than this would space the taps 2^15 = 32768 pixels apart, wider than any image.
pub const MAX_ITERATIONS: u32 = 15;

/// Which kernel runs the passes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Variant {
    /// `packed` on CPU devices, `scalar` on the others: on PoCL (CPU) the packed kernel took
    /// 0.12x the scalar one's time at 512 x 512 on Cornell diffuse (0.19x on Outside, whose
    /// sky the scalar kernel skips pixel by pixel), within 5.8e-7 (relative) of the reference
    /// (results/README.md "Roofline", tests/atrous_variants.rs). A GPU's SIMD lanes are its work-items already, and 16
    /// pixels per work-item would mean 16 times fewer of them; not measured (no GPU was
    /// available), so GPUs keep the scalar kernel, as the data-driven filter's `auto` does.
    Auto,
    /// One work-item per pixel (kernels/filters/atrous.cl `atrous_pass`).
    Scalar,
    /// Ours, for CPUs: [`PACK`] adjacent pixels of a row per work-item on float16 lanes,
    /// read from rows of padded lines (kernels/filters/atrous_packed.cl).
    Packed,
}

impl Variant {
    /// The variant this one stands for on a device of `kind` (`DeviceSummary::kind`: "CPU",
    /// "GPU", ...): [`Variant::Auto`] chosen, the others as they are.
    pub fn for_device(self, kind: &str) -> Variant {
        match self {
            Variant::Auto if kind == "CPU" => Variant::Packed,
            Variant::Auto => Variant::Scalar,
            v => v,
        }
    }
}

crate::filter_settings! {
    /// The à-trous filter's parameters. Defaults, demodulated: 5 passes, σ_colour 0.6
    /// (radiance / albedo), σ_normal 0.5, σ_position 5 footprints; chosen by a sweep on
    /// scenes/cornell_diffuse.toml at 128 × 128, 8 spp, against 1024 spp: MSE in CIELUV 30.9
    /// unfiltered, 5.19 filtered. The optimum is flat: σ_colour 0.5-0.7, σ_normal 0.3-1,
    /// σ_position 4-6 all give 5.18-5.58; σ_colour 0.25 or 2 give 7.0 and 5.6 at their best.
    /// Filtering the beauty (`demodulate = false`, the paper's input), the same sweep chose
    /// σ_colour 0.1 (linear radiance), σ_normal 1, σ_position 6 (MSE 13.0): there the colour
    /// weight alone has to stop at texture edges, so σ_colour must be small, and then the
    /// noise is filtered less; hence the demodulated default.
    pub struct AtrousSettings, flags "atrous-" {
        /// Number of passes; pass i spaces its taps 2^i pixels apart, so 5 passes reach
        /// 2·(1 + 2 + 4 + 8 + 16) = 62 pixels either side.
        pub iterations: u32 = 5,
        /// σ of the colour weight in the first pass, halved every pass, in units of the
        /// filtered colour; auto: 0.6 demodulated, 0.1 for the beauty.
        pub sigma_color: Auto<f32> = Auto::Auto,
        /// σ of the normal weight, on the difference of the mean shading normals; auto: 0.5
        /// demodulated, 1 for the beauty.
        pub sigma_normal: Auto<f32> = Auto::Auto,
        /// σ of the position weight in pixel footprints (the world size of one pixel at the
        /// centre's depth); auto: 5 demodulated, 6 for the beauty.
        pub sigma_position: Auto<f32> = Auto::Auto,
        /// Filter light / albedo and multiply the albedo back; false filters the beauty as the
        /// paper does.
        pub demodulate: bool = true,
        /// Kernel: "scalar" (one pixel per work-item), "packed" (ours: 16 pixels of a row per
        /// work-item on float16 lanes) or "auto" (packed on a CPU, scalar on other devices).
        pub variant: Variant = Variant::Auto,
    }
}

impl AtrousSettings {
    /// The settings that filter the beauty, with their own tuned sigmas.
    pub fn for_beauty() -> Self {
        AtrousSettings {
            demodulate: false,
            ..Default::default()
        }
    }

    /// The sigmas (colour, normal, position) with `auto` resolved by `demodulate`.
    pub fn sigmas(&self) -> [f32; 3] {
        let (c, n, p) = if self.demodulate {
            (0.6, 0.5, 5.0)
        } else {
            (0.1, 1.0, 6.0)
        };
        [
            self.sigma_color.or(c),
            self.sigma_normal.or(n),
            self.sigma_position.or(p),
        ]
    }

    pub fn validate(&self) -> Result<()> {
        if self.iterations > MAX_ITERATIONS {
            bail!(
                "the a-trous filter runs at most {MAX_ITERATIONS} iterations (taps 2^i pixels \
                 apart), got {}",
                self.iterations
            );
        }
        for (v, name) in self
            .sigmas()
            .into_iter()
            .zip(["sigma_color", "sigma_normal", "sigma_position"])
        {
            if !(v > 0.0 && v.is_finite()) {
                bail!("the a-trous {name} must be a positive number, got {v}");
            }
        }
        Ok(())
    }

    /// The parameters of pass `iteration` for a w × h image.
    pub fn params(
        &self,
        camera: &CameraBasis,
        width: u32,
        height: u32,
        iteration: u32,
    ) -> AtrousParams {
        let [sigma_color, sigma_normal, sigma_position] = self.sigmas();
        AtrousParams {
            camera_origin: Float4::from_vec3(camera.origin, 0.0),
            camera_forward: Float4::from_vec3(camera.forward, 0.0),
            camera_right: Float4::from_vec3(camera.right, 0.0),
            camera_up: Float4::from_vec3(camera.up, 0.0),
            width,
            height,
            step: 1 << iteration,
            iteration,
            sigma_color,
            sigma_normal,
            sigma_position,
            tan_half_fov: camera.tan_half_fov,
        }
    }
}

/// The à-trous filter in the registry.
pub struct Atrous;

impl FilterKind for Atrous {
    type Settings = AtrousSettings;
    const NAME: &'static str = "atrous";
    const SUMMARY: &'static str =
        "the edge-avoiding à-trous wavelet filter of Dammertz et al. 2010 (on the device)";

    fn check(s: &AtrousSettings) -> Result<()> {
        s.validate()
    }

    /// The sigmas left on auto take the values tuned for what is filtered.
    fn specialise(s: &mut AtrousSettings, _scene: &SceneInfo) -> Vec<String> {
        let [c, n, p] = s.sigmas();
        let what = if s.demodulate {
            "light / albedo"
        } else {
            "the beauty"
        };
        let mut notes = Vec::new();
        for (field, v, name) in [
            (&mut s.sigma_color, c, "sigma_color"),
            (&mut s.sigma_normal, n, "sigma_normal"),
            (&mut s.sigma_position, p, "sigma_position"),
        ] {
            if field.is_auto() {
                *field = Auto::Set(v);
                notes.push(format!("{name} = {v}: tuned for filtering {what}"));
            }
        }
        notes
    }

    /// Depth (for positions), normals and albedo of F, and the colour.
    fn needs(_: &AtrousSettings) -> OutputSet {
        OutputSet::of(&[Output::Colour, Output::Features])
    }

    fn prepare(
        s: &AtrousSettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        Ok(Box::new(AtrousKernel::new(
            gpu.clone(),
            s,
            &frame.scene.camera,
            frame.width,
            frame.height,
        )?))
    }
}
