//! The stylized-shadows filter on the device (kernels/filters/stylized.cl), in three stages
//! that can run alone: [`StylizedKernel::distance`] (contour, compaction on the host, eq. 3.2;
//! once per render), [`StylizedKernel::blur`] (when α changes) and
//! [`StylizedKernel::compose`] (when i, s or b change).

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel, Program};

use super::transfer::{Controls, LANES};
use super::{DISTANCE_SEED, StylizedSettings, blur, contour};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue, event_duration, read_rgb};
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{Float2, Float4};
use crate::render::Frame;

/// The kernels and their buffers for one image size.
struct Passes {
    program: Program,
    slots: Buffer<Float4>,
    /// The compacted contour list of the last `distance` (None: not run yet).
    contour: Option<Buffer<Float4>>,
    contour_points: u32,
    dist: Buffer<f32>,
    occluder: Buffer<f32>,
    blurred: [Buffer<f32>; 2],
    stencils: [Buffer<Float2>; 2],
    controls: Buffer<f32>,
    matte: Buffer<f32>,
    image: Buffer<Float4>,
}

/// The stylized-shadows filter, built for an image size (without a light the image passes
/// through untouched).
pub struct StylizedKernel {
    gpu: Arc<Gpu>,
    settings: StylizedSettings,
    passes: Option<Passes>,
    width: u32,
    height: u32,
    /// The shadow pixels the last distance step read (bytes), and whether the blur is of
    /// that distance with the current α: [`Self::filter`] re-runs a step only when its input
    /// changed (the shadow output is computed once per render, before the path samples, so a
    /// progressive render's frames re-run the compose alone; §3.3.3: the distance "only when
    /// the camera or light changes").
    last_pixels: Option<Vec<u8>>,
    blur_current: bool,
}

