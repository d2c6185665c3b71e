//! The renderer: uploads the scene arrays, builds the megakernel specialised to the scene, and
//! adds samples progressively to the per-pixel FilterVector buffer (thesis §4.2.3, §4.3).

pub mod cpu;
pub mod features;

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result};
use ocl::{Buffer, Event, Kernel};

pub use crate::arrays::{FrameSettings, SceneArrays};
use crate::gpu::{Gpu, event_duration, round_up};
use crate::layout::{
    BvhNode, FilterVector, Float4, GBuffer, Light, Material, SampleVector, SceneParams, Sphere,
    StatsState, TextureInfo, TriangleGeom, TriangleShading,
};
use crate::scene::Scene;
use crate::stats::PixelBuffers;
pub use features::{FeatureSet, Outputs};

/// How to render, besides the scene itself.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub frame: FrameSettings,
    pub outputs: Outputs,
    /// Build the generic kernel with every effect compiled in (for comparison).
    pub all_features: bool,
    /// Work-group size; None lets the driver choose. The image does not depend on it.
    pub local_size: Option<[usize; 2]>,
    /// Compile in the debug counters of kernels/arrays/trace.cl (tests only).
    pub debug_counters: bool,
}

impl RenderOptions {
    pub fn for_scene(scene: &Scene) -> Self {
        RenderOptions {
            frame: FrameSettings::from_scene(scene),
            outputs: Outputs::default(),
            all_features: false,
            local_size: None,
            debug_counters: false,
        }
    }
}

/// The scene's buffers on the device.
struct DeviceScene {
    params: Buffer<SceneParams>,
    nodes: Buffer<BvhNode>,
    tri_geom: Buffer<TriangleGeom>,
    tri_shading: Buffer<TriangleShading>,
    spheres: Buffer<Sphere>,
    materials: Buffer<Material>,
    textures: Buffer<TextureInfo>,
    texels: Buffer<Float4>,
    lights: Buffer<Light>,
    light_cdf: Buffer<f32>,
}

impl DeviceScene {
    fn upload(gpu: &Gpu, a: &SceneArrays) -> Result<DeviceScene> {
        Ok(DeviceScene {
            params: gpu.upload(std::slice::from_ref(&a.params))?,
            nodes: gpu.upload(&a.nodes)?,
            tri_geom: gpu.upload(&a.tri_geom)?,
            tri_shading: gpu.upload(&a.tri_shading)?,
            spheres: gpu.upload(&a.spheres)?,
            materials: gpu.upload(&a.materials)?,
            textures: gpu.upload(&a.textures)?,
            texels: gpu.upload(&a.texels)?,
            lights: gpu.upload(&a.lights)?,
            light_cdf: gpu.upload(&a.light_cdf)?,
        })
    }
}

/// Kernel time and rays of one launch.
#[derive(Clone, Copy, Debug, Default)]
pub struct LaunchStats {
    pub samples: u32,
    pub kernel_time: Duration,
    pub rays: u64,
}

/// Positions of the per-launch arguments of kernels/render/pathtrace.cl `render`.
const ARG_SAMPLE_BASE: u32 = 17;
const ARG_SAMPLE_COUNT: u32 = 18;

/// What the debug counters of kernels/arrays/trace.cl count (same order as COUNT_*).
pub const DEBUG_COUNTERS: [&str; 12] = [
    "lens samples",
    "diffuse scatters",
    "mirror scatters",
    "glass scatters",
    "metal scatters",
    "environment lookups",
    "environment texture lookups",
    "sphere light samples",
    "triangle light samples",
    "surface texture lookups",
    "sphere list tests",
    "BVH traversals",
];

pub struct Renderer {
    pub gpu: Arc<Gpu>,
    pub arrays: SceneArrays,
    pub features: FeatureSet,
    /// Running means per pixel (eq. 6.1, 6.5).
    pub film: Buffer<FilterVector>,
    /// Running S_n per pixel (eq. 6.2, 6.6); one dummy element unless variances are wanted.
    pub gbuffers: Buffer<GBuffer>,
    /// Mean first-bounce directions and the depth shift (see kernels/render/film.cl).
    pub stats_state: Buffer<StatsState>,
    ray_counts: Buffer<u32>,
    /// Every sample's vector for RPF; one dummy element unless requested.
    pub sample_vectors: Buffer<SampleVector>,
    sample_capacity: u32,
    debug_counters: Buffer<u32>,
    kernel: Kernel,
    _scene: DeviceScene,
    samples_done: u32,
    pub rays_total: u64,
    pub kernel_time_total: Duration,
}

