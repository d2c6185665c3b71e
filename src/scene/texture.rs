//! Texture images: PNG and JPEG (8-bit sRGB, decoded to linear) and OpenEXR (already linear),
//! held as linear RGBA floats.

use std::path::Path;

use glam::Vec2;

use super::SceneError;
use crate::imaging::srgb_to_linear;

#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Linear RGBA, rows top to bottom.
    pub texels: Vec<[f32; 4]>,
    pub uv_scale: Vec2,
    pub uv_shift: Vec2,
}

/// The floats [`load_image`] makes of each 8-bit code: colour channels decoded from sRGB,
/// alpha as is, by the same conversion (src/arrays/texels.rs stores 8-bit textures as codes and
/// the kernels decode them with these tables).
pub fn srgb8_tables() -> ([f32; 256], [f32; 256]) {
    let codes = image::RgbaImage::from_fn(256, 1, |x, _| image::Rgba([x as u8; 4]));
    let floats = image::DynamicImage::ImageRgba8(codes).to_rgba32f();
    let (mut rgb, mut alpha) = ([0.0; 256], [0.0; 256]);
    for (c, p) in floats.pixels().enumerate() {
        rgb[c] = srgb_to_linear(p[0]);
        alpha[c] = p[3];
    }
    (rgb, alpha)
}

/// Loads an image file as linear RGBA. `what` names the file's role in messages.
pub fn load_image(path: &Path) -> Result<(u32, u32, Vec<[f32; 4]>), SceneError> {
    let meta = std::fs::metadata(path)
        .map_err(|e| SceneError::new(path, format!("cannot open texture image: {e}")))?;
    if meta.is_dir() {
        return Err(SceneError::new(
            path,
            "is a directory, expected a texture image file",
        ));
    }
    super::check_file_kind(path, &meta, "a texture image file")?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let (w, h, texels) = if ext == "exr" {
        load_exr(path)?
    } else {
        let img = image::ImageReader::open(path)
            .and_then(|r| r.with_guessed_format())
            .map_err(|e| SceneError::new(path, format!("cannot read texture image: {e}")))?
            .decode()
            .map_err(|e| SceneError::new(path, format!("cannot decode texture image: {e}")))?;
        let rgba = img.to_rgba32f();
        let (w, h) = rgba.dimensions();
        // 8- and 16-bit images are sRGB-encoded; float images (e.g. HDR) are linear.
        let encoded = !matches!(
            img,
            image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
        );
        let texels = rgba
            .pixels()
            .map(|p| {
                let f = |c: f32| if encoded { srgb_to_linear(c) } else { c };
                [f(p[0]), f(p[1]), f(p[2]), p[3]]
            })
            .collect();
        (w, h, texels)
    };
    if w == 0 || h == 0 {
        return Err(SceneError::new(
            path,
            format!("texture image is {w}x{h}: it has no pixels"),
        ));
    }
    if let Some(bad) = texels
        .iter()
        .position(|t: &[f32; 4]| t.iter().any(|c| !c.is_finite()))
    {
        return Err(SceneError::new(
            path,
            format!(
                "texture pixel ({}, {}) is not a finite number (NaN or infinity)",
                bad as u32 % w,
                bad as u32 / w
            ),
        ));
    }
    Ok((w, h, texels))
}

fn load_exr(path: &Path) -> Result<(u32, u32, Vec<[f32; 4]>), SceneError> {
    use exr::prelude::*;
    // The header first: a damaged one can claim an image too large to allocate.
    crate::imaging::check_exr_memory(path, 4 * 4)
        .map_err(|e| SceneError::new(path, format!("cannot read OpenEXR texture: {e}")))?;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            let (w, h) = (resolution.width(), resolution.height());
            (w, vec![[0.0f32; 4]; w * h])
        },
        |(w, texels): &mut (usize, Vec<[f32; 4]>), pos, (r, g, b, a): (f32, f32, f32, f32)| {
            texels[pos.y() * *w + pos.x()] = [r, g, b, a];
        },
    )
    .map_err(|e| SceneError::new(path, format!("cannot read OpenEXR texture: {e}")))?;
    let size = image.layer_data.size;
    Ok((
        size.width() as u32,
        size.height() as u32,
        image.layer_data.channel_data.pixels.1,
    ))
}
