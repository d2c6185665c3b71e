//! The data-driven filter of thesis ch. 6 (Algorithm 8): a cross-bilateral filter without a
//! spatial term whose feature weights relax where the pixel's own features are noisy
//! (eq. 6.10), filtering direct and indirect light separately (eqs. 6.11-6.21).
//!
//! - [`DdfSettings`]: the parameters of Table 6.2, defaults of Table 7.2;
//! - `device.rs`: the OpenCL kernels of kernels/filters/ddf.cl (naive, vector loads,
//!   local-memory rows; holes; packed float16 lanes);
//! - `reference.rs`: the plain Rust reference of the same equations.

mod device;
mod reference;

use std::sync::Arc;

use anyhow::{Result, bail};
use serde::{Deserialize, Serialize};

use super::{Auto, FilterKind, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::DdfParams;
use crate::layout::outputs::{Output, OutputSet};
use crate::render::{FrameInfo, SceneInfo};
pub use device::{DdfKernel, PACKED_GROUP};
pub use reference::reference;

/// How a pixel's neighbourhood is read (§6.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Variant {
    /// `packed` on CPU devices, `naive` on NVIDIA's GPUs without holes, `rows` on the others:
    /// on PoCL (CPU) the packed variant took 0.15x the time of rows at 512 x 512, kw 21,
    /// within 2.8e-7 (relative) of its image (results/README.md "Roofline", tests/ddf.rs).
    /// On an H200 packed took 9-15x the time of rows (16 pixels per work-item leave 16 times
    /// fewer work-items), and the thesis's local-memory rows were slower than the naive
    /// kernel, whose reads the L1 cache serves: 0.97 against 1.52 ms at kw 21, 6.4 against
    /// 10.6 ms at kw 55 (512 x 512, cornell_diffuse; results/gpu/nvidia-h200/). Naive with
    /// holes was not measured there, so holes keep rows; other GPUs keep the thesis's rows.
    Auto,
    /// Every neighbour's FilterVector from global memory, field by field (Fig. 6.8).
    Naive,
    /// The same with float16 vector loads (§6.3.1).
    Vector,
    /// Local-memory rows (§6.3.2, Fig. 6.10), `work_group` pixels per work-group.
    Rows,
    /// Ours, for CPUs: `device::PACK` adjacent pixels per work-item on float16 lanes
    /// (kernels/filters/ddf_packed.cl), the neighbours read from padded planes.
    Packed,
}

impl Variant {
    /// The variant this one stands for on `device` with or without `holes`:
    /// [`Variant::Auto`] chosen, the others as they are.
    pub fn for_device(self, device: &crate::gpu::DeviceSummary, holes: bool) -> Variant {
        match self {
            Variant::Auto if device.kind == "CPU" => Variant::Packed,
            Variant::Auto if device.platform.contains("NVIDIA") && !holes => Variant::Naive,
            Variant::Auto => Variant::Rows,
            v => v,
        }
    }
}

/// The direction factor of eq. 6.14.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DirectionTerm {
    /// As printed: exp(-sigma2_f,3), the same for every neighbour of a pixel, so it cancels in
    /// the normalisation of eq. 6.21 (the filter does not depend on sigma_f direction).
    #[default]
    Thesis,
    /// Our variant: exp(-sigma2_f,3 |d - d_N|^2) on the pixels' mean first-bounce directions,
    /// so glossy (high direction variance) and mirror-like pixels are told apart.
    Difference,
    /// The other reading of the printed factor: exp(-sigma2_f,3) with sigma2_f,3 formed by
    /// eq. 6.10 from the neighbour's own direction variance (§6.2.3: "the bounce direction
    /// variance ... is used when the indirect weight is calculated"), so it differs from
    /// neighbour to neighbour and does not cancel: rough neighbours (whose bounce directions
    /// scatter) weigh more than mirror-like ones.
    Neighbour,
}

/// The variance scales s_f (depth, normal, texture, direction, texture2). The thesis leaves
/// them open. Ours come from `noisefree bench --study sweep` (results/pocl-cpu/sweep.md: 512 x
/// 512, Table 7.1's base sigmas, each scale tried at 0, 0.1, 1, 10 and 100 on its own), by the
/// rule: the value with the lowest MSE summed over the swept scenes, unless another value is
/// within 1 % of it, then the neutral 1.
/// Sums over Cornell diffuse with and without depth of field (depth, normal, texture) and over
/// those and Cornell glossy and Outside (direction, texture2), at kw 21, 2048-spp references
/// (sweep of 2026-11-23):
/// - depth 0: 6.79 (0) against 7.44 (1); relaxing the depth weight where depth varies lets
///   out-of-focus colour bleed into sharp objects.
/// - normal 1, texture 1: every value from 0 to 1 within 1 % (7.44-7.44).
/// - direction 1: no effect, the printed direction factor cancels (see [`DirectionTerm`]).
/// - texture2 100: 44.99 (100) against 45.09 (10) and 47.79 (1): the largest value of the
///   range wins, by 0.2 % over 10; large scales let noisy texture2 differences pass where their
///   variance is high, i.e. the term acts only where the reflected texture is well sampled.
pub const DEFAULT_VARIANCE_SCALE: [f32; 5] = [0.0, 1.0, 1.0, 1.0, 100.0];

