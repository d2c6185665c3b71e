//! The wavefront path tracer's host side (kernels/render/wavefront.cl; Laine, Karras & Aila
//! 2013, "Megakernels considered harmful"): the megakernel's samples as a generate kernel, then
//! extension, shading and shadow-ray kernels over queues of paths until no path is left, and
//! the film kernel. Selected with [`Tracer::Wavefront`] (`render --tracer wavefront`); the
//! megakernel stays the default and the reference. Both run the steps of
//! kernels/render/path.cl in the same order, so the images are the same bytes
//! (tests/wavefront.rs); `bench --study tracers` measures the two side by side.

use std::time::Duration;

use anyhow::{Context as _, Result};
use ocl::{Buffer, Event, Kernel, Program};

use super::{DeviceScene, Tile, over_pixels};
use crate::gpu::{Gpu, enqueue_rows, event_duration, round_up};
use crate::layout::outputs::BufferId;

/// Which kernels trace the paths.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Tracer {
    /// One work-item per pixel traces each sample's whole path (thesis §4.3, the reference).
    #[default]
    Megakernel,
    /// One kernel per step of the paths over queues (Laine et al. 2013); the same bytes.
    Wavefront,
}

/// Work-group size of the kernels launched over a queue: fixed, because PoCL compiles a kernel
/// anew for every work-group size it picks itself, and the queues' lengths change every bounce.
const QUEUE_WORK_GROUP: usize = 64;

/// Paths in flight at most on a device of kind `kind`. A GPU needs many (Laine et al. keep
/// about a million) to hide memory latency; on a CPU a wave's records (about 400 bytes a
/// path) should stay in the caches. PoCL, 2 cores with 1 MB L2 each and 32 MB L3, kernel time
/// of `render scenes/cornell_diffuse.toml --spp 16 --tracer wavefront --wave-paths N`:
/// 3.17 / 2.66 / 2.62 / 2.99 / 2.98 s for N = 4,096 / 8,192 / 16,384 / 32,768 / 262,144 (the
/// whole 512² image); small waves also pay a host round trip per bounce each.
pub fn wave_paths(kind: &str) -> usize {
    if kind == "CPU" { 1 << 14 } else { 1 << 20 }
}

/// The wavefront kernels, in the order of [`StepTimes`].
pub const STEPS: [&str; 5] = ["generate", "extend", "shade", "shadow", "accumulate"];
const GENERATE: usize = 0;
const EXTEND: usize = 1;
const SHADE: usize = 2;
const SHADOW_RAYS: usize = 3;
const ACCUMULATE: usize = 4;

/// Kernel time per step ([`STEPS`]), from the launches' profiling events.
pub type StepTimes = [Duration; 5];

/// Queue counters (kernels/render/wavefront.cl WAVEFRONT_NEXT, WAVEFRONT_SHADOW).
const NEXT: usize = 0;
const SHADOW: usize = 1;

/// The wavefront kernels, bound to the renderer's buffers, and the per-path records: one path
/// in flight per pixel of a wave (`wave_rows` rows of the renderer's tile).
pub struct Wavefront {
    generate: Kernel,
    extend: Kernel,
    shade: Kernel,
    shadow: Kernel,
    accumulate: Kernel,
    /// Two queues used in turn: each path's slot, and its ray at the same place.
    queues: [(Buffer<u32>, Buffer<u8>); 2],
    counts: Buffer<u32>,
    width: u32,
    height: u32,
    /// Rows of a wave: the rows of a launch are traced this many at a time, each wave all its
    /// samples; the records hold one wave (a multiple of the work-group height).
    wave_rows: u32,
    // The records the kernels keep between launches; held here so they live as long as the
    // kernels bound to them.
    _paths: Buffer<u8>,
    _hits: Buffer<u8>,
    _connections: Buffer<u8>,
    _shadow_queue: Buffer<u32>,
}

