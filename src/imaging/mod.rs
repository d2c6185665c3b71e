//! Images at the bottom of the module tree: the linear RGB image every stage hands on, the sRGB
//! transfer functions, the perceptual colour map of false-colour pictures, and files: tone-mapped
//! sRGB PNG for people, linear float OpenEXR for tools. Every file is written to a temporary name
//! in the same folder and renamed into place, so a failed or interrupted write never destroys an
//! existing image.

mod colormap;
mod exr;
mod files;
mod png;

pub use colormap::{COLORMAP_ANCHORS, colormap, colormap_exact};
pub use exr::{
    DETERMINISTIC_ENCODING, check_exr_memory, read_exr_metadata, read_exr_rgb, write_exr,
    write_exr_with_metadata,
};
pub use files::{check_output_path, write_atomically};
pub use png::{to_srgb8, write_png, write_rgb8_png};

use crate::layout::FilterVector;

/// A linear RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl RgbImage {
    /// direct + indirect: the beauty image (eq. 6.21 without filtering).
    pub fn beauty(width: u32, height: u32, filter_vectors: &[FilterVector]) -> RgbImage {
        let pixels = filter_vectors
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

/// The sRGB electro-optical transfer function (IEC 61966-2-1): encoded value to linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The inverse of [`srgb_to_linear`]: linear to encoded.
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}
