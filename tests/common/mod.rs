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
    ]
    .iter()
    .map(|d| (d.to_string(), "1".to_string()))
    .collect()
}

pub fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}
