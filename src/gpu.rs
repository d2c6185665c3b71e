//! A thin layer over the `ocl` crate: device discovery and selection, one profiling queue,
//! programs built from the embedded sources with `-D` options and cached per option set, and
//! buffer helpers. Everything OpenCL-specific that is not a kernel lives here, so a later move
//! to another binding touches this module only.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, anyhow, bail};
use ocl::core::QUEUE_PROFILING_ENABLE;
use ocl::enums::{DeviceInfo, DeviceInfoResult, ProfilingInfo};
use ocl::flags::{DeviceType, MemFlags};
use ocl::{Buffer, Context, Device, Event, OclPrm, Platform, Program, Queue};

use crate::kernels;

/// What the user is told when no OpenCL platform is installed.
pub const NO_PLATFORM_HELP: &str = "no OpenCL platform found. noisefree needs an OpenCL driver; \
on Debian/Ubuntu install the portable CPU driver with\n    \
sudo apt-get install pocl-opencl-icd ocl-icd-opencl-dev\n\
or install your GPU vendor's OpenCL driver (it must register an .icd file in /etc/OpenCL/vendors).";

/// One OpenCL device as listed by `noisefree devices`.
#[derive(Clone, Debug)]
pub struct DeviceSummary {
    pub index: usize,
    pub platform: String,
    pub name: String,
    pub kind: String,
    pub version: String,
    pub driver: String,
    pub compute_units: u32,
    pub local_mem_bytes: u64,
    pub global_mem_bytes: u64,
    pub max_alloc_bytes: u64,
    pub max_work_group_size: usize,
    pub max_clock_mhz: u32,
}

fn platforms() -> Result<Vec<Platform>> {
    let ids = ocl::core::get_platform_ids().map_err(|_| anyhow!(NO_PLATFORM_HELP))?;
    if ids.is_empty() {
        bail!(NO_PLATFORM_HELP);
    }
    Ok(Platform::list_from_core(ids))
}

/// Every (platform, device) pair, flattened in the order `--device N` counts them.
fn all_devices() -> Result<Vec<(Platform, Device)>> {
    let mut out = Vec::new();
    for p in platforms()? {
        for d in Device::list_all(p)? {
            out.push((p, d));
        }
    }
    if out.is_empty() {
        bail!(NO_PLATFORM_HELP);
    }
    Ok(out)
}

fn info_u64(d: &Device, kind: DeviceInfo) -> u64 {
    match d.info(kind) {
        Ok(DeviceInfoResult::MaxComputeUnits(v)) => v as u64,
        Ok(DeviceInfoResult::LocalMemSize(v)) => v,
        Ok(DeviceInfoResult::GlobalMemSize(v)) => v,
        Ok(DeviceInfoResult::MaxMemAllocSize(v)) => v,
        Ok(DeviceInfoResult::MaxWorkGroupSize(v)) => v as u64,
        Ok(DeviceInfoResult::MaxClockFrequency(v)) => v as u64,
        _ => 0,
    }
}

fn info_string(d: &Device, kind: DeviceInfo) -> String {
    d.info(kind)
        .map(|r| r.to_string())
        .unwrap_or_default()
        .trim()
        .to_string()
}

fn summarize(index: usize, p: &Platform, d: &Device) -> DeviceSummary {
    let kind = match d.info(DeviceInfo::Type) {
        Ok(DeviceInfoResult::Type(t)) if t.contains(DeviceType::GPU) => "GPU",
        Ok(DeviceInfoResult::Type(t)) if t.contains(DeviceType::CPU) => "CPU",
        Ok(DeviceInfoResult::Type(t)) if t.contains(DeviceType::ACCELERATOR) => "accelerator",
        _ => "other",
    };
    DeviceSummary {
        index,
        platform: p.name().unwrap_or_default(),
        name: d.name().unwrap_or_default().trim().to_string(),
        kind: kind.to_string(),
        version: info_string(d, DeviceInfo::Version),
        driver: info_string(d, DeviceInfo::DriverVersion),
        compute_units: info_u64(d, DeviceInfo::MaxComputeUnits) as u32,
        local_mem_bytes: info_u64(d, DeviceInfo::LocalMemSize),
        global_mem_bytes: info_u64(d, DeviceInfo::GlobalMemSize),
        max_alloc_bytes: info_u64(d, DeviceInfo::MaxMemAllocSize),
        max_work_group_size: info_u64(d, DeviceInfo::MaxWorkGroupSize) as usize,
        max_clock_mhz: info_u64(d, DeviceInfo::MaxClockFrequency) as u32,
    }
}

