//! The sheared depth-of-field filter on the device (kernels/filters/sheared_dof.cl): prepare,
//! steps 1a, 1b, 2a, 2b; src/filters/sheared/dof.rs is its reference and says why. The GI
//! filter (kernels/filters/sheared_gi.cl, reference src/filters/sheared/gi.rs) has the same
//! launches, arguments and buffers over the GI field: [`DofKernel::gi`].

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

use super::dof::{g_floats, p_floats};
use crate::filters::FilterRun;
use crate::gpu::{Gpu, enqueue_rows, event_duration, read_rgb_rows};
use crate::layout::outputs::{BufferId, FieldKind, OutputSet};
use crate::layout::{Float4, LightFieldPixel, ShearedParams};
use crate::render::Frame;

/// Names of the five launches, in order.
pub const DOF_STEPS: [&str; 5] = ["prepare", "1a", "1b", "2a", "2b"];

/// What each step left on the device, read back (tests compare them with the reference).
pub struct DofIntermediates {
    pub guide: Vec<[f32; 4]>,
    pub p1a: Vec<f32>,
    pub g1b: Vec<f32>,
    pub q2a: Vec<f32>,
}

/// The sheared depth-of-field (or GI) filter, built for an image size and a lens (or the
/// v-plane).
pub struct DofKernel {
    gpu: Arc<Gpu>,
    kernels: [Kernel; 5],
    _params: Buffer<ShearedParams>,
    guide: Buffer<Float4>,
    p1a: Buffer<f32>,
    g1b: Buffer<f32>,
    q2a: Buffer<f32>,
    image: Buffer<Float4>,
    width: u32,
    height: u32,
    max_radius: u32,
    step_times: [Duration; 5],
    effect: &'static str,
    /// The light field the effect reads.
    field: FieldKind,
}

/// Device bytes per pixel: the light field, steps 1a-2a, the guide and the image.
pub fn bytes_per_pixel(bins: u32) -> u64 {
    (std::mem::size_of::<LightFieldPixel>() + 4 * (p_floats(bins) + 2 * g_floats(bins)) + 32)
        as u64
}

impl DofKernel {
    pub fn new(gpu: Arc<Gpu>, params: ShearedParams) -> Result<DofKernel> {
        let file = "filters/sheared_dof.cl";
        DofKernel::build(gpu, params, file, "dof", "depth-of-field", FieldKind::Lens)
    }

    /// The GI filter (kernels/filters/sheared_gi.cl) over the GI field.
    pub fn gi(gpu: Arc<Gpu>, params: ShearedParams) -> Result<DofKernel> {
        DofKernel::build(gpu, params, "filters/sheared_gi.cl", "gi", "GI", FieldKind::Gi)
    }

    fn build(
        gpu: Arc<Gpu>,
        params: ShearedParams,
        file: &str,
        prefix: &str,
        effect: &'static str,
        field: FieldKind,
    ) -> Result<DofKernel> {
        let (w, h) = (params.width, params.height);
        if w == 0 || h == 0 {
            bail!("the image must be at least 1x1 pixels, got {w}x{h}");
        }
        let n = w as usize * h as usize;
        let bins = params.bins;
        gpu.check_alloc(
            (n * p_floats(bins) * 4) as u64,
            &format!("sheared {effect} step 1a (rgbw per bin and row)"),
        )?;
        gpu.check_total(
            n as u64 * bytes_per_pixel(bins),
            &format!("the sheared {effect} filter's buffers"),
        )?;
        let program = gpu.program(file, &[], "")?;
        let params_buffer = gpu.upload(std::slice::from_ref(&params))?;
        let guide = gpu.zeroed::<Float4>(n, "sheared DOF guide")?;
        let p1a = gpu.zeroed::<f32>(n * p_floats(bins), "sheared DOF step 1a")?;
        let g1b = gpu.zeroed::<f32>(n * g_floats(bins), "sheared DOF step 1b")?;
        let q2a = gpu.zeroed::<f32>(n * g_floats(bins), "sheared DOF step 2a")?;
        let image = gpu.zeroed::<Float4>(n, "sheared DOF image")?;
        let none = None::<&Buffer<u8>>;
        let build = |name: &str| {
            let mut b = Kernel::builder();
            b.program(&program)
                .name(format!("{prefix}_{name}"))
                .queue(gpu.queue.clone())
                .global_work_size([w as usize, h as usize])
                .arg_named("p", &params_buffer);
            b
        };
        let what = format!("creating a sheared {effect} kernel");
        let prepare = build("prepare")
            .arg_named("light_field", none)
            .arg(&guide)
            .build()
            .context(what.clone())?;
        let k1a = build("1a")
            .arg_named("light_field", none)
            .arg(&guide)
            .arg(&p1a)
            .build()
            .context(what.clone())?;
        let k1b = build("1b")
            .arg_named("light_field", none)
            .arg(&guide)
            .arg(&p1a)
            .arg(&g1b)
            .build()
            .context(what.clone())?;
        let k2a = build("2a")
            .arg(&guide)
            .arg(&g1b)
            .arg(&q2a)
            .build()
            .context(what.clone())?;
        let k2b = build("2b")
            .arg_named("light_field", none)
            .arg_named("fv", none)
            .arg(&guide)
            .arg(&q2a)
            .arg(&image)
            .build()
            .context(what.clone())?;
        Ok(DofKernel {
            gpu,
            kernels: [prepare, k1a, k1b, k2a, k2b],
            _params: params_buffer,
            guide,
            p1a,
            g1b,
            q2a,
            image,
            width: w,
            height: h,
            max_radius: params.max_radius.max(0) as u32,
            step_times: [Duration::ZERO; 5],
            effect,
            field,
        })
    }

