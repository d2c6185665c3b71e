//! Shared test helpers: the device (PoCL in CI), small scenes, image statistics.
#![allow(dead_code)]

pub mod aaf;
pub mod merge;
pub mod sheared;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use noisefree::gpu::Gpu;

/// One device per test binary (OpenCL contexts are expensive on PoCL).
pub fn gpu() -> Arc<Gpu> {
    static GPU: OnceLock<Arc<Gpu>> = OnceLock::new();
    GPU.get_or_init(|| Gpu::open(None).expect("an OpenCL device (install pocl-opencl-icd)"))
        .clone()
}

/// Every feature switch on: for probe kernels that do not depend on the scene.
pub fn generic_defines() -> Vec<(String, String)> {
    noisefree::render::features::generic_defines()
}

/// The filter `K` with `settings` as `render --filter` runs it on `frame` (configured,
/// specialised for the frame's scene, prepared, run): its image.
pub fn filtered<K: noisefree::filters::FilterKind>(
    frame: &noisefree::render::Frame,
    settings: &K::Settings,
) -> RgbImage {
    noisefree::filters::Configured::typed::<K>(settings.clone(), &frame.info().scene)
        .unwrap()
        .prepare(frame.info(), &gpu())
        .unwrap()
        .run(frame)
        .unwrap()
        .image
}

/// The settings `render --filter K` uses on `scene` (specialised: what `auto` decides), its
/// notes printed.
pub fn specialised<K: noisefree::filters::FilterKind>(
    scene: &noisefree::render::SceneInfo,
    mut settings: K::Settings,
) -> K::Settings {
    let notes = K::specialise(&mut settings, scene);
    eprintln!("{notes:?}");
    settings
}

/// What the filters see of `scene` at w × h.
pub fn scene_info(scene: &Scene, w: u32, h: u32) -> noisefree::render::SceneInfo {
    let o = options(scene, w, h, 1);
    let arrays = SceneArrays::build(scene, &o.frame).unwrap();
    noisefree::render::SceneInfo::new(scene, &arrays)
}

/// RMS of `a` against `b` over the pixels of `mask`.
pub fn masked_rms(a: &RgbImage, b: &RgbImage, mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0f64, 0usize);
    for ((p, q), &m) in a.pixels.iter().zip(&b.pixels).zip(mask) {
        if m {
            sum += (0..3).map(|c| ((p[c] - q[c]) as f64).powi(2)).sum::<f64>();
            n += 3;
        }
    }
    (sum / n as f64).sqrt()
}

/// The record of an AOV file of `frame`: its scene, no filter.
pub fn record_of(frame: &noisefree::render::Frame) -> noisefree::stats::RenderRecord {
    noisefree::stats::RenderRecord {
        scene: Some(frame.info().scene.clone()),
        ..Default::default()
    }
}

/// `frame` written to the AOV file `dir`/frame.exr (with [`record_of`]) and read back: the
/// offline side of online == offline.
pub fn aov_round_trip(frame: &noisefree::render::Frame, dir: &Path) -> noisefree::render::Frame {
    let aov = dir.join("frame.exr");
    noisefree::stats::aov::write_aov_exr(&aov, frame, &record_of(frame)).unwrap();
    noisefree::stats::aov::read_aov_exr(&aov).unwrap().0
}

/// A path in the repository (`rel` relative to its root; "" for the root itself).
pub fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

use glam::Vec3;
use noisefree::bvh::BvhLayout;
use noisefree::imaging::RgbImage;
use noisefree::layout::{FilterVector, Float4};
use noisefree::render::{RenderOptions, Renderer, SceneArrays};
use noisefree::scene::{Scene, load_scene, load_scene_str};

