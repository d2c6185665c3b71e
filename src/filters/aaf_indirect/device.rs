//! The AAF indirect filter (diffuse and glossy) on the device (kernels/filters/aaf_indirect.cl and the
//! shared passes of kernels/filters/aaf_pass.cl): prepare, rows, columns, compose.

use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

use super::AafIndirectSettings;
use crate::filters::aaf_pass::DevicePasses;
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{AafIndirectParams, Float4};
use crate::render::Frame;

/// The AAF indirect filter, built for an image size.
pub struct AafIndirectKernel {
    gpu: Arc<Gpu>,
    prepare: Kernel,
    passes: DevicePasses,
    compose: Kernel,
    _params: Buffer<AafIndirectParams>,
    image: Buffer<Float4>,
    width: u32,
    height: u32,
    /// Half width of the 1-D passes, pixels: the rows a band's pixels read beyond it.
    radius: u32,
}

impl AafIndirectKernel {
    pub fn new(
        gpu: Arc<Gpu>,
        s: &AafIndirectSettings,
        width: u32,
        height: u32,
    ) -> Result<AafIndirectKernel> {
        s.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let program = gpu.program("filters/aaf_indirect.cl", &[], "")?;
        let params = gpu.upload(&[s.params(width, height)])?;
        let passes = DevicePasses::new(&gpu, &s.pass_params(width, height))?;
        let image = gpu.zeroed::<Float4>(width as usize * height as usize, "AAF image")?;
        let kernel = |name: &str| {
            let mut b = Kernel::builder();
            b.program(&program)
                .name(name)
                .queue(gpu.queue.clone())
                .global_work_size([width as usize, height as usize]);
            b
        };
        let none = None::<&Buffer<u8>>;
        let prepare = kernel("aaf_indirect_prepare")
            .arg_named("p", &params)
            .arg_named("pixels", none)
            .arg(&passes.guide)
            .arg(&passes.values[0])
            .build()
            .context("creating the AAF indirect prepare kernel")?;
        let compose = kernel("aaf_indirect_compose")
            .arg_named("p", &params)
            .arg_named("fv", none)
            .arg_named("pixels", none)
            .arg(&passes.guide)
            .arg(&passes.values[0])
            .arg(&image)
            .build()
            .context("creating the AAF indirect compose kernel")?;
        Ok(AafIndirectKernel {
            gpu,
            prepare,
            passes,
            compose,
            _params: params,
            image,
            width,
            height,
            radius: s.radius,
        })
    }

    /// Filters `frame` and reads the image back; the kernel time sums the four launches.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    /// Filters the pixels of `rows` only (one band of a frame split across devices,
    /// [`DevicePasses::filter_band`]); the other rows are black.
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        frame.check_size(self.width, self.height, "the aaf-indirect filter")?;
        frame.require(
            OutputSet::of(&[Output::Colour, Output::Indirect]),
            "the aaf-indirect filter",
        )?;
        let pixels = frame.device(&self.gpu, BufferId::IndirectPixels)?;
        self.prepare.set_arg("pixels", pixels)?;
        self.compose.set_arg("pixels", pixels)?;
        self.compose
            .set_arg("fv", frame.device(&self.gpu, BufferId::FilterVectors)?)?;
        self.passes.filter_band(
            &self.prepare,
            &self.compose,
            &self.image,
            self.radius,
            rows,
            start,
        )
    }
}

impl PreparedFilter for AafIndirectKernel {
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
