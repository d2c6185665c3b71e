//! Several OpenCL devices rendering one frame (thesis §4.2: "If we have more than one render
//! device, the renderer will create multiple render devices where each one gets its own thread
//! ... Each render device is assigned to a specific part of the screen depending on the speed
//! of the device").
//!
//! Every device holds the whole film (full-size output buffers) and renders one band of rows
//! per launch, each from its own thread; [`super::balance`] moves the band boundaries after
//! every frame from the measured kernel times. Since every random number is a hash of (seed,
//! pixel, sample, bounce, dimension) (kernels/render/rng.cl) and each pixel's samples are
//! folded in the same order wherever they run, the film is bit for bit the film one device
//! renders: a pixel does not know which device traced it (tests/multi_device.rs).
//!
//! Where the film is read whole (filters, AOVs, images), the bands are first *merged* into the
//! first device (the primary): each other device's band is read back and written there. When
//! rows change hands, their state goes with them, from the device that rendered them last. A
//! filter that runs on the bands instead (src/filters/placement.rs) needs only a border of rows
//! around each band, which [`SplitRenderer::exchange_borders`] copies between neighbours.

use std::cell::Cell;
use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, anyhow, bail};

use super::balance::{Balancer, owners};
use super::{Frame, LaunchStats, RenderOptions, Renderer, SceneArrays, SceneInfo};
use crate::gpu::Gpu;
use crate::layout::outputs::OutputSet;
use crate::scene::Scene;

/// One device's part of a frame.
#[derive(Clone, Debug)]
pub struct DeviceTiming {
    pub rows: Range<u32>,
    /// Kernel time of its launch (OpenCL profiling events).
    pub kernel: Duration,
}

/// What one frame cost on each device, and what moving rows cost.
#[derive(Clone, Debug, Default)]
pub struct SplitFrame {
    pub samples: u32,
    pub devices: Vec<DeviceTiming>,
    /// Wall-clock time from the first launch to the last device's end.
    pub render_wall: Duration,
    /// Rows whose state was copied to another device after the frame (re-balancing).
    pub moved_rows: u32,
    /// Wall-clock time of the copies after the frame: merging and moved rows.
    pub transfer: Duration,
}

impl SplitFrame {
    /// The slowest device's kernel time: the frame's critical path.
    pub fn slowest(&self) -> Duration {
        self.devices
            .iter()
            .map(|d| d.kernel)
            .max()
            .unwrap_or_default()
    }

    /// How long device `i` waited for the slowest one.
    pub fn idle(&self, i: usize) -> Duration {
        self.slowest().saturating_sub(self.devices[i].kernel)
    }
}

/// A film rendered by one or more devices, each on a band of rows.
pub struct SplitRenderer {
    parts: Vec<Renderer>,
    bands: Vec<Range<u32>>,
    pub balancer: Balancer,
    /// Merge after every frame (a filter reads the whole film every frame).
    merge_each_frame: bool,
    /// The primary holds every row's current state.
    merged: Cell<bool>,
    last: Option<SplitFrame>,
    pub rays_total: u64,
    /// Sum over frames of the slowest device's kernel time.
    pub kernel_time_total: Duration,
}

impl SplitRenderer {
    /// A renderer per device, over arrays built from `scene`; the first split is in
    /// proportion to compute units × clock, until kernel times are measured.
    pub fn new(
        gpus: &[Arc<Gpu>],
        scene: &Scene,
        arrays: SceneArrays,
        options: &RenderOptions,
    ) -> Result<SplitRenderer> {
        let Some((first, rest)) = gpus.split_first() else {
            bail!("no device to render with");
        };
        let mut options = options.clone();
        if gpus.len() > 1 && options.local_size.is_none() {
            // Bands change height when re-balanced; a fixed work-group size keeps one compiled
            // kernel (see BAND_WORK_GROUP).
            options.local_size = Some(crate::gpu::BAND_WORK_GROUP);
        }
        let options = &options;
        let mut parts = Vec::with_capacity(gpus.len());
        for gpu in rest {
            parts.push(
                Renderer::with_arrays(gpu.clone(), scene, arrays.clone(), options)
                    .with_context(|| format!("setting up {}", gpu.summary.name))?,
            );
        }
        parts.insert(
            0,
            Renderer::with_arrays(first.clone(), scene, arrays, options)?,
        );
        let weights: Vec<f64> = gpus
            .iter()
            .map(|g| g.summary.compute_units as f64 * g.summary.max_clock_mhz as f64)
            .collect();
        Ok(SplitRenderer::from_parts(parts, &weights))
    }

    /// One device: a plain [`Renderer`] behind the same interface.
    pub fn single(renderer: Renderer) -> SplitRenderer {
        SplitRenderer::from_parts(vec![renderer], &[1.0])
    }

