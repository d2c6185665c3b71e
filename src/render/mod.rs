//! The renderer: uploads the scene arrays, builds the megakernel specialised to the scene and
//! to the outputs asked for, and adds samples progressively to the per-pixel outputs (thesis
//! §4.2.3, §4.3). Which buffers exist, and how they are bound to the kernel, comes from the
//! output table of src/layout/outputs.rs; what the renderer leaves is read through a
//! [`Frame`]. A renderer may cover a range of the samples and a [`Tile`] of the image: such
//! partial renders merge into the whole (src/stats/merge/).

pub mod balance;
pub mod cpu;
pub mod features;
pub mod frame;
pub mod gi_field;
pub mod indirect;
pub mod lens_field;
pub mod progressive;
pub mod shadows;
pub mod split;
pub mod subtractive;
pub mod tile;
pub mod wavefront;

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result};
use ocl::{Buffer, Kernel};

pub use crate::arrays::{FrameSettings, SceneArrays};
use crate::bvh::BvhLayout;
use crate::bvh::wide::MAX_BVH_STACK;
use crate::gpu::{Gpu, enqueue_rows, event_duration, fnv1a, round_up};
use crate::layout::outputs::{BUFFERS, BufferId, Output, OutputSet};
use crate::layout::{
    BvhNode, Float4, Light, Material, SceneParams, Sphere, TextureInfo, TriangleGeom, TrianglePack,
    TriangleShading, WideBvhNode,
};
use crate::scene::Scene;
pub use features::FeatureSet;
pub use frame::{Frame, FrameInfo, HostBuffer, SceneInfo, VarianceForm};
pub use indirect::{IndirectSampling, IndirectStats};
pub use progressive::{Budget, progress_bar, render_progressively};
pub use shadows::{LightPlanes, ShadowSampling, ShadowStats};
pub use split::{SplitFrame, SplitRenderer};
pub use tile::Tile;
pub use wavefront::Tracer;

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
    /// How the indirect output is sampled (with [`Output::Indirect`]).
    pub indirect: IndirectSampling,
    /// The render's first sample: it renders the samples from here on (`render --samples
    /// A..B`), counted from here in its statistics. 0 for a whole render.
    pub first_sample: u32,
    /// The part of the image rendered; None: all of it.
    pub tile: Option<Tile>,
    /// The megakernel or the wavefront kernels (the same image).
    pub tracer: Tracer,
    /// The wavefront tracer's paths in flight at most (whole rows of them); None: by the
    /// device's kind ([`wavefront::wave_paths`]). The image does not depend on it.
    pub wave_paths: Option<usize>,
    /// The tree the ray queries walk. The image does not depend on it.
    pub bvh: BvhLayout,
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
            indirect: IndirectSampling::default(),
            first_sample: 0,
            tile: None,
            tracer: Tracer::Megakernel,
            wave_paths: None,
            bvh: BvhLayout::default(),
        }
    }

    /// The rectangle rendered: the tile, or the whole image.
    pub fn tile(&self) -> Tile {
        self.tile
            .unwrap_or_else(|| Tile::whole(self.frame.width, self.frame.height))
    }
}

/// The scene's buffers on the device.
struct DeviceScene {
    params: Buffer<SceneParams>,
    nodes: NodeBuffer,
    tri_geom: Buffer<TriangleGeom>,
    /// The wide BVH's leaves; a one-pack stand-in for the skip-index walk.
    tri_packs: Buffer<TrianglePack>,
    tri_shading: Buffer<TriangleShading>,
    spheres: Buffer<Sphere>,
    materials: Buffer<Material>,
    textures: Buffer<TextureInfo>,
    texels: Buffer<Float4>,
    lights: Buffer<Light>,
    light_cdf: Buffer<f32>,
}

/// The tree the kernels walk, in its layout.
enum NodeBuffer {
    Skip(Buffer<BvhNode>),
    Wide(Buffer<WideBvhNode>),
}

