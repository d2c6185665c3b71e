//! Launching kernels and reading images back: profiling events, launches over the whole
//! image or a band of its rows (several devices per frame, src/render/split.rs), and the
//! work-group rounding.

use std::time::Duration;

use anyhow::{Context as _, Result};
use ocl::Event;
use ocl::enums::ProfilingInfo;

use crate::imaging::RgbImage;

/// Kernel execution time of a finished command, from its profiling event.
pub fn event_duration(event: &Event) -> Result<Duration> {
    event.wait_for()?;
    let start = event.profiling_info(ProfilingInfo::Start)?.time()?;
    let end = event.profiling_info(ProfilingInfo::End)?.time()?;
    Ok(Duration::from_nanos(end.saturating_sub(start)))
}

/// Enqueues `kernel` and returns its profiling event (the caller waits on it, e.g. with
/// [`event_duration`]).
///
/// # Safety
/// Every buffer argument of `kernel` must be alive and sized for its global range until the
/// event completes.
pub unsafe fn enqueue(kernel: &ocl::Kernel, what: &str) -> Result<Event> {
    let mut event = Event::empty();
    // SAFETY: the caller's contract.
    unsafe {
        kernel
            .cmd()
            .enew(&mut event)
            .enq()
            .with_context(|| format!("launching {what}"))?;
    }
    super::profile::record(kernel, &event);
    Ok(event)
}

/// The work-group size of a launch over a band of rows when the kernel has none of its own.
/// Fixed, because a driver that chooses one from the global size (PoCL) compiles the kernel
/// anew for each size it chooses, and bands change height whenever the split is re-balanced.
pub const BAND_WORK_GROUP: [usize; 2] = [32, 1];

/// Like [`enqueue`], over the rows `rows` of a `width × height` image (one band of a frame
/// split across devices) instead of the kernel's default range: one work-item per pixel,
/// rounded up to the kernel's work-group size (kernels skip work-items outside the image).
/// A kernel without a work-group size of its own gets [`BAND_WORK_GROUP`] for a band short of
/// the whole image.
///
/// # Safety
/// As for [`enqueue`], for the given range.
pub unsafe fn enqueue_rows(
    kernel: &ocl::Kernel,
    width: u32,
    height: u32,
    rows: std::ops::Range<u32>,
    what: &str,
) -> Result<Event> {
    if rows.start == 0 && rows.end >= height {
        // The whole image: exactly the kernel's own launch, so that one device renders and
        // filters as it always has (PoCL compiles a launch with a global offset separately).
        // SAFETY: the caller's contract.
        return unsafe { enqueue(kernel, what) };
    }
    let (w, n) = (width as usize, rows.len());
    let local = match kernel.default_local_work_size().to_lens() {
        Ok(l) => [l[0], l[1]],
        Err(_) => BAND_WORK_GROUP,
    };
    let mut event = Event::empty();
    let cmd = kernel
        .cmd()
        .global_work_offset([0, rows.start as usize])
        .enew(&mut event);
    let cmd = cmd
        .global_work_size([round_up(w, local[0]), round_up(n, local[1])])
        .local_work_size(local);
    // SAFETY: the caller's contract.
    unsafe {
        cmd.enq().with_context(|| format!("launching {what}"))?;
    }
    super::profile::record(kernel, &event);
    Ok(event)
}

/// The first `width × height` pixels of a device image of `float4`s (rgb, w unused).
pub fn read_rgb(
    buffer: &ocl::Buffer<crate::layout::Float4>,
    width: u32,
    height: u32,
) -> Result<RgbImage> {
    read_rgb_rows(buffer, width, height, 0..height)
}

/// Like [`read_rgb`], reading back only `rows` (a band a filter wrote); the other rows are
/// black.
pub fn read_rgb_rows(
    buffer: &ocl::Buffer<crate::layout::Float4>,
    width: u32,
    height: u32,
    rows: std::ops::Range<u32>,
) -> Result<RgbImage> {
    let w = width as usize;
    let mut band = vec![crate::layout::Float4::default(); rows.len() * w];
    if !band.is_empty() {
        buffer
            .read(&mut band)
            .offset(rows.start as usize * w)
            .enq()
            .context("reading an image back")?;
    }
    let mut pixels = vec![[0.0f32; 3]; w * height as usize];
    for (dst, p) in pixels[rows.start as usize * w..].iter_mut().zip(&band) {
        *dst = [p.0[0], p.0[1], p.0[2]];
    }
    Ok(RgbImage {
        width,
        height,
        pixels,
    })
}

/// Rounds `n` up to a multiple of `m`.
pub fn round_up(n: usize, m: usize) -> usize {
    n.div_ceil(m) * m
}