/// Every bundled scene file (scenes/*.toml), sorted by name.
pub fn bundled_scenes() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo_path("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

/// The path of the bundled scene scenes/`name`.toml.
pub fn bundled_scene_path(name: &str) -> PathBuf {
    repo_path(&format!("scenes/{name}.toml"))
}

/// The bundled scene scenes/`name`.toml, loaded.
pub fn bundled_scene(name: &str) -> Scene {
    load_scene(&bundled_scene_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// A scene from TOML text, resolved as if it lived in scenes/ (for relative asset paths).
pub fn scene_from_toml(text: &str) -> Scene {
    load_scene_str(&repo_path("scenes/test.toml"), text).unwrap_or_else(|e| panic!("{e}"))
}

/// A Cornell box of `quad` walls with an emissive panel under the ceiling; not closed. The
/// floor and ceiling are 2 x 2 (z from -1 to 1) and the back wall is at z = -1, but the side
/// walls run from z = -1 to 3.5, where a white wall stands behind the camera (z = 3.4): above
/// and below z from 1 to 3.5 the box is open. Every camera ray hits a wall (the 40° vertical
/// field of view reaches the floor and ceiling before z = 1); bounced rays can leave through
/// the openings, and bring no light back (there is no environment). `render` is the contents
/// of the [render] table; `extra` is appended (more materials and objects).
pub fn cornell(render: &str, extra: &str) -> String {
    format!(
        r#"
[render]
{render}

[camera]
origin = [0, 1, 3.4]
target = [0, 1, 0]
fov = 40

[[material]]
name = "white"
type = "diffuse"
color = [0.75, 0.75, 0.75]

[[material]]
name = "red"
type = "diffuse"
color = [0.75, 0.1, 0.1]

[[material]]
name = "green"
type = "diffuse"
color = [0.1, 0.75, 0.1]

[[material]]
name = "lamp"
type = "emitter"
emission = [6, 6, 6]

[[mesh]]
generator = "quad"
material = "white"
scale = 2

[[mesh]]
generator = "quad"
material = "white"
scale = 2
rotate = [180, 0, 0]
translate = [0, 2, 0]

[[mesh]]
generator = "quad"
material = "white"
scale = 2
rotate = [90, 0, 0]
translate = [0, 1, -1]

[[mesh]]
generator = "quad"
material = "white"
scale = 2
rotate = [-90, 0, 0]
translate = [0, 1, 3.5]

[[mesh]]
generator = "quad"
material = "red"
scale = [2, 2, 4.5]
rotate = [0, 0, -90]
translate = [-1, 1, 1.25]

[[mesh]]
generator = "quad"
material = "green"
scale = [2, 2, 4.5]
rotate = [0, 0, 90]
translate = [1, 1, 1.25]

[[mesh]]
generator = "quad"
material = "lamp"
scale = 0.8
rotate = [180, 0, 0]
translate = [0, 1.99, 0]

{extra}
"#
    )
}

/// [`cornell`] at max_depth 3 with a mirror sphere and a red sphere (mirror reflections,
/// curved normals, texture2 that varies).
pub fn cornell_with_spheres() -> Scene {
    let extra = r#"
[[material]]
name = "mirror"
type = "specular"
color = [0.9, 0.9, 0.9]

[[sphere]]
center = [-0.4, 0.35, -0.3]
radius = 0.35
material = "mirror"

[[sphere]]
center = [0.4, 0.3, 0.3]
radius = 0.3
material = "red"
"#;
    scene_from_toml(&cornell("max_depth = 3", extra))
}

/// Renders `spp` samples (in launches of `batch`) and returns the FilterVector means.
pub fn render_film(
    scene: &Scene,
    options: &RenderOptions,
    spp: u32,
    batch: u32,
) -> Vec<FilterVector> {
    let mut r = Renderer::new(gpu(), scene, options).unwrap_or_else(|e| panic!("{e:#}"));
    while r.samples_done() < spp {
        r.render_samples(batch.min(spp - r.samples_done())).unwrap();
    }
    r.frame().filter_vectors().unwrap().to_vec()
}

/// A reference image ("ground truth"): the beauty of `spp` samples of `scene` at `w` x `h`
/// with `seed`, rendered in launches of at most 256 samples.
pub fn reference_image(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> RgbImage {
    let film = render_film(scene, &options(scene, w, h, seed), spp, 256);
    RgbImage::beauty(w, h, &film)
}

pub fn options(scene: &Scene, width: u32, height: u32, seed: u32) -> RenderOptions {
    let mut o = RenderOptions::for_scene(scene);
    o.frame.width = width;
    o.frame.height = height;
    o.frame.seed = seed;
    o
}

/// direct + indirect per pixel.
pub fn beauty(film: &[FilterVector]) -> Vec<[f32; 3]> {
    film.iter()
        .map(|f| std::array::from_fn(|c| f.direct[c] + f.indirect[c]))
        .collect()
}

pub fn mean_rgb(img: &[[f32; 3]]) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for p in img {
        for c in 0..3 {
            m[c] += p[c] as f64;
        }
    }
    m.map(|v| v / img.len() as f64)
}

pub fn mse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (0..3).map(|c| ((x[c] - y[c]) as f64).powi(2)).sum::<f64>())
        .sum::<f64>()
        / (3 * a.len()) as f64
}

/// A FilterVector's 16 lanes in field order: direct, indirect, depth, normal, albedo, albedo2.
pub fn lanes(f: &FilterVector) -> [f32; 16] {
    f.lanes()
}

/// A render's every output, its rays traced and its debug counters.
pub type RenderRecord = (noisefree::render::Frame, u64, Vec<u32>);

/// Renders `scene` with `options` (and the debug counters) in launches of `batches` samples.
/// Every second launch covers a band of rows only (a renderer's share of a frame split across
/// devices, src/render/split.rs), not starting at the top.
pub fn render_in_launches(
    scene: &Scene,
    options: &RenderOptions,
    batches: &[u32],
    what: &str,
) -> RenderRecord {
    let mut o = options.clone();
    o.debug_counters = true;
    let mut r = Renderer::new(gpu(), scene, &o).unwrap_or_else(|e| panic!("{what}: {e:#}"));
    let h = r.height();
    for (k, &n) in batches.iter().enumerate() {
        if k % 2 == 1 && h > 4 {
            r.render_rows(n, 2..h - 1).unwrap();
        } else {
            r.render_samples(n).unwrap();
        }
    }
    (r.frame(), r.rays_total, r.read_debug_counters().unwrap())
}

/// Renders `scene` with options `a` and `b` ([`render_in_launches`]) and asserts the same
/// bytes, rays and counters ([`assert_same_render`]).
pub fn assert_options_agree(
    scene: &Scene,
    a: &RenderOptions,
    b: &RenderOptions,
    batches: &[u32],
    what: &str,
) {
    let first = render_in_launches(scene, a, batches, what);
    let second = render_in_launches(scene, b, batches, what);
    assert_same_render(&first, &second, what);
}

/// Asserts that two renders wrote the same bytes to every buffer, traced as many rays and
/// counted the same.
pub fn assert_same_render(a: &RenderRecord, b: &RenderRecord, what: &str) {
    assert_eq!(a.0.info().spp, b.0.info().spp, "{what}");
    for ((name, x), (_, y)) in output_bytes(&a.0).iter().zip(output_bytes(&b.0)) {
        assert!(*x == y, "{what}: the {name} buffers differ");
    }
    assert_eq!(a.1, b.1, "{what}: rays traced");
    assert_eq!(a.2, b.2, "{what}: debug counters");
    assert!(a.1 > 0, "{what}: nothing was traced");
}

/// Every output buffer of `frame`, named, as bytes (for bit-for-bit comparisons).
pub fn output_bytes(frame: &noisefree::render::Frame) -> Vec<(String, Vec<u8>)> {
    frame
        .outputs()
        .buffers()
        .map(|b| {
            let bytes = frame.host(b.id).unwrap().as_bytes().to_vec();
            (b.name.to_string(), bytes)
        })
        .collect()
}

/// The film as raw bytes, for bit-exact comparisons.
pub fn film_bytes(film: &[FilterVector]) -> Vec<u8> {
    film.iter()
        .flat_map(lanes)
        .flat_map(f32::to_le_bytes)
        .collect()
}

/// The largest relative difference of two images' channels (relative to the larger of the
/// two values, or to 1e-3 where both are smaller).
pub fn max_rel_diff(a: &RgbImage, b: &RgbImage) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(x, y)| {
            (0..3).map(move |c| (x[c] - y[c]).abs() / x[c].abs().max(y[c].abs()).max(1e-3))
        })
        .fold(0.0, f32::max)
}