/// Bytes the RPF sample vectors of a w x h image at `spp` take (26 * 4 * spp * w * h).
pub fn sample_vector_bytes(width: u32, height: u32, spp: u32) -> u64 {
    width as u64 * height as u64 * spp as u64 * std::mem::size_of::<SampleVector>() as u64
}

/// Bytes of device memory the per-pixel buffers of a w x h image take.
pub fn film_bytes(width: u32, height: u32, variance: bool) -> u64 {
    let px = width as u64 * height as u64;
    let mut per_pixel = std::mem::size_of::<FilterVector>() as u64 + 4;
    if variance {
        per_pixel += (std::mem::size_of::<GBuffer>() + std::mem::size_of::<StatsState>()) as u64;
    }
    px * per_pixel
}

impl Renderer {
    pub fn new(gpu: Arc<Gpu>, scene: &Scene, options: &RenderOptions) -> Result<Renderer> {
        let frame = &options.frame;
        // Refuse impossible sizes before building anything.
        let pixels = frame.width as usize * frame.height as usize;
        gpu.check_alloc(
            pixels as u64 * std::mem::size_of::<FilterVector>() as u64,
            "FilterVector film",
        )?;
        let variance = options.outputs.variance;
        gpu.check_total(
            film_bytes(frame.width, frame.height, variance),
            "the per-pixel buffers",
        )?;

        let arrays = SceneArrays::build(scene, frame)?;
        let features = if options.all_features {
            FeatureSet::all_features(scene, options.outputs)
        } else {
            FeatureSet::for_scene(scene, options.outputs)
        };
        let mut defines = features.defines();
        defines.push((
            "DEBUG_COUNTERS".into(),
            (options.debug_counters as u32).to_string(),
        ));
        let program = gpu.program("render/pathtrace.cl", &defines, "")?;
        let device_scene = DeviceScene::upload(&gpu, &arrays)?;
        let film = gpu.zeroed::<FilterVector>(pixels, "FilterVector film")?;
        // Only what is asked for is allocated: without variances these are one element each.
        let stats_pixels = if variance { pixels } else { 1 };
        let gbuffers = gpu.zeroed::<GBuffer>(stats_pixels, "variance GBuffer")?;
        let stats_state = gpu.zeroed::<StatsState>(stats_pixels, "statistics state")?;
        let sample_capacity = options.outputs.sample_vectors.unwrap_or(0);
        let sample_len = if sample_capacity > 0 {
            let bytes = sample_vector_bytes(frame.width, frame.height, sample_capacity);
            gpu.check_alloc(
                bytes,
                "RPF sample vectors (26 floats per sample, thesis §5.1.1)",
            )?;
            gpu.check_total(
                bytes + film_bytes(frame.width, frame.height, variance),
                "the RPF sample vectors and per-pixel buffers",
            )?;
            pixels * sample_capacity as usize
        } else {
            1
        };
        let sample_vectors = gpu.zeroed::<SampleVector>(sample_len, "RPF sample vector")?;
        let debug_counters = gpu.zeroed::<u32>(DEBUG_COUNTERS.len(), "debug counter")?;
        let ray_counts = gpu.zeroed::<u32>(pixels, "ray count")?;

        let (w, h) = (frame.width as usize, frame.height as usize);
        let mut builder = Kernel::builder();
        builder
            .program(&program)
            .name("render")
            .queue(gpu.queue.clone());
        match options.local_size {
            Some(l) => {
                builder
                    .global_work_size([round_up(w, l[0]), round_up(h, l[1])])
                    .local_work_size(l);
            }
            None => {
                builder.global_work_size([w, h]);
            }
        }
        let d = &device_scene;
        builder
            .arg(&d.params)
            .arg(&d.nodes)
            .arg(&d.tri_geom)
            .arg(&d.tri_shading)
            .arg(&d.spheres)
            .arg(&d.materials)
            .arg(&d.textures)
            .arg(&d.texels)
            .arg(&d.lights)
            .arg(&d.light_cdf)
            .arg(&film)
            .arg(&gbuffers)
            .arg(&stats_state)
            .arg(&ray_counts)
            .arg(&sample_vectors)
            .arg(sample_capacity)
            .arg(&debug_counters)
            .arg(0u32)
            .arg(0u32);
        let kernel = builder.build().context("creating the render kernel")?;
        Ok(Renderer {
            gpu,
            arrays,
            features,
            film,
            gbuffers,
            stats_state,
            ray_counts,
            sample_vectors,
            sample_capacity,
            debug_counters,
            kernel,
            _scene: device_scene,
            samples_done: 0,
            rays_total: 0,
            kernel_time_total: Duration::ZERO,
        })
    }

    pub fn width(&self) -> u32 {
        self.arrays.params.image_width
    }

