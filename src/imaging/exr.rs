//! Linear float OpenEXR: single-layer RGB images with text metadata, and the header check that
//! keeps a damaged file from allocating terabytes.

use std::path::Path;

use anyhow::Result;

use super::{RgbImage, write_atomically};
use crate::memory::{available_memory_bytes, human_bytes};

/// A linear, single-layer float RGB OpenEXR.
pub fn write_exr(path: &Path, img: &RgbImage) -> Result<()> {
    write_exr_with_metadata(path, img, &std::collections::BTreeMap::new())
}

/// RLE in 64 × 64 tiles (exr's FAST_LOSSLESS) written in increasing order: with the default
/// "unspecified" order the tiles compressed in parallel are written as they finish, and the
/// same image gives different bytes from run to run.
pub const DETERMINISTIC_ENCODING: exr::prelude::Encoding = exr::prelude::Encoding {
    line_order: exr::prelude::LineOrder::Increasing,
    ..exr::prelude::Encoding::FAST_LOSSLESS
};

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
        DETERMINISTIC_ENCODING,
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
pub fn check_exr_memory(path: &Path, bytes_per_pixel: u64) -> Result<(), String> {
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
