//! The renderer: uploads the scene arrays, builds the megakernel specialised to the scene and
//! to the outputs asked for, and adds samples progressively to the per-pixel outputs (thesis
//! §4.2.3, §4.3). Which buffers exist, and how they are bound to the kernel, comes from the
//! output table of src/layout/outputs.rs; what the renderer leaves is read through a
//! [`Frame`].

pub mod cpu;
pub mod features;
pub mod frame;
pub mod progressive;
pub mod shadows;

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

pub use crate::arrays::{FrameSettings, SceneArrays};
use crate::gpu::{Gpu, enqueue, event_duration, round_up};
use crate::layout::outputs::{BUFFERS, BufferId, Output, OutputSet};
use crate::layout::{
    BvhNode, Float4, Light, Material, SceneParams, Sphere, TextureInfo, TriangleGeom,
    TriangleShading,
};
use crate::scene::Scene;
pub use features::FeatureSet;
pub use frame::{Frame, FrameInfo, HostBuffer, SceneInfo, VarianceForm};
pub use progressive::{Budget, progress_bar, render_progressively};
pub use shadows::{ShadowSampling, ShadowStats};

/// How to render, besides the scene itself.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub frame: FrameSettings,
    /// The outputs to gather (colour is always gathered).
    pub outputs: OutputSet,
    /// Samples per pixel the per-sample outputs keep (with [`Output::Samples`]).
    pub sample_capacity: u32,
    /// Build the generic kernel with every effect compiled in (for comparison).
    pub all_features: bool,
    /// Work-group size; None lets the driver choose. The image does not depend on it.
    pub local_size: Option<[usize; 2]>,
    /// Compile in the debug counters of kernels/arrays/trace.cl (tests only).
    pub debug_counters: bool,
    /// How the shadow output is sampled (with [`Output::Shadows`]).
    pub shadows: ShadowSampling,
}

impl RenderOptions {
    pub fn for_scene(scene: &Scene) -> Self {
        RenderOptions {
            frame: FrameSettings::from_scene(scene),
            outputs: OutputSet::colour(),
            sample_capacity: 0,
            all_features: false,
            local_size: None,
            debug_counters: false,
            shadows: ShadowSampling::default(),
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

    /// Binds the scene arguments every scene kernel starts with, by name, in their order.
    fn bind<'b>(&'b self, b: &mut ocl::builders::KernelBuilder<'b>) {
        b.arg_named("params", &self.params)
            .arg_named("nodes", &self.nodes)
            .arg_named("tri_geom", &self.tri_geom)
            .arg_named("tri_shading", &self.tri_shading)
            .arg_named("spheres", &self.spheres)
            .arg_named("materials", &self.materials)
            .arg_named("textures", &self.textures)
            .arg_named("texels", &self.texels)
            .arg_named("lights", &self.lights)
            .arg_named("light_cdf", &self.light_cdf);
    }
}

/// Kernel time and rays of one launch.
#[derive(Clone, Copy, Debug, Default)]
pub struct LaunchStats {
    pub samples: u32,
    pub kernel_time: Duration,
    pub rays: u64,
}

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
    /// What filters may know about the scene (recorded in AOV files).
    pub scene_info: SceneInfo,
    outputs: OutputSet,
    sample_capacity: u32,
    /// One buffer per entry of the output table: allocated when its output is on, a
    /// one-element stand-in otherwise.
    buffers: Vec<(BufferId, Buffer<u8>)>,
    ray_counts: Buffer<u32>,
    debug_counters: Buffer<u32>,
    kernel: Kernel,
    /// The AAF shadow passes, with the shadow output; run before the first path samples.
    shadow_passes: Option<shadows::ShadowPasses>,
    shadow_stats: Option<ShadowStats>,
    _scene: DeviceScene,
    samples_done: u32,
    pub rays_total: u64,
    pub kernel_time_total: Duration,
}

impl Renderer {
    pub fn new(gpu: Arc<Gpu>, scene: &Scene, options: &RenderOptions) -> Result<Renderer> {
        check_size(&gpu, options)?;
        let arrays = SceneArrays::build(scene, &options.frame)?;
        Renderer::with_arrays(gpu, scene, arrays, options)
    }

