//! The à-trous filter on the device: an init kernel, `iterations` pass kernels ping-ponging
//! between two colour buffers, and a finish kernel; kernels/filters/atrous.cl (one pixel per
//! work-item) or, for the packed variant, kernels/filters/atrous_packed.cl (16 pixels of a
//! row per work-item, colour and guides in rows of padded lines).

use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use ocl::builders::KernelBuilder;
use ocl::{Buffer, Kernel, Program};

use super::{ALBEDO_EPSILON, AtrousSettings, Variant};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue_rows, event_duration, read_rgb_rows, round_up};
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{AtrousParams, Float4};
use crate::render::Frame;
use crate::scene::CameraBasis;

/// Pixels per work-item of the packed variant (ATROUS_PACK: one float16 lane each), and the
/// zeros either side of each of its lines (kernels/filters/atrous_packed.cl).
pub const PACK: u32 = 16;

/// Work-items per work-group of the packed passes. PoCL runs a work-group's work-items in one
/// thread and may keep each one's private arrays on its stack; the data-driven filter's packed
/// kernel crashed at 512 x 512 with the group PoCL chose (src/filters/ddf/device.rs), so
/// this one's group is fixed the same way.
pub const PACKED_GROUP: usize = 8;

/// Lines per image row of the packed variant: colour rgb, and the guides (normal xyz, surface
/// flag, position xyz, footprint); ATROUS_COLOUR_LINES and ATROUS_GUIDE_LINES.
const COLOUR_LINES: usize = 3;
const GUIDE_LINES: usize = 8;

/// The à-trous filter on the device: an init kernel, `iterations` pass kernels ping-ponging
/// between two colour buffers, and a finish kernel, built once for a camera and image size.
pub struct AtrousKernel {
    gpu: Arc<Gpu>,
    init: Kernel,
    passes: Vec<Kernel>,
    finish: Kernel,
    /// The variant run (auto resolved for the device).
    variant: Variant,
    /// One parameter block per pass (pass 0's also serves init and finish).
    _params: Vec<Buffer<AtrousParams>>,
    /// The filtered image: the last pass's colour buffer (scalar) or the packed finish's
    /// output.
    result: Buffer<Float4>,
    /// The buffers the kernels read and write (kept alive with them): float4 images (scalar)
    /// or lines (packed).
    _images: Vec<Buffer<Float4>>,
    _lines: Vec<Buffer<f32>>,
    width: u32,
    height: u32,
}