impl DeviceScene {
    fn upload(gpu: &Gpu, a: &SceneArrays, bvh: BvhLayout) -> Result<DeviceScene> {
        Ok(DeviceScene {
            params: gpu.upload(std::slice::from_ref(&a.params))?,
            nodes: match bvh {
                BvhLayout::Skip => NodeBuffer::Skip(gpu.upload(&a.nodes)?),
                BvhLayout::Wide => NodeBuffer::Wide(gpu.upload(&a.wide_bvh.nodes)?),
            },
            tri_geom: gpu.upload(&a.tri_geom)?,
            tri_packs: match bvh {
                BvhLayout::Skip => gpu.upload(&[TrianglePack::default()])?,
                BvhLayout::Wide => gpu.upload(&a.wide_bvh.packs)?,
            },
            tri_shading: gpu.upload(&a.tri_shading)?,
            spheres: gpu.upload(&a.spheres)?,
            materials: gpu.upload(&a.materials)?,
            textures: gpu.upload(&a.textures)?,
            texels: gpu.upload(&a.texels)?,
            lights: gpu.upload(&a.lights)?,
            light_cdf: gpu.upload(&a.light_cdf)?,
        })
    }

    /// Binds the scene arguments every scene kernel starts with (kernels/arrays/trace.cl
    /// SCENE_PARAMS), by name, in their order: the scene's buffers, then the debug counters.
    fn bind<'b>(
        &'b self,
        b: &mut ocl::builders::KernelBuilder<'b>,
        debug_counters: &'b Buffer<u32>,
    ) {
        b.arg_named("params", &self.params);
        match &self.nodes {
            NodeBuffer::Skip(n) => b.arg_named("nodes", n),
            NodeBuffer::Wide(n) => b.arg_named("nodes", n),
        };
        b.arg_named("tri_geom", &self.tri_geom)
            .arg_named("tri_packs", &self.tri_packs)
            .arg_named("tri_shading", &self.tri_shading)
            .arg_named("spheres", &self.spheres)
            .arg_named("materials", &self.materials)
            .arg_named("textures", &self.textures)
            .arg_named("texels", &self.texels)
            .arg_named("lights", &self.lights)
            .arg_named("light_cdf", &self.light_cdf)
            .arg_named("debug_counters", debug_counters);
    }
}

/// The tree the kernels walk when `asked` is asked for: the skip-index tree when the wide
/// tree's walk could need a stack larger than [`MAX_BVH_STACK`] (a tree far deeper than any
/// bundled scene's; src/bvh/wide.rs), which gives the same image.
fn bvh_walked(arrays: &SceneArrays, asked: BvhLayout) -> BvhLayout {
    if asked == BvhLayout::Wide && !arrays.wide_bvh.fits_stack() {
        eprintln!(
            "note: the wide BVH's walk could need {} stack entries, more than {MAX_BVH_STACK}: \
             walking the skip-index BVH instead (the same image)",
            arrays.wide_bvh.stack_need,
        );
        return BvhLayout::Skip;
    }
    asked
}

/// Gives a kernel one work-item per pixel of `tile`, rounded up to the work-group size when
/// there is one (the kernels skip work-items beyond the tile).
fn over_pixels(k: &mut ocl::builders::KernelBuilder, tile: Tile, local_size: Option<[usize; 2]>) {
    let (w, h) = (tile.width as usize, tile.height as usize);
    match local_size {
        Some(l) => {
            k.global_work_size([round_up(w, l[0]), round_up(h, l[1])])
                .local_work_size(l);
        }
        None => {
            k.global_work_size([w, h]);
        }
    }
}

/// What [`Renderer::build_kernels`] builds from one program.
struct RenderKernels {
    kernel: Kernel,
    shadow_passes: Option<shadows::ShadowPasses>,
    lens_pass: Option<lens_field::LensPass>,
    indirect_passes: Option<indirect::IndirectPasses>,
    wavefront: Option<wavefront::Wavefront>,
}

