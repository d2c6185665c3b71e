//! What the studies share: a scene's name in the tables and, for the quality studies (quality,
//! accuracy-time, sweep), image sizes, the methods compared, the ground-truth image, the metric
//! cells of a row and the renderer of a study's noisy images.

use std::path::Path;

use anyhow::Result;

use super::Context;
use super::ground_truth::{self, ReferenceRequest};
use super::table::num;
use crate::filters::atrous::AtrousSettings;
use crate::filters::ddf::{DdfSettings, Variant};
use crate::filters::method::Method;
use crate::filters::rpf::{RpfSettings, SceneKind};
use crate::imaging::RgbImage;
use crate::metrics;
use crate::render::{Outputs, RenderOptions, Renderer};
use crate::scene::{Scene, Setting};

/// Resolution, reference spp and the spp of the studies, full or quick.
pub struct Sizes {
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
}

pub fn sizes(ctx: &Context) -> Sizes {
    if ctx.quick {
        Sizes {
            width: 64,
            height: 64,
            reference_spp: 256,
        }
    } else {
        Sizes {
            width: 512,
            height: 512,
            reference_spp: ground_truth::DEFAULT_REFERENCE_SPP,
        }
    }
}

pub(super) fn scene_name(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The filters compared, with the thesis's defaults (Table 7.2 for ours; RPF's sigma^2_8 from
/// the scene's setting).
pub fn methods(scene: &Scene) -> Vec<Method> {
    let kind = if scene.render.setting == Setting::Outdoor {
        SceneKind::Outdoor
    } else {
        SceneKind::Indoor
    };
    vec![
        Method::Ddf {
            settings: DdfSettings::default(),
            variant: Variant::Rows { work_group: 64 },
        },
        Method::Rpf(RpfSettings::for_scene(kind)),
        Method::Atrous(AtrousSettings::default()),
    ]
}

pub(super) fn reference_image(ctx: &Context, path: &Path, s: &Sizes) -> Result<RgbImage> {
    let req = ReferenceRequest {
        scene: path.to_path_buf(),
        width: s.width,
        height: s.height,
        spp: s.reference_spp,
        seed: ground_truth::REFERENCE_SEED,
    };
    ctx.say(&format!(
        "reference: {} ({} spp)",
        path.display(),
        s.reference_spp
    ));
    Ok(ground_truth::get_or_render(&ctx.gpu, &req, &ctx.reference_cache, ctx.quiet)?.0)
}

/// Metrics of `img` against `reference` as table cells: mse_luv, rel_mse, mse_rgb, ssim.
pub(super) fn metric_cells(img: &RgbImage, reference: &RgbImage) -> Result<Vec<String>> {
    let m = metrics::compare(img, reference)?;
    Ok(vec![
        num(m.mse_luv),
        num(m.rel_mse),
        num(m.mse_rgb),
        num(m.ssim),
    ])
}

pub(super) fn renderer_for(
    ctx: &Context,
    scene: &Scene,
    s: &Sizes,
    seed: u32,
    outputs: Outputs,
) -> Result<Renderer> {
    let mut o = RenderOptions::for_scene(scene);
    o.frame.width = s.width;
    o.frame.height = s.height;
    o.frame.seed = seed;
    o.outputs = outputs;
    Renderer::new(ctx.gpu.clone(), scene, &o)
}

/// The seed of a study's noisy renders (the reference uses another).
pub(super) const STUDY_SEED: u32 = 7;