    pub fn height(&self) -> u32 {
        self.arrays.params.image_height
    }

    /// Samples per pixel accumulated so far.
    pub fn samples_done(&self) -> u32 {
        self.samples_done
    }

    /// Adds `count` samples per pixel in one launch and waits for it.
    pub fn render_samples(&mut self, count: u32) -> Result<LaunchStats> {
        if count == 0 {
            return Ok(LaunchStats::default());
        }
        self.kernel.set_arg(ARG_SAMPLE_BASE, self.samples_done)?;
        self.kernel.set_arg(ARG_SAMPLE_COUNT, count)?;
        let mut event = Event::empty();
        // SAFETY: every buffer argument is alive (owned by self) and sized for the global range.
        unsafe {
            self.kernel
                .cmd()
                .enew(&mut event)
                .enq()
                .context("launching the render kernel")?;
        }
        let kernel_time = event_duration(&event)?;
        let mut counts = vec![0u32; self.ray_counts.len()];
        self.ray_counts.read(&mut counts).enq()?;
        let rays: u64 = counts.iter().map(|&c| c as u64).sum();
        self.samples_done += count;
        self.rays_total += rays;
        self.kernel_time_total += kernel_time;
        Ok(LaunchStats {
            samples: count,
            kernel_time,
            rays,
        })
    }

    /// Reads the FilterVector means back to the host.
    pub fn read_film(&self) -> Result<Vec<FilterVector>> {
        let mut out = vec![FilterVector::default(); self.film.len()];
        self.film
            .read(&mut out)
            .enq()
            .context("reading the film from the device")?;
        out.truncate(self.width() as usize * self.height() as usize);
        Ok(out)
    }

    /// The statistics every filter reads: F and, if they were gathered, the feature variances
    /// S_n / (n - 1) and mean first-bounce directions.
    pub fn read_buffers(&self) -> Result<PixelBuffers> {
        let filter_vectors = self.read_film()?;
        let (variances, directions) = if self.features.is_on("OUTPUT_VARIANCE") {
            let mut s = vec![GBuffer::default(); self.gbuffers.len()];
            self.gbuffers
                .read(&mut s)
                .enq()
                .context("reading the variance GBuffer")?;
            let mut st = vec![StatsState::default(); self.stats_state.len()];
            self.stats_state
                .read(&mut st)
                .enq()
                .context("reading the statistics state")?;
            (
                Some(crate::stats::variances_from_sums(&s, self.samples_done)),
                Some(st.iter().map(|s| s.direction_mean).collect()),
            )
        } else {
            (None, None)
        };
        Ok(PixelBuffers {
            width: self.width(),
            height: self.height(),
            spp: self.samples_done,
            filter_vectors,
            variances,
            directions,
            scene_size: self.arrays.params.offset_scale,
        })
    }

    /// The device buffers for filters that run on the device after each frame.
    pub fn device_buffers(&self) -> crate::filters::DeviceBuffers<'_> {
        let n = self.samples_done;
        crate::filters::DeviceBuffers {
            width: self.width(),
            height: self.height(),
            filter_vectors: &self.film,
            gbuffers: &self.gbuffers,
            stats_state: &self.stats_state,
            variance_factor: if n > 1 { 1.0 / (n - 1) as f32 } else { 0.0 },
            depth_scale: crate::stats::depth_scale(self.arrays.params.offset_scale),
        }
    }

    /// Every stored sample vector, pixel-major (index = pixel * spp + sample), for the
    /// samples rendered so far (at most the capacity asked for).
    pub fn read_sample_vectors(&self) -> Result<(u32, Vec<SampleVector>)> {
        if self.sample_capacity == 0 {
            anyhow::bail!("sample vectors were not requested for this render");
        }
        let spp = self.samples_done.min(self.sample_capacity);
        let mut all = vec![SampleVector::default(); self.sample_vectors.len()];
        self.sample_vectors
            .read(&mut all)
            .enq()
            .context("reading the RPF sample vectors")?;
        if spp == self.sample_capacity {
            return Ok((spp, all));
        }
        let cap = self.sample_capacity as usize;
        let out = all
            .chunks(cap)
            .flat_map(|px| px[..spp as usize].iter().copied())
            .collect();
        Ok((spp, out))
    }

    /// The debug counters (all zero unless built with `debug_counters`), named by
    /// [`DEBUG_COUNTERS`].
    pub fn read_debug_counters(&self) -> Result<Vec<u32>> {
        let mut c = vec![0u32; DEBUG_COUNTERS.len()];
        self.debug_counters
            .read(&mut c)
            .enq()
            .context("reading the debug counters")?;
        Ok(c)
    }
}
