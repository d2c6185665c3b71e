//! The shared 1-D passes on the device (kernels/filters/aaf_pass.cl): the guide and value
//! buffers a filter's prepare kernel writes, and the two passes over them.

use std::ops::Range;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use ocl::{Buffer, Kernel};

use super::PassParams;
use crate::filters::FilterRun;
use crate::gpu::{Gpu, enqueue_rows, event_duration, read_rgb_rows};
use crate::layout::Float4;

/// The guide (three float4 per pixel), two value buffers and the passes along rows (values[0]
/// into values[1]) and columns (back into values[0]).
pub struct DevicePasses {
    rows: Kernel,
    columns: Kernel,
    pub guide: Buffer<Float4>,
    /// The prepare kernel writes values[0]; after [`DevicePasses::run`] it holds the result.
    pub values: [Buffer<Float4>; 2],
    width: u32,
    height: u32,
}

impl DevicePasses {
    pub fn new(gpu: &Gpu, p: &PassParams) -> Result<DevicePasses> {
        let program = gpu.program("filters/aaf_pass.cl", &[], "")?;
        let n = p.width as usize * p.height as usize;
        let guide = gpu.zeroed::<Float4>(3 * n, "AAF guide")?;
        let values = [
            gpu.zeroed::<Float4>(n, "AAF values")?,
            gpu.zeroed::<Float4>(n, "AAF values")?,
        ];
        let build = |axis: u32, from: &Buffer<Float4>, to: &Buffer<Float4>| {
            Kernel::builder()
                .program(&program)
                .name("aaf_pass")
                .queue(gpu.queue.clone())
                .global_work_size([p.width as usize, p.height as usize])
                .arg(&guide)
                .arg(from)
                .arg(to)
                .arg(p.width)
                .arg(p.height)
                .arg(p.radius)
                .arg(axis)
                .arg(p.normal_cos)
                .arg(p.depth_tolerance)
                .arg(p.beta_tolerance)
                .build()
                .context("creating an AAF pass kernel")
        };
        Ok(DevicePasses {
            rows: build(0, &values[0], &values[1])?,
            columns: build(1, &values[1], &values[0])?,
            guide,
            values,
            width: p.width,
            height: p.height,
        })
    }

    /// A whole AAF filter over the pixels of `rows` (one band of a frame split across
    /// devices, or all of it): the filter's `prepare` kernel and the pass along rows on the
    /// band widened by `radius` rows (which the pass along columns reads), so the band's
    /// pixels get the bytes filtering the whole frame gives them; the pass along columns and
    /// `compose` (which writes `image`) on the band. The image is read back, its other rows
    /// black; the kernel time sums the four launches.
    pub fn filter_band(
        &self,
        prepare: &Kernel,
        compose: &Kernel,
        image: &Buffer<Float4>,
        radius: u32,
        rows: Range<u32>,
        start: Instant,
    ) -> Result<FilterRun> {
        let h = self.height;
        let rows = rows.start.min(h)..rows.end.min(h);
        let kernel_time = self.run_band(prepare, compose, radius, rows.clone())?;
        Ok(FilterRun {
            image: read_rgb_rows(image, self.width, self.height, rows)?,
            wall_time: start.elapsed(),
            kernel_time: Some(kernel_time),
        })
    }

    /// [`Self::filter_band`]'s four launches without the read-back (a filter of several
    /// lights runs them once per light); returns their kernel time.
    pub fn run_band(
        &self,
        prepare: &Kernel,
        compose: &Kernel,
        radius: u32,
        rows: Range<u32>,
    ) -> Result<Duration> {
        let h = self.height;
        let rows = rows.start.min(h)..rows.end.min(h);
        let widened = rows.start.saturating_sub(radius)..(rows.end + radius).min(h);
        let mut kernel_time = Duration::ZERO;
        // SAFETY (both launches): the kernels' buffers are owned by the filter or the frame,
        // alive until the event completes (we wait on it here), sized for width x height.
        let event = unsafe {
            enqueue_rows(
                prepare,
                self.width,
                h,
                widened.clone(),
                "the AAF prepare pass",
            )?
        };
        kernel_time += event_duration(&event)?;
        kernel_time += self.run(widened, rows.clone())?;
        let event =
            unsafe { enqueue_rows(compose, self.width, h, rows.clone(), "the AAF compose pass")? };
        kernel_time += event_duration(&event)?;
        Ok(kernel_time)
    }

    /// The pass along rows over `widened` (the band and the rows the column pass reads
    /// beyond it), then the pass along columns over `rows`; returns their kernel time.
    pub fn run(&self, widened: Range<u32>, rows: Range<u32>) -> Result<Duration> {
        let mut time = Duration::ZERO;
        for (k, band, what) in [
            (&self.rows, widened, "the AAF pass along rows"),
            (&self.columns, rows, "the AAF pass along columns"),
        ] {
            // SAFETY: the buffers are owned by self, alive until the event completes (we wait
            // on it here), and sized for width x height pixels.
            let event = unsafe { enqueue_rows(k, self.width, self.height, band, what)? };
            time += event_duration(&event)?;
        }
        Ok(time)
    }
}
