//! Arbitrary output variables (AOVs): the per-pixel buffers as one multi-channel OpenEXR that
//! standard tools read (layer.channel names) and that noisefree reads back to filter offline,
//! plus false-colour PNGs of each buffer for people (like the thesis's Figs. 4.3, 6.3, 6.4).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context as _, Result, anyhow, bail};

use super::{PixelBuffers, feature_variance_sums};
use crate::imaging::{RgbImage, write_atomically, write_png};
use crate::layout::{FilterVector, GBuffer, SKY_DEPTH};

/// Every channel, in the order written: name, reader of the value from (F, variances, mean
/// direction).
type Getter = fn(&FilterVector, &GBuffer, &[f32; 3]) -> f32;

fn channels() -> Vec<(&'static str, Getter)> {
    vec![
        ("R", |f, _, _| f.direct[0] + f.indirect[0]),
        ("G", |f, _, _| f.direct[1] + f.indirect[1]),
        ("B", |f, _, _| f.direct[2] + f.indirect[2]),
        ("direct.R", |f, _, _| f.direct[0]),
        ("direct.G", |f, _, _| f.direct[1]),
        ("direct.B", |f, _, _| f.direct[2]),
        ("indirect.R", |f, _, _| f.indirect[0]),
        ("indirect.G", |f, _, _| f.indirect[1]),
        ("indirect.B", |f, _, _| f.indirect[2]),
        ("depth.Z", |f, _, _| f.depth),
        ("normal.X", |f, _, _| f.normal[0]),
        ("normal.Y", |f, _, _| f.normal[1]),
        ("normal.Z", |f, _, _| f.normal[2]),
        ("albedo.R", |f, _, _| f.albedo[0]),
        ("albedo.G", |f, _, _| f.albedo[1]),
        ("albedo.B", |f, _, _| f.albedo[2]),
        ("albedo2.R", |f, _, _| f.albedo2[0]),
        ("albedo2.G", |f, _, _| f.albedo2[1]),
        ("albedo2.B", |f, _, _| f.albedo2[2]),
        ("direction.X", |_, _, d| d[0]),
        ("direction.Y", |_, _, d| d[1]),
        ("direction.Z", |_, _, d| d[2]),
        ("var.depth", |_, g, _| g.depth),
        ("var.normal.X", |_, g, _| g.normal[0]),
        ("var.normal.Y", |_, g, _| g.normal[1]),
        ("var.normal.Z", |_, g, _| g.normal[2]),
        ("var.albedo.R", |_, g, _| g.albedo[0]),
        ("var.albedo.G", |_, g, _| g.albedo[1]),
        ("var.albedo.B", |_, g, _| g.albedo[2]),
        ("var.direction.X", |_, g, _| g.direction[0]),
        ("var.direction.Y", |_, g, _| g.direction[1]),
        ("var.direction.Z", |_, g, _| g.direction[2]),
        ("var.albedo2.R", |_, g, _| g.albedo2[0]),
        ("var.albedo2.G", |_, g, _| g.albedo2[1]),
        ("var.albedo2.B", |_, g, _| g.albedo2[2]),
    ]
}

