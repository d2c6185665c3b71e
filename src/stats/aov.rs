//! Arbitrary output variables (AOVs): every per-pixel output of a render as one multi-channel
//! OpenEXR that standard tools read (`layer.channel` names) and that `noisefree filter` reads
//! back, plus false-colour PNGs of each buffer for people (like the thesis's Figs. 4.3, 6.3,
//! 6.4).
//!
//! The channels come from the output table (src/layout/outputs.rs): whatever outputs the
//! render gathered are written, and reading takes whichever complete outputs a file holds, so a
//! file without an optional output (variances, positions) still loads, and a filter that needs
//! it says so. Variances are stored as variances (S_n / (n − 1)), the form tools expect; the
//! header holds the [`RenderRecord`] (scene information, filter settings) and what the
//! light-field output holds ([`LIGHT_FIELD_KEY`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Result, anyhow, bail};

use super::{RenderRecord, feature_variance_sums};
use crate::imaging::{RgbImage, colormap, to_srgb8, write_atomically, write_rgb8_png};
use crate::layout::outputs::{
    BufferId, ChannelDecl, ChannelScale, OUTPUTS, Output, OutputSet, Per, channel_name,
};
use crate::layout::{FilterVector, SKY_DEPTH, ShadowPixel, WelfordSums};
use crate::render::{Frame, FrameInfo, HostBuffer, SceneInfo, VarianceForm};

/// The header attribute that holds the render record.
pub const RECORD_ATTRIBUTE: &str = "noisefree.record";

/// The key of the record's table that says what the light-field output holds
/// ([`crate::layout::outputs::FieldKind::name`]); files written before it was recorded lack it,
/// and their light field is taken as it is.
pub const LIGHT_FIELD_KEY: &str = "light_field";

