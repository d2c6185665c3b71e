//! The kernels of kernels/render/subtractive.cl on the device, timed by their profiling
//! events (kernel time only: uploads and the host's shadow rays are outside it).

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result};
use ocl::{Buffer, Kernel, Program};

use super::{DirLight, GBuffer};
use crate::gpu::{Gpu, enqueue, event_duration};
use crate::layout::Float4;

/// A result read back and the kernel time that made it.
pub struct Timed {
    pub image: Vec<[f32; 4]>,
    pub time: Duration,
}

/// The G-buffer on the device.
pub struct DeviceGBuffer {
    width: u32,
    height: u32,
    position: Buffer<Float4>,
    normal: Buffer<Float4>,
    albedo: Buffer<Float4>,
}

/// The two builds of the kernel file: SUB_VISIBLE = 0 (shadow buffer S) and 1 (additive).
pub struct SubtractiveKernels {
    gpu: Arc<Gpu>,
    blocked: Program,
    visible: Program,
}

fn f4(v: &[[f32; 4]]) -> Vec<Float4> {
    v.iter().map(|a| Float4(*a)).collect()
}

fn lights_buffers(gpu: &Gpu, lights: &[DirLight]) -> Result<(Buffer<Float4>, Buffer<Float4>)> {
    let dirs: Vec<Float4> = lights
        .iter()
        .map(|l| Float4([l.dir.x, l.dir.y, l.dir.z, 0.0]))
        .collect();
    let irr: Vec<Float4> = lights
        .iter()
        .map(|l| Float4([l.irradiance.x, l.irradiance.y, l.irradiance.z, 0.0]))
        .collect();
    Ok((gpu.upload(&dirs)?, gpu.upload(&irr)?))
}

fn read(buffer: &Buffer<Float4>, len: usize) -> Result<Vec<[f32; 4]>> {
    let mut out = vec![Float4::default(); buffer.len()];
    buffer
        .read(&mut out)
        .enq()
        .context("reading a subtractive-shadow image")?;
    Ok(out.into_iter().take(len).map(|f| f.0).collect())
}

impl SubtractiveKernels {
    pub fn new(gpu: Arc<Gpu>) -> Result<SubtractiveKernels> {
        let build = |visible: &str| {
            let defines = [
                ("SUB_VISIBLE", visible.to_string()),
                ("MAP_W", super::MAP_W.to_string()),
                ("MAP_H", super::MAP_H.to_string()),
            ];
            let defines: Vec<(String, String)> = defines
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect();
            gpu.program("render/subtractive.cl", &defines, "")
        };
        Ok(SubtractiveKernels {
            blocked: build("0")?,
            visible: build("1")?,
            gpu,
        })
    }

    pub fn upload(&self, g: &GBuffer) -> Result<DeviceGBuffer> {
        Ok(DeviceGBuffer {
            width: g.width,
            height: g.height,
            position: self.gpu.upload(&f4(&g.position))?,
            normal: self.gpu.upload(&f4(&g.normal))?,
            albedo: self.gpu.upload(&f4(&g.albedo))?,
        })
    }

    fn run(&self, k: &Kernel, what: &str) -> Result<Duration> {
        // SAFETY: every buffer argument is created by the caller for this launch's range
        // and outlives it (we wait on the event).
        event_duration(&unsafe { enqueue(k, what)? })
    }

    /// Step 3: C from `lights`, unshadowed.
    pub fn unshadowed(&self, g: &DeviceGBuffer, lights: &[DirLight]) -> Result<Timed> {
        let n = (g.width * g.height) as usize;
        let (dirs, irr) = lights_buffers(&self.gpu, lights)?;
        let out = self.gpu.zeroed::<Float4>(n, "unshadowed light")?;
        let k = Kernel::builder()
            .program(&self.blocked)
            .name("sub_unshadowed")
            .queue(self.gpu.queue.clone())
            .global_work_size(n)
            .arg(&g.position)
            .arg(&g.normal)
            .arg(&g.albedo)
            .arg(&dirs)
            .arg(&irr)
            .arg(lights.len() as u32)
            .arg(n as u32)
            .arg(&out)
            .build()
            .context("creating sub_unshadowed")?;
        let time = self.run(&k, "sub_unshadowed")?;
        Ok(Timed {
            image: read(&out, n)?,
            time,
        })
    }

