//! Ground-truth images (thesis §7: 2048 spp at 512 x 512), rendered once and cached in a folder
//! that git ignores. A cached reference is reused only if the scene, the resolution, spp, seed
//! and the renderer's kernels are all the same: the file name carries a hash of them and the
//! EXR header records them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context as _, Result};

use crate::gpu::Gpu;
use crate::imaging::{self, RgbImage};
pub use crate::render::render_hash;
use crate::render::{RenderOptions, Renderer, SceneArrays};
use crate::scene::{self, Scene};

/// Default reference samples per pixel on this project's 2-core PoCL machine (the thesis used
/// 2048; `--spp` raises it on a GPU).
pub const DEFAULT_REFERENCE_SPP: u32 = 1024;

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
    let stem = req
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let file = cache.join(format!(
        "{stem}-{}x{}-{}spp-seed{}-{hash:016x}.exr",
        req.width, req.height, req.spp, req.seed
    ));
    if file.exists() {
        let img = imaging::read_exr_rgb(&file)?;
        if img.width == req.width && img.height == req.height {
            return Ok((img, file, true));
        }
    }
    std::fs::create_dir_all(cache).with_context(|| format!("creating {}", cache.display()))?;
    let mut renderer = Renderer::new(gpu.clone(), &scene, &options)?;
    let start = std::time::Instant::now();
    let budget = crate::render::Budget {
        spp: req.spp,
        time_limit: None,
    };
    let bar = crate::render::progress_bar(req.spp, quiet);
    crate::render::render_progressively(&mut renderer, budget, &bar, &|| false, |_| Ok(()))?;
    let img = renderer.frame().beauty()?;
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