/// Fails, naming `what` and the first such pixel, if any channel of `img` is NaN or infinite.
pub fn assert_finite(img: &RgbImage, what: &str) {
    if let Some(i) = img
        .pixels
        .iter()
        .position(|p| !p.iter().all(|v| v.is_finite()))
    {
        panic!(
            "{what}: non-finite output, pixel {i} is {:?}",
            img.pixels[i]
        );
    }
}

/// The mean and the sample variance (n - 1) of `x` in float64, in two passes.
pub fn two_pass(x: &[f32]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().map(|&v| v as f64).sum::<f64>() / n;
    let var = x.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var)
}

/// The bytes of a slice of a shared layout struct (plain f32/u32 fields, explicit padding).
pub fn pod_bytes<T: ocl::OclPrm>(v: &[T]) -> Vec<u8> {
    // SAFETY: the layout structs are plain-old-data with every byte initialised
    // (src/layout/mod.rs).
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
        .to_vec()
}

/// Runs kernels/test/probes.cl `probe_intersect` on `arrays`, walking the `bvh` tree: per ray
/// (origin, direction, t_max) returns (t or -1, primitive: triangle k, or -2 - sphere index,
/// or -1 for none, occluded).
pub fn device_intersect(
    arrays: &SceneArrays,
    rays: &[(Vec3, Vec3, f32)],
    bvh: BvhLayout,
) -> Vec<(f32, i32, bool)> {
    let gpu = gpu();
    let mut defines = generic_defines();
    if bvh == BvhLayout::Skip {
        defines.retain(|d| !d.0.starts_with("BVH_"));
        defines.push(("BVH_WIDE".into(), "0".into()));
    }
    let program = gpu.program("test/probes.cl", &defines, "").unwrap();
    let n = rays.len();
    let origins: Vec<Float4> = rays.iter().map(|r| Float4::from_vec3(r.0, r.2)).collect();
    let dirs: Vec<Float4> = rays.iter().map(|r| Float4::from_vec3(r.1, 0.0)).collect();
    let params = gpu.upload(std::slice::from_ref(&arrays.params)).unwrap();
    // One byte buffer either way: the kernel's pointer type follows BVH_WIDE.
    let node_bytes: Vec<u8> = match bvh {
        BvhLayout::Skip => pod_bytes(&arrays.nodes),
        BvhLayout::Wide => pod_bytes(&arrays.wide_bvh.nodes),
    };
    let nodes = gpu.upload(&node_bytes).unwrap();
    let geom = gpu.upload(&arrays.tri_geom).unwrap();
    let packs = match bvh {
        BvhLayout::Skip => gpu.upload(&[noisefree::layout::TrianglePack::default()]),
        BvhLayout::Wide => gpu.upload(&arrays.wide_bvh.packs),
    }
    .unwrap();
    let spheres = gpu.upload(&arrays.spheres).unwrap();
    let o = gpu.upload(&origins).unwrap();
    let d = gpu.upload(&dirs).unwrap();
    let out_t = gpu.zeroed::<f32>(n, "t").unwrap();
    let out_p = gpu.zeroed::<i32>(n, "prim").unwrap();
    let out_o = gpu.zeroed::<i32>(n, "occluded").unwrap();
    let k = ocl::Kernel::builder()
        .program(&program)
        .name("probe_intersect")
        .queue(gpu.queue.clone())
        .global_work_size(n)
        .arg(&params)
        .arg(&nodes)
        .arg(&geom)
        .arg(&packs)
        .arg(&spheres)
        .arg(&o)
        .arg(&d)
        .arg(&out_t)
        .arg(&out_p)
        .arg(&out_o)
        .arg(n as u32)
        .build()
        .unwrap();
    unsafe { k.enq().unwrap() };
    let (mut t, mut p, mut oc) = (vec![0f32; n], vec![0i32; n], vec![0i32; n]);
    out_t.read(&mut t).enq().unwrap();
    out_p.read(&mut p).enq().unwrap();
    out_o.read(&mut oc).enq().unwrap();
    (0..n).map(|i| (t[i], p[i], oc[i] != 0)).collect()
}