    fn from_parts(parts: Vec<Renderer>, weights: &[f64]) -> SplitRenderer {
        let balancer = Balancer::new(parts[0].height(), parts[0].row_granularity());
        let bands = balancer.split(weights);
        SplitRenderer {
            parts,
            bands,
            balancer,
            merge_each_frame: true,
            merged: Cell::new(true),
            last: None,
            rays_total: 0,
            kernel_time_total: Duration::ZERO,
        }
    }

    /// The renderers, the primary first.
    pub fn parts(&self) -> &[Renderer] {
        &self.parts
    }

    pub fn primary(&self) -> &Renderer {
        &self.parts[0]
    }

    pub fn bands(&self) -> &[Range<u32>] {
        &self.bands
    }

    pub fn width(&self) -> u32 {
        self.parts[0].width()
    }

    pub fn height(&self) -> u32 {
        self.parts[0].height()
    }

    pub fn samples_done(&self) -> u32 {
        self.parts[0].samples_done()
    }

    pub fn outputs(&self) -> OutputSet {
        self.parts[0].outputs()
    }

    pub fn scene_info(&self) -> &SceneInfo {
        &self.parts[0].scene_info
    }

    /// The last frame's timings.
    pub fn last_frame(&self) -> Option<&SplitFrame> {
        self.last.as_ref()
    }

    /// "AMD EPYC" or "basic-… 40 % + pthread-… 60 %".
    pub fn describe(&self) -> String {
        if self.parts.len() == 1 {
            return self.parts[0].gpu.summary.name.clone();
        }
        self.parts
            .iter()
            .zip(&self.bands)
            .map(|(p, b)| {
                format!(
                    "{} {:.0} %",
                    p.gpu.summary.name,
                    100.0 * b.len() as f64 / self.height() as f64
                )
            })
            .collect::<Vec<_>>()
            .join(" + ")
    }

    /// Merge the bands into the primary after every frame (true, the default: whatever reads
    /// the film reads it whole), or only when [`SplitRenderer::frame`] asks.
    pub fn set_merge_each_frame(&mut self, on: bool) {
        self.merge_each_frame = on;
    }

    /// Adds `count` samples per pixel: every device renders its band at once, each from its
    /// own thread; then the bands are merged (see [`SplitRenderer::set_merge_each_frame`]) and
    /// re-balanced from the kernel times.
    pub fn render_samples(&mut self, count: u32) -> Result<LaunchStats> {
        let start = Instant::now();
        let stats: Vec<LaunchStats> = if self.parts.len() == 1 {
            vec![self.parts[0].render_samples(count)?]
        } else {
            let bands = &self.bands;
            std::thread::scope(|s| {
                let handles: Vec<_> = self
                    .parts
                    .iter_mut()
                    .zip(bands)
                    .map(|(r, b)| s.spawn(move || r.render_rows(count, b.clone())))
                    .collect();
                handles
                    .into_iter()
                    .map(|h| {
                        h.join()
                            .unwrap_or_else(|_| Err(anyhow!("a render thread panicked")))
                    })
                    .collect::<Result<Vec<_>>>()
            })?
        };
        let render_wall = start.elapsed();
        let mut frame = SplitFrame {
            samples: count,
            devices: self
                .bands
                .iter()
                .zip(&stats)
                .map(|(b, s)| DeviceTiming {
                    rows: b.clone(),
                    kernel: s.kernel_time,
                })
                .collect(),
            render_wall,
            ..Default::default()
        };
        let rays: u64 = stats.iter().map(|s| s.rays).sum();
        // The once-per-render passes run over the whole image on every device (their output
        // depends on neighbours): count one device's, the slowest.
        let pass_time = stats.iter().map(|s| s.pass_time).max().unwrap_or_default();
        let pass_rays = stats.iter().map(|s| s.pass_rays).max().unwrap_or_default();
        self.rays_total += rays + pass_rays;
        self.kernel_time_total += frame.slowest() + pass_time;
        if self.parts.len() > 1 {
            let copies = Instant::now();
            self.merged.set(false);
            if self.merge_each_frame {
                self.merge()?;
            }
            let seconds: Vec<f64> = stats.iter().map(|s| s.kernel_time.as_secs_f64()).collect();
            if let Some(next) = self.balancer.next(&self.bands, &seconds) {
                frame.moved_rows = self.set_bands(next)?;
            }
            frame.transfer = copies.elapsed();
        }
        self.last = Some(frame);
        Ok(LaunchStats {
            samples: count,
            kernel_time: self
                .last
                .as_ref()
                .map(SplitFrame::slowest)
                .unwrap_or_default(),
            rays,
            pass_time,
            pass_rays,
        })
    }

    /// Copies every other device's band into the primary, so that it holds the whole film.
    pub fn merge(&self) -> Result<()> {
        if self.merged.get() {
            return Ok(());
        }
        for (part, band) in self.parts.iter().zip(&self.bands).skip(1) {
            copy_rows(part, &self.parts[0], band.clone(), None)?;
        }
        self.merged.set(true);
        Ok(())
    }