    /// Step 3 from the prefiltered irradiance map ([`super::irradiance_map`]).
    pub fn prefiltered(&self, g: &DeviceGBuffer, map: &[[f32; 4]]) -> Result<Timed> {
        let n = (g.width * g.height) as usize;
        let m = self.gpu.upload(&f4(map))?;
        let out = self.gpu.zeroed::<Float4>(n, "unshadowed light")?;
        let k = Kernel::builder()
            .program(&self.blocked)
            .name("sub_prefiltered")
            .queue(self.gpu.queue.clone())
            .global_work_size(n)
            .arg(&g.position)
            .arg(&g.normal)
            .arg(&g.albedo)
            .arg(&m)
            .arg(n as u32)
            .arg(&out)
            .build()
            .context("creating sub_prefiltered")?;
        let time = self.run(&k, "sub_prefiltered")?;
        Ok(Timed {
            image: read(&out, n)?,
            time,
        })
    }

    /// Step 2(c-d): per sample at `pixels`, the blocked lights' light (S) or, with
    /// `visible`, the visible lights' (the additive form).
    pub fn shadow(
        &self,
        g: &DeviceGBuffer,
        pixels: &[u32],
        lights: &[DirLight],
        bits: &[u32],
        visible: bool,
    ) -> Result<Timed> {
        let n = pixels.len();
        let (dirs, irr) = lights_buffers(&self.gpu, lights)?;
        let px = self.gpu.upload(pixels)?;
        let vis = self.gpu.upload(bits)?;
        let out = self.gpu.zeroed::<Float4>(n, "shadow buffer")?;
        let program = if visible {
            &self.visible
        } else {
            &self.blocked
        };
        let k = Kernel::builder()
            .program(program)
            .name("sub_shadow")
            .queue(self.gpu.queue.clone())
            .global_work_size(n)
            .arg(&g.position)
            .arg(&g.normal)
            .arg(&g.albedo)
            .arg(&px)
            .arg(&dirs)
            .arg(&irr)
            .arg(lights.len() as u32)
            .arg(&vis)
            .arg(n as u32)
            .arg(&out)
            .build()
            .context("creating sub_shadow")?;
        let time = self.run(&k, "sub_shadow")?;
        Ok(Timed {
            image: read(&out, n)?,
            time,
        })
    }

    /// Steps 4-5: max(C − S′, 0) with S′ the joint-bilateral upsampling of `s_low`.
    #[allow(clippy::too_many_arguments)]
    pub fn compose(
        &self,
        g: &DeviceGBuffer,
        c: &[[f32; 4]],
        s_low: &[[f32; 4]],
        pixels: &[u32],
        lw: u32,
        lh: u32,
        block: u32,
        sigma: f32,
    ) -> Result<Timed> {
        let n = (g.width * g.height) as usize;
        let col = self.gpu.upload(&f4(c))?;
        let low = self.gpu.upload(&f4(s_low))?;
        let px = self.gpu.upload(pixels)?;
        let out = self.gpu.zeroed::<Float4>(n, "subtractive image")?;
        let k = Kernel::builder()
            .program(&self.blocked)
            .name("sub_compose")
            .queue(self.gpu.queue.clone())
            .global_work_size([g.width as usize, g.height as usize])
            .arg(&g.position)
            .arg(&g.normal)
            .arg(&col)
            .arg(&low)
            .arg(&px)
            .arg(g.width)
            .arg(g.height)
            .arg(lw)
            .arg(lh)
            .arg(block)
            .arg(sigma)
            .arg(&out)
            .build()
            .context("creating sub_compose")?;
        let time = self.run(&k, "sub_compose")?;
        Ok(Timed {
            image: read(&out, n)?,
            time,
        })
    }
}
