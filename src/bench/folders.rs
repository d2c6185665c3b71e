//! Where the benchmark reads and writes: the bundled scenes folder it renders and the device's
//! name for its results folder.

use std::path::{Path, PathBuf};

use anyhow::{Result, anyhow, bail};

use crate::gpu::Gpu;

/// A file-system friendly name for the device, e.g. "pocl-cpu" or "nvidia-h100-80gb-hbm3".
pub fn device_slug(gpu: &Gpu) -> String {
    let s = &gpu.summary;
    let raw = if s.platform.contains("Portable Computing Language") {
        format!("pocl-{}", s.kind.to_lowercase())
    } else {
        s.name.to_lowercase()
    };
    let mut out = String::new();
    for c in raw.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c);
        } else if !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_matches('-').to_string()
}

/// `scenes/` of the source tree this binary was built from.
fn built_scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// The bundled scenes folder: `given` (--scenes) if any, else `scenes/` of the source tree the
/// binary was built from, else `./scenes`. None if no default exists; an error if `given` is
/// not a folder.
pub fn scenes_dir(given: Option<&Path>) -> Result<Option<PathBuf>> {
    if let Some(dir) = given {
        if !dir.is_dir() {
            bail!("--scenes {}: not a folder", dir.display());
        }
        return Ok(Some(dir.to_path_buf()));
    }
    Ok([built_scenes_dir(), PathBuf::from("scenes")]
        .into_iter()
        .find(|d| d.is_dir()))
}

pub(super) fn no_scenes_dir() -> anyhow::Error {
    anyhow!(
        "no bundled scenes: neither {} (the source tree this binary was built from) nor ./scenes \
         is a folder; pass --scenes DIR with the scenes/ folder of a noisefree checkout",
        built_scenes_dir().display()
    )
}

/// The bundled scenes in `dir`, the five of the thesis and their depth-of-field variants.
pub fn bundled_scenes(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    Ok(v)
}