/// What [`Wavefront::new`] binds besides the scene: the renderer's buffers and settings.
pub struct WavefrontBindings<'a> {
    pub outputs: &'a [(BufferId, Buffer<u8>)],
    pub shadow_pixels: &'a Buffer<u8>,
    pub ray_counts: &'a Buffer<u32>,
    pub debug_counters: &'a Buffer<u32>,
    pub tile: Tile,
    pub local_size: Option<[usize; 2]>,
    pub sample_capacity: u32,
    pub range_first: u32,
    pub shadow_lights: u32,
    /// Paths in flight at most; None: [`wave_paths`] for the device.
    pub wave_paths: Option<usize>,
}

impl Wavefront {
    /// The kernels of `program` (built with WAVEFRONT=1), their records allocated for one
    /// wave of rows of `b.tile`.
    pub(super) fn new(
        gpu: &Gpu,
        program: &Program,
        scene: &DeviceScene,
        b: &WavefrontBindings,
    ) -> Result<Wavefront> {
        let (w, h) = (b.tile.width, b.tile.height);
        let granularity = b.local_size.map_or(1, |l| l[1] as u32);
        let paths_in_flight = b
            .wave_paths
            .unwrap_or_else(|| wave_paths(&gpu.summary.kind));
        let wave_rows = ((paths_in_flight / w.max(1) as usize).max(1) as u32).div_ceil(granularity)
            * granularity;
        let pixels = w as usize * wave_rows.min(h) as usize;
        let [path_bytes, hit_bytes, connection_bytes, ray_bytes] = record_sizes(gpu, program)?;
        let paths = gpu.zeroed::<u8>(pixels * path_bytes, "wavefront path state")?;
        let hits = gpu.zeroed::<u8>(pixels * hit_bytes, "wavefront hit")?;
        let connections = gpu.zeroed::<u8>(pixels * connection_bytes, "wavefront connection")?;
        let queue = || -> Result<(Buffer<u32>, Buffer<u8>)> {
            Ok((
                gpu.zeroed::<u32>(pixels, "wavefront path queue")?,
                gpu.zeroed::<u8>(pixels * ray_bytes, "wavefront ray queue")?,
            ))
        };
        let queues = [queue()?, queue()?];
        let shadow_queue = gpu.zeroed::<u32>(pixels, "wavefront shadow-ray queue")?;
        let counts = gpu.zeroed::<u32>(2, "wavefront queue length")?;
        let builder = |name: &'static str| {
            let mut k = Kernel::builder();
            k.program(program).name(name).queue(gpu.queue.clone());
            scene.bind(&mut k, b.debug_counters);
            k
        };
        let over_queue = |k: &mut ocl::builders::KernelBuilder| {
            k.global_work_size(QUEUE_WORK_GROUP)
                .local_work_size(QUEUE_WORK_GROUP)
                .arg_named("count", 0u32);
        };
        let tile_args = |k: &mut ocl::builders::KernelBuilder| {
            k.arg_named("tile_x", b.tile.x)
                .arg_named("tile_y", b.tile.y)
                .arg_named("tile_width", w)
                .arg_named("tile_height", h);
        };
        let created = |k: ocl::builders::KernelBuilder, name: &str| {
            k.build()
                .with_context(|| format!("creating the wavefront kernel {name}"))
        };

        let mut k = builder("wavefront_generate");
        over_pixels(&mut k, b.tile, b.local_size);
        k.arg_named("paths", &paths)
            .arg_named("queue", &queues[0].0)
            .arg_named("rays", &queues[0].1)
            .arg_named("counts", &counts);
        tile_args(&mut k);
        k.arg_named("path_base", 0u32).arg_named("sample", 0u32);
        let generate = created(k, "wavefront_generate")?;

        let mut k = builder("wavefront_extend");
        k.arg_named("rays", &queues[0].1)
            .arg_named("hits", &hits)
            .arg_named("queue", &queues[0].0);
        over_queue(&mut k);
        k.arg_named("ray_counts", b.ray_counts)
            .arg_named("path_base", 0u32);
        let extend = created(k, "wavefront_extend")?;

