//! Ground-truth images (thesis §7: 2048 spp at 512 x 512), rendered once and cached in a folder
//! that git ignores. A cached reference is reused only if the scene, the resolution, spp, seed
//! and the renderer's kernels are all the same: the file name carries a hash of them and the
//! EXR header records them. A reference too long for one machine is rendered as sample ranges
//! on many (`reference --slurm N`) and merged into the cache ([`store_merged`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context as _, Result, bail};

use crate::gpu::Gpu;
use crate::imaging::{self, RgbImage};
pub use crate::render::render_hash;
use crate::render::{
    RenderOptions, Renderer, SceneArrays, SplitRenderer, kernel_hash, render_hash_with, scene_hash,
};
use crate::scene::{self, Scene};
use crate::stats::merge::{CostSummary, Plan};

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
    let hash = render_hash_with(arrays, &params);
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

/// A reference as the cache knows it: the scene, how it is rendered and its file.
struct Target {
    scene: Scene,
    options: RenderOptions,
    arrays: SceneArrays,
    hash: u64,
    file: PathBuf,
}

impl Target {
    fn new(req: &ReferenceRequest, cache: &Path) -> Result<Target> {
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
        Ok(Target {
            scene,
            options,
            arrays,
            hash,
            file,
        })
    }

    /// Writes `img` into the cache with what made it in the header.
    fn store(&self, req: &ReferenceRequest, img: &RgbImage, made: &[(&str, String)]) -> Result<()> {
        let dir = self.file.parent().unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let mut meta = BTreeMap::new();
        meta.insert("scene".to_string(), req.scene.display().to_string());
        meta.insert("scene_hash".to_string(), format!("{:016x}", self.hash));
        meta.insert("spp".to_string(), req.spp.to_string());
        meta.insert("seed".to_string(), req.seed.to_string());
        for (k, v) in made {
            meta.insert(k.to_string(), v.clone());
        }
        imaging::write_exr_with_metadata(&self.file, img, &meta)
    }
}

/// The file the reference for `req` is cached in.
pub fn cached_file(req: &ReferenceRequest, cache: &Path) -> Result<PathBuf> {
    Ok(Target::new(req, cache)?.file)
}

/// The reference image for `req`: from the cache if present, else rendered and stored.
/// Returns the image, its file and whether it came from the cache.
pub fn get_or_render(
    gpu: &Arc<Gpu>,
    req: &ReferenceRequest,
    cache: &Path,
    quiet: bool,
) -> Result<(RgbImage, PathBuf, bool)> {
    let t = Target::new(req, cache)?;
    if t.file.exists() {
        let img = imaging::read_exr_rgb(&t.file)?;
        if img.width == req.width && img.height == req.height {
            return Ok((img, t.file, true));
        }
    }
    std::fs::create_dir_all(cache).with_context(|| format!("creating {}", cache.display()))?;
    let mut renderer = SplitRenderer::single(Renderer::new(gpu.clone(), &t.scene, &t.options)?);
    let start = std::time::Instant::now();
    let budget = crate::render::Budget {
        spp: req.spp,
        time_limit: None,
    };
    let bar = crate::render::progress_bar(req.spp, quiet);
    crate::render::render_progressively(&mut renderer, budget, &bar, &|| false, |_| Ok(()))?;
    let img = renderer.frame()?.beauty()?;
    t.store(
        req,
        &img,
        &[
            ("device", gpu.summary.name.clone()),
            ("seconds", format!("{:.1}", start.elapsed().as_secs_f64())),
        ],
    )?;
    Ok((img, t.file, false))
}

/// The reference for `req` merged from partial renders of it (`render --samples A..B
/// --partial`, as `reference --slurm` runs them) and stored in the cache. The parts must be
/// exactly this reference: its scene, resolution, seed and samples, rendered by this build's
/// kernels. Returns the file and what rendering the parts cost.
pub fn store_merged(
    req: &ReferenceRequest,
    cache: &Path,
    parts: &[PathBuf],
) -> Result<(PathBuf, CostSummary)> {
    let t = Target::new(req, cache)?;
    let plan = Plan::new(parts)?;
    let id = &plan.identity;
    let want = (scene_hash(&t.arrays), kernel_hash(), req.spp);
    if (id.scene_hash, id.kernel_hash, id.spp) != want {
        bail!(
            "the parts are not of this reference: they render {} at {}x{} with seed {} and {} \
             spp (scene hash {:016x}, kernel hash {:016x}), the reference is {} at {}x{} with \
             seed {} and {} spp (scene hash {:016x}, kernel hash {:016x})",
            id.scene,
            id.width,
            id.height,
            id.seed,
            id.spp,
            id.scene_hash,
            id.kernel_hash,
            req.scene.display(),
            req.width,
            req.height,
            req.seed,
            req.spp,
            want.0,
            want.1
        );
    }
    let merged = plan.merge(|_| {})?;
    let cost = merged.cost;
    let seconds: f64 = cost.seconds.iter().sum();
    t.store(
        req,
        &merged.frame.beauty()?,
        &[
            ("device", cost.devices.join(", ")),
            ("seconds", format!("{seconds:.1}")),
            ("pieces", cost.pieces.to_string()),
        ],
    )?;
    Ok((t.file, cost))
}
