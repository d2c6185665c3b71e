//! The stylized-shadows filter on the device (kernels/filters/stylized.cl), in three stages
//! that can run alone: [`StylizedKernel::distance`] (contour, compaction on the host, eq. 3.2;
//! once per render), [`StylizedKernel::blur`] (when α changes) and
//! [`StylizedKernel::compose`] (when i, s or b change). One pipeline (contour, distance, blur,
//! controls, matte) per stylized light, each on its light's plane of the shadow output, and
//! one compose over all of them (eq. 3.1).

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel, Program};

use super::transfer::{Controls, LANES};
use super::{DISTANCE_SEED, StylizedSettings, Variant, blur, contour};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue, event_duration, read_rgb, round_up};
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{Float2, Float4};
use crate::render::Frame;

/// Work-items per work-group of the lanes' `st_distance` (see where it is launched).
const DISTANCE_GROUP: usize = 8;
/// Pixels a work-item of the lanes' `st_distance` takes, side by side in a row: pass 2's
/// sums of two pixels overlap (kernels/filters/stylized.cl `st_add_pair`, which takes two).
const PIXELS_PER_ITEM: usize = 2;

/// The kernels' buffers of one stylized light for one image size.
struct Passes {
    /// The scene's sphere light.
    light: u32,
    slots: Buffer<Float4>,
    /// The compacted contour list of the last `distance` (None: not run yet).
    contour: Option<Buffer<Float4>>,
    contour_points: u32,
    dist: Buffer<f32>,
    occluder: Buffer<f32>,
    blurred: [Buffer<f32>; 2],
    stencils: [Buffer<Float2>; 2],
    controls: Buffer<f32>,
    /// What `controls` holds.
    controls_now: Controls,
    matte: Buffer<f32>,
    /// The light's α changed (or nothing was blurred since the distance step).
    blur_stale: bool,
}

/// The stylized-shadows filter, built for an image size (without a light the image passes
/// through untouched).
pub struct StylizedKernel {
    gpu: Arc<Gpu>,
    settings: StylizedSettings,
    program: Option<Program>,
    /// The distance kernel's loop (`auto` resolved for the device).
    variant: Variant,
    /// One per stylized light, in the order of [`StylizedSettings::stylized_lights`] (empty:
    /// the image passes through).
    lights: Vec<Passes>,
    image: Option<Buffer<Float4>>,
    /// hash_u32(k << 8) for the `contour_samples` draws (`distance::draw_hashes`): the same
    /// at every pixel and every frame, made once.
    draws: Option<Buffer<u32>>,
    width: u32,
    height: u32,
    /// The shadow pixels the last distance step read (bytes), and whether the blur is of
    /// that distance with the current α: [`Self::filter`] re-runs a step only when its input
    /// changed (the shadow output is computed once per render, before the path samples, so a
    /// progressive render's frames re-run the compose alone; §3.3.3: the distance "only when
    /// the camera or light changes").
    last_pixels: Option<Vec<u8>>,
}

