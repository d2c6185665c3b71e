//! What the studies share: a scene's name in the tables and, for the quality studies (quality,
//! accuracy-time, sweep), image sizes, the methods compared, the ground-truth image, the metric
//! cells of a row and the renderer of a study's noisy images.

use std::path::Path;

use anyhow::Result;

use super::Context;
use super::ground_truth::{self, ReferenceRequest};
use super::table::num;
use crate::filters::{Configured, FilterRequest, Registry};
use crate::imaging::RgbImage;
use crate::layout::outputs::{Output, OutputSet};
use crate::metrics;
use crate::render::{RenderOptions, Renderer, SceneArrays, SceneInfo};
use crate::scene::{self, Scene};

/// Resolution, reference spp and the spp of the studies, full or quick.
pub struct Sizes {
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
}

pub fn sizes(ctx: &Context) -> Sizes {
    sizes_for(ctx.quick, ctx.reference_spp)
}

/// The image sizes of a run (`--quick`) and its references' spp (`--reference-spp`).
pub fn sizes_for(quick: bool, reference_spp: Option<u32>) -> Sizes {
    if quick {
        Sizes {
            width: 64,
            height: 64,
            reference_spp: reference_spp.unwrap_or(256),
        }
    } else {
        Sizes {
            width: 512,
            height: 512,
            reference_spp: reference_spp.unwrap_or(ground_truth::DEFAULT_REFERENCE_SPP),
        }
    }
}

pub(super) fn scene_name(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// A scene of a study at the study's size and seed, with its arrays built once for every
/// renderer of the study and the scene information the filters specialise to.
pub struct StudyScene {
    pub name: String,
    pub scene: Scene,
    pub arrays: SceneArrays,
    pub info: SceneInfo,
}

impl StudyScene {
    pub fn load(path: &Path, s: &Sizes, seed: u32) -> Result<StudyScene> {
        let scene = scene::load_scene(path)?;
        let o = options(&scene, s, seed);
        let arrays = SceneArrays::build(&scene, &o.frame)?;
        let info = SceneInfo::new(&scene, &arrays);
        Ok(StudyScene {
            name: scene_name(path),
            scene,
            arrays,
            info,
        })
    }

    /// A renderer gathering `outputs` (and, for per-sample outputs, `spp` samples of each
    /// pixel).
    pub fn renderer(
        &self,
        ctx: &Context,
        s: &Sizes,
        outputs: OutputSet,
        spp: u32,
    ) -> Result<Renderer> {
        let mut o = options(&self.scene, s, self.arrays.params.seed);
        o.outputs = outputs;
        if outputs.contains(Output::Samples) {
            o.sample_capacity = spp;
        }
        Renderer::with_arrays(ctx.gpu.clone(), &self.scene, self.arrays.clone(), &o)
    }

    /// The thesis's own variants of its filter, as extra cells of the quality study: with
    /// holes (Fig. 6.12) and, where the scene has an environment light, without the sky
    /// special case (Figs. 6.13, 7.19). (label, filter).
    pub fn thesis_variants(&self) -> Result<Vec<(String, Configured)>> {
        use crate::filters::FilterKind;
        use crate::filters::ddf::{Ddf, DdfSettings};
        let mut v = vec![(
            format!("{}-holes", Ddf::NAME),
            Configured::typed::<Ddf>(
                DdfSettings {
                    holes: true,
                    ..Default::default()
                },
                &self.info,
            )?,
        )];
        if self.info.has("HAS_ENV") {
            v.push((
                format!("{}-nosky", Ddf::NAME),
                Configured::typed::<Ddf>(
                    DdfSettings {
                        sky: crate::filters::Auto::Set(false),
                        ..Default::default()
                    },
                    &self.info,
                )?,
            ));
        }
        Ok(v)
    }

    /// The filters compared: every registered filter with its defaults (Table 7.2 for the
    /// thesis's), specialised to this scene.
    pub fn methods(&self) -> Result<Vec<Configured>> {
        let r = Registry::builtin();
        r.filters()
            .iter()
            .map(|f| r.configure(*f, &FilterRequest::default(), &self.info))
            .collect()
    }
}

/// The compared filters and their default settings, for the reports (`auto` settings are
/// decided per scene; `noisefree render SCENE --filter NAME --explain` shows the decisions).
pub fn methods_markdown() -> String {
    let mut md = String::from("Settings of the compared filters (their defaults):\n\n");
    for f in Registry::builtin().filters() {
        let text = crate::filters::settings::describe(&f.defaults(), f.fields());
        let inline: Vec<&str> = text.lines().collect();
        md.push_str(&format!(
            "- **{}** ({}): `{}`\n",
            f.name(),
            f.summary(),
            inline.join("`, `")
        ));
    }
    md.push('\n');
    md
}

/// Filters that read every stored sample (RPF) cost time and memory in proportion to the
/// samples; their curves stop at 8 spp, the spp of the headline.
pub fn reads_every_sample(c: &Configured) -> bool {
    c.needs().contains(Output::Samples)
}

fn options(scene: &Scene, s: &Sizes, seed: u32) -> RenderOptions {
    let mut o = RenderOptions::for_scene(scene);
    o.frame.width = s.width;
    o.frame.height = s.height;
    o.frame.seed = seed;
    o
}

/// The ground truth the studies compare a scene's images with.
pub fn reference_request(path: &Path, s: &Sizes) -> ReferenceRequest {
    ReferenceRequest {
        scene: path.to_path_buf(),
        width: s.width,
        height: s.height,
        spp: s.reference_spp,
        seed: ground_truth::REFERENCE_SEED,
    }
}

pub(super) fn reference_image(ctx: &Context, path: &Path, s: &Sizes) -> Result<RgbImage> {
    let req = reference_request(path, s);
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

/// The seed of a study's noisy renders (the reference uses another).
pub(super) const STUDY_SEED: u32 = 7;
