//! The data-driven filter on the device: kernels/filters/ddf.cl, built once per variant and
//! option set (the disk cache keeps the binaries).

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Event, Kernel};

use super::{DdfSettings, DirectionTerm, Variant};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue_rows, event_duration, read_rgb_rows, round_up};
use crate::layout::outputs::BufferId;
use crate::layout::{DdfParams, Float4};
use crate::render::Frame;

impl Variant {
    /// DDF_VARIANT of a variant resolved for the device ([`Variant::for_device`]).
    fn define(self) -> u32 {
        match self {
            Variant::Auto => unreachable!("auto is resolved for the device before the build"),
            Variant::Naive => 0,
            Variant::Vector => 1,
            Variant::Rows => 2,
            Variant::Packed => 3,
        }
    }
}

/// Pixels per work-item of the packed variant (DDF_PACK: one float16 lane each).
pub const PACK: u32 = 16;

/// Work-items per work-group of the packed variant unless one is given.
pub const PACKED_GROUP: usize = 8;

/// The kernel of one variant and option set, for one image size.
pub struct DdfKernel {
    gpu: Arc<Gpu>,
    kernel: Kernel,
    params: Buffer<DdfParams>,
    out: Buffer<Float4>,
    settings: DdfSettings,
    width: u32,
    height: u32,
    /// The packed variant's first pass, `ddf_pack`, which fills its lines
    /// (kernels/filters/ddf_packed.cl), and the lines; None for the other variants.
    pack: Option<(Kernel, Buffer<f32>)>,
}

impl DdfKernel {
    /// The filter for `settings` (specialised: `auto` sky and texture2 read as on).
    pub fn new(gpu: Arc<Gpu>, settings: &DdfSettings, width: u32, height: u32) -> Result<Self> {
        DdfKernel::with_work_group(gpu, settings, width, height, None)
    }