pub const FEATURE_NAMES: [&str; 5] = ["depth", "normal", "texture", "direction", "texture2"];

crate::filter_settings! {
    /// The data-driven filter's parameters (thesis Table 6.2; defaults Table 7.2).
    pub struct DdfSettings, flags "" {
        /// Kernel width kw, odd (Table 6.2).
        pub kw: u32 = 21,
        /// Direct colour sigma_dc (eq. 6.8).
        pub sigma_dc: f32 = 0.75,
        /// Indirect colour sigma_ic (eq. 6.9).
        pub sigma_ic: f32 = 0.5,
        /// Feature sigmas sigma_f: depth (in hundredths of the scene size), normal, texture,
        /// direction, texture2 (eq. 6.10).
        pub sigma_f: [f32; 5] = [1.75, 0.25, 0.1, 0.75, 0.1],
        /// Variance scales s_f, same order (eq. 6.10; the thesis gives none, ours come from
        /// the sweep of bench, see DEFAULT_VARIANCE_SCALE).
        pub variance_scale: [f32; 5] = DEFAULT_VARIANCE_SCALE,
        /// Holes: every second neighbour in x and y (§6.3.3).
        pub holes: bool = false,
        /// The direction factor of eq. 6.14: "thesis" (as printed, the centre's variance; it
        /// cancels), "neighbour" (the neighbour's variance) or "difference" (of the mean
        /// first-bounce directions).
        pub direction: DirectionTerm = DirectionTerm::Thesis,
        /// The texture2 term of eq. 6.14; auto: on when the scene has mirror, glass or metal
        /// surfaces (§6.2.1: it keeps detail seen in mirrors and through glass).
        pub texture2: Auto<bool> = Auto::Auto,
        /// Sky pixels keep their unfiltered colour (§6.3.4); auto: on when the scene has an
        /// environment light (else no pixel can be sky).
        pub sky: Auto<bool> = Auto::Auto,
        /// Kernel variant (§6.3): "naive", "vector", "rows", "packed" (ours: 16 pixels per
        /// work-item on float16 lanes) or "auto" (packed on a CPU, naive on NVIDIA GPUs
        /// without holes, rows on other devices).
        pub variant: Variant = Variant::Auto,
        /// Work-group size of the rows variant (§6.3.2).
        pub work_group: u32 = 64,
        /// A fast mode: a degree-5 polynomial exponential (kernels/filters/ddf.cl `ddf_exp`)
        /// in the two weights (eqs. 6.15, 6.16) in place of the built-in `exp`. On PoCL (CPU)
        /// its image differs from the exact one by at most 4.2e-7 (relative;
        /// tests/ddf.rs `fast_exp_stays_near_the_exact_filter`); the exact filter stays the
        /// default. It saved 0-3 % of the packed kernel's time on PoCL (results/README.md
        /// "Roofline"); OpenCL's native_exp gave the same bits as exp there.
        pub fast_exp: bool = false,
    }
}

impl DdfSettings {
    pub fn validate(&self) -> Result<()> {
        if self.kw == 0 || self.kw.is_multiple_of(2) {
            bail!(
                "the kernel width kw must be a positive odd number (Table 6.2), got {}",
                self.kw
            );
        }
        if self.kw > 4095 {
            bail!(
                "kernel width {} is larger than any image noisefree renders",
                self.kw
            );
        }
        for (v, name) in [(self.sigma_dc, "sigma_dc"), (self.sigma_ic, "sigma_ic")] {
            if !(v > 0.0 && v.is_finite()) {
                bail!("{name} must be a positive number (Table 6.2), got {v}");
            }
        }
        for (i, v) in self.sigma_f.iter().enumerate() {
            if !(*v > 0.0 && v.is_finite()) {
                bail!(
                    "sigma_f {} must be a positive number (Table 6.2), got {v}",
                    FEATURE_NAMES[i]
                );
            }
        }
        for (i, v) in self.variance_scale.iter().enumerate() {
            if !(*v >= 0.0 && v.is_finite()) {
                bail!(
                    "variance scale s_f {} must be >= 0 (Table 6.2), got {v}",
                    FEATURE_NAMES[i]
                );
            }
        }
        if self.work_group == 0 {
            bail!("work_group must be at least 1");
        }
        Ok(())
    }

