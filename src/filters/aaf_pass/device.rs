//! The shared 1-D passes on the device (kernels/filters/aaf_pass.cl): the guide and value
//! buffers a filter's prepare kernel writes, and the two passes over them.

use std::ops::Range;
use std::time::Duration;

use anyhow::{Context as _, Result};
use ocl::{Buffer, Kernel};

use super::PassParams;
use crate::gpu::{Gpu, enqueue_rows, event_duration};
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