/// Kernel time and rays of one launch.
#[derive(Clone, Copy, Debug, Default)]
pub struct LaunchStats {
    pub samples: u32,
    pub kernel_time: Duration,
    pub rays: u64,
    /// The passes that run once before the first samples (shadow, lens-field and indirect
    /// passes), over the whole image: not part of `kernel_time`, which balances a split frame
    /// by the rows each device renders.
    pub pass_time: Duration,
    pub pass_rays: u64,
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
    all_features: bool,
    debug: bool,
    local_size: Option<[usize; 2]>,
    tile: Tile,
    first_sample: u32,
    /// One buffer per entry of the output table: allocated when its output is on, a
    /// one-element stand-in otherwise.
    buffers: Vec<(BufferId, Buffer<u8>)>,
    ray_counts: Buffer<u32>,
    debug_counters: Buffer<u32>,
    /// Always Some after construction (built once the buffers exist).
    kernel: Option<Kernel>,
    /// Which kernels trace the paths, and the wavefront's paths in flight (RenderOptions).
    tracer: Tracer,
    wave_paths: Option<usize>,
    /// The tree the kernels walk: the one asked for, unless the wide tree could overflow the
    /// walk's stack ([`bvh_walked`]).
    pub bvh: BvhLayout,
    /// The wavefront kernels, when they render the samples instead of `kernel`.
    wavefront: Option<wavefront::Wavefront>,
    /// The sphere lights of the shadow output, one plane each (with [`Output::Shadows`]), and
    /// how they are sampled.
    shadow_lights: Option<shadows::LightPlanes>,
    shadow_sampling: ShadowSampling,
    /// The AAF shadow passes, with the shadow output; run before the first path samples.
    /// Built with the render kernel, from its program.
    shadow_passes: Option<shadows::ShadowPasses>,
    shadow_stats: Option<ShadowStats>,
    /// The lens-field pass (sheared depth of field: the light-field output without the shadow
    /// output); run before the first path samples.
    lens_pass: Option<lens_field::LensPass>,
    /// The AAF indirect passes (with [`Output::Indirect`]), run like the shadow passes.
    indirect_sampling: Option<IndirectSampling>,
    indirect_passes: Option<indirect::IndirectPasses>,
    indirect_stats: Option<IndirectStats>,
    _scene: DeviceScene,
    samples_done: u32,
    pub rays_total: u64,
    pub kernel_time_total: Duration,
    /// With the wavefront tracer: kernel time per step so far ([`wavefront::STEPS`]).
    pub wavefront_times: wavefront::StepTimes,
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
        let tile = options.tile();
        // Every frame records which light field its light-field output holds, decided here
        // by the renderer's own sampling rule (lens_field.rs), whoever built the options.
        let outputs = options.recorded_outputs();
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
        if outputs.contains(Output::LightField) && !outputs.contains(Output::Shadows) {
            lens_field::check(
                options.shadows.light_field,
                tile == Tile::whole(options.frame.width, options.frame.height),
            )?;
        }
        let shadow_lights = if outputs.contains(Output::Shadows) {
            Some(shadows::shadow_light(
                &arrays,
                &options.shadows,
                tile,
                &options.frame,
            )?)
        } else {
            None
        };
        let indirect_sampling = if outputs.contains(Output::Indirect) {
            indirect::check_whole(
                &options.indirect,
                tile,
                options.frame.width,
                options.frame.height,
            )?;
            Some(options.indirect)
        } else {
            None
        };
        let bvh = bvh_walked(&arrays, options.bvh);
        let device_scene = DeviceScene::upload(&gpu, &arrays, bvh)?;
        let scene_info = SceneInfo::new(scene, &arrays);
        let (w, h) = (tile.width, tile.height);
        let planes = shadow_lights.map_or(0, |l| l.count());
        // Only what is asked for is allocated: the others are one-element stand-ins.
        let buffers = BUFFERS
            .iter()
            .map(|b| {
                let bytes = if outputs.contains(b.id.owner()) {
                    b.bytes(w, h, capacity, planes) as usize
                } else {
                    b.element_bytes
                };
                Ok((b.id, gpu.zeroed::<u8>(bytes, b.doc)?))
            })
            .collect::<Result<Vec<_>>>()?;
        let pixels = w as usize * h as usize;
        let debug_counters = gpu.zeroed::<u32>(DEBUG_COUNTERS.len(), "debug counter")?;
        let ray_counts = gpu.zeroed::<u32>(pixels, "ray count")?;
        let mut r = Renderer {
            gpu,
            arrays,
            features,
            scene_info,
            outputs,
            sample_capacity: capacity,
            all_features: options.all_features,
            debug: options.debug_counters,
            local_size: options.local_size,
            tile,
            first_sample: options.first_sample,
            buffers,
            ray_counts,
            debug_counters,
            kernel: None,
            tracer: options.tracer,
            wave_paths: options.wave_paths,
            bvh,
            wavefront: None,
            shadow_lights,
            shadow_sampling: options.shadows,
            shadow_passes: None,
            shadow_stats: None,
            lens_pass: None,
            indirect_sampling,
            indirect_passes: None,
            indirect_stats: None,
            _scene: device_scene,
            samples_done: 0,
            rays_total: 0,
            kernel_time_total: Duration::ZERO,
            wavefront_times: Default::default(),
        };
        let kernels = r.build_kernels()?;
        r.install(kernels);
        Ok(r)
    }

    /// The megakernel specialised to `self.features`, every argument bound, and the shadow
    /// passes and the indirect passes from its program (with their outputs), or the
    /// lens-field pass (with the light-field output alone), and the wavefront kernels when
    /// they trace the paths.
    fn build_kernels(&self) -> Result<RenderKernels> {
        let mut defines = self.features.defines();
        defines.push(("DEBUG_COUNTERS".into(), (self.debug as u32).to_string()));
        if self.tracer == Tracer::Wavefront {
            defines.push(("WAVEFRONT".into(), "1".into()));
        }
        defines.push((
            "BVH_WIDE".into(),
            ((self.bvh == BvhLayout::Wide) as u32).to_string(),
        ));
        if self.bvh == BvhLayout::Wide {
            let entries = self.arrays.wide_bvh.stack_entries();
            defines.push(("BVH_STACK".into(), entries.to_string()));
        }
        defines.push((
            "SHADOW_PLANES".into(),
            self.shadow_lights.map_or(1, |l| l.count()).to_string(),
        ));
        let program = self.gpu.program("render/pathtrace.cl", &defines, "")?;
        let mut builder = Kernel::builder();
        builder
            .program(&program)
            .name("render")
            .queue(self.gpu.queue.clone());
        over_pixels(&mut builder, self.tile, self.local_size);
        // Every argument by name, in the kernel's order (checked against the kernel's own
        // argument names by tests/layout.rs).
        self._scene.bind(&mut builder, &self.debug_counters);
        for (id, b) in &self.buffers {
            builder.arg_named(id.decl().name, b);
        }
        builder
            .arg_named("ray_counts", &self.ray_counts)
            .arg_named("sample_capacity", self.sample_capacity)
            .arg_named("tile_x", self.tile.x)
            .arg_named("tile_y", self.tile.y)
            .arg_named("tile_width", self.tile.width)
            .arg_named("tile_height", self.tile.height)
            .arg_named("range_first", self.first_sample)
            .arg_named("sample_base", self.first_sample)
            .arg_named("sample_count", 0u32)
            .arg_named("shadow_lights", self.shadow_lights.map_or(0, |l| l.0));
        let kernel = builder.build().context("creating the render kernel")?;
        let shadow_passes = match self.shadow_lights {
            Some(_) => Some(shadows::ShadowPasses::new(
                &self.gpu,
                &program,
                [self.width() as usize, self.height() as usize],
                self.shadow_sampling,
                &self._scene,
                &self.debug_counters,
                self.buffer(BufferId::ShadowPixels),
                self.light_field_frames()
                    .map(|frames| (self.buffer(BufferId::LightFieldPixels), frames)),
            )?),
            None => None,
        };
        // The lens field: with the light-field output alone (depth of field, GI), or beside
        // the shadow fields with the lens-shadows output (both effects, after the shadow
        // passes: it reads their receivers).
        let lens_shadows = match self.shadow_lights {
            Some(lights) if self.outputs.contains(Output::LensShadows) => {
                Some(lens_field::LensShadows {
                    shadow_pixels: self.buffer(BufferId::ShadowPixels),
                    lights: lights.0,
                    lens_field: self.buffer(BufferId::LensFieldPixels),
                    lens_shadow: self.buffer(BufferId::LensShadowPixels),
                })
            }
            _ => None,
        };
        let lens_pass = if self.outputs.contains(Output::LightField)
            && (self.shadow_lights.is_none() || lens_shadows.is_some())
        {
            Some(lens_field::LensPass::new(
                &self.gpu,
                &program,
                [self.width() as usize, self.height() as usize],
                self.shadow_sampling,
                &self._scene,
                &self.debug_counters,
                self.buffer(BufferId::LightFieldPixels),
                lens_shadows,
            )?)
        } else {
            None
        };
        let indirect_passes = match self.indirect_sampling {
            Some(sampling) => Some(indirect::IndirectPasses::new(
                &self.gpu,
                &program,
                [self.width() as usize, self.height() as usize],
                sampling,
                &self._scene,
                &self.debug_counters,
                self.buffer(BufferId::IndirectPixels),
            )?),
            None => None,
        };
        let wavefront = match self.tracer {
            Tracer::Megakernel => None,
            Tracer::Wavefront => Some(wavefront::Wavefront::new(
                &self.gpu,
                &program,
                &self._scene,
                &wavefront::WavefrontBindings {
                    outputs: &self.buffers,
                    shadow_pixels: self.buffer(BufferId::ShadowPixels),
                    ray_counts: &self.ray_counts,
                    debug_counters: &self.debug_counters,
                    tile: self.tile,
                    local_size: self.local_size,
                    sample_capacity: self.sample_capacity,
                    range_first: self.first_sample,
                    shadow_lights: self.shadow_lights.map_or(0, |l| l.0),
                    wave_paths: self.wave_paths,
                },
            )?),
        };
        Ok(RenderKernels {
            kernel,
            shadow_passes,
            lens_pass,
            indirect_passes,
            wavefront,
        })
    }

    fn install(&mut self, k: RenderKernels) {
        self.kernel = Some(k.kernel);
        self.shadow_passes = k.shadow_passes;
        self.lens_pass = k.lens_pass;
        self.indirect_passes = k.indirect_passes;
        self.wavefront = k.wavefront;
    }
    /// The names of the render kernel's arguments in the order they are bound.
    pub fn argument_names() -> Vec<&'static str> {
        let mut v = vec![
            "params",
            "nodes",
            "tri_geom",
            "tri_packs",
            "tri_shading",
            "spheres",
            "materials",
            "textures",
            "texels",
            "lights",
            "light_cdf",
            "debug_counters",
        ];
        v.extend(BUFFERS.iter().map(|b| b.name));
        v.extend([
            "ray_counts",
            "sample_capacity",
            "tile_x",
            "tile_y",
            "tile_width",
            "tile_height",
            "range_first",
            "sample_base",
            "sample_count",
            "shadow_lights",
        ]);
        v
    }

    /// Light planes of the shadow output (0 without it).
    pub fn shadow_planes(&self) -> u32 {
        self.shadow_lights.map_or(0, |l| l.count())
    }

    /// Width of what this renderer's buffers hold: the tile's (the image's for a whole render).
    pub fn width(&self) -> u32 {
        self.tile.width
    }

    pub fn height(&self) -> u32 {
        self.tile.height
    }

    /// The part of the image rendered.
    pub fn tile(&self) -> Tile {
        self.tile
    }

    /// The first sample of the render's range: it has rendered samples
    /// `first_sample()..first_sample() + samples_done()`.
    pub fn first_sample(&self) -> u32 {
        self.first_sample
    }

    /// The outputs this renderer gathers.
    pub fn outputs(&self) -> OutputSet {
        self.outputs
    }

    /// Samples per pixel accumulated so far (from [`Renderer::first_sample`] on).
    pub fn samples_done(&self) -> u32 {
        self.samples_done
    }

    /// Adds `count` samples per pixel in one launch and waits for it.
    pub fn render_samples(&mut self, count: u32) -> Result<LaunchStats> {
        self.render_rows(count, 0..self.height())
    }

    /// Band boundaries must fall on multiples of this many rows: the work-group height, so
    /// that no work-group of a band reaches into the next band (whose pixels another device
    /// renders).
    pub fn row_granularity(&self) -> u32 {
        self.local_size.map_or(1, |l| l[1] as u32)
    }

    /// Adds `count` samples per pixel to the pixels of `rows` only (one band of a frame split
    /// across devices, §4.2), in one launch, and waits for it. The film counts `count` more
    /// samples per pixel either way: the caller renders the other rows elsewhere. A band must
    /// start on a multiple of [`Renderer::row_granularity`].
    pub fn render_rows(&mut self, count: u32, rows: std::ops::Range<u32>) -> Result<LaunchStats> {
        if count == 0 {
            return Ok(LaunchStats::default());
        }
        let (mut pass_rays, mut pass_time) = (0u64, Duration::ZERO);
        if self.samples_done == 0
            && let Some(passes) = &self.shadow_passes
        {
            // Over the whole image, whatever the rows: a device of a split frame computes
            // every pixel's receiver and slopes (they depend on the pixel alone), so its
            // film holds the same shadow pixels as one device's would.
            let (rays, time) = passes.run()?;
            let frame = self.frame();
            let pixels = frame.host_slice::<crate::layout::ShadowPixel>(BufferId::ShadowPixels)?;
            self.shadow_stats = Some(shadows::shadow_stats(pixels, rays, time));
            pass_rays += rays;
            pass_time += time;
        }
        if self.samples_done == 0
            && let Some(pass) = &self.lens_pass
        {
            // Over the whole image, as the shadow passes (the field depends on the pixel alone).
            let (rays, time) = pass.run()?;
            pass_rays += rays;
            pass_time += time;
        }
        if self.samples_done == 0
            && let Some(passes) = &self.indirect_passes
        {
            // Over the whole image, as the shadow passes.
            let (rays, time) = passes.run()?;
            let frame = self.frame();
            let pixels =
                frame.host_slice::<crate::layout::IndirectPixel>(BufferId::IndirectPixels)?;
            self.indirect_stats = Some(indirect::indirect_stats(pixels, rays, time));
            pass_rays += rays;
            pass_time += time;
        }
        let rows = rows.start.min(self.height())..rows.end.min(self.height());
        let mut stats = if rows.is_empty() {
            LaunchStats {
                samples: count,
                ..Default::default()
            }
        } else {
            self.launch(count, rows)?
        };
        (stats.pass_rays, stats.pass_time) = (pass_rays, pass_time);
        self.samples_done += count;
        self.rays_total += stats.rays + pass_rays;
        self.kernel_time_total += stats.kernel_time + pass_time;
        Ok(stats)
    }

    fn launch(&mut self, count: u32, rows: std::ops::Range<u32>) -> Result<LaunchStats> {
        let first = self.first_sample + self.samples_done;
        let w = self.width() as usize;
        let kernel_time = if let Some(wavefront) = &self.wavefront {
            let steps = wavefront.run(first, count, rows.clone(), &self.ray_counts)?;
            for (total, t) in self.wavefront_times.iter_mut().zip(steps) {
                *total += t;
            }
            steps.iter().sum()
        } else {
            let kernel = self.kernel.as_ref().expect("built in with_arrays");
            kernel.set_arg("sample_base", first)?;
            kernel.set_arg("sample_count", count)?;
            // SAFETY: every buffer argument is alive (owned by self) and sized for the whole
            // image; the kernel skips work-items beyond the image.
            let event = unsafe {
                enqueue_rows(
                    kernel,
                    self.width(),
                    self.height(),
                    rows.clone(),
                    "the render kernel",
                )?
            };
            event_duration(&event)?
        };
        let first = rows.start as usize * w;
        let mut counts = vec![0u32; rows.len() * w];
        self.ray_counts
            .read(&mut counts)
            .offset(first)
            .enq()
            .context("reading the ray counts")?;
        Ok(LaunchStats {
            samples: count,
            kernel_time,
            rays: counts.iter().map(|&c| c as u64).sum(),
            ..Default::default()
        })
    }

    /// Empties the film (thesis §4.2.2 "Film": the buffers are emptied when the camera
    /// updates): every output buffer to zero, no samples.
    pub fn reset(&mut self) -> Result<()> {
        for (id, b) in &self.buffers {
            if self.outputs.contains(id.owner()) {
                b.cmd()
                    .fill(0u8, None)
                    .enq()
                    .with_context(|| format!("emptying the {} buffer", id.decl().name))?;
            }
        }
        self.samples_done = 0;
        Ok(())
    }

    /// Moves the camera to `scene.camera` (the scene this renderer was built from, camera
    /// changed) and empties the film; the kernel is rebuilt when the camera changes which
    /// effects it needs (a lens: `HAS_DOF`). Renders then give exactly the bytes of a
    /// renderer built for `scene`.
    pub fn set_camera(&mut self, scene: &Scene) -> Result<()> {
        self.arrays.set_camera(scene);
        let features = if self.all_features {
            FeatureSet::all_features(scene, self.outputs)
        } else {
            FeatureSet::for_scene(scene, self.outputs)
        };
        self._scene
            .params
            .write(std::slice::from_ref(&self.arrays.params))
            .enq()
            .context("uploading the camera")?;
        if features != self.features {
            self.features = features;
            let kernels = self.build_kernels()?;
            self.install(kernels);
        }
        self.scene_info = SceneInfo::new(scene, &self.arrays);
        self.reset()
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
                shadow_lights: self.shadow_lights.map_or_else(Vec::new, |l| l.lights()),
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

    /// How the indirect output was sampled, and what it spent (after the first launch); None
    /// without the indirect output.
    pub fn indirect_stats(&self) -> Option<(IndirectSampling, IndirectStats)> {
        Some((
            self.indirect_passes.as_ref()?.sampling(),
            self.indirect_stats?,
        ))
    }

    /// With the light-field output: e1, e2 of the frame of each shadow plane's light
    /// ([`shadows::light_field::light_frame`]), in plane order.
    fn light_field_frames(&self) -> Option<Vec<[Float4; 2]>> {
        let lights = self.shadow_lights?.lights();
        if !self.outputs.contains(Output::LightField) {
            return None;
        }
        lights
            .into_iter()
            .map(|light| {
                let l = self.scene_info.sphere_lights.get(light as usize)?;
                let [e1, e2] = shadows::light_field::sphere_frame(*l, self.scene_info.scene_centre);
                Some([Float4::from_vec3(e1, 0.0), Float4::from_vec3(e2, 0.0)])
            })
            .collect()
    }

    fn buffer(&self, id: BufferId) -> &Buffer<u8> {
        &self
            .buffers
            .iter()
            .find(|(i, _)| *i == id)
            .expect("every buffer is allocated")
            .1
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
    let tile = options.tile();
    tile.check_within(options.frame.width, options.frame.height)?;
    let (w, h) = (tile.width, tile.height);
    let outputs = options.outputs.closed();
    let capacity = options.sample_capacity.max(1);
    let planes = options.shadows.lights.count();
    for b in outputs.buffers() {
        gpu.check_alloc(b.bytes(w, h, capacity, planes), b.doc)?;
    }
    gpu.check_total(
        outputs.bytes(w, h, capacity, planes) + 4 * w as u64 * h as u64,
        &format!("the per-pixel outputs ({})", outputs.names().join(", ")),
    )
}

fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // SAFETY: the shared layout types are plain f32/u32/i32 with explicit padding fields
    // (src/layout/mod.rs), so every byte is initialised.
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}

