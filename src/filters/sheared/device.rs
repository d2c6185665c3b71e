//! The sheared soft-shadow filter on the device (kernels/filters/sheared.cl): prepare, steps
//! 1a, 1b, 2a, 2b, then AAF's compose (kernels/filters/aaf_shadows.cl `aaf_compose_sheared`,
//! which reads the kind from the same guide lane).

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

use super::ShearedSettings;
use super::reference::{g_floats, p_floats};
use crate::filters::aaf_shadows::AafShadowSettings;
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue_rows, event_duration, read_rgb_rows};
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{AafShadowParams, Float4, ShearedParams};
use crate::render::Frame;

/// Names of the six launches, in order (per-step times in [`ShearedKernel::step_times`]).
pub const STEPS: [&str; 6] = ["prepare", "1a", "1b", "2a", "2b", "compose"];

/// What each step left on the device, read back (tests compare them with the reference).
pub struct Intermediates {
    pub guide: Vec<[f32; 4]>,
    pub p1a: Vec<f32>,
    pub g1b: Vec<f32>,
    pub q2a: Vec<f32>,
    pub visibility: Vec<f32>,
}

struct Passes {
    kernels: [Kernel; 6],
    _params: Buffer<ShearedParams>,
    _compose_params: Buffer<AafShadowParams>,
    guide: Buffer<Float4>,
    p1a: Buffer<f32>,
    g1b: Buffer<f32>,
    q2a: Buffer<f32>,
    visibility: Buffer<f32>,
    image: Buffer<Float4>,
}

/// The sheared filter, built for an image size and a light (none: the image passes through).
pub struct ShearedKernel {
    gpu: Arc<Gpu>,
    /// The sphere light filtered: the frame's shadow plane read (src/layout/outputs.rs
    /// `Per::Light`; a frame with other planes too gives its copy of this one).
    light_index: Option<u32>,
    passes: Option<Passes>,
    width: u32,
    height: u32,
    /// Most steps of a 1-D gather: the rows 1b and 2b each read beyond a band.
    max_radius: u32,
    step_times: [Duration; 6],
}

impl ShearedKernel {
    /// `light`: the filtered sphere light's centre and radius and the scene's centre, or None.
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &ShearedSettings,
        light: Option<([f32; 4], [f32; 3])>,
        width: u32,
        height: u32,
    ) -> Result<ShearedKernel> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let passes = match light {
            Some((l, centre)) => {
                let p = settings.params(l, centre, width, height);
                Some(Passes::new(&gpu, settings, &p, l)?)
            }
            None => None,
        };
        Ok(ShearedKernel {
            gpu,
            light_index: settings.light_index(),
            passes,
            width,
            height,
            max_radius: settings.max_radius,
            step_times: [Duration::ZERO; 6],
        })
    }

    /// Kernel time of each launch of the last run, in the order of [`STEPS`].
    pub fn step_times(&self) -> [Duration; 6] {
        self.step_times
    }

    /// Filters `frame` (width × height, with the light-field output unless there is no light)
    /// and reads the image back.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    /// Filters the pixels of `rows` only (one band of a frame split across devices): 2b reads
    /// q up to max_radius rows away (a step moves at most one row), 1b reads p and the guide
    /// up to max_radius rows further, so prepare and 1a run on the band widened by twice that,
    /// 1b and 2a by once, and the band's pixels get the bytes of the whole frame's filtering.
    /// The image's other rows are black.
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        let own = match self.light_index {
            Some(l) if self.passes.is_some() => {
                // The light field is sampled for the first plane's light only
                // (kernels/render/light_field.cl).
                if let Some(&first) = frame.info().shadow_lights.first()
                    && first != l
                {
                    bail!(
                        "the sheared filter reads the light field of sphere light {l}, but \
                         the frame's is of sphere light {first} (its first shadow plane): \
                         render it for the sheared filter"
                    );
                }
                frame.light_plane(l, "the sheared filter")?
            }
            _ => None,
        };
        let frame = own.as_ref().unwrap_or(frame);
        let h = self.height;
        let rows = rows.start.min(h)..rows.end.min(h);
        let widen = |r: u32| rows.start.saturating_sub(r)..(rows.end + r).min(h);
        let (wide, wider) = (widen(self.max_radius), widen(2 * self.max_radius));
        frame.check_size(self.width, self.height, "the sheared filter")?;
        let Some(p) = &mut self.passes else {
            let mut image = frame.beauty()?;
            for (y, row) in image.pixels.chunks_mut(self.width as usize).enumerate() {
                if !rows.contains(&(y as u32)) {
                    row.fill([0.0; 3]);
                }
            }
            return Ok(FilterRun {
                image,
                wall_time: start.elapsed(),
                kernel_time: Some(Duration::ZERO),
            });
        };
        frame.require(
            OutputSet::of(&[Output::Colour, Output::Shadows, Output::LightField]),
            "the sheared filter",
        )?;
        let shadow = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let field = frame.device(&self.gpu, BufferId::LightFieldPixels)?;
        let [prepare, k1a, k1b, _, k2b, compose] = &p.kernels;
        for k in [prepare, k1b, k2b] {
            k.set_arg("shadow_pixels", shadow)?;
        }
        for k in [prepare, k1a, k1b, k2b] {
            k.set_arg("light_field", field)?;
        }
        compose.set_arg("pixels", shadow)?;
        compose.set_arg("fv", frame.device(&self.gpu, BufferId::FilterVectors)?)?;
        compose.set_arg("terms", frame.device(&self.gpu, BufferId::ShadowTerms)?)?;
        let mut total = Duration::ZERO;
        let bands = [&wider, &wider, &wide, &wide, &rows, &rows];
        for (n, k) in p.kernels.iter().enumerate() {
            // SAFETY: every buffer is owned by self or the frame, both alive until the event
            // completes (enqueue_rows waits), and sized for width x height pixels.
            let event =
                unsafe { enqueue_rows(k, self.width, h, bands[n].clone(), STEPS[n])? };
            self.step_times[n] = event_duration(&event)?;
            total += self.step_times[n];
        }
        Ok(FilterRun {
            image: read_rgb_rows(&p.image, self.width, self.height, rows)?,
            wall_time: start.elapsed(),
            kernel_time: Some(total),
        })
    }

    /// The last run's intermediate buffers (None without a light).
    pub fn intermediates(&self) -> Result<Option<Intermediates>> {
        let Some(p) = &self.passes else {
            return Ok(None);
        };
        let read = |b: &Buffer<f32>| -> Result<Vec<f32>> {
            let mut v = vec![0f32; b.len()];
            b.read(&mut v).enq()?;
            Ok(v)
        };
        let mut guide = vec![Float4::default(); p.guide.len()];
        p.guide.read(&mut guide).enq()?;
        Ok(Some(Intermediates {
            guide: guide.into_iter().map(|g| g.0).collect(),
            p1a: read(&p.p1a)?,
            g1b: read(&p.g1b)?,
            q2a: read(&p.q2a)?,
            visibility: read(&p.visibility)?,
        }))
    }
}