/// Writes the frame's per-pixel outputs as one OpenEXR layer with named channels, plus the
/// beauty (`R`, `G`, `B`) for viewers and a constant `spp` channel; `record` goes into the
/// header as one text attribute, `noisefree.record`: its attributes as a TOML table, keys
/// sorted. One attribute, because the exr crate writes a header's attributes in the order of
/// a std HashMap, which differs from process to process: with one, the same frame gives the
/// same bytes every time (what `noisefree merge` promises).
pub fn write_aov_exr(path: &Path, frame: &Frame, record: &RenderRecord) -> Result<()> {
    use exr::prelude::*;
    let info = frame.info();
    let n = info.pixels();
    let beauty = frame.beauty()?;
    let mut list: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        list.push(AnyChannel::new(
            *name,
            FlatSamples::F32(beauty.pixels.iter().map(|p| p[c]).collect()),
        ));
    }
    let variance = match frame.variance_form() {
        VarianceForm::Sums => frame.variance_factor(),
        VarianceForm::Variances => 1.0,
    };
    for o in OUTPUTS
        .iter()
        .filter(|o| frame.outputs().contains(o.output))
    {
        for c in o.channels {
            let floats = frame.host(c.buffer)?.floats();
            let stride = c.buffer.decl().element_bytes / 4;
            let scale = match c.scale {
                ChannelScale::AsIs => None,
                ChannelScale::Variance => Some(variance),
            };
            // One channel per light plane (`shadow.l1.direct.R`), or one per pixel.
            for (plane, light) in planes_of(c, &info.shadow_lights) {
                let planes = c.buffer.decl().per_pixel(0, info.shadow_planes());
                let values: Vec<f32> = (0..n)
                    .map(|i| {
                        let v = floats[(i * planes + plane) * stride + c.lane];
                        scale.map_or(v, |s| v * s)
                    })
                    .collect();
                list.push(AnyChannel::new(
                    channel_name(c, light).as_str(),
                    FlatSamples::F32(values),
                ));
            }
        }
    }
    list.push(AnyChannel::new(
        "spp",
        FlatSamples::F32(vec![info.spp as f32; n]),
    ));
    let mut attributes = LayerAttributes::named("noisefree");
    let mut text = record.to_attributes();
    if let Some(kind) = frame.outputs().light_field() {
        text.insert(LIGHT_FIELD_KEY.into(), kind.name().into());
    }
    let table = toml::to_string(&text).expect("text attributes serialise");
    attributes.other.insert(
        Text::from(RECORD_ATTRIBUTE),
        AttributeValue::Text(Text::from(table.as_str())),
    );
    let layer = Layer::new(
        (info.width as usize, info.height as usize),
        attributes,
        crate::imaging::DETERMINISTIC_ENCODING,
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

/// Reads an AOV file written by [`write_aov_exr`] (or any EXR with the same channel names):
/// every output whose channels are all present. Colour (`direct.*`, `indirect.*`) is required.
pub fn read_aov_exr(path: &Path) -> Result<(Frame, RenderRecord)> {
    use exr::prelude::*;
    let fail = |e: &dyn std::fmt::Display| anyhow!("{}: cannot read OpenEXR: {e}", path.display());
    // The header first: a damaged one can claim an image too large to allocate.
    let per_pixel: usize = crate::layout::outputs::BUFFERS
        .iter()
        // One plane of the per-light buffers: the check bounds the image, not every plane.
        .filter(|b| b.per != Per::Sample)
        .map(|b| b.element_bytes)
        .sum();
    crate::imaging::check_exr_memory(path, per_pixel as u64).map_err(|e| fail(&e))?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| fail(&e))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let channel = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
    };
    let n = w * h;
    // The light planes of the shadow output: the lights whose first channel is there.
    let first = &Output::Shadows.decl().channels[0];
    let shadow_lights: Vec<u32> = (0..32)
        .filter(|&l| channel(&channel_name(first, Some(l))).is_some())
        .collect();
    // An output is in the file when all its channels are; a partial one is damage.
    let mut outputs = OutputSet::default();
    for o in OUTPUTS.iter().filter(|o| !o.channels.is_empty()) {
        let names: Vec<String> = o
            .channels
            .iter()
            .flat_map(|c| {
                planes_of(c, &shadow_lights)
                    .into_iter()
                    .map(|(_, l)| channel_name(c, l))
            })
            .collect();
        let count = names.iter().filter(|c| channel(c).is_some()).count();
        if count == names.len() && count > 0 {
            outputs = outputs.with(o.output);
        } else if count > 0 || o.output == Output::Colour {
            let missing = names
                .iter()
                .find(|c| channel(c).is_none())
                .cloned()
                .unwrap_or_else(|| channel_name(first, Some(0)));
            bail!(
                "{}: not a complete noisefree AOV file: channel {:?} of the {} output is missing",
                path.display(),
                missing,
                o.name
            );
        }
    }
    let shadow_lights = if outputs.contains(Output::Shadows) {
        shadow_lights
    } else {
        Vec::new()
    };
    let planes = shadow_lights.len() as u32;
    let mut buffers: Vec<(BufferId, HostBuffer)> = outputs
        .buffers()
        .map(|b| {
            (
                b.id,
                HostBuffer::zeroed(b.bytes(w as u32, h as u32, 0, planes) as usize),
            )
        })
        .collect();
    // Features live in the colour output's buffer.
    for o in OUTPUTS.iter().filter(|o| outputs.contains(o.output)) {
        for c in o.channels {
            for (plane, light) in planes_of(c, &shadow_lights) {
                let name = channel_name(c, light);
                let data = channel(&name).expect("checked above");
                let stride = c.buffer.decl().element_bytes / 4;
                let per = c.buffer.decl().per_pixel(0, planes);
                let (_, buf) = buffers
                    .iter_mut()
                    .find(|(id, _)| *id == c.buffer)
                    .expect("the owner's buffer");
                let floats = buf.floats_mut();
                for (i, v) in data.sample_data.values_as_f32().enumerate().take(n) {
                    if !v.is_finite() {
                        bail!(
                            "{}: channel {name} has a non-finite value at pixel ({}, {})",
                            path.display(),
                            i % w,
                            i / w
                        );
                    }
                    floats[(i * per + plane) * stride + c.lane] = v;
                }
            }
        }
    }
    let spp = channel("spp")
        .and_then(|c| c.sample_data.values_as_f32().next())
        .ok_or_else(|| anyhow!("{}: channel \"spp\" is missing", path.display()))?;
    if !(spp >= 1.0 && spp.fract() == 0.0 && spp < 1e9) {
        bail!(
            "{}: channel spp holds {spp}, expected a positive whole number",
            path.display()
        );
    }
    // The record: one TOML attribute, or (files written before it was one) an attribute
    // `noisefree.<key>` per key.
    let mut attributes = BTreeMap::new();
    for (k, v) in &layer.attributes.other {
        let (k, AttributeValue::Text(t)) = (k.to_string(), v) else {
            continue;
        };
        if k == RECORD_ATTRIBUTE {
            let table: BTreeMap<String, String> = toml::from_str(&t.to_string()).map_err(|e| {
                anyhow!(
                    "{}: the render record in the header: {}",
                    path.display(),
                    e.message()
                )
            })?;
            attributes.extend(table);
        } else if let Some(key) = k.strip_prefix("noisefree.") {
            attributes.insert(key.to_string(), t.to_string());
        }
    }
    if let Some(name) = attributes.remove(LIGHT_FIELD_KEY) {
        outputs = outputs.with_field_named(&name).ok_or_else(|| {
            anyhow!(
                "{}: the header says the light-field output holds {name:?}, which the file's \
                 outputs ({}) cannot hold",
                path.display(),
                outputs.names().join(", ")
            )
        })?;
    }
    let record = RenderRecord::from_attributes(&attributes)
        .map_err(|e| anyhow!("{}: the render record in the header: {e:#}", path.display()))?;
    let info = FrameInfo {
        width: w as u32,
        height: h as u32,
        spp: spp as u32,
        sample_capacity: 0,
        shadow_lights,
        scene: record.scene.clone().unwrap_or_else(SceneInfo::unknown),
    };
    let frame = Frame::on_host(info, outputs, VarianceForm::Variances, buffers)?;
    Ok((frame, record))
}