/// The kernels of one variant, their buffers and the filtered image.
struct Built {
    init: Kernel,
    passes: Vec<Kernel>,
    finish: Kernel,
    result: Buffer<Float4>,
    images: Vec<Buffer<Float4>>,
    lines: Vec<Buffer<f32>>,
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
        let variant = settings.variant.for_device(&gpu.summary.kind);
        let mut defines = vec![
            (
                "ATROUS_DEMODULATE".to_string(),
                (settings.demodulate as u32).to_string(),
            ),
            (
                "ATROUS_ALBEDO_EPSILON".to_string(),
                format!("{ALBEDO_EPSILON:e}f"),
            ),
        ];
        let params = (0..settings.iterations.max(1))
            .map(|i| gpu.upload(&[settings.params(camera, width, height, i)]))
            .collect::<Result<Vec<_>>>()?;
        let built = match variant {
            Variant::Packed => {
                defines.push(("ATROUS_PACK".to_string(), PACK.to_string()));
                let program = gpu.program("filters/atrous_packed.cl", &defines, "")?;
                build_packed(&gpu, &program, &params, settings.iterations, width, height)?
            }
            _ => {
                let program = gpu.program("filters/atrous.cl", &defines, "")?;
                build_scalar(&gpu, &program, &params, settings.iterations, width, height)?
            }
        };
        Ok(AtrousKernel {
            gpu,
            init: built.init,
            passes: built.passes,
            finish: built.finish,
            variant,
            _params: params,
            result: built.result,
            _images: built.images,
            _lines: built.lines,
            width,
            height,
        })
    }

    /// The variant run (auto resolved for the device).
    pub fn variant(&self) -> Variant {
        self.variant
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
        let pass_items = match self.variant {
            Variant::Packed => self.width.div_ceil(PACK),
            _ => self.width,
        };
        for (i, (k, band)) in launches.enumerate() {
            let items = if (1..=n).contains(&i) {
                pass_items
            } else {
                self.width
            };
            // SAFETY: every buffer outlives its launch (we wait for all of them below) and
            // holds width x height pixels; the in-order queue runs the passes one by one.
            events.push(unsafe {
                enqueue_rows(k, items, h, band, "an a-trous filter pass")?
            });
        }
        let mut kernel_time = std::time::Duration::ZERO;
        for e in &events {
            kernel_time += event_duration(e)?;
        }
        Ok(FilterRun {
            image: read_rgb_rows(&self.result, self.width, self.height, rows)?,
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


/// A kernel of `program` on the device's queue over `size` work-items, its arguments to add.
fn builder<'b>(gpu: &Gpu, program: &'b Program, name: &str, size: [usize; 2]) -> KernelBuilder<'b> {
    let mut b = Kernel::builder();
    b.program(program)
        .name(name)
        .queue(gpu.queue.clone())
        .global_work_size(size);
    b
}

/// The scalar variant (kernels/filters/atrous.cl): colour, positions and normals as float4
/// images, one work-item per pixel.
fn build_scalar(
    gpu: &Gpu,
    program: &Program,
    params: &[Buffer<AtrousParams>],
    iterations: u32,
    width: u32,
    height: u32,
) -> Result<Built> {
    let pixels = width as usize * height as usize;
    let colour = [
        gpu.zeroed::<Float4>(pixels, "a-trous colour")?,
        gpu.zeroed::<Float4>(pixels, "a-trous colour")?,
    ];
    let position = gpu.zeroed::<Float4>(pixels, "a-trous position")?;
    let normal = gpu.zeroed::<Float4>(pixels, "a-trous normal")?;
    let size = [width as usize, height as usize];
    let init = builder(gpu, program, "atrous_init", size)
        .arg_named("p", &params[0])
        .arg_named("fv", None::<&Buffer<u8>>)
        .arg(&colour[0])
        .arg(&position)
        .arg(&normal)
        .build()
        .context("creating the a-trous init kernel")?;
    let passes = (0..iterations as usize)
        .map(|i| {
            builder(gpu, program, "atrous_pass", size)
                .arg(&params[i])
                .arg(&colour[i % 2])
                .arg(&position)
                .arg(&normal)
                .arg(&colour[(i + 1) % 2])
                .build()
                .context("creating an a-trous pass kernel")
        })
        .collect::<Result<Vec<_>>>()?;
    let result = colour[iterations as usize % 2].clone();
    let finish = builder(gpu, program, "atrous_finish", size)
        .arg_named("p", &params[0])
        .arg_named("fv", None::<&Buffer<u8>>)
        .arg(&result)
        .build()
        .context("creating the a-trous finish kernel")?;
    Ok(Built {
        init,
        passes,
        finish,
        result,
        images: [colour, [position, normal]].concat(),
        lines: Vec::new(),
    })
}

/// The packed variant (kernels/filters/atrous_packed.cl): colour and guides as rows of padded
/// lines written by `atrous_init_packed`, PACK pixels per pass work-item, and
/// `atrous_finish_packed` writing the float4 image.
fn build_packed(
    gpu: &Gpu,
    program: &Program,
    params: &[Buffer<AtrousParams>],
    iterations: u32,
    width: u32,
    height: u32,
) -> Result<Built> {
    let (w, h) = (width as usize, height as usize);
    let pack = PACK as usize;
    // PACK zeros, the row rounded up to PACK pixels, PACK zeros: every read of a tap that
    // has a lane inside the image stays within the row's line (atrous_packed.cl).
    let stride = pack + round_up(w, pack) + pack;
    // Zeroed once: the padding is never written, so it stays 0 (not a surface).
    let colour = [
        gpu.zeroed::<f32>(COLOUR_LINES * stride * h, "a-trous colour lines")?,
        gpu.zeroed::<f32>(COLOUR_LINES * stride * h, "a-trous colour lines")?,
    ];
    let guides = gpu.zeroed::<f32>(GUIDE_LINES * stride * h, "a-trous guide lines")?;
    let result = gpu.zeroed::<Float4>(w * h, "a-trous filtered image")?;
    let stride = stride as u32;
    let size = [w, h];
    let init = builder(gpu, program, "atrous_init_packed", size)
        .arg_named("p", &params[0])
        .arg_named("fv", None::<&Buffer<u8>>)
        .arg(&colour[0])
        .arg(&guides)
        .arg(stride)
        .build()
        .context("creating the packed a-trous init kernel")?;
    let items = round_up(w.div_ceil(pack), PACKED_GROUP);
    let passes = (0..iterations as usize)
        .map(|i| {
            builder(gpu, program, "atrous_pass_packed", [items, h])
                .local_work_size([PACKED_GROUP, 1])
                .arg(&params[i])
                .arg(&colour[i % 2])
                .arg(&guides)
                .arg(&colour[(i + 1) % 2])
                .arg(stride)
                .build()
                .context("creating a packed a-trous pass kernel")
        })
        .collect::<Result<Vec<_>>>()?;
    let finish = builder(gpu, program, "atrous_finish_packed", size)
        .arg_named("p", &params[0])
        .arg_named("fv", None::<&Buffer<u8>>)
        .arg(&colour[iterations as usize % 2])
        .arg(&result)
        .arg(stride)
        .build()
        .context("creating the packed a-trous finish kernel")?;
    Ok(Built {
        init,
        passes,
        finish,
        result,
        images: Vec::new(),
        lines: [colour.to_vec(), vec![guides]].concat(),
    })
}
