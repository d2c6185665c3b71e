//! The data-driven filter of thesis ch. 6 (Algorithm 8): settings, the OpenCL kernels of
//! kernels/filters/ddf.cl (naive, vector loads, local-memory rows; holes) and the plain Rust reference
//! of the same equations.

use std::sync::Arc;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Event, Kernel};
use rayon::prelude::*;

use super::{DeviceBuffers, Filtered};
use crate::gpu::{Gpu, event_duration, round_up};
use crate::imaging::RgbImage;
use crate::layout::{DdfParams, FilterVector, Float4, GBuffer, SKY_DEPTH};
use crate::stats::PixelBuffers;

/// How a pixel's neighbourhood is read (§6.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// Every neighbour's FilterVector from global memory, field by field (Fig. 6.8).
    Naive,
    /// The same with float16 vector loads (§6.3.1).
    Vector,
    /// Local-memory rows (§6.3.2, Fig. 6.10) with a work-group of this many pixels.
    Rows { work_group: usize },
}

impl Variant {
    fn define(self) -> u32 {
        match self {
            Variant::Naive => 0,
            Variant::Vector => 1,
            Variant::Rows { .. } => 2,
        }
    }

    pub fn label(self) -> String {
        match self {
            Variant::Naive => "naive".into(),
            Variant::Vector => "vector".into(),
            Variant::Rows { work_group } => format!("rows-wg{work_group}"),
        }
    }
}

/// The direction factor of eq. 6.14.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DirectionTerm {
    /// As printed: exp(-sigma2_f,3), the same for every neighbour of a pixel, so it cancels in
    /// the normalisation of eq. 6.21 (the filter does not depend on sigma_f direction).
    #[default]
    Thesis,
    /// Our variant: exp(-sigma2_f,3 |d - d_N|^2) on the pixels' mean first-bounce directions,
    /// so glossy (high direction variance) and mirror-like pixels are told apart.
    Difference,
}

/// The user's parameters (Table 6.2), defaults from Table 7.2.
#[derive(Clone, Debug, PartialEq)]
pub struct DdfSettings {
    /// Kernel width kw (odd).
    pub kw: u32,
    pub sigma_dc: f32,
    pub sigma_ic: f32,
    /// sigma_f for depth, normal, texture, direction, texture2.
    pub sigma_f: [f32; 5],
    /// Variance scales s_f, same order. The thesis gives no values; see DEFAULT_VARIANCE_SCALE.
    pub variance_scale: [f32; 5],
    /// Holes: every second neighbour in x and y (§6.3.3).
    pub holes: bool,
    pub direction: DirectionTerm,
    /// Use the texture2 term of eq. 6.14.
    pub texture2: bool,
    /// Sky pixels keep their unfiltered colour (§6.3.4).
    pub sky: bool,
}

/// The variance scales s_f (depth, normal, texture, direction, texture2). The thesis leaves
/// them open. Ours come from `noisefree bench --study sweep` (results/pocl-cpu/sweep.md: 512 x
/// 512, Table 7.1's base sigmas, each scale tried at 0, 0.1, 1, 10 and 100 on its own), by the
/// rule: the value with the lowest MSE summed over the swept scenes, unless another value is
/// within 1 % of it, then the neutral 1.
/// - depth 0: Cornell diffuse with and without depth of field 7.07 (0) against 7.72 (1);
///   relaxing the depth weight where depth varies lets out-of-focus colour bleed into sharp
///   objects.
/// - normal 1, texture 1: every value within 1 % (normal 7.71-7.72, texture 7.71-7.72).
/// - direction 1: no effect, the printed direction factor cancels (see [`DirectionTerm`]).
/// - texture2 10: Cornell glossy and Outside 38.4 (10) against 41.1 (1).
pub const DEFAULT_VARIANCE_SCALE: [f32; 5] = [0.0, 1.0, 1.0, 1.0, 10.0];

impl Default for DdfSettings {
    fn default() -> Self {
        DdfSettings {
            kw: 21,
            sigma_dc: 0.75,
            sigma_ic: 0.5,
            sigma_f: [1.75, 0.25, 0.1, 0.75, 0.1],
            variance_scale: DEFAULT_VARIANCE_SCALE,
            holes: false,
            direction: DirectionTerm::Thesis,
            texture2: true,
            sky: true,
        }
    }
}

pub const FEATURE_NAMES: [&str; 5] = ["depth", "normal", "texture", "direction", "texture2"];