/// The (plane, light) of each AOV channel of `c`: one per light plane of the shadow output
/// for its per-light buffers (`shadow.l<light>.*`, `lightfield.l<light>.*`), else one,
/// (0, None) (also a per-light buffer without the shadow output: the light field of depth of
/// field, `lightfield.*`).
fn planes_of(c: &ChannelDecl, shadow_lights: &[u32]) -> Vec<(usize, Option<u32>)> {
    if c.buffer.decl().per == Per::Light && !shadow_lights.is_empty() {
        shadow_lights
            .iter()
            .enumerate()
            .map(|(p, &l)| (p, Some(l)))
            .collect()
    } else {
        vec![(0, None)]
    }
}

/// One false-colour PNG per buffer in `dir` (which is created), from [`aov_pictures`].
pub fn write_aov_pngs(dir: &Path, frame: &Frame, exposure: f32) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("creating {}: {e}", dir.display()))?;
    let mut written = Vec::new();
    for (name, bytes) in aov_pictures(frame, exposure)? {
        let p = dir.join(format!("{name}.png"));
        write_rgb8_png(&p, &bytes, frame.width(), frame.height())?;
        written.push(p);
    }
    Ok(written)
}

/// A false-colour picture of every buffer the frame holds, as (name, 8-bit sRGB bytes): the
/// light buffers tone-mapped, depth as grey (near bright, sky black), normals as 0.5 + 0.5 n,
/// albedos as they are, and each feature variance (sum over its components) on a log scale
/// from 1e-4 (dark) to 1 (bright) with the colour map of src/imaging. For AOV files and the
/// viewer.
pub fn aov_pictures(frame: &Frame, exposure: f32) -> Result<Vec<(&'static str, Vec<u8>)>> {
    let (w, h) = (frame.width(), frame.height());
    let fv: &[FilterVector] = frame.filter_vectors()?;
    let image = |f: &dyn Fn(&FilterVector) -> [f32; 3]| RgbImage {
        width: w,
        height: h,
        pixels: fv.iter().map(f).collect(),
    };
    let mut out = Vec::new();
    out.push(("beauty", to_srgb8(&frame.beauty()?, exposure)));
    out.push(("direct", to_srgb8(&image(&|f| f.direct), exposure)));
    out.push(("indirect", to_srgb8(&image(&|f| f.indirect), exposure)));
    if frame.outputs().contains(Output::Features) {
        let finite_depths = fv.iter().map(|f| f.depth).filter(|d| *d < SKY_DEPTH * 0.5);
        let (lo, hi) = finite_depths.fold((f32::INFINITY, 0.0f32), |(lo, hi), d| {
            (lo.min(d), hi.max(d))
        });
        let depth = image(&|f| {
            if f.depth >= SKY_DEPTH * 0.5 || !(hi > lo) {
                return [0.0; 3];
            }
            let v = 1.0 - 0.9 * (f.depth - lo) / (hi - lo);
            [v; 3]
        });
        out.push(("depth", to_srgb8(&depth, 0.0)));
        let normal = image(&|f| f.normal.map(|c| 0.5 + 0.5 * c));
        out.push(("normal", to_srgb8(&normal, 0.0)));
        out.push(("albedo", to_srgb8(&image(&|f| f.albedo), 0.0)));
        out.push(("albedo2", to_srgb8(&image(&|f| f.albedo2), 0.0)));
    }
    if frame.outputs().contains(Output::Variance) {
        let sums: &[WelfordSums] = frame.host_slice(BufferId::WelfordSums)?;
        let factor = frame.variance_factor();
        let names = [
            "var_depth",
            "var_normal",
            "var_albedo",
            "var_direction",
            "var_albedo2",
        ];
        for (k, name) in names.into_iter().enumerate() {
            let bytes: Vec<u8> = sums
                .iter()
                .flat_map(|g| {
                    let v = feature_variance_sums(&super::scaled(g, factor))[k].max(0.0) as f64;
                    let t = ((v.max(1e-12).log10() + 4.0) / 4.0).clamp(0.0, 1.0);
                    colormap(if v > 0.0 { t } else { 0.0 })
                })
                .collect();
            out.push((name, bytes));
        }
    }
    if frame.outputs().contains(Output::Shadows) {
        out.extend(shadow_pictures(frame)?);
    }
    Ok(out)
}