        let mut k = builder("wavefront_shade");
        k.arg_named("paths", &paths)
            .arg_named("hits", &hits)
            .arg_named("connections", &connections)
            .arg_named("queue", &queues[0].0);
        over_queue(&mut k);
        k.arg_named("next_queue", &queues[1].0)
            .arg_named("next_rays", &queues[1].1)
            .arg_named("shadow_queue", &shadow_queue)
            .arg_named("counts", &counts)
            .arg_named("shadow_pixels", b.shadow_pixels)
            .arg_named("shadow_lights", b.shadow_lights)
            .arg_named("path_base", 0u32);
        let shade = created(k, "wavefront_shade")?;

        let mut k = builder("wavefront_shadow");
        k.arg_named("connections", &connections)
            .arg_named("shadow_queue", &shadow_queue);
        over_queue(&mut k);
        k.arg_named("ray_counts", b.ray_counts)
            .arg_named("path_base", 0u32);
        let shadow = created(k, "wavefront_shadow")?;

        let mut k = builder("wavefront_accumulate");
        over_pixels(&mut k, b.tile, b.local_size);
        k.arg_named("paths", &paths)
            .arg_named("connections", &connections);
        for (id, buffer) in b.outputs {
            k.arg_named(id.decl().name, buffer);
        }
        k.arg_named("sample_capacity", b.sample_capacity);
        tile_args(&mut k);
        k.arg_named("path_base", 0u32)
            .arg_named("range_first", b.range_first)
            .arg_named("sample", 0u32);
        let accumulate = created(k, "wavefront_accumulate")?;

        Ok(Wavefront {
            generate,
            extend,
            shade,
            shadow,
            accumulate,
            queues,
            counts,
            width: w,
            height: h,
            wave_rows,
            _paths: paths,
            _hits: hits,
            _connections: connections,
            _shadow_queue: shadow_queue,
        })
    }

    /// Adds samples `first..first + count` of the pixels of `rows`, one sample of every pixel
    /// of a wave at a time, and returns each step's kernel time. `ray_counts` gets each
    /// pixel's rays.
    pub(super) fn run(
        &self,
        first: u32,
        count: u32,
        rows: std::ops::Range<u32>,
        ray_counts: &Buffer<u32>,
    ) -> Result<StepTimes> {
        // The kernels add to each pixel's count; the megakernel writes its launch's count.
        let w = self.width as usize;
        ray_counts
            .cmd()
            .fill(0u32, Some(rows.len() * w))
            .offset(rows.start as usize * w)
            .enq()
            .context("clearing the ray counts")?;
        let mut events = Vec::new();
        let mut start = rows.start;
        while start < rows.end {
            let wave = start..(start + self.wave_rows).min(rows.end);
            for sample in first..first + count {
                self.trace_wave(sample, wave.clone(), &mut events)?;
            }
            start = wave.end;
        }
        let mut times = StepTimes::default();
        for (step, e) in &events {
            times[*step] += event_duration(e)?;
        }
        Ok(times)
    }

    /// Sample `sample` of the pixels of `rows`: generate, then extension, shading and shadow
    /// rays until no path is left, then the film. Pushes the launches' events.
    fn trace_wave(
        &self,
        sample: u32,
        rows: std::ops::Range<u32>,
        events: &mut Vec<(usize, Event)>,
    ) -> Result<()> {
        let path_base = rows.start * self.width;
        for k in [
            &self.generate,
            &self.extend,
            &self.shade,
            &self.shadow,
            &self.accumulate,
        ] {
            k.set_arg("path_base", path_base)?;
        }
        self.generate.set_arg("sample", sample)?;
        self.reset_counts()?;
        // SAFETY: every buffer argument is owned by the renderer or by self: the outputs hold
        // the whole tile, the records one wave, which `rows` (a wave) and `path_base` index;
        // the kernel skips work-items beyond the tile.
        events.push((GENERATE, unsafe {
            enqueue_rows(
                &self.generate,
                self.width,
                self.height,
                rows.clone(),
                "wavefront_generate",
            )?
        }));
        let mut queued = self.read_counts()?[NEXT];
        let mut current = 0;
        while queued > 0 {
            let (queue, next) = (&self.queues[current], &self.queues[1 - current]);
            self.extend.set_arg("queue", &queue.0)?;
            self.extend.set_arg("rays", &queue.1)?;
            self.extend.set_arg("count", queued)?;
            events.push((
                EXTEND,
                launch_queue(&self.extend, queued, "wavefront_extend")?,
            ));
            self.reset_counts()?;
            self.shade.set_arg("queue", &queue.0)?;
            self.shade.set_arg("next_queue", &next.0)?;
            self.shade.set_arg("next_rays", &next.1)?;
            self.shade.set_arg("count", queued)?;
            events.push((SHADE, launch_queue(&self.shade, queued, "wavefront_shade")?));
            let counts = self.read_counts()?;
            if counts[SHADOW] > 0 {
                self.shadow.set_arg("count", counts[SHADOW])?;
                let shadows = launch_queue(&self.shadow, counts[SHADOW], "wavefront_shadow")?;
                events.push((SHADOW_RAYS, shadows));
            }
            queued = counts[NEXT];
            current = 1 - current;
        }
        self.accumulate.set_arg("sample", sample)?;
        // SAFETY: as for the generate kernel.
        events.push((ACCUMULATE, unsafe {
            enqueue_rows(
                &self.accumulate,
                self.width,
                self.height,
                rows,
                "wavefront_accumulate",
            )?
        }));
        Ok(())
    }

    /// Empties the queues' lengths: a fill in the device's queue, ordered with the launches,
    /// so the host does not wait for it (one host round trip per bounce, the read of the
    /// lengths, instead of two).
    fn reset_counts(&self) -> Result<()> {
        self.counts
            .cmd()
            .fill(0u32, None)
            .enq()
            .context("clearing the wavefront queue lengths")
    }

    fn read_counts(&self) -> Result<[u32; 2]> {
        let mut c = [0u32; 2];
        self.counts
            .read(&mut c[..])
            .enq()
            .context("reading the wavefront queue lengths")?;
        Ok(c)
    }
}