impl DdfSettings {
    pub fn validate(&self) -> Result<()> {
        if self.kw == 0 || self.kw % 2 == 0 {
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
        Ok(())
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

/// The data-driven filter on the device, built once per variant and option set.
pub struct DdfFilter {
    _gpu: Arc<Gpu>,
    /// Stand-ins for the input buffers until the first run sets them.
    _placeholders: (
        Buffer<FilterVector>,
        Buffer<GBuffer>,
        Buffer<crate::layout::StatsState>,
    ),
    kernel: Kernel,
    params: Buffer<DdfParams>,
    out: Buffer<Float4>,
    variant: Variant,
    settings: DdfSettings,
    width: u32,
    height: u32,
}

impl DdfFilter {
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &DdfSettings,
        variant: Variant,
        width: u32,
        height: u32,
    ) -> Result<DdfFilter> {
        DdfFilter::with_work_group(gpu, settings, variant, width, height, None)
    }

    /// Like [`DdfFilter::new`]; the naive and vector variants run in work-groups of
    /// `work_group` x 1 pixels when given (the driver chooses otherwise). The rows variant's
    /// work-group is part of the variant.
    pub fn with_work_group(
        gpu: Arc<Gpu>,
        settings: &DdfSettings,
        variant: Variant,
        width: u32,
        height: u32,
        work_group: Option<usize>,
    ) -> Result<DdfFilter> {
        settings.validate()?;
        let defines = vec![
            ("DDF_VARIANT".to_string(), variant.define().to_string()),
            ("DDF_SKY".to_string(), (settings.sky as u32).to_string()),
            (
                "DDF_TEXTURE2".to_string(),
                (settings.texture2 as u32).to_string(),
            ),
            (
                "DDF_DIRECTION".to_string(),
                ((settings.direction == DirectionTerm::Difference) as u32).to_string(),
            ),
        ];
        let program = gpu.program("filters/ddf.cl", &defines, "")?;
        let pixels = width as usize * height as usize;
        let params = gpu.upload(&[settings.params(width, height, 1.0, 1.0)])?;
        let out = gpu.zeroed::<Float4>(pixels, "filtered image")?;
        let (w, h) = (width as usize, height as usize);
        let mut b = Kernel::builder();
        b.program(&program)
            .name("ddf_filter")
            .queue(gpu.queue.clone());
        // Placeholders for the input buffers; set per run.
        let dummy_f = gpu.zeroed::<FilterVector>(1, "placeholder")?;
        let dummy_g = gpu.zeroed::<GBuffer>(1, "placeholder")?;
        let dummy_s = gpu.zeroed::<crate::layout::StatsState>(1, "placeholder")?;
        b.arg(&params)
            .arg(&dummy_f)
            .arg(&dummy_g)
            .arg(&dummy_s)
            .arg(&out);
        match variant {
            Variant::Rows { work_group } => {
                let max = gpu.summary.max_work_group_size;
                if work_group == 0 || (max > 0 && work_group > max) {
                    bail!(
                        "work-group size {work_group} is not supported by {} (max {max})",
                        gpu.summary.name
                    );
                }
                // One float16 per work-item: 64 bytes x work-group size (§6.3.2).
                b.arg_local::<ocl::prm::Float16>(work_group);
                b.global_work_size([round_up(w, work_group), h])
                    .local_work_size([work_group, 1]);
            }
            _ => match work_group {
                Some(wg) if wg > 0 => {
                    b.global_work_size([round_up(w, wg), h])
                        .local_work_size([wg, 1]);
                }
                _ => {
                    b.global_work_size([w, h]);
                }
            },
        }
        let kernel = b
            .build()
            .context("creating the data-driven filter kernel")?;
        Ok(DdfFilter {
            _gpu: gpu,
            _placeholders: (dummy_f, dummy_g, dummy_s),
            kernel,
            params,
            out,
            variant,
            settings: settings.clone(),
            width,
            height,
        })
    }

    pub fn variant(&self) -> Variant {
        self.variant
    }

    /// Filters `buffers` (which must be width x height) and reads the image back.
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
        let p = self.settings.params(
            self.width,
            self.height,
            buffers.variance_factor,
            buffers.depth_scale,
        );
        self.params.write(std::slice::from_ref(&p)).enq()?;
        self.kernel.set_arg(1, buffers.filter_vectors)?;
        self.kernel.set_arg(2, buffers.gbuffers)?;
        self.kernel.set_arg(3, buffers.stats_state)?;
        let mut event = Event::empty();
        // SAFETY: all buffers outlive the launch (we wait for it) and hold width x height pixels.
        unsafe {
            self.kernel
                .cmd()
                .enew(&mut event)
                .enq()
                .context("launching the data-driven filter")?;
        }
        let kernel_time = event_duration(&event)?;
        let mut out = vec![Float4::default(); self.out.len()];
        self.out.read(&mut out).enq()?;
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

/// The plain Rust reference of kernels/filters/ddf.cl (all variants compute this).
pub fn reference(b: &PixelBuffers, s: &DdfSettings) -> Result<RgbImage> {
    s.validate()?;
    let variances = b
        .variances
        .as_ref()
        .context("the data-driven filter needs the feature variances")?;
    let (w, h) = (b.width as i32, b.height as i32);
    let p = s.params(
        b.width,
        b.height,
        1.0,
        crate::stats::depth_scale(b.scene_size),
    );
    let dir = |i: usize| b.directions.as_ref().map_or([0.0; 3], |d| d[i]);
    let lanes = |f: &FilterVector| -> [f32; 16] {
        let mut x = [0f32; 16];
        x[..3].copy_from_slice(&f.direct);
        x[3..6].copy_from_slice(&f.indirect);
        x[6] = f.depth;
        x[7..10].copy_from_slice(&f.normal);
        x[10..13].copy_from_slice(&f.albedo);
        x[13..16].copy_from_slice(&f.albedo2);
        x
    };
    let sq = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f32>();
    let pixels = (0..(w * h) as usize)
        .into_par_iter()
        .map(|pixel| {
            let fc = lanes(&b.filter_vectors[pixel]);
            if s.sky && fc[6] >= SKY_DEPTH {
                return [fc[0] + fc[3], fc[1] + fc[4], fc[2] + fc[5]];
            }
            let g: &GBuffer = &variances[pixel];
            let mut sums = crate::stats::feature_variance_sums(g);
            sums[0] *= p.depth_scale * p.depth_scale;
            let sigma2_f: [f32; 5] = std::array::from_fn(|i| {
                p.sigma2_f[i] * (1.0 - (sums[i] * p.variance_scale[i]).clamp(0.0, 1.0))
            });
            let (mut c_fd, mut c_fi, mut tw_d, mut tw_i) = ([0f32; 3], [0f32; 3], 0f32, 0f32);
            let dc = dir(pixel);
            let mut visit = |n: &[f32; 16], dn: [f32; 3]| {
                let e_dc = p.sigma2_dc * sq(&fc[0..3], &n[0..3]);
                let e_ic = p.sigma2_ic * sq(&fc[3..6], &n[3..6]);
                let dd = (fc[6] - n[6]) * p.depth_scale;
                let e_fd = sigma2_f[0] * dd * dd
                    + sigma2_f[1] * sq(&fc[7..10], &n[7..10])
                    + sigma2_f[2] * sq(&fc[10..13], &n[10..13]);
                let mut e_fi = e_fd;
                if s.texture2 {
                    e_fi += sigma2_f[4] * sq(&fc[13..16], &n[13..16]);
                }
                e_fi += match s.direction {
                    DirectionTerm::Thesis => sigma2_f[3],
                    DirectionTerm::Difference => sigma2_f[3] * sq(&dc, &dn),
                };
                let w_d = (-(e_dc + e_fd)).exp();
                let w_i = (-(e_ic + e_fi)).exp();
                for c in 0..3 {
                    c_fd[c] += w_d * n[c];
                    c_fi[c] += w_i * n[3 + c];
                }
                tw_d += w_d;
                tw_i += w_i;
            };
            let (x, y) = (pixel as i32 % w, pixel as i32 / w);
            let mut dy = -p.half_width;
            while dy <= p.half_width {
                let ny = y + dy;
                if (0..h).contains(&ny) {
                    let mut dx = -p.half_width;
                    while dx <= p.half_width {
                        let nx = x + dx;
                        if (0..w).contains(&nx) {
                            let ni = (ny * w + nx) as usize;
                            visit(&lanes(&b.filter_vectors[ni]), dir(ni));
                        }
                        dx += p.step;
                    }
                }
                dy += p.step;
            }
            if p.half_width % p.step != 0 {
                visit(&fc, dc);
            }
            std::array::from_fn(|c| {
                let d = if tw_d > 0.0 { c_fd[c] / tw_d } else { fc[c] };
                let i = if tw_i > 0.0 {
                    c_fi[c] / tw_i
                } else {
                    fc[3 + c]
                };
                d + i
            })
        })
        .collect();
    Ok(RgbImage {
        width: b.width,
        height: b.height,
        pixels,
    })
}