    /// Like [`DdfKernel::new`]; the naive and vector variants run in work-groups of
    /// `work_group` x 1 pixels when given (the driver chooses otherwise), the packed variant
    /// in work-groups of `work_group` x 1 work-items of [`PACK`] pixels. The rows variant's
    /// work-group is `settings.work_group`.
    pub fn with_work_group(
        gpu: Arc<Gpu>,
        settings: &DdfSettings,
        width: u32,
        height: u32,
        work_group: Option<usize>,
    ) -> Result<Self> {
        settings.validate()?;
        let settings = &DdfSettings {
            variant: settings.variant.for_device(&gpu.summary, settings.holes),
            ..settings.clone()
        };
        let flag = |b: bool| (b as u32).to_string();
        let defines = vec![
            (
                "DDF_VARIANT".to_string(),
                settings.variant.define().to_string(),
            ),
            ("DDF_SKY".to_string(), flag(settings.keeps_sky())),
            ("DDF_TEXTURE2".to_string(), flag(settings.uses_texture2())),
            (
                "DDF_DIRECTION".to_string(),
                match settings.direction {
                    DirectionTerm::Thesis => "0",
                    DirectionTerm::Difference => "1",
                    DirectionTerm::Neighbour => "2",
                }
                .to_string(),
            ),
            ("DDF_PACK".to_string(), PACK.to_string()),
            ("DDF_FAST_EXP".to_string(), flag(settings.fast_exp)),
        ];
        let program = gpu.program("filters/ddf.cl", &defines, "")?;
        let pixels = width as usize * height as usize;
        let params = gpu.upload(&[settings.params(width, height, 1.0, 1.0)])?;
        let out = gpu.zeroed::<Float4>(pixels, "filtered image")?;
        let (w, h) = (width as usize, height as usize);
        // The packed variant's lines and the pass that fills them (ddf_packed.cl).
        let lines = if settings.variant == Variant::Packed {
            let half = settings.params(width, height, 1.0, 1.0).half_width as u32;
            // Floats per padded line: half, the row rounded up to PACK pixels, half.
            let stride = half + round_up(w, PACK as usize) as u32 + half;
            // Lines per image row: the 16 lanes of F and the direction term's input.
            let lines = 16 + match settings.direction {
                DirectionTerm::Thesis => 0,
                DirectionTerm::Difference => 3,
                DirectionTerm::Neighbour => 1,
            };
            // Zeroed once: the padding is never written, so it stays 0 (finite, masked).
            let buffer = gpu.zeroed::<f32>(
                lines * stride as usize * h,
                "the packed data-driven filter's lines",
            )?;
            let pack = Kernel::builder()
                .program(&program)
                .name("ddf_pack")
                .queue(gpu.queue.clone())
                .arg_named("p", &params)
                .arg_named("f", None::<&Buffer<u8>>)
                .arg_named("gb", None::<&Buffer<u8>>)
                .arg_named("state", None::<&Buffer<u8>>)
                .arg(&buffer)
                .arg(stride)
                .arg_named("row0", 0u32)
                .global_work_size([w, h])
                .build()
                .context("creating the data-driven filter's packing kernel")?;
            Some((pack, buffer, stride))
        } else {
            None
        };
        let mut b = Kernel::builder();
        b.program(&program)
            .name("ddf_filter")
            .queue(gpu.queue.clone());
        // The inputs are set per run, from the frame.
        b.arg_named("p", &params)
            .arg_named("f", None::<&Buffer<u8>>)
            .arg_named("gb", None::<&Buffer<u8>>)
            .arg_named("state", None::<&Buffer<u8>>)
            .arg_named("out", &out);
        match settings.variant {
            Variant::Rows => {
                let work_group = settings.work_group as usize;
                let max = gpu.summary.max_work_group_size;
                if max > 0 && work_group > max {
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
            v => {
                // The packed variant: one work-item per PACK pixels of a row.
                let items = if v == Variant::Packed {
                    w.div_ceil(PACK as usize)
                } else {
                    w
                };
                // PoCL runs a work-group's work-items in one thread and may keep every
                // work-item's private arrays (kB each for the packed variant) on that
                // thread's stack: letting it choose the group for 32 x 512 items overflowed
                // the stack (a crash at 512 x 512), so the packed variant's group is fixed.
                let work_group = match (v, work_group) {
                    (Variant::Packed, None) => Some(PACKED_GROUP),
                    _ => work_group,
                };
                match work_group {
                    Some(wg) if wg > 0 => {
                        b.global_work_size([round_up(items, wg), h])
                            .local_work_size([wg, 1]);
                    }
                    _ => {
                        b.global_work_size([items, h]);
                    }
                }
            }
        }
        if let Some((_, buffer, stride)) = &lines {
            b.arg(buffer).arg(*stride);
        }
        let kernel = b
            .build()
            .context("creating the data-driven filter kernel")?;
        Ok(DdfKernel {
            gpu,
            kernel,
            params,
            out,
            settings: settings.clone(),
            width,
            height,
            pack: lines.map(|(pack, buffer, _)| (pack, buffer)),
        })
    }

    /// The variant run (auto resolved for the device).
    pub fn variant(&self) -> Variant {
        self.settings.variant
    }

    /// Filters `frame` (which must be width x height); returns the image and the kernel time.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    /// Rows a band's pixels read beyond the band: half the kernel width (Alg. 8's window).
    pub fn reach(&self) -> u32 {
        (self.settings.kw - 1) / 2
    }

    /// Filters the pixels of `rows` only (one band of a frame split across devices); the
    /// frame's rows within [`DdfKernel::reach`] of the band must be current. The image's other
    /// rows are zero. Each pixel gets the bytes filtering the whole frame gives it: its window
    /// and the image bounds are the same.
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        frame.check_size(self.width, self.height, "the data-driven filter")?;
        frame.require(
            <super::Ddf as crate::filters::FilterKind>::needs(&self.settings),
            "the data-driven filter",
        )?;
        let depth_scale = crate::stats::depth_scale(frame.info().scene.scene_size);
        let p = self.settings.params(
            self.width,
            self.height,
            frame.variance_factor(),
            depth_scale,
        );
        self.params.write(std::slice::from_ref(&p)).enq()?;
        self.kernel
            .set_arg("f", frame.device(&self.gpu, BufferId::FilterVectors)?)?;
        self.kernel
            .set_arg("gb", frame.device(&self.gpu, BufferId::WelfordSums)?)?;
        self.kernel
            .set_arg("state", frame.device(&self.gpu, BufferId::WelfordState)?)?;
        let rows = rows.start.min(self.height)..rows.end.min(self.height);
        let mut kernel_time = Duration::ZERO;
        let mut items = self.width;
        if self.pack.is_some() {
            kernel_time += self.fill_lines(frame, &rows)?;
            items = self.width.div_ceil(PACK);
        }
        // SAFETY: all buffers outlive the launch (we wait for it) and hold width x height
        // pixels; the kernel skips work-items outside the image.
        let event = unsafe {
            enqueue_rows(
                &self.kernel,
                items,
                self.height,
                rows.clone(),
                "the data-driven filter",
            )?
        };
        kernel_time += event_duration(&event)?;
        Ok(FilterRun {
            image: read_rgb_rows(&self.out, self.width, self.height, rows)?,
            wall_time: start.elapsed(),
            kernel_time: Some(kernel_time),
        })
    }
}

impl DdfKernel {
    /// The packed variant's first pass (its lines) over the rows the band `rows` reads (the band and
    /// [`DdfKernel::reach`] rows either side); returns its kernel time.
    fn fill_lines(&mut self, frame: &Frame, rows: &Range<u32>) -> Result<Duration> {
        let Some((pack, _)) = &self.pack else {
            return Ok(Duration::ZERO);
        };
        let reach = self.reach();
        let (r0, r1) = (
            rows.start.saturating_sub(reach),
            rows.end.saturating_add(reach).min(self.height),
        );
        if r0 >= r1 {
            return Ok(Duration::ZERO);
        }
        pack.set_arg("f", frame.device(&self.gpu, BufferId::FilterVectors)?)?;
        pack.set_arg("gb", frame.device(&self.gpu, BufferId::WelfordSums)?)?;
        pack.set_arg("state", frame.device(&self.gpu, BufferId::WelfordState)?)?;
        pack.set_arg("row0", r0)?;
        let mut event = Event::empty();
        // SAFETY: the frame's buffers and the lines outlive the launch (we wait for it); the
        // kernel skips work-items outside the image.
        unsafe {
            pack.cmd()
                .global_work_size([self.width as usize, (r1 - r0) as usize])
                .enew(&mut event)
                .enq()
                .context("launching the data-driven filter's packing pass")?;
        }
        crate::gpu::profile::record(pack, &event);
        event_duration(&event)
    }
}

impl PreparedFilter for DdfKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    fn reach(&self) -> Option<u32> {
        Some(DdfKernel::reach(self))
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}