/// Launches a queue kernel over `count` work-items (rounded up to its work-group).
fn launch_queue(kernel: &Kernel, count: u32, what: &str) -> Result<Event> {
    let mut event = Event::empty();
    // SAFETY: the queue kernels' buffers are owned by the renderer or the Wavefront; the
    // queues and records hold a wave, and `count` is at most a wave's paths; work-items past
    // `count` return at once.
    unsafe {
        kernel
            .cmd()
            .global_work_size(round_up(count as usize, QUEUE_WORK_GROUP))
            .enew(&mut event)
            .enq()
            .with_context(|| format!("launching {what}"))?;
    }
    crate::gpu::profile::record(kernel, &event);
    Ok(event)
}

/// sizeof(PathState), sizeof(Hit), sizeof(LightConnection) and sizeof(QueuedRay) as the device
/// lays them out: the host only allocates these records, so the device's own answer is the one
/// source of truth.
fn record_sizes(gpu: &Gpu, program: &Program) -> Result<[usize; 4]> {
    let out = gpu.zeroed::<u32>(4, "wavefront record sizes")?;
    let k = Kernel::builder()
        .program(program)
        .name("wavefront_sizes")
        .queue(gpu.queue.clone())
        .global_work_size(1)
        .arg_named("out", &out)
        .build()
        .context("creating the wavefront kernel wavefront_sizes")?;
    // SAFETY: `out` holds the four words the kernel writes.
    unsafe { k.enq().context("launching wavefront_sizes")? };
    let mut v = [0u32; 4];
    out.read(&mut v[..])
        .enq()
        .context("reading the wavefront record sizes")?;
    Ok(v.map(|s| s as usize))
}