    /// The texture2 term is on (auto, before specialisation: as printed, on).
    pub fn uses_texture2(&self) -> bool {
        self.texture2.or(true)
    }

    /// Sky pixels keep their colour (auto, before specialisation: as printed, on).
    pub fn keeps_sky(&self) -> bool {
        self.sky.or(true)
    }

    /// Eqs. 6.8-6.9 and the constant part of 6.10, for an image of w x h.
    pub fn params(
        &self,
        width: u32,
        height: u32,
        variance_factor: f32,
        depth_scale: f32,
    ) -> DdfParams {
        let inv2 = |s: f32| 1.0 / (2.0 * s * s);
        DdfParams {
            width,
            height,
            half_width: ((self.kw - 1) / 2) as i32,
            step: if self.holes { 2 } else { 1 },
            sigma2_dc: inv2(self.sigma_dc),
            sigma2_ic: inv2(self.sigma_ic),
            variance_factor,
            depth_scale,
            sigma2_f: self.sigma_f.map(inv2),
            variance_scale: self.variance_scale,
            ..Default::default()
        }
    }
}

/// The data-driven filter in the registry.
pub struct Ddf;

impl FilterKind for Ddf {
    type Settings = DdfSettings;
    const NAME: &'static str = "ddf";
    const SUMMARY: &'static str = "the data-driven filter of thesis ch. 6 (on the device)";

    fn check(s: &DdfSettings) -> Result<()> {
        s.validate()
    }

    /// Like the megakernel, the filter is specialised to the scene: no sky branch without an
    /// environment light (§6.3.4), no texture2 term when nothing in the scene reflects or
    /// refracts (§6.2.1).
    fn specialise(s: &mut DdfSettings, scene: &SceneInfo) -> Vec<String> {
        let mut notes = Vec::new();
        if s.sky.is_auto() {
            let env = scene.has("HAS_ENV");
            s.sky = Auto::Set(env);
            notes.push(format!(
                "sky = {env}: {}",
                if env {
                    "the scene has an environment light, sky pixels keep their colour (§6.3.4)"
                } else {
                    "no environment light, so no pixel is sky"
                }
            ));
        }
        if s.texture2.is_auto() {
            let reflects = ["HAS_SPECULAR", "HAS_GLASS", "HAS_METAL"]
                .iter()
                .any(|e| scene.has(e));
            s.texture2 = Auto::Set(reflects);
            notes.push(format!(
                "texture2 = {reflects}: {}",
                if reflects {
                    "the scene has mirror, glass or metal surfaces (§6.2.1)"
                } else {
                    "no mirror, glass or metal surface, nothing is seen through them"
                }
            ));
        }
        notes
    }

    /// The feature variances of eq. 6.10 (and, with them in WelfordState, the mean
    /// first-bounce directions of the `difference` variant).
    fn needs(_: &DdfSettings) -> OutputSet {
        OutputSet::of(&[Output::Colour, Output::Features, Output::Variance])
    }

    fn prepare(
        s: &DdfSettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        Ok(Box::new(DdfKernel::new(
            gpu.clone(),
            s,
            frame.width,
            frame.height,
        )?))
    }
}

#[cfg(test)]
mod tests {
    use super::Variant;
    use crate::gpu::DeviceSummary;

    fn device(platform: &str, kind: &str) -> DeviceSummary {
        DeviceSummary {
            index: 0,
            platform: platform.into(),
            name: String::new(),
            kind: kind.into(),
            version: String::new(),
            driver: String::new(),
            compute_units: 1,
            local_mem_bytes: 0,
            global_mem_bytes: 0,
            max_alloc_bytes: 0,
            max_work_group_size: 1,
            max_clock_mhz: 0,
            correctly_rounded_divide_sqrt: true,
        }
    }

    #[test]
    fn auto_takes_the_variant_measured_fastest_on_each_kind_of_device() {
        let pocl = device("Portable Computing Language", "CPU");
        let nvidia = device("NVIDIA CUDA", "GPU");
        let amd = device("AMD Accelerated Parallel Processing", "GPU");
        assert_eq!(Variant::Auto.for_device(&pocl, false), Variant::Packed);
        assert_eq!(Variant::Auto.for_device(&pocl, true), Variant::Packed);
        assert_eq!(Variant::Auto.for_device(&nvidia, false), Variant::Naive);
        assert_eq!(Variant::Auto.for_device(&nvidia, true), Variant::Rows);
        assert_eq!(Variant::Auto.for_device(&amd, false), Variant::Rows);
        // A variant named is kept.
        assert_eq!(Variant::Vector.for_device(&nvidia, false), Variant::Vector);
    }
}