impl StylizedKernel {
    /// The filter for the sphere lights `lights` (stylized with `settings`' controls).
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &StylizedSettings,
        lights: &[u32],
        width: u32,
        height: u32,
    ) -> Result<StylizedKernel> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let variant = settings.variant.for_device(&gpu.summary.kind);
        let (program, image, draws) = if lights.is_empty() {
            (None, None, None)
        } else {
            let n = width as usize * height as usize;
            let lanes = (variant == Variant::Lanes) as u32;
            let defines = [
                ("ST_DISTANCE_LANES".to_string(), lanes.to_string()),
                ("ST_PIXELS".to_string(), PIXELS_PER_ITEM.to_string()),
            ];
            (
                Some(gpu.program("filters/stylized.cl", &defines, "")?),
                Some(gpu.zeroed::<Float4>(n, "stylized image")?),
                Some(gpu.upload(&super::distance::draw_hashes(settings.contour_samples))?),
            )
        };
        let lights = lights
            .iter()
            .map(|&l| Passes::new(&gpu, settings, l, width, height))
            .collect::<Result<Vec<_>>>()?;
        Ok(StylizedKernel {
            gpu,
            settings: settings.clone(),
            program,
            variant,
            lights,
            image,
            draws,
            width,
            height,
            last_pixels: None,
        })
    }

    /// The distance kernel's loop (`auto` resolved for the device).
    pub fn variant(&self) -> Variant {
        self.variant
    }

    /// The sphere lights stylized, in pipeline order.
    pub fn lights(&self) -> Vec<u32> {
        self.lights.iter().map(|p| p.light).collect()
    }

    /// The plane of light `light` in `frame`'s shadow output, and how many planes it has.
    fn plane(frame: &Frame, light: u32) -> Result<(u32, u32)> {
        let info = frame.info();
        match info.shadow_plane(light) {
            Some(p) => Ok((p as u32, info.shadow_planes())),
            None => bail!(
                "the stylized-shadows filter stylizes sphere light {light}, but the frame's \
                 shadow output holds sphere light(s) {:?}: render it with this filter's \
                 settings",
                info.shadow_lights
            ),
        }
    }

    fn kernel<'a>(&'a self, name: &str) -> ocl::builders::KernelBuilder<'a> {
        let mut b = Kernel::builder();
        b.program(self.program.as_ref().expect("built with a light"))
            .name(name.to_string())
            .queue(self.gpu.queue.clone())
            .global_work_size([self.width as usize, self.height as usize]);
        b
    }

    /// Steps 1-2 on `frame`, for every stylized light: the contour (compacted in pixel order
    /// on the host, as the thesis does on its CPU) and D with d(x). Returns the kernel time.
    pub fn distance(&mut self, frame: &Frame) -> Result<Duration> {
        frame.check_size(self.width, self.height, "the stylized-shadows filter")?;
        if self.lights.is_empty() {
            return Ok(Duration::ZERO);
        }
        frame.require(
            OutputSet::of(&[Output::Colour, Output::Shadows]),
            "the stylized-shadows filter",
        )?;
        let mut time = Duration::ZERO;
        for k in 0..self.lights.len() {
            time += self.distance_of(frame, k)?;
        }
        Ok(time)
    }

    fn distance_of(&mut self, frame: &Frame, k: usize) -> Result<Duration> {
        let s = &self.settings;
        let p = &self.lights[k];
        let (plane, planes) = Self::plane(frame, p.light)?;
        let pixels = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let normal_cos = s.normal_cos();
        let kernel = self
            .kernel("st_contour")
            .arg(pixels)
            .arg(plane)
            .arg(planes)
            .arg(&p.slots)
            .arg(self.width)
            .arg(self.height)
            .arg(normal_cos)
            .arg(s.surface_gap)
            .build()
            .context("creating the contour kernel")?;
        // SAFETY: the buffers are the frame's and ours, sized for the image, alive until the
        // event completes (we wait on it).
        let mut time = event_duration(&unsafe { enqueue(&kernel, "the contour kernel")? })?;
        let mut slots = vec![Float4::default(); p.slots.len()];
        p.slots.read(&mut slots).enq().context("reading the contour slots")?;
        let list = contour::compact(&slots);
        let count = (list.len() / 2) as u32;
        let buffer = self.gpu.upload(&list)?;
        let sampling =
            super::distance::Sampling::new(count, s.contour_samples, DISTANCE_SEED, normal_cos);
        // The lanes read the points as planes (a window of them when they draw a subset).
        let (planes_of_points, stride) = if self.variant == Variant::Lanes {
            contour::planes(&list)
        } else {
            (Vec::new(), 0)
        };
        let point_planes = self.gpu.upload(&planes_of_points)?;
        let mut kernel = self.kernel("st_distance");
        if self.variant == Variant::Lanes {
            // The lanes take two pixels a work-item (2x and 2x + 1) and keep pass 1's
            // distances of both in private arrays (16 KiB a work-item). PoCL holds a whole
            // work-group's private arrays at once on its thread's stack: with the work-group
            // it chose itself st_distance crashed at 512², so the host picks a small one.
            let columns = round_up((self.width as usize).div_ceil(PIXELS_PER_ITEM), DISTANCE_GROUP);
            kernel
                .local_work_size([DISTANCE_GROUP, 1])
                .global_work_size([columns, self.height as usize]);
        }
        let kernel = kernel
            .arg(pixels)
            .arg(plane)
            .arg(planes)
            .arg(&buffer)
            .arg(&point_planes)
            .arg(stride as u32)
            .arg(self.draws.as_ref().expect("built with a light"))
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
        // SAFETY: as above; `buffer` lives until it is stored below and `point_planes` until
        // the end of this function, both after the wait.
        time += event_duration(&unsafe { enqueue(&kernel, "the distance kernel")? })?;
        let p = &mut self.lights[k];
        p.contour = Some(buffer);
        p.contour_points = count;
        p.blur_stale = true;
        Ok(time)
    }

    /// Writes the controls of every stylized light (no kernel runs).
    pub fn set_controls(&mut self, c: &Controls) -> Result<()> {
        for k in 0..self.lights.len() {
            self.set_light_controls(k, c)?;
        }
        self.settings.inflation = c.inflation;
        self.settings.softness = c.softness;
        self.settings.brightness = c.brightness;
        self.settings.abstraction = c.abstraction;
        self.settings.validate()
    }

    /// Writes the controls of the `k`-th stylized light alone (no kernel runs): the next
    /// [`Self::filter`] re-runs its blur if its α changed, and the compose.
    pub fn set_light_controls(&mut self, k: usize, c: &Controls) -> Result<()> {
        let Some(p) = self.lights.get_mut(k) else {
            bail!("the stylized-shadows filter has {} light(s), not {}", self.lights.len(), k + 1);
        };
        let mut check = self.settings.clone();
        (check.inflation, check.softness, check.brightness, check.abstraction) =
            (c.inflation, c.softness, c.brightness, c.abstraction);
        check.validate()?;
        if c.abstraction != p.controls_now.abstraction {
            p.blur_stale = true;
        }
        p.controls_now = *c;
        p.controls
            .write(&c.lanes()[..])
            .enq()
            .context("writing the stylized-shadow controls")?;
        Ok(())
    }

    /// Step 3: the two blur passes of D of every light whose blur is stale (after
    /// [`Self::distance`]).
    pub fn blur(&mut self, frame: &Frame) -> Result<Duration> {
        let mut time = Duration::ZERO;
        for k in 0..self.lights.len() {
            self.lights[k].blur_stale = true;
            time += self.blur_of(frame, k)?;
        }
        Ok(time)
    }

    fn blur_of(&mut self, frame: &Frame, k: usize) -> Result<Duration> {
        let p = &self.lights[k];
        if !p.blur_stale {
            return Ok(Duration::ZERO);
        }
        if p.contour.is_none() {
            bail!("the stylized-shadows blur runs after the distance step");
        }
        let (plane, planes) = Self::plane(frame, p.light)?;
        let pixels = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let mut time = Duration::ZERO;
        for pass in 0..2 {
            let input = if pass == 0 { &p.dist } else { &p.blurred[0] };
            let kernel = self
                .kernel("st_blur")
                .arg(pixels)
                .arg(plane)
                .arg(planes)
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
            time += event_duration(&unsafe { enqueue(&kernel, "a blur pass")? })?;
        }
        self.lights[k].blur_stale = false;
        Ok(time)
    }

    /// Step 4 and the shading of every light: S_l and F − Σ_l direct_l + Σ_l r_l·S_l, one
    /// launch per light (after [`Self::blur`]).
    pub fn compose(&mut self, frame: &Frame) -> Result<(crate::imaging::RgbImage, Duration)> {
        let Some(image) = &self.image else {
            return Ok((frame.beauty()?, Duration::ZERO));
        };
        let fv = frame.device(&self.gpu, BufferId::FilterVectors)?;
        let terms = frame.device(&self.gpu, BufferId::ShadowTerms)?;
        let pixels = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let mut time = Duration::ZERO;
        for (k, p) in self.lights.iter().enumerate() {
            let (plane, planes) = Self::plane(frame, p.light)?;
            let kernel = self
                .kernel("st_compose")
                .arg(fv)
                .arg((k == 0) as u32)
                .arg(terms)
                .arg(pixels)
                .arg(plane)
                .arg(planes)
                .arg(&p.controls)
                .arg(&p.occluder)
                .arg(&p.blurred[1])
                .arg(self.width)
                .arg(self.height)
                .arg(&p.matte)
                .arg(image)
                .build()
                .context("creating the compose kernel")?;
            // SAFETY: as in `distance`.
            time += event_duration(&unsafe { enqueue(&kernel, "the compose kernel")? })?;
        }
        Ok((read_rgb(image, self.width, self.height)?, time))
    }

    /// Every stage on `frame` that its inputs call for: the distance steps when the shadow
    /// pixels changed, the blurs whose α changed, and the compose.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        let start = Instant::now();
        let mut kernel_time = Duration::ZERO;
        let pixels = if self.lights.is_empty() {
            None
        } else {
            frame.require(
                OutputSet::of(&[Output::Colour, Output::Shadows]),
                "the stylized-shadows filter",
            )?;
            let b = frame.device(&self.gpu, BufferId::ShadowPixels)?;
            let mut bytes = vec![0u8; b.len()];
            b.read(&mut bytes).enq().context("reading the shadow pixels")?;
            Some(bytes)
        };
        if pixels.is_none() || pixels != self.last_pixels {
            kernel_time += self.distance(frame)?;
            self.last_pixels = pixels;
        }
        for k in 0..self.lights.len() {
            kernel_time += self.blur_of(frame, k)?;
        }
        let (image, t) = self.compose(frame)?;
        Ok(FilterRun {
            image,
            wall_time: start.elapsed(),
            kernel_time: Some(kernel_time + t),
        })
    }

    /// The device's intermediates of the last run of the first stylized light, for tests:
    /// contour points, D, d(x), G * D and S (empty without a light).
    pub fn stages(&self) -> Result<DeviceStages> {
        self.light_stages(0)
    }

    /// The same for the `k`-th stylized light.
    pub fn light_stages(&self, k: usize) -> Result<DeviceStages> {
        let Some(p) = self.lights.get(k) else {
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
    fn new(gpu: &Gpu, s: &StylizedSettings, light: u32, width: u32, height: u32) -> Result<Passes> {
        let n = width as usize * height as usize;
        let b = s.blur_samples;
        let own = s.controls_of(light);
        let controls = gpu.zeroed::<f32>(LANES, "stylized-shadow controls")?;
        controls
            .write(&own.lanes()[..])
            .enq()
            .context("writing the stylized-shadow controls")?;
        Ok(Passes {
            light,
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
            controls_now: own,
            matte: gpu.zeroed::<f32>(n, "stylized matte")?,
            blur_stale: true,
        })
    }
}

impl PreparedFilter for StylizedKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    /// The next run computes the contour, D and the blur again (a run on the same shadow
    /// output otherwise re-runs only the compose).
    fn forget(&mut self) {
        self.last_pixels = None;
    }

    /// With a light, D at a pixel depends on every contour point of the image: no bounded
    /// reach, whole frames only. Without one the image passes through, row by row.
    fn reach(&self) -> Option<u32> {
        self.lights.is_empty().then_some(0)
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
