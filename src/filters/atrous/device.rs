//! The à-trous filter on the device: an init kernel, `iterations` pass kernels ping-ponging
//! between two colour buffers, and a finish kernel (kernels/filters/atrous.cl).

use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

use super::{ALBEDO_EPSILON, AtrousSettings};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue_rows, event_duration, read_rgb_rows};
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{AtrousParams, Float4};
use crate::render::Frame;
use crate::scene::CameraBasis;

/// The à-trous filter on the device: an init kernel, `iterations` pass kernels ping-ponging
/// between two colour buffers, and a finish kernel, built once for a camera and image size.
pub struct AtrousKernel {
    gpu: Arc<Gpu>,
    init: Kernel,
    passes: Vec<Kernel>,
    finish: Kernel,
    /// One parameter block per pass (pass 0's also serves init and finish).
    _params: Vec<Buffer<AtrousParams>>,
    /// Ping-pong colour buffers; the result ends in `colour[iterations % 2]`.
    colour: [Buffer<Float4>; 2],
    _position: Buffer<Float4>,
    _normal: Buffer<Float4>,
    width: u32,
    height: u32,
}

impl AtrousKernel {
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &AtrousSettings,
        camera: &CameraBasis,
        width: u32,
        height: u32,
    ) -> Result<AtrousKernel> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let defines = vec![
            (
                "ATROUS_DEMODULATE".to_string(),
                (settings.demodulate as u32).to_string(),
            ),
            (
                "ATROUS_ALBEDO_EPSILON".to_string(),
                format!("{ALBEDO_EPSILON:e}f"),
            ),
        ];
        let program = gpu.program("filters/atrous.cl", &defines, "")?;
        let pixels = width as usize * height as usize;
        let params = (0..settings.iterations.max(1))
            .map(|i| gpu.upload(&[settings.params(camera, width, height, i)]))
            .collect::<Result<Vec<_>>>()?;
        let colour = [
            gpu.zeroed::<Float4>(pixels, "a-trous colour")?,
            gpu.zeroed::<Float4>(pixels, "a-trous colour")?,
        ];
        let position = gpu.zeroed::<Float4>(pixels, "a-trous position")?;
        let normal = gpu.zeroed::<Float4>(pixels, "a-trous normal")?;
        let size = [width as usize, height as usize];
        let init = Kernel::builder()
            .program(&program)
            .name("atrous_init")
            .queue(gpu.queue.clone())
            .global_work_size(size)
            .arg_named("p", &params[0])
            .arg_named("fv", None::<&Buffer<u8>>)
            .arg(&colour[0])
            .arg(&position)
            .arg(&normal)
            .build()
            .context("creating the a-trous init kernel")?;
        let passes = (0..settings.iterations as usize)
            .map(|i| {
                Kernel::builder()
                    .program(&program)
                    .name("atrous_pass")
                    .queue(gpu.queue.clone())
                    .global_work_size(size)
                    .arg(&params[i])
                    .arg(&colour[i % 2])
                    .arg(&position)
                    .arg(&normal)
                    .arg(&colour[(i + 1) % 2])
                    .build()
                    .context("creating an a-trous pass kernel")
            })
            .collect::<Result<Vec<_>>>()?;
        let finish = Kernel::builder()
            .program(&program)
            .name("atrous_finish")
            .queue(gpu.queue.clone())
            .global_work_size(size)
            .arg_named("p", &params[0])
            .arg_named("fv", None::<&Buffer<u8>>)
            .arg(&colour[settings.iterations as usize % 2])
            .build()
            .context("creating the a-trous finish kernel")?;
        Ok(AtrousKernel {
            gpu,
            init,
            passes,
            finish,
            _params: params,
            colour,
            _position: position,
            _normal: normal,
            width,
            height,
        })
    }

    /// Filters `frame` (which must be width × height) and reads the image back. The kernel
    /// time is the sum over init, every pass and finish, from their profiling events.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    /// Rows that pass `i` must produce beyond a band, so that the passes after it see every
    /// tap they read: the sum of their reaches (pass j reaches 2 · 2^j rows).
    fn margin_after(&self, i: usize) -> u32 {
        (i + 1..self.passes.len()).map(|j| 2u32 << j).sum()
    }

    /// Rows a band's pixels read beyond the band: 2 · (1 + 2 + ... + 2^(n−1)).
    pub fn reach(&self) -> u32 {
        (0..self.passes.len()).map(|j| 2u32 << j).sum()
    }

    /// Filters the pixels of `rows` only (one band of a frame split across devices), reading
    /// the frame's rows within [`AtrousKernel::reach`]: init and every pass run on the band
    /// widened by what the later passes read, so each pixel of the band gets the bytes that
    /// filtering the whole frame gives it. The image's other rows are black.
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        frame.check_size(self.width, self.height, "the a-trous filter")?;
        frame.require(
            OutputSet::of(&[Output::Colour, Output::Features]),
            "the a-trous filter",
        )?;
        let fv = frame.device(&self.gpu, BufferId::FilterVectors)?;
        self.init.set_arg("fv", fv)?;
        self.finish.set_arg("fv", fv)?;
        let h = self.height;
        let rows = rows.start.min(h)..rows.end.min(h);
        let widened = |m: u32| rows.start.saturating_sub(m)..(rows.end + m).min(h);
        let n = self.passes.len();
        let launches = std::iter::once((&self.init, widened(self.reach())))
            .chain(
                self.passes
                    .iter()
                    .enumerate()
                    .map(|(i, k)| (k, widened(self.margin_after(i)))),
            )
            .chain(std::iter::once((&self.finish, rows.clone())));
        let mut events = Vec::with_capacity(n + 2);
        for (k, band) in launches {
            // SAFETY: every buffer outlives its launch (we wait for all of them below) and
            // holds width x height pixels; the in-order queue runs the passes one by one.
            events.push(unsafe {
                enqueue_rows(k, self.width, h, band, "an a-trous filter pass")?
            });
        }
        let mut kernel_time = std::time::Duration::ZERO;
        for e in &events {
            kernel_time += event_duration(e)?;
        }
        let result = &self.colour[self.passes.len() % 2];
        Ok(FilterRun {
            image: read_rgb_rows(result, self.width, self.height, rows)?,
            wall_time: start.elapsed(),
            kernel_time: Some(kernel_time),
        })
    }
}

impl PreparedFilter for AtrousKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    fn reach(&self) -> Option<u32> {
        Some(AtrousKernel::reach(self))
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}

