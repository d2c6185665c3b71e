//! What the studies share: a scene's name in the tables and, for the quality studies (quality,
//! accuracy-time, sweep), image sizes, the methods compared, the ground-truth image, the metric
//! cells of a row and the renderer of a study's noisy images.

use std::path::Path;

use anyhow::Result;

use super::Context;
use super::ground_truth::{self, ReferenceRequest};
use super::table::num;
use crate::filters::{Configured, FilterRequest, Purpose, Registry};
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
    sizes_for(ctx.quick, ctx.reference_spp, ctx.size)
}

/// The image sizes of a run (`--quick`, `--size`) and its references' spp (`--reference-spp`).
pub fn sizes_for(quick: bool, reference_spp: Option<u32>, size: Option<u32>) -> Sizes {
    let (side, spp) = if quick {
        (64, 256)
    } else {
        (512, ground_truth::DEFAULT_REFERENCE_SPP)
    };
    let side = size.unwrap_or(side);
    Sizes {
        width: side,
        height: side,
        reference_spp: reference_spp.unwrap_or(spp),
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
        Self::from_scene(&scene_name(path), scene::load_scene(path)?, s, seed)
    }

    /// A study scene of a scene already loaded (and perhaps changed, e.g. scaled).
    pub fn from_scene(name: &str, scene: Scene, s: &Sizes, seed: u32) -> Result<StudyScene> {
        let o = options(&scene, s, seed);
        let arrays = SceneArrays::build(&scene, &o.frame)?;
        let info = SceneInfo::new(&scene, &arrays);
        Ok(StudyScene {
            name: name.to_string(),
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
        self.renderer_for(ctx, s, outputs, spp, None)
    }

    /// [`StudyScene::renderer`], sampling as `filter` asks ([`Configured::adjust_render`]:
    /// AAF's sample counts, the sheared filter's field and its effect), as `render --filter`
    /// does.
    pub fn renderer_for(
        &self,
        ctx: &Context,
        s: &Sizes,
        outputs: OutputSet,
        spp: u32,
        filter: Option<&Configured>,
    ) -> Result<Renderer> {
        let mut o = options(&self.scene, s, self.arrays.params.seed);
        o.outputs = outputs;
        if outputs.contains(Output::Samples) {
            o.sample_capacity = spp;
        }
        if let Some(f) = filter {
            f.adjust_render(&mut o);
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

    /// The regression filter's variants beside its defaults: without its per-pixel selection
    /// (`bmfr-fit`, the fit alone, as the paper's single frame: what the selection changes),
    /// and with the guided filter as the selection's fourth candidate (`bmfr-guided`, off by
    /// default: what it buys and what it costs). (label, filter).
    pub fn bmfr_variants(&self) -> Result<Vec<(String, Configured)>> {
        use crate::filters::FilterKind;
        use crate::filters::bmfr::{Bmfr, BmfrSettings};
        let fit = BmfrSettings {
            select: false,
            ..Default::default()
        };
        let guided = BmfrSettings {
            guided: true,
            ..Default::default()
        };
        [("fit", fit), ("guided", guided)]
            .into_iter()
            .map(|(label, settings)| {
                Ok((
                    format!("{}-{label}", Bmfr::NAME),
                    Configured::typed::<Bmfr>(settings, &self.info)?,
                ))
            })
            .collect()
    }

    /// The path-density filter's chains (DeCoro 2009 ch. 5: outlier removal first, then a
    /// filter of the inter-pixel variance), as extra cells of the quality and accuracy-time
    /// studies: path-density → ddf, → atrous and → bmfr. (label, filter).
    pub fn chains(&self) -> Result<Vec<(String, Configured)>> {
        use crate::filters::path_density::{PathDensity, PathDensitySettings, Then};
        [
            (Then::Ddf, "ddf"),
            (Then::Atrous, "atrous"),
            (Then::Bmfr, "bmfr"),
        ]
        .into_iter()
        .map(|(then, name)| {
            let settings = PathDensitySettings {
                then,
                ..Default::default()
            };
            Ok((
                format!("path-density->{name}"),
                Configured::typed::<PathDensity>(settings, &self.info)?,
            ))
        })
        .collect()
    }

    /// The filters compared: every registered denoiser with its defaults (Table 7.2 for the
    /// thesis's) and the scene file's `[filter.<name>]` tables (as `render` takes them: room_gi
    /// asks the sheared filter for its GI effect), specialised to this scene, less those that
    /// change nothing here (a shadow filter without a sphere light): [`Configured::applies`].
    pub fn methods(&self) -> Result<Vec<Configured>> {
        let r = Registry::builtin();
        let request = FilterRequest {
            scene: self.scene.filter.settings.clone(),
            scene_origin: self.scene.path.display().to_string(),
            scene_lines: self.scene.filter.lines.clone(),
            ..Default::default()
        };
        let mut methods = Vec::new();
        for f in r.filters() {
            if f.purpose() != Purpose::Denoise {
                continue;
            }
            let c = r.configure(*f, &request, &self.info)?;
            if c.applies() {
                methods.push(c);
            }
        }
        Ok(methods)
    }
}

/// The compared filters and their default settings, for the reports (`auto` settings are
/// decided per scene; `noisefree render SCENE --filter NAME --explain` shows the decisions).
pub fn methods_markdown() -> String {
    let mut md = String::from(
        "Settings of the compared filters (their defaults). A filter has rows only on the \
         scenes where it changes the image (the shadow filters need a sphere light); \
         `pass_spp` counts the samples of a filter's own sampling passes per pixel (AAF's \
         light and indirect samples, the sheared filters' fields), besides `spp` path \
         samples:\n\n",
    );
    let registry = Registry::builtin();
    for f in registry
        .filters()
        .iter()
        .filter(|f| f.purpose() == Purpose::Denoise)
    {
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

pub(super) fn options(scene: &Scene, s: &Sizes, seed: u32) -> RenderOptions {
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

/// What a study compares: the unfiltered image, a registered filter (or one of the thesis's
/// variants of its own), or OIDN beside them.
#[derive(Clone)]
pub enum Candidate<'a> {
    Unfiltered,
    Filter {
        label: String,
        configured: &'a Configured,
    },
    Oidn(&'a super::oidn::Oidn, super::oidn::Quality),
}

/// A candidate ready for frames of one size.
pub enum Prepared<'a> {
    Unfiltered,
    Filter(Box<dyn crate::filters::PreparedFilter>),
    Oidn(&'a super::oidn::Oidn, super::oidn::Quality),
}

impl<'a> Candidate<'a> {
    /// The registered filters (and `extra`, e.g. the thesis's variants), then OIDN's qualities
    /// when it is set up; the unfiltered image first.
    pub fn all(
        methods: &'a [Configured],
        extra: &'a [(String, Configured)],
        oidn: Option<&'a super::oidn::Oidn>,
    ) -> Vec<Candidate<'a>> {
        let mut v = vec![Candidate::Unfiltered];
        v.extend(methods.iter().map(|c| Candidate::Filter {
            label: c.name().to_string(),
            configured: c,
        }));
        v.extend(extra.iter().map(|(label, c)| Candidate::Filter {
            label: label.clone(),
            configured: c,
        }));
        if let Some(o) = oidn {
            v.extend(super::oidn::Quality::ALL.map(|q| Candidate::Oidn(o, q)));
        }
        v
    }

    pub fn label(&self) -> String {
        match self {
            Candidate::Unfiltered => "unfiltered".into(),
            Candidate::Filter { label, .. } => label.clone(),
            Candidate::Oidn(_, q) => q.label(),
        }
    }

    /// The filter, for candidates that are one of ours.
    pub fn filter(&self) -> Option<&'a Configured> {
        match self {
            Candidate::Filter { configured, .. } => Some(configured),
            _ => None,
        }
    }

    /// The outputs the render must gather.
    pub fn needs(&self) -> OutputSet {
        match self {
            Candidate::Unfiltered => OutputSet::colour(),
            Candidate::Filter { configured, .. } => configured.needs(),
            Candidate::Oidn(..) => OutputSet::of(&[Output::Colour, Output::Features]),
        }
    }

    /// Filters that read every stored sample (RPF) cost time and memory in proportion to the
    /// samples; their curves stop at 8 spp, the spp of the headline.
    pub fn reads_every_sample(&self) -> bool {
        self.needs().contains(Output::Samples)
    }

    pub fn prepare(&self, ctx: &Context, frame: &crate::render::FrameInfo) -> Result<Prepared<'a>> {
        Ok(match self {
            Candidate::Unfiltered => Prepared::Unfiltered,
            Candidate::Filter { configured, .. } => {
                let mut f = configured.prepare(frame, &ctx.gpu)?;
                f.show_progress(!ctx.quiet);
                Prepared::Filter(f)
            }
            Candidate::Oidn(o, q) => Prepared::Oidn(o, *q),
        })
    }
}

impl Prepared<'_> {
    /// Runs a device filter once untimed: drivers such as PoCL finish compiling a kernel at its
    /// first launch, which is not the filter's cost per frame. (Host filters and OIDN warm up
    /// on their own or need not.)
    pub fn warm_up(&mut self, frame: &crate::render::Frame) -> Result<()> {
        if let Prepared::Filter(f) = self
            && f.interactive()
        {
            f.run(frame)?;
        }
        Ok(())
    }

    /// The image and the time of the filter alone (wall-clock for our filters, OIDN's own
    /// median time with prefiltering for OIDN; 0 unfiltered).
    pub fn run(&mut self, frame: &crate::render::Frame) -> Result<(RgbImage, std::time::Duration)> {
        Ok(match self {
            Prepared::Unfiltered => (frame.beauty()?, std::time::Duration::ZERO),
            Prepared::Filter(f) => {
                // After `warm_up`: the timed run does the frame's whole work again.
                f.forget();
                let run = f.run(frame)?;
                (run.image, run.wall_time)
            }
            Prepared::Oidn(o, q) => {
                let run = o.denoise(frame, *q, 3)?;
                let t = run.median_total();
                (run.image, std::time::Duration::from_secs_f64(t))
            }
        })
    }
}
