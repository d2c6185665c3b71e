//! The path-density study (DeCoro 2009 ch. 5; src/filters/path_density/): per scene, one
//! progressive render taken at 8, 16, 32 and 64 spp, each step the unfiltered image, the
//! path-density filter (k = 10 and 50, accumulated, and k = 50 with the ε-approximate kNN;
//! k = 10 per frame of 4 samples, biased), its chains into the data-driven and à-trous
//! filters, those filters alone, and the α-trimmed means the seed shows failing (10%, 1%, the
//! median), against the cached reference; for the path-density cells also the fractions of
//! samples rejected and down-weighted. The seed's
//! claims to check: the accumulated mode rejects less and less as spp grows (consistent),
//! the per-frame mode does not (a bias that stays), and outlier removal lowers the error where
//! fireflies dominate it (its interior: RMS .0519 → .041 against 1024 spp).
//!
//! Every cell filters the same frame, so the ratios in one row are measured side by side.

use anyhow::Result;

use super::study::{STUDY_SEED, StudyScene, metric_cells, reference_image, sizes};
use super::table::num;
use super::{Context, bar};
use crate::filters::path_density::{DensityMode, PathDensity, PathDensitySettings, Then};
use crate::filters::path_density::{PathDensityKernel, PathDensityParams};
use crate::filters::trimmed::{Trimmed, TrimmedSettings};
use crate::filters::{Configured, FilterKind};
use crate::layout::outputs::OutputSet;
use crate::render::SceneInfo;

/// The progressive steps.
pub const SPP: [u32; 4] = [8, 16, 32, 64];
/// Samples per frame of the per-frame (biased) cells.
pub const FRAME_SPP: u32 = 4;

/// ε of the approximate-kNN cell (against the exact k = 50 cell beside it).
pub const EPSILON: f32 = 1.0;

/// A cell of the study: a path-density setting run by its kernel (so that its densities can be
/// read back), or any configured filter.
enum Method {
    Unfiltered,
    Density(PathDensityParams),
    Filter(Configured),
}

fn pd(k: u32, mode: DensityMode, then: Then) -> PathDensitySettings {
    PathDensitySettings {
        k,
        mode,
        frame_spp: FRAME_SPP,
        then,
        ..Default::default()
    }
}

fn methods(scene: &SceneInfo) -> Result<Vec<(String, Method)>> {
    use DensityMode::*;
    let mut v = vec![
        ("unfiltered".to_string(), Method::Unfiltered),
        (
            "path-density k10".into(),
            Method::Density(pd(10, Accumulated, Then::None).params()),
        ),
        (
            "path-density k50".into(),
            Method::Density(pd(50, Accumulated, Then::None).params()),
        ),
        (
            format!("path-density k50 eps {EPSILON}"),
            Method::Density(
                PathDensitySettings {
                    epsilon: EPSILON,
                    ..pd(50, Accumulated, Then::None)
                }
                .params(),
            ),
        ),
        (
            format!("path-density k10 per-frame {FRAME_SPP} spp (biased)"),
            Method::Density(pd(10, PerFrame, Then::None).params()),
        ),
    ];
    for alpha in [0.1, 0.01, 0.5] {
        let label = if alpha == 0.5 {
            "median".to_string()
        } else {
            format!("trimmed {}%", alpha * 100.0)
        };
        let c = Configured::typed::<Trimmed>(TrimmedSettings { alpha }, scene)?;
        v.push((label, Method::Filter(c)));
    }
    let registry = crate::filters::Registry::builtin();
    for name in ["ddf", "atrous"] {
        let c = registry.configure(registry.get(name)?, &Default::default(), scene)?;
        v.push((name.to_string(), Method::Filter(c)));
    }
    for (then, name) in [(Then::Ddf, "ddf"), (Then::Atrous, "atrous")] {
        let c = Configured::typed::<PathDensity>(pd(10, Accumulated, then), scene)?;
        v.push((format!("path-density k10 -> {name}"), Method::Filter(c)));
    }
    Ok(v)
}

pub fn path_density(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let columns = [
        "scene", "spp", "method", "mse_luv", "rel_mse", "mse_rgb", "ssim", "rejected", "reduced",
        "filter_s",
    ];
    let mut t = ctx.table("path_density", &columns, 3, fresh)?;
    let pb = bar(ctx, ctx.scenes.len() as u64, "path-density");
    for path in &ctx.scenes {
        let study = StudyScene::load(path, &s, STUDY_SEED)?;
        let name = study.name.clone();
        pb.set_message(format!("path-density: {name}"));
        let methods = methods(&study.info)?;
        let key = |spp: u32, label: &str| vec![name.clone(), spp.to_string(), label.to_string()];
        if SPP
            .iter()
            .all(|&n| methods.iter().all(|(l, _)| t.has(&key(n, l))))
        {
            pb.inc(1);
            continue;
        }
        let reference = reference_image(ctx, path, &s)?;
        let needs = methods
            .iter()
            .fold(OutputSet::colour(), |acc, (_, m)| match m {
                Method::Filter(c) => acc.union(c.needs()),
                _ => acc.union(PathDensity::needs(&PathDensitySettings::default())),
            });
        let last = *SPP.last().expect("steps");
        let mut r = study.renderer(ctx, &s, needs, last)?;
        let mut done = 0;
        for &spp in &SPP {
            r.render_samples(spp - done)?;
            done = spp;
            let frame = r.frame();
            for (label, m) in &methods {
                if t.has(&key(spp, label)) {
                    continue;
                }
                ctx.say(&format!("path-density: {name} {spp} spp {label}"));
                let (image, secs, fractions) = match m {
                    Method::Unfiltered => (frame.beauty()?, 0.0, None),
                    Method::Density(p) => {
                        let mut k = PathDensityKernel::new(ctx.gpu.clone(), *p)?;
                        let run = k.run(&frame)?;
                        let f = k.densities()?.fractions();
                        (run.image, run.kernel_time.as_secs_f64(), Some(f))
                    }
                    Method::Filter(c) => {
                        let run = c.prepare(frame.info(), &ctx.gpu)?.run(&frame)?;
                        (run.image, run.wall_time.as_secs_f64(), None)
                    }
                };
                let mut row = key(spp, label);
                row.extend(metric_cells(&image, &reference)?);
                match fractions {
                    Some((rejected, reduced)) => row.extend([num(rejected), num(reduced)]),
                    None => row.extend([String::new(), String::new()]),
                }
                row.push(num(secs));
                t.push(row)?;
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let md = format!(
        "# The path-density filter (DeCoro 2009 ch. 5)\n\n\
         One progressive render per scene ({}x{}, seed {STUDY_SEED}) taken at {SPP:?} spp, \
         against the {}-spp reference. `rejected` / `reduced`: fractions of the samples with \
         weight 0 / between 0 and 1. The per-frame cells filter each frame of {FRAME_SPP} \
         samples alone and average the frames: biased by design. `filter_s`: kernel time \
         for the path-density cells, wall-clock time for the others (a loaded machine).\n\n{}",
        s.width,
        s.height,
        s.reference_spp,
        t.markdown()
    );
    std::fs::write(ctx.out.join("path_density.md"), md)?;
    Ok(())
}
