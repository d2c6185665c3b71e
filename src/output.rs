//! Images out: tone-mapped sRGB PNG for people, linear float OpenEXR for tools. Every file is
//! written to a temporary name in the same folder and renamed into place, so a failed or
//! interrupted write never destroys an existing image.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, bail};

use crate::layout::FilterVector;
use crate::memory::{available_memory_bytes, human_bytes};
use crate::scene::texture::linear_to_srgb;

/// A linear RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl RgbImage {
    /// direct + indirect: the beauty image (eq. 6.21 without filtering).
    pub fn beauty(width: u32, height: u32, film: &[FilterVector]) -> RgbImage {
        let pixels = film
            .iter()
            .map(|f| std::array::from_fn(|c| f.direct[c] + f.indirect[c]))
            .collect();
        RgbImage {
            width,
            height,
            pixels,
        }
    }

    pub fn mean(&self) -> [f64; 3] {
        let mut m = [0.0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                m[c] += p[c] as f64;
            }
        }
        m.map(|v| v / self.pixels.len().max(1) as f64)
    }
}

/// Checks that `path` can be written: its folder exists and it is not a folder itself.
pub fn check_output_path(path: &Path) -> Result<()> {
    if path.is_dir() {
        bail!(
            "{} is a directory; give a file name for the output",
            path.display()
        );
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        bail!(
            "cannot write {}: the folder {} does not exist",
            path.display(),
            parent.display()
        );
    }
    Ok(())
}

/// Writes through `write` to a temporary file next to `path`, then renames it over `path`.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    check_output_path(path)?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp: PathBuf = path.with_file_name(format!(".{name}.partial-{}.{ext}", std::process::id()));
    let result = write(&tmp).and_then(|_| {
        std::fs::rename(&tmp, path)
            .with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(|| format!("writing {}", path.display()))
}

/// Tone mapping for PNG: scale by 2^exposure, clamp to [0, 1], sRGB-encode.
pub fn to_srgb8(img: &RgbImage, exposure: f32) -> Vec<u8> {
    let scale = 2f32.powf(exposure);
    img.pixels
        .iter()
        .flat_map(|p| {
            p.map(|c| {
                let v = if c.is_finite() {
                    (c * scale).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (linear_to_srgb(v) * 255.0 + 0.5) as u8
            })
        })
        .collect()
}

pub fn write_png(path: &Path, img: &RgbImage, exposure: f32) -> Result<()> {
    let bytes = to_srgb8(img, exposure);
    write_atomically(path, |tmp| {
        image::save_buffer_with_format(
            tmp,
            &bytes,
            img.width,
            img.height,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .context("encoding PNG")
    })
}

/// A linear, single-layer float RGB OpenEXR.
pub fn write_exr(path: &Path, img: &RgbImage) -> Result<()> {
    write_exr_with_metadata(path, img, &std::collections::BTreeMap::new())
}

/// A linear float RGB OpenEXR with `metadata` as text attributes named `noisefree.<key>`.
pub fn write_exr_with_metadata(
    path: &Path,
    img: &RgbImage,
    metadata: &std::collections::BTreeMap<String, String>,
) -> Result<()> {
    use exr::prelude::*;
    let w = img.width as usize;
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = img.pixels[pos.y() * w + pos.x()];
        (p[0], p[1], p[2])
    });
    let mut attributes = LayerAttributes::named("noisefree");
    for (k, v) in metadata {
        attributes.other.insert(
            Text::from(format!("noisefree.{k}").as_str()),
            AttributeValue::Text(Text::from(v.as_str())),
        );
    }
    let layer = Layer::new(
        (w, img.height as usize),
        attributes,
        Encoding::FAST_LOSSLESS,
        channels,
    );
    let image = Image::from_layer(layer);
    write_atomically(path, |tmp| {
        image
            .write()
            .to_file(tmp)
            .map_err(|e| anyhow::anyhow!("encoding OpenEXR: {e}"))
    })
}

/// The `noisefree.<key>` text attributes of an OpenEXR file's first layer.
pub fn read_exr_metadata(path: &Path) -> Result<std::collections::BTreeMap<String, String>> {
    use exr::prelude::*;
    let meta = MetaData::read_from_file(path, false)
        .map_err(|e| anyhow::anyhow!("{}: cannot read OpenEXR header: {e}", path.display()))?;
    let mut out = std::collections::BTreeMap::new();
    if let Some(h) = meta.headers.first() {
        for (k, v) in &h.own_attributes.other {
            if let (Some(key), AttributeValue::Text(t)) =
                (k.to_string().strip_prefix("noisefree."), v)
            {
                out.insert(key.to_string(), t.to_string());
            }
        }
    }
    Ok(out)
}

/// Reads only the header of the OpenEXR file at `path` and checks, before any pixel is
/// allocated, that decoding its largest layer fits in the memory available (16 GiB where that
/// is unknown). A damaged or hostile header can claim up to 2^30 x 2^30 pixels, and the exr
/// crate's readers allocate the whole image before they find that the pixel data is missing;
/// an allocation that large aborts the process instead of returning an error.
/// `bytes_per_pixel` is what the caller keeps per pixel; 4 bytes per channel sample are added.
/// The message does not name the file: the callers put their own prefix in front.
pub(crate) fn check_exr_memory(path: &Path, bytes_per_pixel: u64) -> Result<(), String> {
    use exr::prelude::*;
    let meta = MetaData::read_from_file(path, false)
        .map_err(|e| format!("cannot read OpenEXR header: {e}"))?;
    let mut need = 0u64;
    let mut size = (0, 0);
    for h in &meta.headers {
        let (w, hgt) = (h.layer_size.width() as u64, h.layer_size.height() as u64);
        let per_pixel = bytes_per_pixel.saturating_add(4 * h.channels.list.len() as u64);
        let bytes = w.saturating_mul(hgt).saturating_mul(per_pixel);
        if bytes > need {
            need = bytes;
            size = (w, hgt);
        }
    }
    let available = available_memory_bytes().unwrap_or(16 << 30);
    if need > available {
        return Err(format!(
            "the OpenEXR header says {}x{} pixels, which would take {} to read, but only {} of \
             memory is available (a damaged file, or an image too large for this machine)",
            size.0,
            size.1,
            human_bytes(need),
            human_bytes(available)
        ));
    }
    Ok(())
}

/// Reads the RGB channels of an OpenEXR file (the first RGBA layer).
pub fn read_exr_rgb(path: &Path) -> Result<RgbImage> {
    use exr::prelude::*;
    check_exr_memory(path, 3 * 4)
        .map_err(|e| anyhow::anyhow!("{}: cannot read OpenEXR: {e}", path.display()))?;
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )
    .map_err(|e| anyhow::anyhow!("{}: cannot read OpenEXR: {e}", path.display()))?;
    let size = image.layer_data.size;
    Ok(RgbImage {
        width: size.width() as u32,
        height: size.height() as u32,
        pixels: image.layer_data.channel_data.pixels.1,
    })
}