/// Writes the buffers as one OpenEXR layer with named channels (see [`channels`]) plus a
/// constant `spp` channel; `metadata` goes into the header as text attributes.
pub fn write_aov_exr(
    path: &Path,
    b: &PixelBuffers,
    metadata: &BTreeMap<String, String>,
) -> Result<()> {
    use exr::prelude::*;
    let variances = b
        .variances
        .as_ref()
        .ok_or_else(|| anyhow!("the AOV file needs feature variances"))?;
    let n = (b.width * b.height) as usize;
    let zero = vec![[0.0f32; 3]; n];
    let directions = b.directions.as_ref().unwrap_or(&zero);
    if b.filter_vectors.len() != n || variances.len() != n {
        bail!(
            "buffer sizes do not match the image size {}x{}",
            b.width,
            b.height
        );
    }
    let mut list: Vec<AnyChannel<FlatSamples>> = channels()
        .into_iter()
        .map(|(name, get)| {
            let values = b
                .filter_vectors
                .iter()
                .zip(variances)
                .zip(directions)
                .map(|((f, g), d)| get(f, g, d))
                .collect();
            AnyChannel::new(name, FlatSamples::F32(values))
        })
        .collect();
    list.push(AnyChannel::new(
        "spp",
        FlatSamples::F32(vec![b.spp as f32; n]),
    ));
    let mut attributes = LayerAttributes::named("noisefree");
    let mut metadata = metadata.clone();
    metadata.insert("scene_size".to_string(), format!("{:e}", b.scene_size));
    for (k, v) in &metadata {
        attributes.other.insert(
            Text::from(format!("noisefree.{k}").as_str()),
            AttributeValue::Text(Text::from(v.as_str())),
        );
    }
    let layer = Layer::new(
        (b.width as usize, b.height as usize),
        attributes,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let image = Image::from_layer(layer);
    write_atomically(path, |tmp| {
        image
            .write()
            .to_file(tmp)
            .map_err(|e| anyhow!("encoding OpenEXR: {e}"))
    })
}

/// Reads an AOV file written by [`write_aov_exr`] (or any EXR with the same channel names).
pub fn read_aov_exr(path: &Path) -> Result<(PixelBuffers, BTreeMap<String, String>)> {
    use exr::prelude::*;
    // The header first: a damaged one can claim an image too large to allocate.
    let ours = std::mem::size_of::<FilterVector>() + std::mem::size_of::<GBuffer>() + 3 * 4;
    crate::imaging::check_exr_memory(path, ours as u64)
        .map_err(|e| anyhow!("{}: cannot read OpenEXR: {e}", path.display()))?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| anyhow!("{}: cannot read OpenEXR: {e}", path.display()))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let find = |name: &str| -> anyhow::Result<Vec<f32>> {
        let c = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .ok_or_else(|| {
                anyhow!(
                    "{}: not a noisefree AOV file: channel {name:?} is missing",
                    path.display()
                )
            })?;
        Ok(c.sample_data.values_as_f32().collect())
    };
    let n = w * h;
    let mut fv = vec![FilterVector::default(); n];
    let mut gb = vec![GBuffer::default(); n];
    let mut dirs = vec![[0.0f32; 3]; n];
    for (name, _) in channels() {
        if name.len() == 1 {
            continue; // R, G, B are the sum of direct and indirect
        }
        let values = find(name)?;
        for (i, v) in values.into_iter().enumerate() {
            if !v.is_finite() {
                bail!(
                    "{}: channel {name} has a non-finite value at pixel ({}, {})",
                    path.display(),
                    i % w,
                    i / w
                );
            }
            let (f, g, d) = (&mut fv[i], &mut gb[i], &mut dirs[i]);
            let slot: &mut f32 = match name {
                "direct.R" => &mut f.direct[0],
                "direct.G" => &mut f.direct[1],
                "direct.B" => &mut f.direct[2],
                "indirect.R" => &mut f.indirect[0],
                "indirect.G" => &mut f.indirect[1],
                "indirect.B" => &mut f.indirect[2],
                "depth.Z" => &mut f.depth,
                "normal.X" => &mut f.normal[0],
                "normal.Y" => &mut f.normal[1],
                "normal.Z" => &mut f.normal[2],
                "albedo.R" => &mut f.albedo[0],
                "albedo.G" => &mut f.albedo[1],
                "albedo.B" => &mut f.albedo[2],
                "albedo2.R" => &mut f.albedo2[0],
                "albedo2.G" => &mut f.albedo2[1],
                "albedo2.B" => &mut f.albedo2[2],
                "direction.X" => &mut d[0],
                "direction.Y" => &mut d[1],
                "direction.Z" => &mut d[2],
                "var.depth" => &mut g.depth,
                "var.normal.X" => &mut g.normal[0],
                "var.normal.Y" => &mut g.normal[1],
                "var.normal.Z" => &mut g.normal[2],
                "var.albedo.R" => &mut g.albedo[0],
                "var.albedo.G" => &mut g.albedo[1],
                "var.albedo.B" => &mut g.albedo[2],
                "var.direction.X" => &mut g.direction[0],
                "var.direction.Y" => &mut g.direction[1],
                "var.direction.Z" => &mut g.direction[2],
                "var.albedo2.R" => &mut g.albedo2[0],
                "var.albedo2.G" => &mut g.albedo2[1],
                "var.albedo2.B" => &mut g.albedo2[2],
                other => unreachable!("channel {other} has no slot"),
            };
            *slot = v;
        }
    }
    let spp_values = find("spp")?;
    let spp = spp_values.first().copied().unwrap_or(0.0);
    if !(spp >= 1.0 && spp.fract() == 0.0 && spp < 1e9) {
        bail!(
            "{}: channel spp holds {spp}, expected a positive whole number",
            path.display()
        );
    }
    let mut metadata = BTreeMap::new();
    for (k, v) in &layer.attributes.other {
        if let (Some(key), AttributeValue::Text(t)) = (k.to_string().strip_prefix("noisefree."), v)
        {
            metadata.insert(key.to_string(), t.to_string());
        }
    }
    let buffers = PixelBuffers {
        width: w as u32,
        height: h as u32,
        spp: spp as u32,
        filter_vectors: fv,
        variances: Some(gb),
        directions: Some(dirs),
        scene_size: metadata
            .get("scene_size")
            .and_then(|v| v.parse::<f32>().ok())
            .filter(|v| *v > 0.0 && v.is_finite())
            .unwrap_or(0.0),
    };
    Ok((buffers, metadata))
}

