//! The path-density filter on the device: `pd_lab`, `pd_density` and `pd_reconstruct` of
//! kernels/filters/path_density.cl over the frame's sample vectors.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel, Program};

use super::{ColorSpace, PathDensityParams};
use super::reference::Densities;
use crate::gpu::{Gpu, enqueue, event_duration, read_rgb};
use crate::imaging::RgbImage;
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{Float2, Float4};
use crate::render::Frame;

/// The three kernels, built for one k, and their per-sample buffers.
pub struct PathDensityKernel {
    gpu: Arc<Gpu>,
    program: Program,
    params: PathDensityParams,
    /// Allocated on the first run for every sample the frame can store, and kept: a
    /// progressive render (the viewer) filters every frame, and its stored samples only grow
    /// up to the capacity.
    scratch: Option<Scratch>,
    /// Samples of the last run (its σ and weights are the first `last` of the scratch's).
    last: Option<usize>,
}

/// The per-sample intermediates (Lab colour, film position, σ, weight) and the image.
struct Scratch {
    samples: usize,
    pixels: usize,
    lab: Buffer<Float4>,
    xy: Buffer<Float2>,
    sigma: Buffer<f32>,
    weight: Buffer<f32>,
    out: Buffer<Float4>,
}

impl Scratch {
    fn new(gpu: &Gpu, samples: usize, pixels: usize) -> Result<Scratch> {
        Ok(Scratch {
            samples,
            pixels,
            lab: gpu.zeroed::<Float4>(samples, "path-density Lab")?,
            xy: gpu.zeroed::<Float2>(samples, "path-density positions")?,
            sigma: gpu.zeroed::<f32>(samples, "path-density sigma")?,
            weight: gpu.zeroed::<f32>(samples, "path-density weights")?,
            out: gpu.zeroed::<Float4>(pixels, "path-density image")?,
        })
    }
}

/// What one run produced.
pub struct DeviceRun {
    pub image: RgbImage,
    pub kernel_time: Duration,
    pub wall_time: Duration,
}

impl PathDensityKernel {
    pub fn new(gpu: Arc<Gpu>, params: PathDensityParams) -> Result<PathDensityKernel> {
        params.validate()?;
        let mut defines = vec![("PD_K".to_string(), params.k.to_string())];
        if params.color_space == ColorSpace::Rgb {
            defines.push(("PD_RGB".to_string(), "1".to_string()));
        }
        let program = gpu.program("filters/path_density.cl", &defines, "")?;
        Ok(PathDensityKernel {
            gpu,
            program,
            params,
            scratch: None,
            last: None,
        })
    }

    fn kernel(&self, name: &str, global: usize) -> ocl::builders::KernelBuilder<'_> {
        let mut b = Kernel::builder();
        b.program(&self.program)
            .name(name)
            .queue(self.gpu.queue.clone())
            .global_work_size(global.max(1));
        b
    }

    /// Filters the samples stored in `frame` (which must hold the samples output).
    pub fn run(&mut self, frame: &Frame) -> Result<DeviceRun> {
        let start = Instant::now();
        frame.require(OutputSet::of(&[Output::Samples]), "the path-density filter")?;
        let info = frame.info();
        let (w, h, spp, capacity) = (
            info.width,
            info.height,
            info.samples_stored(),
            info.sample_capacity,
        );
        if spp == 0 {
            bail!("the path-density filter needs at least one stored sample per pixel");
        }
        let pixels = w as usize * h as usize;
        let count = pixels * spp as usize;
        if count > u32::MAX as usize {
            bail!("{count} samples are more than the path-density kernels index (2^32)");
        }
        let frame_spp = self.params.frame_spp_for(spp);
        let sv = frame.device(&self.gpu, BufferId::SampleVectors)?;
        if self
            .scratch
            .as_ref()
            .is_none_or(|b| b.samples < count || b.pixels != pixels)
        {
            self.scratch = None;
            let room = count.max(pixels * capacity as usize);
            self.scratch = Some(Scratch::new(&self.gpu, room, pixels)?);
        }
        let b = self.scratch.as_ref().expect("allocated above");
        let (lab, xy, sigma, weight, out) = (&b.lab, &b.xy, &b.sigma, &b.weight, &b.out);
        let p = &self.params;
        let k_lab = self
            .kernel("pd_lab", count)
            .arg(sv)
            .arg(count as u32)
            .arg(spp)
            .arg(capacity)
            .arg(lab)
            .arg(xy)
            .build()
            .context("creating pd_lab")?;
        let k_density = self
            .kernel("pd_density", count)
            .arg(lab)
            .arg(xy)
            .arg(w)
            .arg(h)
            .arg(spp)
            .arg(frame_spp)
            .arg(p.inv_w())
            .arg(p.inv_c())
            .arg(p.shrink())
            .arg(p.keep)
            .arg(p.reject)
            .arg(sigma)
            .arg(weight)
            .build()
            .context("creating pd_density")?;
        let k_rec = self
            .kernel("pd_reconstruct", pixels)
            .arg(sv)
            .arg(lab)
            .arg(weight)
            .arg(w)
            .arg(h)
            .arg(spp)
            .arg(capacity)
            .arg(frame_spp)
            .arg(out)
            .build()
            .context("creating pd_reconstruct")?;
        let mut kernel_time = Duration::ZERO;
        for (k, what) in [
            (&k_lab, "pd_lab"),
            (&k_density, "pd_density"),
            (&k_rec, "pd_reconstruct"),
        ] {
            // SAFETY: every buffer is alive until the event is waited for just below, and is
            // sized for the kernel's range (count samples, pixels pixels; the kernels return
            // beyond them).
            let e = unsafe { enqueue(k, what)? };
            kernel_time += event_duration(&e)?;
        }
        let image = read_rgb(out, w, h)?;
        self.last = Some(count);
        Ok(DeviceRun {
            image,
            kernel_time,
            wall_time: start.elapsed(),
        })
    }

    /// The last run's σ and weights per stored sample (pixel-major), read back.
    pub fn densities(&self) -> Result<Densities> {
        let (Some(count), Some(b)) = (self.last, &self.scratch) else {
            bail!("the path-density filter has not run yet");
        };
        let mut sigma = vec![0.0f32; count];
        let mut weight = vec![0.0f32; count];
        b.sigma.read(&mut sigma).enq().context("reading sigma back")?;
        b.weight.read(&mut weight).enq().context("reading weights back")?;
        Ok(Densities { sigma, weight })
    }
}