impl StylizedKernel {
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &StylizedSettings,
        light: bool,
        width: u32,
        height: u32,
    ) -> Result<StylizedKernel> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let passes = if light {
            Some(Passes::new(&gpu, settings, width, height)?)
        } else {
            None
        };
        Ok(StylizedKernel {
            gpu,
            settings: settings.clone(),
            passes,
            width,
            height,
            last_pixels: None,
            blur_current: false,
        })
    }

    fn kernel<'a>(&self, p: &'a Passes, name: &str) -> ocl::builders::KernelBuilder<'a> {
        let mut b = Kernel::builder();
        b.program(&p.program)
            .name(name.to_string())
            .queue(self.gpu.queue.clone())
            .global_work_size([self.width as usize, self.height as usize]);
        b
    }

    /// Steps 1-2 on `frame`: the contour (compacted in pixel order on the host, as the thesis
    /// does on its CPU) and D with d(x). Returns the kernel time.
    pub fn distance(&mut self, frame: &Frame) -> Result<Duration> {
        frame.check_size(self.width, self.height, "the stylized-shadows filter")?;
        let Some(p) = &self.passes else {
            return Ok(Duration::ZERO);
        };
        frame.require(
            OutputSet::of(&[Output::Colour, Output::Shadows]),
            "the stylized-shadows filter",
        )?;
        let s = &self.settings;
        let pixels = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let normal_cos = s.normal_cos();
        let k = self
            .kernel(p, "st_contour")
            .arg(pixels)
            .arg(&p.slots)
            .arg(self.width)
            .arg(self.height)
            .arg(normal_cos)
            .arg(s.surface_gap)
            .build()
            .context("creating the contour kernel")?;
        // SAFETY: the buffers are the frame's and ours, sized for the image, alive until the
        // event completes (we wait on it).
        let mut time = event_duration(&unsafe { enqueue(&k, "the contour kernel")? })?;
        let mut slots = vec![Float4::default(); p.slots.len()];
        p.slots.read(&mut slots).enq().context("reading the contour slots")?;
        let list = contour::compact(&slots);
        let count = (list.len() / 2) as u32;
        let buffer = self.gpu.upload(&list)?;
        let sampling =
            super::distance::Sampling::new(count, s.contour_samples, DISTANCE_SEED, normal_cos);
        let k = self
            .kernel(p, "st_distance")
            .arg(pixels)
            .arg(&buffer)
            .arg(count)
            .arg(sampling.n)
            .arg(sampling.scale)
            .arg(sampling.seed)
            .arg(normal_cos)
            .arg(self.width)
            .arg(self.height)
            .arg(&p.dist)
            .arg(&p.occluder)
            .build()
            .context("creating the distance kernel")?;
        // SAFETY: as above; `buffer` lives until it is stored below, after the wait.
        time += event_duration(&unsafe { enqueue(&k, "the distance kernel")? })?;
        let p = self.passes.as_mut().expect("checked above");
        p.contour = Some(buffer);
        p.contour_points = count;
        self.blur_current = false;
        Ok(time)
    }

    /// Writes the controls (no kernel runs).
    pub fn set_controls(&mut self, c: &Controls) -> Result<()> {
        if c.abstraction != self.settings.abstraction {
            self.blur_current = false;
        }
        self.settings.inflation = c.inflation;
        self.settings.softness = c.softness;
        self.settings.brightness = c.brightness;
        self.settings.abstraction = c.abstraction;
        self.settings.validate()?;
        if let Some(p) = &self.passes {
            p.controls
                .write(&c.lanes()[..])
                .enq()
                .context("writing the stylized-shadow controls")?;
        }
        Ok(())
    }

    /// Step 3: the two blur passes of D (after [`Self::distance`]).
    pub fn blur(&mut self, frame: &Frame) -> Result<Duration> {
        let Some(p) = &self.passes else {
            return Ok(Duration::ZERO);
        };
        if p.contour.is_none() {
            bail!("the stylized-shadows blur runs after the distance step");
        }
        let pixels = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let mut time = Duration::ZERO;
        for pass in 0..2 {
            let input = if pass == 0 { &p.dist } else { &p.blurred[0] };
            let k = self
                .kernel(p, "st_blur")
                .arg(pixels)
                .arg(&p.controls)
                .arg(&p.occluder)
                .arg(&p.stencils[pass])
                .arg(input)
                .arg(&p.blurred[pass])
                .arg(self.width)
                .arg(self.height)
                .arg(self.settings.blur_samples)
                .arg(self.settings.normal_cos())
                .arg(self.settings.surface_gap)
                .build()
                .context("creating the blur kernel")?;
            // SAFETY: as in `distance`.
            time += event_duration(&unsafe { enqueue(&k, "a blur pass")? })?;
        }
        self.blur_current = true;
        Ok(time)
    }

    /// Step 4 and the shading: S and F − direct + r·S (after [`Self::blur`]).
    pub fn compose(&mut self, frame: &Frame) -> Result<(crate::imaging::RgbImage, Duration)> {
        let Some(p) = &self.passes else {
            return Ok((frame.beauty()?, Duration::ZERO));
        };
        let k = self
            .kernel(p, "st_compose")
            .arg(frame.device(&self.gpu, BufferId::FilterVectors)?)
            .arg(frame.device(&self.gpu, BufferId::ShadowTerms)?)
            .arg(frame.device(&self.gpu, BufferId::ShadowPixels)?)
            .arg(&p.controls)
            .arg(&p.occluder)
            .arg(&p.blurred[1])
            .arg(self.width)
            .arg(self.height)
            .arg(&p.matte)
            .arg(&p.image)
            .build()
            .context("creating the compose kernel")?;
        // SAFETY: as in `distance`.
        let time = event_duration(&unsafe { enqueue(&k, "the compose kernel")? })?;
        Ok((read_rgb(&p.image, self.width, self.height)?, time))
    }

    /// Every stage on `frame`.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        let start = Instant::now();
        let mut kernel_time = Duration::ZERO;
        let pixels = match &self.passes {
            Some(_) => {
                frame.require(
                    OutputSet::of(&[Output::Colour, Output::Shadows]),
                    "the stylized-shadows filter",
                )?;
                let b = frame.device(&self.gpu, BufferId::ShadowPixels)?;
                let mut bytes = vec![0u8; b.len()];
                b.read(&mut bytes).enq().context("reading the shadow pixels")?;
                Some(bytes)
            }
            None => None,
        };
        if pixels.is_none() || pixels != self.last_pixels {
            kernel_time += self.distance(frame)?;
            self.last_pixels = pixels;
        }
        if !self.blur_current {
            kernel_time += self.blur(frame)?;
        }
        let (image, t) = self.compose(frame)?;
        Ok(FilterRun {
            image,
            wall_time: start.elapsed(),
            kernel_time: Some(kernel_time + t),
        })
    }

    /// The device's intermediates of the last run, for tests: contour points, D, d(x), G * D
    /// and S (empty without a light).
    pub fn stages(&self) -> Result<DeviceStages> {
        let Some(p) = &self.passes else {
            return Ok(DeviceStages::default());
        };
        let read = |b: &Buffer<f32>| -> Result<Vec<f32>> {
            let mut v = vec![0.0; b.len()];
            b.read(&mut v).enq()?;
            Ok(v)
        };
        Ok(DeviceStages {
            contour_points: p.contour_points,
            distance: read(&p.dist)?,
            occluder: read(&p.occluder)?,
            blurred: read(&p.blurred[1])?,
            matte: read(&p.matte)?,
        })
    }
}

