//! The AAF soft-shadow filter on the device (kernels/filters/aaf_shadows.cl): prepare, the
//! pass along rows, the pass along columns, compose.

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

use super::AafShadowSettings;
use crate::filters::aaf_pass::DevicePasses;
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{AafShadowParams, Float4};
use crate::render::Frame;

/// The filter's kernels and buffers for one image size and light.
struct Passes {
    prepare: Kernel,
    passes: DevicePasses,
    compose: Kernel,
    _params: Buffer<AafShadowParams>,
    image: Buffer<Float4>,
}

/// The AAF soft-shadow filter, built for an image size and a light (none: the image passes
/// through untouched).
pub struct AafShadowKernel {
    gpu: Arc<Gpu>,
    /// The sphere light filtered: the frame's shadow plane read (src/layout/outputs.rs
    /// `Per::Light`; a frame with other planes too gives its copy of this one).
    light_index: Option<u32>,
    passes: Option<Passes>,
    width: u32,
    height: u32,
    /// Half width of eq. 3.7's 1-D passes, pixels: the rows a band's pixels read beyond it.
    radius: u32,
}

impl AafShadowKernel {
    /// `light`: the filtered sphere light's centre and radius, or None.
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &AafShadowSettings,
        light: Option<[f32; 4]>,
        width: u32,
        height: u32,
    ) -> Result<AafShadowKernel> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let passes = match light {
            Some(l) => Some(Passes::new(&gpu, settings, l, width, height)?),
            None => None,
        };
        Ok(AafShadowKernel {
            gpu,
            light_index: settings.light_index(),
            passes,
            width,
            height,
            radius: settings.radius,
        })
    }

    /// Filters `frame` (width × height, with the shadow output unless there is no light) and
    /// reads the image back; the kernel time sums the four launches.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    /// Filters the pixels of `rows` only (one band of a frame split across devices): the
    /// prepare pass and the pass along rows run on the band widened by `radius` rows, which
    /// the pass along columns reads, so the band's pixels get the bytes that filtering the
    /// whole frame gives them. The image's other rows are black.
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        let own = match self.light_index {
            Some(l) if self.passes.is_some() => frame.light_plane(l, "the aaf-shadows filter")?,
            _ => None,
        };
        let frame = own.as_ref().unwrap_or(frame);
        let h = self.height;
        let rows = rows.start.min(h)..rows.end.min(h);
        frame.check_size(self.width, self.height, "the aaf-shadows filter")?;
        let Some(p) = &mut self.passes else {
            let mut image = frame.beauty()?;
            let w = self.width as usize;
            for (y, row) in image.pixels.chunks_mut(w).enumerate() {
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
            OutputSet::of(&[Output::Colour, Output::Shadows]),
            "the aaf-shadows filter",
        )?;
        let pixels = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        for k in [&p.prepare, &p.compose] {
            k.set_arg("pixels", pixels)?;
        }
        p.compose
            .set_arg("fv", frame.device(&self.gpu, BufferId::FilterVectors)?)?;
        p.compose
            .set_arg("terms", frame.device(&self.gpu, BufferId::ShadowTerms)?)?;
        p.passes
            .filter_band(&p.prepare, &p.compose, &p.image, self.radius, rows, start)
    }
}

impl Passes {
    fn new(
        gpu: &Gpu,
        s: &AafShadowSettings,
        light: [f32; 4],
        width: u32,
        height: u32,
    ) -> Result<Passes> {
        let program = gpu.program("filters/aaf_shadows.cl", &[], "")?;
        let n = width as usize * height as usize;
        let params = gpu.upload(&[s.params(light, width, height, 0)])?;
        let passes = DevicePasses::new(gpu, &s.pass_params(width, height))?;
        let image = gpu.zeroed::<Float4>(n, "AAF image")?;
        let size = [width as usize, height as usize];
        let kernel = |name: &str| {
            let mut b = Kernel::builder();
            b.program(&program)
                .name(name)
                .queue(gpu.queue.clone())
                .global_work_size(size);
            b
        };
        let none = None::<&Buffer<u8>>;
        let prepare = kernel("aaf_prepare")
            .arg_named("p", &params)
            .arg_named("pixels", none)
            .arg(&passes.guide)
            .arg(&passes.values[0])
            .build()
            .context("creating the AAF prepare kernel")?;
        let compose = kernel("aaf_compose")
            .arg_named("p", &params)
            .arg_named("fv", none)
            .arg_named("terms", none)
            .arg_named("pixels", none)
            .arg(&passes.guide)
            .arg(&passes.values[0])
            .arg(&image)
            .build()
            .context("creating the AAF compose kernel")?;
        Ok(Passes {
            prepare,
            passes,
            compose,
            _params: params,
            image,
        })
    }
}

impl PreparedFilter for AafShadowKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    fn reach(&self) -> Option<u32> {
        Some(self.radius)
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}