/// One false-colour PNG per buffer in `dir` (which is created): the light buffers tone-mapped,
/// depth as grey (near bright, sky black), normals as 0.5 + 0.5 n, albedos as they are, and each
/// feature variance (sum over its components) on a log scale from 1e-4 (dark) to 1 (bright)
/// with the viridis-like map of src/metrics.
pub fn write_aov_pngs(
    dir: &Path,
    b: &PixelBuffers,
    exposure: f32,
) -> Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let (w, h) = (b.width, b.height);
    let image = |f: &dyn Fn(&FilterVector) -> [f32; 3]| RgbImage {
        width: w,
        height: h,
        pixels: b.filter_vectors.iter().map(f).collect(),
    };
    let mut written = Vec::new();
    let mut save = |name: &str, img: &RgbImage, exposure: f32| -> Result<()> {
        let p = dir.join(format!("{name}.png"));
        write_png(&p, img, exposure)?;
        written.push(p);
        Ok(())
    };
    save("beauty", &b.beauty(), exposure)?;
    save("direct", &image(&|f| f.direct), exposure)?;
    save("indirect", &image(&|f| f.indirect), exposure)?;
    let finite_depths = b
        .filter_vectors
        .iter()
        .map(|f| f.depth)
        .filter(|d| *d < SKY_DEPTH * 0.5);
    let (lo, hi) = finite_depths.fold((f32::INFINITY, 0.0f32), |(lo, hi), d| {
        (lo.min(d), hi.max(d))
    });
    save(
        "depth",
        &image(&|f| {
            if f.depth >= SKY_DEPTH * 0.5 || !(hi > lo) {
                return [0.0; 3];
            }
            let v = 1.0 - 0.9 * (f.depth - lo) / (hi - lo);
            [v; 3]
        }),
        0.0,
    )?;
    save("normal", &image(&|f| f.normal.map(|c| 0.5 + 0.5 * c)), 0.0)?;
    save("albedo", &image(&|f| f.albedo), 0.0)?;
    save("albedo2", &image(&|f| f.albedo2), 0.0)?;
    if let Some(vars) = &b.variances {
        let names = [
            "var_depth",
            "var_normal",
            "var_albedo",
            "var_direction",
            "var_albedo2",
        ];
        for (k, name) in names.iter().enumerate() {
            let bytes: Vec<u8> = vars
                .iter()
                .flat_map(|g| {
                    let v = feature_variance_sums(g)[k].max(0.0) as f64;
                    let t = ((v.max(1e-12).log10() + 4.0) / 4.0).clamp(0.0, 1.0);
                    crate::imaging::colormap(if v > 0.0 { t } else { 0.0 })
                })
                .collect();
            let p = dir.join(format!("{name}.png"));
            write_atomically(&p, |tmp| {
                image::save_buffer_with_format(
                    tmp,
                    &bytes,
                    w,
                    h,
                    image::ColorType::Rgb8,
                    image::ImageFormat::Png,
                )
                .context("encoding PNG")
            })?;
            written.push(p);
        }
    }
    Ok(written)
}

/// The camera as text for AOV metadata ("origin forward right up tan_half_fov", 13 numbers),
/// so filters that need world positions (à-trous) can run offline.
pub fn camera_to_text(p: &crate::layout::SceneParams) -> String {
    let v = [
        p.camera_origin,
        p.camera_forward,
        p.camera_right,
        p.camera_up,
    ];
    let mut parts: Vec<String> = v
        .iter()
        .flat_map(|f| f.0[..3].iter().map(|x| format!("{x:e}")))
        .collect();
    parts.push(format!("{:e}", p.tan_half_fov));
    parts.join(" ")
}

/// Parses [`camera_to_text`]'s output into (origin, forward, right, up, tan_half_fov).
pub fn camera_from_text(text: &str) -> Result<crate::filters::atrous::AtrousCamera> {
    let v: Vec<f32> = text
        .split_whitespace()
        .map(|t| t.parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow!("the AOV file's camera attribute is not 13 numbers: {text:?}"))?;
    if v.len() != 13 || !v.iter().all(|x| x.is_finite()) {
        bail!("the AOV file's camera attribute is not 13 finite numbers: {text:?}");
    }
    let v3 = |i: usize| glam::Vec3::new(v[i], v[i + 1], v[i + 2]);
    Ok(crate::filters::atrous::AtrousCamera {
        origin: v3(0),
        forward: v3(3),
        right: v3(6),
        up: v3(9),
        tan_half_fov: v[12],
    })
}
