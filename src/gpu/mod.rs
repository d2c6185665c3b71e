//! A thin layer over the `ocl` crate: device discovery and selection, one profiling queue,
//! programs built from the embedded sources with `-D` options and cached per option set, and
//! buffer helpers. Everything OpenCL-specific that is not a kernel lives here, so a later move
//! to another binding touches this module only.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::{Context as _, Result, anyhow, bail};
use ocl::core::QUEUE_PROFILING_ENABLE;
use ocl::enums::{DeviceInfo, DeviceInfoResult, ProgramInfo, ProgramInfoResult};
use ocl::flags::{DeviceFpConfig, DeviceType, MemFlags};
use ocl::{Buffer, Context, Device, OclPrm, Platform, Program, Queue};

use crate::kernels;
pub use crate::memory::human_bytes;
pub use launch::{
    BAND_WORK_GROUP, enqueue, enqueue_rows, event_duration, read_rgb, read_rgb_rows, round_up,
};

mod launch;
pub mod profile;

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
    /// The device offers correctly rounded single-precision division and square root
    /// (CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT), so every program is built with
    /// `-cl-fp32-correctly-rounded-divide-sqrt` ([`Gpu::program`]).
    pub correctly_rounded_divide_sqrt: bool,
}

fn platforms() -> Result<Vec<Platform>> {
    let ids = ocl::core::get_platform_ids().map_err(|_| anyhow!(NO_PLATFORM_HELP))?;
    if ids.is_empty() {
        bail!(NO_PLATFORM_HELP);
    }
    Ok(Platform::list_from_core(ids))
}

/// Serialises OpenCL set-up in the process: the ICD loader's first platform query is not
/// thread-safe (two threads opening devices at once saw "no platform" or crashed).
static SETUP_LOCK: Mutex<()> = Mutex::new(());

/// Every (platform, device) pair, flattened in the order `--device N` counts them.
fn all_devices() -> Result<Vec<(Platform, Device)>> {
    let _serial = SETUP_LOCK.lock().unwrap_or_else(|e| e.into_inner());
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
        correctly_rounded_divide_sqrt: matches!(
            d.info(DeviceInfo::SingleFpConfig),
            Ok(DeviceInfoResult::SingleFpConfig(c))
                if c.contains(DeviceFpConfig::CORRECTLY_ROUNDED_DIVIDE_SQRT)
        ),
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

/// A selected device with its context, one in-order profiling queue and a program cache:
/// in memory for the run, and on disk (program binaries) across runs.
pub struct Gpu {
    pub summary: DeviceSummary,
    pub device: Device,
    pub context: Context,
    pub queue: Queue,
    /// Where program binaries are kept; None disables the disk cache.
    pub cache_dir: Option<PathBuf>,
    programs: Mutex<HashMap<String, Program>>,
    build_log: Mutex<Vec<BuildRecord>>,
}

static BUILD_LOCK: Mutex<()> = Mutex::new(());

/// Where a program came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildSource {
    /// Already built in this run.
    Memory,
    /// A program binary from the disk cache.
    Disk,
    /// Compiled from source (and stored in the disk cache).
    Compiled,
}

/// One program build (or cache hit), for "compiling kernels" reports.
#[derive(Clone, Debug)]
pub struct BuildRecord {
    pub main: String,
    pub options: String,
    pub seconds: f64,
    pub source: BuildSource,
}

/// The kernel cache folder: NOISEFREE_CACHE_DIR, else $XDG_CACHE_HOME/noisefree/kernels,
/// else ~/.cache/noisefree/kernels. `noisefree cache --clear` empties it.
pub fn default_cache_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("NOISEFREE_CACHE_DIR") {
        return (!d.is_empty()).then(|| PathBuf::from(d));
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("noisefree").join("kernels"))
}

/// FNV-1a, 64 bit: a stable hash (std's hasher may change between Rust releases).
pub fn fnv1a(parts: &[&[u8]]) -> u64 {
    let mut h = Fnv1a::new();
    for part in parts {
        h.update(part);
        h.end_part();
    }
    h.finish()
}

/// [`fnv1a`] fed part by part (data that is streamed, e.g. a file's payload).
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a::new()
    }
}

impl Fnv1a {
    pub fn new() -> Fnv1a {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }

    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    /// Separates the parts, so ("ab", "c") and ("a", "bc") differ.
    pub fn end_part(&mut self) {
        self.update(&[0xff]);
    }

    pub fn finish(&self) -> u64 {
        self.0
    }
}

impl Gpu {
    /// Opens device `index` (or the default choice, see [`choose_index`]) with the default
    /// kernel cache folder.
    pub fn open(index: Option<usize>) -> Result<Arc<Gpu>> {
        Gpu::open_with_cache(index, default_cache_dir())
    }

    /// Opens every device of `indices` (`--devices 0,1`), each with its own context and queue;
    /// empty: the one device [`Gpu::open`] chooses.
    pub fn open_all(indices: &[usize]) -> Result<Vec<Arc<Gpu>>> {
        if indices.is_empty() {
            return Ok(vec![Gpu::open(None)?]);
        }
        for (k, i) in indices.iter().enumerate() {
            if indices[..k].contains(i) {
                bail!("device {i} is listed twice in --devices (see `noisefree devices`)");
            }
        }
        indices.iter().map(|&i| Gpu::open(Some(i))).collect()
    }