    /// The whole film, on the primary device (merged first where needed).
    pub fn frame(&self) -> Result<Frame> {
        self.merge()?;
        Ok(self.parts[0].frame())
    }

    /// Hands rows to devices as `bands` says (contiguous, top to bottom, covering the image,
    /// on multiples of the row granularity), moving the state of every row that changes hands
    /// from the device that holds it. Returns the number of rows moved.
    pub fn set_bands(&mut self, bands: Vec<Range<u32>>) -> Result<u32> {
        let h = self.height();
        let g = self.balancer.granularity;
        let contiguous = bands.len() == self.parts.len()
            && bands.first().is_some_and(|b| b.start == 0)
            && bands.last().is_some_and(|b| b.end == h)
            && bands
                .windows(2)
                .all(|w| w[0].end == w[1].start && w[0].start <= w[0].end);
        if !contiguous || bands.iter().any(|b| b.start % g != 0) {
            bail!(
                "bands {bands:?} do not split {h} rows on multiples of {g} among {} devices",
                self.parts.len()
            );
        }
        let old = owners(&self.bands, h);
        let new = owners(&bands, h);
        let mut moved = 0;
        let mut y = 0;
        while y < h {
            let (from, to) = (old[y as usize], new[y as usize]);
            let mut end = y + 1;
            while end < h && old[end as usize] == from && new[end as usize] == to {
                end += 1;
            }
            // After a merge the primary already holds every row.
            if from != to && !(to == 0 && self.merged.get()) {
                copy_rows(&self.parts[from], &self.parts[to], y..end, None)?;
            }
            if from != to {
                moved += end - y;
            }
            y = end;
        }
        self.bands = bands;
        Ok(moved)
    }

    /// Copies to every device the `border` rows above and below its band, of the outputs in
    /// `outputs`, from the devices that hold them: what a filter of that reach needs to filter
    /// the band alone exactly as it filters the whole film.
    pub fn exchange_borders(&self, border: u32, outputs: OutputSet) -> Result<()> {
        if self.parts.len() == 1 || border == 0 {
            return Ok(());
        }
        let h = self.height();
        let owner = owners(&self.bands, h);
        for (i, band) in self.bands.iter().enumerate() {
            if band.is_empty() {
                continue;
            }
            let above = band.start.saturating_sub(border)..band.start;
            let below = band.end..(band.end + border).min(h);
            for rows in [above, below] {
                for (from, run) in runs(&owner, rows) {
                    if from != i {
                        copy_rows(&self.parts[from], &self.parts[i], run, Some(outputs))?;
                    }
                }
            }
        }
        Ok(())
    }

    /// Empties the film on every device.
    pub fn reset(&mut self) -> Result<()> {
        for p in &mut self.parts {
            p.reset()?;
        }
        self.merged.set(true);
        Ok(())
    }

    /// Moves the camera on every device and empties the film (thesis §4.2.2: "Every time an
    /// update happens, the Film is reset and the new camera parameters are send to all
    /// devices").
    pub fn set_camera(&mut self, scene: &Scene) -> Result<()> {
        for p in &mut self.parts {
            p.set_camera(scene)?;
        }
        self.merged.set(true);
        Ok(())
    }
}

/// `rows` cut into runs of one owner each.
fn runs(owner: &[usize], rows: Range<u32>) -> Vec<(usize, Range<u32>)> {
    let mut out: Vec<(usize, Range<u32>)> = Vec::new();
    for y in rows {
        let o = owner[y as usize];
        match out.last_mut() {
            Some((last, run)) if *last == o && run.end == y => run.end = y + 1,
            _ => out.push((o, y..y + 1)),
        }
    }
    out
}

/// Copies `rows` of every output buffer (or only those of `only`) from one device's film to
/// another's, through the host (the devices may sit in different OpenCL contexts).
fn copy_rows(
    from: &Renderer,
    to: &Renderer,
    rows: Range<u32>,
    only: Option<OutputSet>,
) -> Result<()> {
    if rows.is_empty() {
        return Ok(());
    }
    let w = from.width();
    for ((id, src), (_, dst)) in from.buffers.iter().zip(&to.buffers) {
        if !from.outputs.contains(id.owner()) || only.is_some_and(|o| !o.contains(id.owner())) {
            continue;
        }
        let row = id
            .decl()
            .bytes(w, 1, from.sample_capacity, from.shadow_planes()) as usize;
        let (offset, len) = (rows.start as usize * row, rows.len() * row);
        let mut bytes = vec![0u8; len];
        src.read(&mut bytes)
            .offset(offset)
            .enq()
            .with_context(|| format!("reading rows of the {} buffer", id.decl().name))?;
        dst.write(&bytes)
            .offset(offset)
            .enq()
            .with_context(|| format!("writing rows of the {} buffer", id.decl().name))?;
    }
    Ok(())
}