/// All OpenCL devices on this machine.
pub fn list_devices() -> Result<Vec<DeviceSummary>> {
    Ok(all_devices()?
        .iter()
        .enumerate()
        .map(|(i, (p, d))| summarize(i, p, d))
        .collect())
}

/// The device index to use: the explicit choice, else `NOISEFREE_DEVICE`, else the first GPU,
/// else device 0.
fn choose_index(explicit: Option<usize>, devices: &[DeviceSummary]) -> Result<usize> {
    let from_env = match std::env::var("NOISEFREE_DEVICE") {
        Ok(v) if !v.trim().is_empty() => Some(v.trim().parse::<usize>().map_err(|_| {
            anyhow!("NOISEFREE_DEVICE={v:?} is not a device number (see `noisefree devices`)")
        })?),
        _ => None,
    };
    let index = explicit
        .or(from_env)
        .unwrap_or_else(|| devices.iter().position(|d| d.kind == "GPU").unwrap_or(0));
    if index >= devices.len() {
        bail!(
            "device {index} does not exist: this machine has {} OpenCL device(s), numbered from 0 \
             (see `noisefree devices`)",
            devices.len()
        );
    }
    Ok(index)
}

/// A selected device with its context, one in-order profiling queue and a program cache.
pub struct Gpu {
    pub summary: DeviceSummary,
    pub device: Device,
    pub context: Context,
    pub queue: Queue,
    programs: Mutex<HashMap<String, Program>>,
    build_log: Mutex<Vec<BuildRecord>>,
}

/// One program build (or cache hit), for "compiling kernels" reports.
#[derive(Clone, Debug)]
pub struct BuildRecord {
    pub main: String,
    pub options: String,
    pub seconds: f64,
    pub cached: bool,
}

impl Gpu {
    /// Opens device `index` (or the default choice, see [`choose_index`]).
    pub fn open(index: Option<usize>) -> Result<Arc<Gpu>> {
        let devices = all_devices()?;
        let summaries: Vec<_> = devices
            .iter()
            .enumerate()
            .map(|(i, (p, d))| summarize(i, p, d))
            .collect();
        let index = choose_index(index, &summaries)?;
        let (platform, device) = devices[index];
        let context = Context::builder()
            .platform(platform)
            .devices(device)
            .build()
            .with_context(|| format!("creating an OpenCL context on {}", summaries[index].name))?;
        let queue = Queue::new(&context, device, Some(QUEUE_PROFILING_ENABLE))
            .context("creating an OpenCL command queue")?;
        Ok(Arc::new(Gpu {
            summary: summaries[index].clone(),
            device,
            context,
            queue,
            programs: Mutex::new(HashMap::new()),
            build_log: Mutex::new(Vec::new()),
        }))
    }

    /// Builds `main` (a file under kernels/) with `defines` as `-D NAME=VALUE` options, or
    /// returns the program already built with the same source and options. A failed build
    /// reports the compiler's log.
    pub fn program(
        &self,
        main: &str,
        defines: &[(String, String)],
        prelude: &str,
    ) -> Result<Program> {
        let source = kernels::assemble(main, prelude)?;
        let mut options = String::from("-cl-std=CL1.2");
        for (k, v) in defines {
            options.push_str(&format!(" -D {k}={v}"));
        }
        let key = format!("{main}\u{0}{options}\u{0}{source}");
        if let Some(p) = self.programs.lock().unwrap().get(&key) {
            self.build_log.lock().unwrap().push(BuildRecord {
                main: main.into(),
                options: options.clone(),
                seconds: 0.0,
                cached: true,
            });
            return Ok(p.clone());
        }
        let start = Instant::now();
        let program = Program::builder()
            .source(source)
            .devices(self.device)
            .cmplr_opt(options.clone())
            .build(&self.context)
            .map_err(|e| {
                anyhow!(
                    "building the OpenCL program kernels/{main} for {} failed.\n\
                     build options: {options}\n{e}",
                    self.summary.name
                )
            })?;
        let seconds = start.elapsed().as_secs_f64();
        self.build_log.lock().unwrap().push(BuildRecord {
            main: main.into(),
            options,
            seconds,
            cached: false,
        });
        self.programs.lock().unwrap().insert(key, program.clone());
        Ok(program)
    }