    /// A renderer over arrays already built from `scene` with `options.frame` (the caller
    /// needed them first, e.g. for [`SceneInfo`]).
    pub fn with_arrays(
        gpu: Arc<Gpu>,
        scene: &Scene,
        arrays: SceneArrays,
        options: &RenderOptions,
    ) -> Result<Renderer> {
        check_size(&gpu, options)?;
        let frame = &options.frame;
        let outputs = options.outputs.closed();
        let capacity = if outputs.contains(Output::Samples) {
            options.sample_capacity.max(1)
        } else {
            0
        };
        let features = if options.all_features {
            FeatureSet::all_features(scene, outputs)
        } else {
            FeatureSet::for_scene(scene, outputs)
        };
        let mut defines = features.defines();
        defines.push((
            "DEBUG_COUNTERS".into(),
            (options.debug_counters as u32).to_string(),
        ));
        // The shadow output samples one sphere light (they lead the light list).
        let shadow_light = if outputs.contains(Output::Shadows) {
            options.shadows.check()?;
            let spheres = arrays
                .lights
                .iter()
                .take_while(|l| l.kind == crate::layout::LIGHT_SPHERE)
                .count() as u32;
            if options.shadows.light >= spheres {
                bail!(
                    "the shadow output samples sphere light {} (counting from 0), but the scene \
                     has {spheres} sphere light(s)",
                    options.shadows.light
                );
            }
            Some(options.shadows.light)
        } else {
            None
        };
        let program = gpu.program("render/pathtrace.cl", &defines, "")?;
        let device_scene = DeviceScene::upload(&gpu, &arrays)?;
        let (w, h) = (frame.width, frame.height);
        // Only what is asked for is allocated: the others are one-element stand-ins.
        let buffers = BUFFERS
            .iter()
            .map(|b| {
                let bytes = if outputs.contains(b.id.owner()) {
                    b.bytes(w, h, capacity) as usize
                } else {
                    b.element_bytes
                };
                Ok((b.id, gpu.zeroed::<u8>(bytes, b.doc)?))
            })
            .collect::<Result<Vec<_>>>()?;
        let pixels = w as usize * h as usize;
        let debug_counters = gpu.zeroed::<u32>(DEBUG_COUNTERS.len(), "debug counter")?;
        let ray_counts = gpu.zeroed::<u32>(pixels, "ray count")?;

        let mut builder = Kernel::builder();
        builder
            .program(&program)
            .name("render")
            .queue(gpu.queue.clone());
        let (wu, hu) = (w as usize, h as usize);
        match options.local_size {
            Some(l) => {
                builder
                    .global_work_size([round_up(wu, l[0]), round_up(hu, l[1])])
                    .local_work_size(l);
            }
            None => {
                builder.global_work_size([wu, hu]);
            }
        }
        // Every argument by name, in the kernel's order (checked against the kernel's own
        // argument names by tests/layout.rs).
        device_scene.bind(&mut builder);
        for (id, b) in &buffers {
            builder.arg_named(id.decl().name, b);
        }
        builder
            .arg_named("ray_counts", &ray_counts)
            .arg_named("debug_counters", &debug_counters)
            .arg_named("sample_capacity", capacity)
            .arg_named("sample_base", 0u32)
            .arg_named("sample_count", 0u32)
            .arg_named("shadow_light", shadow_light.unwrap_or(u32::MAX));
        let kernel = builder.build().context("creating the render kernel")?;
        let scene_info = SceneInfo::new(scene, &arrays);
        let shadow_passes = match shadow_light {
            Some(_) => {
                let pixels = &buffers
                    .iter()
                    .find(|(id, _)| *id == BufferId::ShadowPixels)
                    .expect("every buffer is allocated")
                    .1;
                Some(shadows::ShadowPasses::new(
                    &gpu,
                    &program,
                    [wu, hu],
                    options.shadows,
                    &device_scene,
                    &debug_counters,
                    pixels,
                )?)
            }
            None => None,
        };
        Ok(Renderer {
            gpu,
            arrays,
            features,
            scene_info,
            outputs,
            sample_capacity: capacity,
            buffers,
            ray_counts,
            debug_counters,
            kernel,
            shadow_passes,
            shadow_stats: None,
            _scene: device_scene,
            samples_done: 0,
            rays_total: 0,
            kernel_time_total: Duration::ZERO,
        })
    }

