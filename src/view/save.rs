//! What the viewer saves: screenshots (the image as PNG and linear EXR, and the window with its
//! heads-up lines as PNG) and the current camera as a scene file that `noisefree render`
//! reproduces exactly.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, anyhow};
use toml::{Table, Value};

use crate::imaging::{self, RgbImage};
use crate::render::FrameSettings;
use crate::scene::Camera;

/// The window's picture beside a screenshot: `shot.png` → `shot-window.png`.
pub fn window_path(png: &Path) -> PathBuf {
    let stem = png
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    png.with_file_name(format!("{stem}-window.png"))
}

/// Writes the image shown (`rgb8`, and `linear` for the EXR) and the window's pixels. For the
/// rendered image `rgb8` is what `render` writes for it (src/imaging/png.rs), byte for byte.
pub fn screenshot(png: &Path, rgb8: &[u8], linear: &RgbImage, window_rgb8: &[u8]) -> Result<()> {
    let (w, h) = (linear.width, linear.height);
    imaging::write_rgb8_png(png, rgb8, w, h)?;
    imaging::write_exr(&png.with_extension("exr"), linear)?;
    imaging::write_rgb8_png(&window_path(png), window_rgb8, w, h)
}

/// What a saved scene holds besides the original file.
pub struct SavedView<'a> {
    pub camera: &'a Camera,
    pub frame: &'a FrameSettings,
    pub spp: u32,
    /// The filter shown and its requested settings; None: no filter (`method = "none"`).
    pub filter: Option<(&'a str, &'a Table)>,
}

/// The scene file at `original` with the viewer's camera, size, seed, spp and filter, as the
/// text of a file to be written at `dest`: `noisefree render` of it gives the viewer's image.
/// Comments are not kept. Relative asset paths are made absolute unless `dest` is in the
/// original's folder.
pub fn scene_text(original: &Path, dest: &Path, view: &SavedView) -> Result<String> {
    let text = std::fs::read_to_string(original)
        .with_context(|| format!("reading {}", original.display()))?;
    let mut doc: Table = toml::from_str(&text)
        .map_err(|e| anyhow!("{}: not a TOML scene file: {e}", original.display()))?;
    let folder = |p: &Path| {
        let dir = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf())
    };
    let scene_dir = folder(original);
    if folder(dest) != scene_dir {
        for (section, key) in [("mesh", "file"), ("texture", "file")] {
            let Some(Value::Array(items)) = doc.get_mut(section) else {
                continue;
            };
            for item in items.iter_mut().filter_map(Value::as_table_mut) {
                if let Some(Value::String(p)) = item.get_mut(key)
                    && Path::new(p.as_str()).is_relative()
                {
                    *p = scene_dir.join(&*p).to_string_lossy().into_owned();
                }
            }
        }
    }
    let c = view.camera;
    let vec3 = |v: glam::Vec3| Value::Array(v.to_array().map(|x| Value::Float(x as f64)).into());
    let mut camera = Table::new();
    camera.insert("origin".into(), vec3(c.origin));
    camera.insert("target".into(), vec3(c.target));
    camera.insert("up".into(), vec3(c.up));
    camera.insert("fov".into(), Value::Float(c.fov_degrees as f64));
    camera.insert("lens_radius".into(), Value::Float(c.lens_radius as f64));
    if let Some(f) = c.focal_distance {
        camera.insert("focal_distance".into(), Value::Float(f as f64));
    }
    camera.insert("autofocus".into(), Value::Boolean(c.autofocus));
    doc.insert("camera".into(), Value::Table(camera));
    let render = doc
        .entry("render")
        .or_insert_with(|| Value::Table(Table::new()))
        .as_table_mut()
        .ok_or_else(|| anyhow!("{}: [render] is not a table", original.display()))?;
    let f = view.frame;
    for (key, v) in [
        ("width", f.width),
        ("height", f.height),
        ("spp", view.spp),
        ("seed", f.seed),
        ("max_depth", f.max_depth),
    ] {
        render.insert(key.into(), Value::Integer(v as i64));
    }
    if f.sample_clamp > 0.0 {
        render.insert("clamp".into(), Value::Float(f.sample_clamp as f64));
    }
    let filter = doc
        .entry("filter")
        .or_insert_with(|| Value::Table(Table::new()))
        .as_table_mut()
        .ok_or_else(|| anyhow!("{}: [filter] is not a table", original.display()))?;
    match view.filter {
        Some((name, settings)) => {
            filter.insert("method".into(), Value::String(name.into()));
            filter.insert(name.into(), Value::Table(settings.clone()));
        }
        None => {
            filter.insert("method".into(), Value::String("none".into()));
        }
    }
    let body = toml::to_string(&doc).context("writing the scene as TOML")?;
    Ok(format!(
        "# Saved by `noisefree view` from {} (its camera, size, seed, filter and {} spp):\n\
         # `noisefree render` of this file gives the viewer's image.\n\n{body}",
        original.display(),
        view.spp
    ))
}