/// A small deterministic generator for test inputs (not the renderer's RNG).
pub struct TestRng(pub u64);

impl TestRng {
    pub fn next_u32(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 33) as u32
    }
    /// Uniform in [0, 1): the top 24 of `next_u32`'s 31 bits.
    pub fn uniform(&mut self) -> f32 {
        (self.next_u32() >> 7) as f32 / (1u32 << 24) as f32
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.uniform()
    }
    /// A normal variate of mean `mean` and standard deviation `sd` (Box-Muller, one of the
    /// pair; two uniforms per value).
    pub fn normal(&mut self, mean: f32, sd: f32) -> f32 {
        let (u1, u2) = (self.uniform().max(1e-7), self.uniform());
        mean + sd * (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }
    /// `n` normal variates (see [`TestRng::normal`]).
    pub fn normals(&mut self, n: usize, mean: f32, sd: f32) -> Vec<f32> {
        (0..n).map(|_| self.normal(mean, sd)).collect()
    }
    pub fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

/// Feeds one stream of values per pixel (equal lengths) through the kernel's statistics stage
/// (kernels/test/probes.cl probe_film) in launches of `chunk` samples; returns (F, S_n) per pixel.
pub fn device_welford(
    streams: &[Vec<f32>],
    chunk: usize,
) -> (Vec<FilterVector>, Vec<noisefree::layout::WelfordSums>) {
    use noisefree::layout::outputs::{BUFFERS, BufferId};
    let gpu = gpu();
    let program = gpu
        .program("test/probes.cl", &generic_defines(), "")
        .unwrap();
    let (pixels, len) = (streams.len(), streams[0].len());
    let flat: Vec<f32> = streams.iter().flatten().copied().collect();
    let stream = gpu.upload(&flat).unwrap();
    // Every output buffer of the render kernel, one sample per pixel where per-sample.
    let buffers: Vec<(BufferId, ocl::Buffer<u8>)> = BUFFERS
        .iter()
        .map(|b| {
            let bytes = b.bytes(pixels as u32, 1, 1, 1) as usize;
            (b.id, gpu.zeroed::<u8>(bytes, b.name).unwrap())
        })
        .collect();
    let mut kb = ocl::Kernel::builder();
    kb.program(&program)
        .name("probe_film")
        .queue(gpu.queue.clone())
        .global_work_size(pixels)
        .arg(&stream)
        .arg(len as u32)
        .arg_named("first", 0u32)
        .arg_named("count", 0u32);
    for (_, b) in &buffers {
        kb.arg(b);
    }
    let kernel = kb.arg(pixels as u32).build().unwrap();
    let mut first = 0;
    while first < len {
        let count = chunk.min(len - first);
        kernel.set_arg("first", first as u32).unwrap();
        kernel.set_arg("count", count as u32).unwrap();
        unsafe { kernel.enq().unwrap() };
        first += count;
    }
    let read = |id: BufferId| {
        let b = &buffers.iter().find(|(i, _)| *i == id).unwrap().1;
        let mut h = noisefree::render::HostBuffer::zeroed(b.len());
        b.read(h.as_bytes_mut()).enq().unwrap();
        h
    };
    let fv = read(BufferId::FilterVectors)
        .as_slice::<FilterVector>()
        .to_vec();
    let s = read(BufferId::WelfordSums)
        .as_slice::<noisefree::layout::WelfordSums>()
        .to_vec();
    (fv, s)
}

/// Host-side per-pixel buffers for building test frames: the FilterVector means and, where
/// given, the feature variances and mean first-bounce directions, like an AOV file holds them.
#[derive(Clone, Debug, PartialEq)]
pub struct Buffers {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub filter_vectors: Vec<FilterVector>,
    pub variances: Option<Vec<noisefree::layout::WelfordSums>>,
    pub directions: Option<Vec<[f32; 3]>>,
    pub scene: noisefree::render::SceneInfo,
}

impl Buffers {
    /// Zero variances and directions, a scene of size `scene_size` (0: unknown).
    pub fn new(
        width: u32,
        height: u32,
        filter_vectors: Vec<FilterVector>,
        scene_size: f32,
    ) -> Self {
        let n = filter_vectors.len();
        let mut scene = noisefree::render::SceneInfo::unknown();
        scene.scene_size = scene_size;
        Buffers {
            width,
            height,
            spp: 8,
            filter_vectors,
            variances: Some(vec![Default::default(); n]),
            directions: Some(vec![[0.0; 3]; n]),
            scene,
        }
    }

    /// [`Buffers::new`] with `f(x, y)` giving each pixel's FilterVector (rows top to bottom).
    pub fn from_fn(
        width: u32,
        height: u32,
        scene_size: f32,
        f: impl Fn(u32, u32) -> FilterVector,
    ) -> Self {
        let filter_vectors = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Buffers::new(width, height, filter_vectors, scene_size)
    }

    /// The frame these buffers describe (variances as variances, as from an AOV file).
    pub fn frame(&self) -> noisefree::render::Frame {
        use noisefree::layout::outputs::{BufferId, Output, OutputSet};
        use noisefree::layout::{DepthShift, WelfordState};
        use noisefree::render::{FrameInfo, HostBuffer, VarianceForm};
        let n = self.filter_vectors.len();
        let mut outputs = OutputSet::of(&[Output::Colour, Output::Features]);
        let mut buffers = vec![
            (
                BufferId::FilterVectors,
                HostBuffer::from_slice(&self.filter_vectors),
            ),
            (
                BufferId::DepthShifts,
                HostBuffer::from_slice(&vec![DepthShift::default(); n]),
            ),
        ];
        if let Some(v) = &self.variances {
            outputs = outputs.with(Output::Variance);
            buffers.push((BufferId::WelfordSums, HostBuffer::from_slice(v)));
            let state: Vec<WelfordState> = (0..n)
                .map(|i| WelfordState {
                    direction_mean: self.directions.as_ref().map_or([0.0; 3], |d| d[i]),
                    ..Default::default()
                })
                .collect();
            buffers.push((BufferId::WelfordState, HostBuffer::from_slice(&state)));
        }
        noisefree::render::Frame::on_host(
            FrameInfo {
                width: self.width,
                height: self.height,
                spp: self.spp,
                sample_capacity: 0,
                shadow_lights: Vec::new(),
                scene: self.scene.clone(),
            },
            outputs,
            VarianceForm::Variances,
            buffers,
        )
        .unwrap_or_else(|e| panic!("{e:#}"))
    }

    /// A frame's buffers on the host (variances formed as the kernels form them).
    pub fn of_frame(f: &noisefree::render::Frame) -> Buffers {
        use noisefree::layout::outputs::{BufferId, Output};
        use noisefree::layout::{WelfordState, WelfordSums};
        let (variances, directions) = if f.outputs().contains(Output::Variance) {
            let s: &[WelfordSums] = f.host_slice(BufferId::WelfordSums).unwrap();
            let st: &[WelfordState] = f.host_slice(BufferId::WelfordState).unwrap();
            (
                Some(
                    s.iter()
                        .map(|g| noisefree::stats::scaled(g, f.variance_factor()))
                        .collect(),
                ),
                Some(st.iter().map(|s| s.direction_mean).collect()),
            )
        } else {
            (None, None)
        };
        Buffers {
            width: f.width(),
            height: f.height(),
            spp: f.info().spp,
            filter_vectors: f.filter_vectors().unwrap().to_vec(),
            variances,
            directions,
            scene: f.info().scene.clone(),
        }
    }

    pub fn beauty(&self) -> noisefree::imaging::RgbImage {
        noisefree::imaging::RgbImage::beauty(self.width, self.height, &self.filter_vectors)
    }
}

/// The largest difference between two lane arrays, each relative to the larger magnitude
/// (absolute below 1): how the kernel-vs-reference tests compare per-pixel records.
pub fn max_lane_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / x.abs().max(y.abs()).max(1.0))
        .fold(0f32, f32::max)
}