    /// The names of the render kernel's arguments in the order they are bound.
    pub fn argument_names() -> Vec<&'static str> {
        let mut v = vec![
            "params",
            "nodes",
            "tri_geom",
            "tri_shading",
            "spheres",
            "materials",
            "textures",
            "texels",
            "lights",
            "light_cdf",
        ];
        v.extend(BUFFERS.iter().map(|b| b.name));
        v.extend([
            "ray_counts",
            "debug_counters",
            "sample_capacity",
            "sample_base",
            "sample_count",
            "shadow_light",
        ]);
        v
    }

    pub fn width(&self) -> u32 {
        self.arrays.params.image_width
    }

    pub fn height(&self) -> u32 {
        self.arrays.params.image_height
    }

    /// The outputs this renderer gathers.
    pub fn outputs(&self) -> OutputSet {
        self.outputs
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
        let (mut rays, mut kernel_time) = (0u64, Duration::ZERO);
        if self.samples_done == 0
            && let Some(passes) = &self.shadow_passes
        {
            (rays, kernel_time) = passes.run()?;
            let frame = self.frame();
            let pixels = frame.host_slice::<crate::layout::ShadowPixel>(BufferId::ShadowPixels)?;
            self.shadow_stats = Some(shadows::shadow_stats(pixels, rays, kernel_time));
        }
        self.kernel.set_arg("sample_base", self.samples_done)?;
        self.kernel.set_arg("sample_count", count)?;
        // SAFETY: every buffer argument is alive (owned by self) and sized for the global range.
        let event = unsafe { enqueue(&self.kernel, "the render kernel")? };
        kernel_time += event_duration(&event)?;
        let mut counts = vec![0u32; self.ray_counts.len()];
        self.ray_counts.read(&mut counts).enq()?;
        rays += counts.iter().map(|&c| c as u64).sum::<u64>();
        self.samples_done += count;
        self.rays_total += rays;
        self.kernel_time_total += kernel_time;
        Ok(LaunchStats {
            samples: count,
            kernel_time,
            rays,
        })
    }

    /// The outputs as they are now, for filters, AOV files and images. Cheap: it shares the
    /// device buffers and reads them back only where asked.
    pub fn frame(&self) -> Frame {
        let buffers = self
            .buffers
            .iter()
            .filter(|(id, _)| self.outputs.contains(id.owner()))
            .map(|(id, b)| (*id, b.clone()))
            .collect();
        Frame::on_device(
            FrameInfo {
                width: self.width(),
                height: self.height(),
                spp: self.samples_done,
                sample_capacity: self.sample_capacity,
                scene: self.scene_info.clone(),
            },
            self.outputs,
            self.gpu.clone(),
            buffers,
        )
    }

    /// How the shadow output was sampled, and what it spent (after the first launch); None
    /// without the shadow output.
    pub fn shadow_stats(&self) -> Option<(ShadowSampling, ShadowStats)> {
        Some((self.shadow_passes.as_ref()?.sampling(), self.shadow_stats?))
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

/// Refuses sizes the device cannot hold, before anything is built.
fn check_size(gpu: &Gpu, options: &RenderOptions) -> Result<()> {
    let (w, h) = (options.frame.width, options.frame.height);
    let outputs = options.outputs.closed();
    let capacity = options.sample_capacity.max(1);
    for b in outputs.buffers() {
        gpu.check_alloc(b.bytes(w, h, capacity), b.doc)?;
    }
    gpu.check_total(
        outputs.bytes(w, h, capacity) + 4 * w as u64 * h as u64,
        &format!("the per-pixel outputs ({})", outputs.names().join(", ")),
    )
}