    /// Opens a device with the given kernel cache folder (None: no disk cache).
    pub fn open_with_cache(index: Option<usize>, cache_dir: Option<PathBuf>) -> Result<Arc<Gpu>> {
        let devices = all_devices()?;
        let summaries: Vec<_> = devices
            .iter()
            .enumerate()
            .map(|(i, (p, d))| summarize(i, p, d))
            .collect();
        let index = choose_index(index, &summaries)?;
        let (platform, device) = devices[index];
        let _serial = SETUP_LOCK.lock().unwrap_or_else(|e| e.into_inner());
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
            cache_dir,
            programs: Mutex::new(HashMap::new()),
            build_log: Mutex::new(Vec::new()),
        }))
    }

    /// A builder of kernel `name` of `program` on this device's queue over a w × h grid
    /// (`size`); the caller adds the arguments in the kernel's order.
    pub fn kernel<'a>(
        &self,
        program: &'a Program,
        name: &str,
        size: [usize; 2],
    ) -> ocl::builders::KernelBuilder<'a> {
        let mut b = ocl::Kernel::builder();
        b.program(program)
            .name(name)
            .queue(self.queue.clone())
            .global_work_size(size);
        b
    }

    /// Builds `main` (a file under kernels/) with `defines` as `-D NAME=VALUE` options, or
    /// returns the program already built with the same source and options: from memory in this
    /// run, or from a program binary in the disk cache, keyed by a hash of (source, options,
    /// device, driver). A failed build reports the compiler's log.
    pub fn program(
        &self,
        main: &str,
        defines: &[(String, String)],
        prelude: &str,
    ) -> Result<Program> {
        self.program_with_options(main, defines, prelude, "")
    }

    /// [`Gpu::program`] with more compiler options (e.g. `-cl-kernel-arg-info` for tests).
    pub fn program_with_options(
        &self,
        main: &str,
        defines: &[(String, String)],
        prelude: &str,
        extra: &str,
    ) -> Result<Program> {
        let source = kernels::assemble(main, prelude)?;
        let mut options = String::from("-cl-std=CL1.2");
        // OpenCL lets single-precision `/` and `sqrt` be 2.5 and 3 ulp off unless this is
        // given, and a compiler may then round one division differently in two inlining
        // contexts (a reciprocal reused, a `div.full` elsewhere): the megakernel, the
        // wavefront steps and the two BVH walks compile the same functions in different
        // contexts and must give the same bytes. Correctly rounded, `/` and `sqrt` give one
        // float for the same operands on every device that offers it, as a CPU's do anyway
        // (PoCL's images are the same bytes with and without it).
        if self.summary.correctly_rounded_divide_sqrt {
            options.push_str(" -cl-fp32-correctly-rounded-divide-sqrt");
        }
        if !extra.is_empty() {
            options.push(' ');
            options.push_str(extra);
        }
        for (k, v) in defines {
            options.push_str(&format!(" -D {k}={v}"));
        }
        let key = format!("{main}\u{0}{options}\u{0}{source}");
        let record = |source: BuildSource, seconds: f64| {
            self.build_log.lock().unwrap().push(BuildRecord {
                main: main.into(),
                options: options.clone(),
                seconds,
                source,
            });
        };
        if let Some(p) = self.programs.lock().unwrap().get(&key) {
            record(BuildSource::Memory, 0.0);
            return Ok(p.clone());
        }
        // One build at a time in the process: PoCL's compiler is not safe to run from two
        // threads on two contexts at once (seen as crashes in the test suite).
        let _serial = BUILD_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let start = Instant::now();
        let s = &self.summary;
        let hash = fnv1a(&[
            source.as_bytes(),
            options.as_bytes(),
            s.platform.as_bytes(),
            s.name.as_bytes(),
            s.version.as_bytes(),
            s.driver.as_bytes(),
            env!("CARGO_PKG_VERSION").as_bytes(),
        ]);
        let cache_file = self
            .cache_dir
            .as_ref()
            .map(|d| d.join(format!("{}-{hash:016x}.bin", main.replace('/', "-"))));
        if let Some(file) = &cache_file
            && let Ok(binary) = std::fs::read(file)
        {
            let bins: [&[u8]; 1] = [&binary];
            // A stale or foreign binary simply fails to build; then we compile from source.
            if let Ok(program) = Program::builder()
                .binaries(&bins)
                .devices(self.device)
                .cmplr_opt(options.clone())
                .build(&self.context)
            {
                record(BuildSource::Disk, start.elapsed().as_secs_f64());
                self.programs.lock().unwrap().insert(key, program.clone());
                return Ok(program);
            }
        }
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
        record(BuildSource::Compiled, start.elapsed().as_secs_f64());
        if let Some(file) = &cache_file {
            // The cache is an optimisation: a folder we cannot write only costs a rebuild.
            let _ = store_binary(&program, file);
        }
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

/// Writes a program's binary to `file` (through a temporary file and a rename).
fn store_binary(program: &Program, file: &std::path::Path) -> Result<()> {
    let Ok(ProgramInfoResult::Binaries(bins)) = program.info(ProgramInfo::Binaries) else {
        bail!("the driver returned no program binary");
    };
    let Some(bin) = bins.into_iter().next().filter(|b| !b.is_empty()) else {
        bail!("the driver returned an empty program binary");
    };
    if let Some(dir) = file.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let tmp = file.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, &bin)?;
    std::fs::rename(&tmp, file)?;
    Ok(())
}
