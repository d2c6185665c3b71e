//! Shared test helpers: the device (PoCL in CI), small scenes, image statistics.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use noisefree::gpu::Gpu;

/// One device per test binary (OpenCL contexts are expensive on PoCL).
pub fn gpu() -> Arc<Gpu> {
    static GPU: OnceLock<Arc<Gpu>> = OnceLock::new();
    GPU.get_or_init(|| Gpu::open(None).expect("an OpenCL device (install pocl-opencl-icd)"))
        .clone()
}

/// Every feature switch on: for probe kernels that do not depend on the scene.
pub fn generic_defines() -> Vec<(String, String)> {
    [
        "HAS_TRIANGLES",
        "HAS_SPHERES",
        "HAS_TEXTURES",
        "HAS_ENV",
        "HAS_ENV_TEXTURE",
        "HAS_SPHERE_LIGHTS",
        "HAS_TRIANGLE_LIGHTS",
        "HAS_DIFFUSE",
        "HAS_SPECULAR",
        "HAS_GLASS",
        "HAS_METAL",
        "HAS_DOF",
        "HAS_RUSSIAN_ROULETTE",
        "NEXT_EVENT_ESTIMATION",
        "OUTPUT_FEATURES",
        "OUTPUT_VARIANCE",
        "OUTPUT_SAMPLES",
    ]
    .iter()
    .map(|d| (d.to_string(), "1".to_string()))
    .collect()
}

pub fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

use glam::Vec3;
use noisefree::layout::{FilterVector, Float4};
use noisefree::render::{RenderOptions, Renderer, SceneArrays};
use noisefree::scene::{Scene, load_scene_str};

/// A scene from TOML text, resolved as if it lived in scenes/ (for relative asset paths).
pub fn scene_from_toml(text: &str) -> Scene {
    load_scene_str(&repo_path("scenes/test.toml"), text).unwrap_or_else(|e| panic!("{e}"))
}

/// A small closed Cornell box (walls from the `quad` generator, an emissive ceiling panel).
/// `extra` is appended: more materials and objects, or camera/render overrides via a
/// replacement of the [render] table contents through `render`.
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
    r.read_film().unwrap()
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

/// The film as raw bytes, for bit-exact comparisons.
pub fn film_bytes(film: &[FilterVector]) -> Vec<u8> {
    film.iter()
        .flat_map(|f| {
            let mut v = Vec::with_capacity(64);
            for x in f
                .direct
                .iter()
                .chain(&f.indirect)
                .chain([&f.depth])
                .chain(&f.normal)
                .chain(&f.albedo)
                .chain(&f.albedo2)
            {
                v.extend_from_slice(&x.to_le_bytes());
            }
            v
        })
        .collect()
}

/// Runs kernels/test/probes.cl `probe_intersect` on `arrays`: per ray (origin, direction, t_max)
/// returns (t or -1, primitive: triangle k, or -2 - sphere index, or -1 for none, occluded).
pub fn device_intersect(arrays: &SceneArrays, rays: &[(Vec3, Vec3, f32)]) -> Vec<(f32, i32, bool)> {
    let gpu = gpu();
    let program = gpu
        .program("test/probes.cl", &generic_defines(), "")
        .unwrap();
    let n = rays.len();
    let origins: Vec<Float4> = rays.iter().map(|r| Float4::from_vec3(r.0, r.2)).collect();
    let dirs: Vec<Float4> = rays.iter().map(|r| Float4::from_vec3(r.1, 0.0)).collect();
    let params = gpu.upload(std::slice::from_ref(&arrays.params)).unwrap();
    let nodes = gpu.upload(&arrays.nodes).unwrap();
    let geom = gpu.upload(&arrays.tri_geom).unwrap();
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
    pub fn uniform(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.uniform()
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
) -> (Vec<FilterVector>, Vec<noisefree::layout::GBuffer>) {
    use noisefree::layout::{GBuffer, StatsState};
    let gpu = gpu();
    let program = gpu
        .program("test/probes.cl", &generic_defines(), "")
        .unwrap();
    let (pixels, len) = (streams.len(), streams[0].len());
    let flat: Vec<f32> = streams.iter().flatten().copied().collect();
    let stream = gpu.upload(&flat).unwrap();
    let f = gpu.zeroed::<FilterVector>(pixels, "F").unwrap();
    let gb = gpu.zeroed::<GBuffer>(pixels, "GB").unwrap();
    let st = gpu.zeroed::<StatsState>(pixels, "state").unwrap();
    let kernel = ocl::Kernel::builder()
        .program(&program)
        .name("probe_film")
        .queue(gpu.queue.clone())
        .global_work_size(pixels)
        .arg(&stream)
        .arg(len as u32)
        .arg(0u32)
        .arg(0u32)
        .arg(&f)
        .arg(&gb)
        .arg(&st)
        .arg(pixels as u32)
        .build()
        .unwrap();
    let mut first = 0;
    while first < len {
        let count = chunk.min(len - first);
        kernel.set_arg(2, first as u32).unwrap();
        kernel.set_arg(3, count as u32).unwrap();
        unsafe { kernel.enq().unwrap() };
        first += count;
    }
    let mut fv = vec![FilterVector::default(); pixels];
    let mut s = vec![GBuffer::default(); pixels];
    f.read(&mut fv).enq().unwrap();
    gb.read(&mut s).enq().unwrap();
    (fv, s)
}