/// See [`StylizedKernel::stages`].
#[derive(Clone, Debug, Default)]
pub struct DeviceStages {
    pub contour_points: u32,
    pub distance: Vec<f32>,
    pub occluder: Vec<f32>,
    pub blurred: Vec<f32>,
    pub matte: Vec<f32>,
}

impl Passes {
    fn new(gpu: &Gpu, s: &StylizedSettings, width: u32, height: u32) -> Result<Passes> {
        let program = gpu.program("filters/stylized.cl", &[], "")?;
        let n = width as usize * height as usize;
        let b = s.blur_samples;
        let controls = gpu.zeroed::<f32>(LANES, "stylized-shadow controls")?;
        controls
            .write(&s.controls().lanes()[..])
            .enq()
            .context("writing the stylized-shadow controls")?;
        Ok(Passes {
            program,
            slots: gpu.zeroed::<Float4>(n * 4, "contour slots")?,
            contour: None,
            contour_points: 0,
            dist: gpu.zeroed::<f32>(n, "stylized distance")?,
            occluder: gpu.zeroed::<f32>(n, "stylized occluder distance")?,
            blurred: [
                gpu.zeroed::<f32>(n, "stylized blur")?,
                gpu.zeroed::<f32>(n, "stylized blur")?,
            ],
            stencils: [
                gpu.upload(&blur::stencil(0, b))?,
                gpu.upload(&blur::stencil(b, b))?,
            ],
            controls,
            matte: gpu.zeroed::<f32>(n, "stylized matte")?,
            image: gpu.zeroed::<Float4>(n, "stylized image")?,
        })
    }
}

impl PreparedFilter for StylizedKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    /// With a light, D at a pixel depends on every contour point of the image: no bounded
    /// reach, whole frames only. Without one the image passes through, row by row.
    fn reach(&self) -> Option<u32> {
        self.passes.is_none().then_some(0)
    }

    fn run_rows(&mut self, frame: &Frame, rows: std::ops::Range<u32>) -> Result<FilterRun> {
        let mut run = self.filter(frame)?;
        let w = self.width as usize;
        for (y, row) in run.image.pixels.chunks_mut(w).enumerate() {
            if !rows.contains(&(y as u32)) {
                row.fill([0.0; 3]);
            }
        }
        Ok(run)
    }
}