    /// Builds so far (and cache hits), oldest first.
    pub fn builds(&self) -> Vec<BuildRecord> {
        self.build_log.lock().unwrap().clone()
    }

    /// A read-only device buffer holding `data`. Empty slices get one default element, since
    /// OpenCL has no zero-sized buffers; kernels are told the real counts separately.
    pub fn upload<T: OclPrm>(&self, data: &[T]) -> Result<Buffer<T>> {
        let dummy = [T::default()];
        let data = if data.is_empty() { &dummy[..] } else { data };
        self.check_alloc(std::mem::size_of_val(data) as u64, "scene buffer")?;
        Buffer::builder()
            .queue(self.queue.clone())
            .flags(MemFlags::new().read_only())
            .len(data.len())
            .copy_host_slice(data)
            .build()
            .context("uploading a scene buffer to the device")
    }

    /// A read-write device buffer of `len` elements filled with `T::default()`.
    pub fn zeroed<T: OclPrm>(&self, len: usize, what: &str) -> Result<Buffer<T>> {
        let len = len.max(1);
        let size = std::mem::size_of::<T>();
        self.check_alloc((len * size) as u64, what)?;
        let context = || format!("allocating the {what} buffer on the device");
        // clEnqueueFillBuffer takes patterns of 1, 2, 4, ..., 128 bytes only.
        if size.is_power_of_two() && size <= 128 {
            return Buffer::builder()
                .queue(self.queue.clone())
                .flags(MemFlags::new().read_write())
                .len(len)
                .fill_val(T::default())
                .build()
                .with_context(context);
        }
        let buffer = Buffer::<T>::builder()
            .queue(self.queue.clone())
            .flags(MemFlags::new().read_write())
            .len(len)
            .build()
            .with_context(context)?;
        let chunk = (1 << 20) / size.max(1) + 1;
        let zeros = vec![T::default(); chunk.min(len)];
        let mut offset = 0;
        while offset < len {
            let n = zeros.len().min(len - offset);
            buffer
                .write(&zeros[..n])
                .offset(offset)
                .enq()
                .with_context(context)?;
            offset += n;
        }
        Ok(buffer)
    }

    /// Refuses allocations the device cannot hold, before OpenCL is asked.
    pub fn check_alloc(&self, bytes: u64, what: &str) -> Result<()> {
        let s = &self.summary;
        if s.max_alloc_bytes > 0 && bytes > s.max_alloc_bytes {
            bail!(
                "the {what} buffer needs {} but {} allows at most {} in one buffer; \
                 lower the resolution (--width/--height)",
                human_bytes(bytes),
                s.name,
                human_bytes(s.max_alloc_bytes)
            );
        }
        Ok(())
    }

    /// Checks that buffers totalling `bytes` fit in device memory.
    pub fn check_total(&self, bytes: u64, what: &str) -> Result<()> {
        let s = &self.summary;
        if s.global_mem_bytes > 0 && bytes > s.global_mem_bytes {
            bail!(
                "{what} need {} of device memory but {} has {}; lower the resolution \
                 (--width/--height)",
                human_bytes(bytes),
                s.name,
                human_bytes(s.global_mem_bytes)
            );
        }
        Ok(())
    }
}

/// Kernel execution time of a finished command, from its profiling event.
pub fn event_duration(event: &Event) -> Result<Duration> {
    event.wait_for()?;
    let start = event.profiling_info(ProfilingInfo::Start)?.time()?;
    let end = event.profiling_info(ProfilingInfo::End)?.time()?;
    Ok(Duration::from_nanos(end.saturating_sub(start)))
}

pub fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Rounds `n` up to a multiple of `m`.
pub fn round_up(n: usize, m: usize) -> usize {
    n.div_ceil(m) * m
}
