//! Ground-truth images (thesis §7: 2048 spp at 512 x 512), rendered once and cached in a folder
//! that git ignores. A cached reference is reused only if the scene, the resolution, spp, seed
//! and the renderer's kernels are all the same: the file name carries a hash of them and the
//! EXR header records them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context as _, Result};

use crate::gpu::{Gpu, fnv1a};
use crate::imaging::{self, RgbImage};
use crate::render::{RenderOptions, Renderer, SceneArrays, SplitRenderer};
use crate::scene::{self, Scene};

/// Samples per pixel of a ground-truth image: the thesis's 2048 (§7; `bench --reference-spp`
/// and `reference --spp` change it).
pub const DEFAULT_REFERENCE_SPP: u32 = 2048;

/// Seed of every reference render (distinct from the seeds of the images compared with it, so
/// their noise is independent).
pub const REFERENCE_SEED: u32 = 0x5eed_2048;

/// What to render.
#[derive(Clone, Debug)]
pub struct ReferenceRequest {
    pub scene: PathBuf,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seed: u32,
}

fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // SAFETY: the shared layout types are plain f32/u32/i32 with explicit padding fields
    // (src/layout.rs), so every byte is initialised.
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}

/// A hash of everything that decides a render's pixels: the scene as uploaded (geometry,
/// materials, textures, lights, camera, resolution, seed) and the megakernel's sources.
pub fn render_hash(arrays: &SceneArrays) -> u64 {
    hash_with_params(arrays, &arrays.params)
}

/// [`render_hash`] with `params` in place of the arrays' own.
fn hash_with_params(arrays: &SceneArrays, params: &crate::layout::SceneParams) -> u64 {
    let kernels: String = crate::kernels::SOURCES.iter().map(|(_, s)| *s).collect();
    fnv1a(&[
        bytes_of(std::slice::from_ref(params)),
        bytes_of(&arrays.nodes),
        bytes_of(&arrays.tri_geom),
        bytes_of(&arrays.tri_shading),
        bytes_of(&arrays.spheres),
        bytes_of(&arrays.materials),
        bytes_of(&arrays.textures),
        bytes_of(&arrays.texels),
        bytes_of(&arrays.lights),
        bytes_of(&arrays.light_cdf),
        kernels.as_bytes(),
    ])
}

/// The cache folder: `cache/references` under the current folder unless given.
pub fn default_cache() -> PathBuf {
    PathBuf::from("cache").join("references")
}

/// Renders `scene` as the request says, with the renderer's options for it.
fn options_for(scene: &Scene, req: &ReferenceRequest) -> RenderOptions {
    let mut o = RenderOptions::for_scene(scene);
    o.frame.width = req.width;
    o.frame.height = req.height;
    o.frame.seed = req.seed;
    o
}

/// The cache file name of a reference: scene, size, spp, seed and [`render_hash`].
fn file_name(scene: &Path, width: u32, height: u32, spp: &str, seed: u32, hash: u64) -> String {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    format!("{stem}-{width}x{height}-{spp}spp-seed{seed}-{hash:016x}.exr")
}

/// The cached reference, at any spp (the most there is), of `scene` seen as `arrays` say
/// (camera and size; rendered with [`REFERENCE_SEED`]): what the viewer compares with.
pub fn find_cached(cache: &Path, scene: &Path, arrays: &SceneArrays) -> Option<PathBuf> {
    let mut params = arrays.params;
    params.seed = REFERENCE_SEED;
    let hash = hash_with_params(arrays, &params);
    let (w, h) = (params.image_width, params.image_height);
    let pattern = file_name(scene, w, h, "*", REFERENCE_SEED, hash);
    let (head, tail) = pattern.split_once('*')?;
    std::fs::read_dir(cache)
        .ok()?
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let spp: u32 = name.strip_prefix(head)?.strip_suffix(tail)?.parse().ok()?;
            Some((spp, e.path()))
        })
        .max_by_key(|(spp, _)| *spp)
        .map(|(_, p)| p)
}

/// The reference image for `req`: from the cache if present, else rendered and stored.
/// Returns the image, its file and whether it came from the cache.
pub fn get_or_render(
    gpu: &Arc<Gpu>,
    req: &ReferenceRequest,
    cache: &Path,
    quiet: bool,
) -> Result<(RgbImage, PathBuf, bool)> {
    let scene = scene::load_scene(&req.scene)?;
    let options = options_for(&scene, req);
    let arrays = SceneArrays::build(&scene, &options.frame)?;
    let hash = render_hash(&arrays);
    let file = cache.join(file_name(
        &req.scene,
        req.width,
        req.height,
        &req.spp.to_string(),
        req.seed,
        hash,
    ));
    if file.exists() {
        let img = imaging::read_exr_rgb(&file)?;
        if img.width == req.width && img.height == req.height {
            return Ok((img, file, true));
        }
    }
    std::fs::create_dir_all(cache).with_context(|| format!("creating {}", cache.display()))?;
    let mut renderer = SplitRenderer::single(Renderer::new(gpu.clone(), &scene, &options)?);
    let start = std::time::Instant::now();
    let budget = crate::render::Budget {
        spp: req.spp,
        time_limit: None,
    };
    let bar = crate::render::progress_bar(req.spp, quiet);
    crate::render::render_progressively(&mut renderer, budget, &bar, &|| false, |_| Ok(()))?;
    let img = renderer.frame()?.beauty()?;
    let mut meta = BTreeMap::new();
    meta.insert("scene".to_string(), req.scene.display().to_string());
    meta.insert("scene_hash".to_string(), format!("{hash:016x}"));
    meta.insert("spp".to_string(), req.spp.to_string());
    meta.insert("seed".to_string(), req.seed.to_string());
    meta.insert("device".to_string(), gpu.summary.name.clone());
    meta.insert(
        "seconds".to_string(),
        format!("{:.1}", start.elapsed().as_secs_f64()),
    );
    imaging::write_exr_with_metadata(&file, &img, &meta)?;
    Ok((img, file, false))
}