/// A hash of the scene as uploaded: geometry, materials, textures, lights, camera, resolution
/// and seed. With [`kernel_hash`] it decides every pixel of a render.
pub fn scene_hash(arrays: &SceneArrays) -> u64 {
    fnv1a(&scene_bytes(arrays))
}

fn scene_bytes(arrays: &SceneArrays) -> [&[u8]; 10] {
    [
        bytes_of(std::slice::from_ref(&arrays.params)),
        bytes_of(&arrays.nodes),
        bytes_of(&arrays.tri_geom),
        bytes_of(&arrays.tri_shading),
        bytes_of(&arrays.spheres),
        bytes_of(&arrays.materials),
        bytes_of(&arrays.textures),
        bytes_of(&arrays.texels),
        bytes_of(&arrays.lights),
        bytes_of(&arrays.light_cdf),
    ]
}

/// The megakernel's complete program text: render/pathtrace.cl with every file it includes
/// (the shadow passes and the light-field output are in the same program). Only these decide
/// a render's pixels, so editing a filter's kernel keeps the reference cache and partial
/// renders valid.
fn kernel_sources() -> String {
    crate::kernels::assemble("render/pathtrace.cl", "")
        .expect("render/pathtrace.cl and its includes are embedded (src/kernels.rs)")
}

/// A hash of the megakernel's sources (this build's megakernel).
pub fn kernel_hash() -> u64 {
    fnv1a(&[kernel_sources().as_bytes()])
}

/// A hash of everything that decides a render's pixels: the scene as uploaded and the
/// megakernel's sources (the key of the reference cache, src/bench/ground_truth.rs).
pub fn render_hash(arrays: &SceneArrays) -> u64 {
    render_hash_with(arrays, &arrays.params)
}

/// [`render_hash`] with `params` in place of the arrays' own (another seed or camera).
pub fn render_hash_with(arrays: &SceneArrays, params: &SceneParams) -> u64 {
    let kernels = kernel_sources();
    let mut parts = scene_bytes(arrays).to_vec();
    parts[0] = bytes_of(std::slice::from_ref(params));
    parts.push(kernels.as_bytes());
    fnv1a(&parts)
}
