//! Tone-mapped 8-bit sRGB PNG.

use std::path::Path;

use anyhow::{Context as _, Result};

use super::{RgbImage, linear_to_srgb, write_atomically};

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

/// Writes `rgb8` (3 bytes per pixel, rows top to bottom) as an 8-bit RGB PNG.
pub fn write_rgb8_png(path: &Path, rgb8: &[u8], width: u32, height: u32) -> Result<()> {
    write_atomically(path, |tmp| {
        image::save_buffer_with_format(
            tmp,
            rgb8,
            width,
            height,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .context("encoding PNG")
    })
}