impl Passes {
    fn new(gpu: &Gpu, s: &ShearedSettings, params: &ShearedParams, light: [f32; 4]) -> Result<Passes> {
        let (w, h) = (params.width, params.height);
        let n = w as usize * h as usize;
        let bins = s.bins;
        let bytes = s.memory_bytes(w, h);
        gpu.check_alloc(
            (n * p_floats(bins) * 4) as u64,
            "sheared filter's step-1a (p per bin and row)",
        )?;
        gpu.check_total(bytes, "the sheared filter's buffers")?;
        let program = gpu.program("filters/sheared.cl", &[], "")?;
        let aaf = gpu.program("filters/aaf_shadows.cl", &[], "")?;
        let params_buffer = gpu.upload(std::slice::from_ref(params))?;
        let compose_params =
            gpu.upload(&[AafShadowSettings::default().params(light, w, h, 0)])?;
        let guide = gpu.zeroed::<Float4>(n, "sheared guide")?;
        let p1a = gpu.zeroed::<f32>(n * p_floats(bins), "sheared step 1a")?;
        let g1b = gpu.zeroed::<f32>(n * g_floats(bins), "sheared step 1b")?;
        let q2a = gpu.zeroed::<f32>(n * g_floats(bins), "sheared step 2a")?;
        let visibility = gpu.zeroed::<f32>(n, "sheared visibility")?;
        let image = gpu.zeroed::<Float4>(n, "sheared image")?;
        let size = [w as usize, h as usize];
        fn kernel<'a>(
            gpu: &Gpu,
            prog: &'a ocl::Program,
            name: &str,
            size: [usize; 2],
        ) -> ocl::builders::KernelBuilder<'a> {
            let mut b = Kernel::builder();
            b.program(prog)
                .name(name)
                .queue(gpu.queue.clone())
                .global_work_size(size);
            b
        }
        let none = None::<&Buffer<u8>>;
        let what = "creating a sheared filter kernel";
        let prepare = kernel(gpu, &program, "sheared_prepare", size)
            .arg_named("p", &params_buffer)
            .arg_named("shadow_pixels", none)
            .arg_named("light_field", none)
            .arg(&guide)
            .build()
            .context(what)?;
        let k1a = kernel(gpu, &program, "sheared_1a", size)
            .arg_named("p", &params_buffer)
            .arg_named("light_field", none)
            .arg(&guide)
            .arg(&p1a)
            .build()
            .context(what)?;
        let k1b = kernel(gpu, &program, "sheared_1b", size)
            .arg_named("p", &params_buffer)
            .arg_named("shadow_pixels", none)
            .arg_named("light_field", none)
            .arg(&guide)
            .arg(&p1a)
            .arg(&g1b)
            .build()
            .context(what)?;
        let k2a = kernel(gpu, &program, "sheared_2a", size)
            .arg_named("p", &params_buffer)
            .arg(&guide)
            .arg(&g1b)
            .arg(&q2a)
            .build()
            .context(what)?;
        let k2b = kernel(gpu, &program, "sheared_2b", size)
            .arg_named("p", &params_buffer)
            .arg_named("shadow_pixels", none)
            .arg_named("light_field", none)
            .arg(&guide)
            .arg(&q2a)
            .arg(&visibility)
            .build()
            .context(what)?;
        let compose = kernel(gpu, &aaf, "aaf_compose_sheared", size)
            .arg_named("p", &compose_params)
            .arg_named("fv", none)
            .arg_named("terms", none)
            .arg_named("pixels", none)
            .arg(&guide)
            .arg(&visibility)
            .arg(&image)
            .build()
            .context(what)?;
        Ok(Passes {
            kernels: [prepare, k1a, k1b, k2a, k2b, compose],
            _params: params_buffer,
            _compose_params: compose_params,
            guide,
            p1a,
            g1b,
            q2a,
            visibility,
            image,
        })
    }
}

impl PreparedFilter for ShearedKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    fn reach(&self) -> Option<u32> {
        Some(2 * self.max_radius)
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}