/// A renderer of `scene` with `options` that has rendered `spp` samples in one launch.
pub fn rendered(scene: &Scene, options: &RenderOptions, spp: u32) -> Renderer {
    let mut r = Renderer::new(gpu(), scene, options).unwrap_or_else(|e| panic!("{e:#}"));
    r.render_samples(spp).unwrap();
    r
}

/// Renders `spp` samples of `scene` with `outputs` in one launch and returns the frame.
pub fn render_frame(scene: &Scene, options: &RenderOptions, spp: u32) -> noisefree::render::Frame {
    rendered(scene, options, spp).frame()
}

/// A fresh, empty temporary folder for one test (named after it and the process).
pub fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("noisefree-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

// ---- The command line ----

/// The noisefree binary of this build, ready for arguments.
pub fn noisefree() -> Command {
    Command::new(env!("CARGO_BIN_EXE_noisefree"))
}

/// The exit status of an error (src/cli/mod.rs); anything else, a signal included, is a bug.
pub const ERROR: i32 = 1;
/// The exit status of an argument the parser refuses (clap's usage errors).
pub const USAGE: i32 = 2;

/// Runs noisefree with `args` and checks the failure: exit status 1 (not another code, not a
/// signal), no panic, no failed allocation, and every `needles` entry in stderr. Returns stderr.
pub fn fails(args: &[&str], needles: &[&str]) -> String {
    fails_with(ERROR, noisefree().args(args), needles)
}

/// [`fails`] for arguments the parser refuses: exit status 2.
pub fn usage_fails(args: &[&str], needles: &[&str]) -> String {
    fails_with(USAGE, noisefree().args(args), needles)
}

/// Runs `command` and checks that it fails with exit status `expected` as [`fails`] does (and
/// within 120 s: errors come before the work). Returns stderr.
pub fn fails_with(expected: i32, command: &mut Command, needles: &[&str]) -> String {
    let args: Vec<String> = command
        .get_args()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let start = Instant::now();
    let out = command.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(
        out.status.code(),
        Some(expected),
        "expected exit status {expected} for {args:?}, got {:?}\nstderr: {err}",
        out.status
    );
    assert!(!err.contains("panicked"), "a panic for {args:?}: {err}");
    assert!(
        !err.contains("memory allocation"),
        "an allocation failure for {args:?}: {err}"
    );
    for n in needles {
        assert!(
            err.contains(n),
            "expected {n:?} in the message for {args:?}: {err}"
        );
    }
    // Errors come before the work: none of these cases may take long.
    assert!(
        start.elapsed() < Duration::from_secs(120),
        "{args:?} took {:?} to fail",
        start.elapsed()
    );
    err
}

/// A minimal scene file: 8 x 8 pixels, 1 spp, a white sphere and no light. tests/cli_errors.rs
/// points at its lines and columns: edit it there too.
pub const MINIMAL_SCENE: &str = r#"[render]
width = 8
height = 8
spp = 1

[camera]
origin = [0, 0, 5]
target = [0, 0, 0]

[[material]]
name = "white"
type = "diffuse"
color = [0.8, 0.8, 0.8]

[[sphere]]
center = [0, 0, 0]
radius = 1
material = "white"
"#;

/// Writes `text` to `dir`/scene.toml and returns that path.
pub fn write_scene(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// A small linear congruential generator (deterministic test data).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn uniform(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
}