/// AAF's shadow output as pictures: `shadow_spp`, the light samples per pixel (the spp map,
/// colour-mapped from 0 to the most any pixel took), and `shadow_visibility`, the noisy
/// visibility h_n (grey; black where no receiver), of the first light plane's light. The frame
/// must hold the shadow output.
pub fn shadow_pictures(frame: &Frame) -> Result<[(&'static str, Vec<u8>); 2]> {
    let first = frame.info().shadow_lights.first().copied().unwrap_or(0);
    let own = frame.light_plane(first, "the shadow pictures")?;
    let frame = own.as_ref().unwrap_or(frame);
    let px: &[ShadowPixel] = frame.host_slice(BufferId::ShadowPixels)?;
    let most = px.iter().map(|p| p.samples).fold(0.0f32, f32::max).max(1.0);
    let spp: Vec<u8> = px
        .iter()
        .flat_map(|p| colormap((p.samples / most) as f64))
        .collect();
    let visibility: Vec<u8> = px
        .iter()
        .flat_map(|p| {
            let v = if p.weight > 0.0 {
                p.visible / p.weight
            } else {
                0.0
            };
            [(v.clamp(0.0, 1.0) * 255.0).round() as u8; 3]
        })
        .collect();
    Ok([("shadow_spp", spp), ("shadow_visibility", visibility)])
}