    /// Kernel time of each launch of the last run, in the order of [`DOF_STEPS`].
    pub fn step_times(&self) -> [Duration; 5] {
        self.step_times
    }

    /// Most rows a pixel's result reads away from it (2b's column gather).
    pub fn reach(&self) -> u32 {
        self.max_radius
    }

    /// Filters the pixels of `rows` (a band of a split frame: the steps before 2b run on the
    /// band widened by 2b's reach, so the band gets the whole frame's bytes).
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        frame.check_size(self.width, self.height, "the sheared filter")?;
        // The frame records which field its light-field output holds (the shadow fields of
        // a render with the shadow output, the lens field or the GI field): another one than
        // this effect reads is refused rather than filtered as the wrong samples.
        frame.require(
            OutputSet::colour().with_field(self.field),
            &format!("the sheared filter ({})", self.effect),
        )?;
        let field = frame.device(&self.gpu, BufferId::LightFieldPixels)?;
        self.filter_field_rows(frame, field, rows)
    }

    /// [`Self::filter_rows`] over `field` (a [`LightFieldPixel`] per pixel on this device)
    /// in place of the frame's light-field output: the lens field that sheared shadows with
    /// depth of field composes (src/filters/sheared/lens_shadows.rs). It must hold the rows
    /// within [`Self::reach`] of `rows`.
    pub fn filter_field_rows(
        &mut self,
        frame: &Frame,
        field: &Buffer<u8>,
        rows: Range<u32>,
    ) -> Result<FilterRun> {
        let start = Instant::now();
        let h = self.height;
        frame.check_size(self.width, h, "the sheared filter")?;
        let rows = rows.start.min(h)..rows.end.min(h);
        let wide = rows.start.saturating_sub(self.max_radius)..(rows.end + self.max_radius).min(h);
        let [prepare, k1a, k1b, _, k2b] = &self.kernels;
        for k in [prepare, k1a, k1b, k2b] {
            k.set_arg("light_field", field)?;
        }
        k2b.set_arg("fv", frame.device(&self.gpu, BufferId::FilterVectors)?)?;
        let mut total = Duration::ZERO;
        for (n, k) in self.kernels.iter().enumerate() {
            let band = if n == 4 { rows.clone() } else { wide.clone() };
            // SAFETY: every buffer is owned by self or the frame, both alive until the event
            // completes (enqueue_rows waits), and sized for width x height pixels.
            let event = unsafe { enqueue_rows(k, self.width, h, band, DOF_STEPS[n])? };
            self.step_times[n] = event_duration(&event)?;
            total += self.step_times[n];
        }
        Ok(FilterRun {
            image: read_rgb_rows(&self.image, self.width, h, rows)?,
            wall_time: start.elapsed(),
            kernel_time: Some(total),
        })
    }

    /// The last run's intermediate buffers.
    pub fn intermediates(&self) -> Result<DofIntermediates> {
        let read = |b: &Buffer<f32>| -> Result<Vec<f32>> {
            let mut v = vec![0f32; b.len()];
            b.read(&mut v).enq()?;
            Ok(v)
        };
        let mut guide = vec![Float4::default(); self.guide.len()];
        self.guide.read(&mut guide).enq()?;
        Ok(DofIntermediates {
            guide: guide.into_iter().map(|g| g.0).collect(),
            p1a: read(&self.p1a)?,
            g1b: read(&self.g1b)?,
            q2a: read(&self.q2a)?,
        })
    }
}

impl crate::filters::PreparedFilter for DofKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    fn reach(&self) -> Option<u32> {
        Some(self.max_radius)
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}
