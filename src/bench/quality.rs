//! Quality study (thesis §7.3, Fig. 7.18): every scene, unfiltered and with each filter, against
//! the ground truth, with contact sheets.

use anyhow::Result;

use super::plot::{contact_sheet, half_size};
use super::study::{
    Candidate, STUDY_SEED, StudyScene, methods_markdown, metric_cells, reference_image, sizes,
};
use super::table::{distinct, num};
use super::{Context, bar};
use crate::filters::FilterKind;
use crate::filters::ddf::Ddf;
use crate::imaging::{RgbImage, write_exr, write_png};

/// Study 2 (thesis §7.3, Fig. 7.18): every scene, unfiltered and filtered, against the
/// reference; a contact sheet per scene.
pub fn quality(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let columns = [
        "scene", "method", "spp", "pass_spp", "mse_luv", "rel_mse", "mse_rgb", "ssim", "filter_s",
    ];
    let mut t = ctx.table("quality", &columns, 3, fresh)?;
    let images = ctx.out.join("images");
    std::fs::create_dir_all(&images)?;
    let ddf_spp: &[u32] = if ctx.quick { &[8] } else { &[8, 16, 32] };
    let oidn = super::oidn::Oidn::find();
    if oidn.is_none() {
        ctx.say(super::oidn::NOT_SET_UP);
    }
    let pb = bar(ctx, ctx.scenes.len() as u64, "quality");
    for path in &ctx.scenes {
        let study = StudyScene::load(path, &s, STUDY_SEED)?;
        let name = study.name.clone();
        pb.set_message(format!("quality: {name}"));
        let reference = reference_image(ctx, path, &s)?;
        let mut tiles: Vec<(String, RgbImage)> = vec![(
            format!("reference {} spp", s.reference_spp),
            reference.clone(),
        )];
        // (candidate, spp) cells: unfiltered at 8, the thesis's filter at 8/16/32, the others
        // at 8: every registered filter, the path-density chains, the thesis's filter with
        // holes and without the sky case, the regression fit without its selection and with
        // the guided candidate, and OIDN's qualities when it is set up.
        let methods = study.methods()?;
        let mut variants = study.thesis_variants()?;
        variants.extend(study.chains()?);
        variants.extend(study.bmfr_variants()?);
        let mut cells: Vec<(Candidate, u32)> = Vec::new();
        for c in Candidate::all(&methods, &variants, oidn.as_ref())
            .into_iter()
            .filter(|c| ctx.wants(&c.label()))
        {
            let thesis = matches!(&c, Candidate::Filter { label, .. } if label == Ddf::NAME);
            let spps: &[u32] = if thesis { ddf_spp } else { &[8] };
            for &spp in spps {
                cells.push((c.clone(), spp));
            }
        }
        for (candidate, spp) in cells {
            let label = candidate.label();
            let key = vec![name.clone(), label.clone(), spp.to_string()];
            let png = images.join(format!("{name}-{label}-{spp}spp.png"));
            let exr = png.with_extension("exr");
            if t.has(&key) && exr.exists() {
                tiles.push((
                    format!("{label} {spp} spp"),
                    crate::imaging::read_exr_rgb(&exr)?,
                ));
                continue;
            }
            ctx.say(&format!("quality: {name} {label} {spp} spp"));
            let mut r = study.renderer_for(ctx, &s, candidate.needs(), spp, candidate.filter())?;
            r.render_samples(spp)?;
            let frame = r.frame();
            let mut prepared = candidate.prepare(ctx, frame.info())?;
            prepared.warm_up(&frame)?;
            let (img, time) = prepared.run(&frame)?;
            let secs = time.as_secs_f64();
            write_png(&png, &img, 0.0)?;
            write_exr(&exr, &img)?;
            if !t.has(&key) {
                let mut row = key;
                row.push(num(frame.pass_spp()?));
                row.extend(metric_cells(&img, &reference)?);
                row.push(num(secs));
                t.push(row)?;
            }
            tiles.push((format!("{label} {spp} spp"), img));
        }
        let refs: Vec<(String, &RgbImage)> = tiles.iter().map(|(l, i)| (l.clone(), i)).collect();
        // The full-size sheet stays with the images (not committed: megabytes per scene).
        contact_sheet(&images.join(format!("quality-{name}.png")), &refs, 4, 0.0)?;
        // A small sheet for documentation: reference, unfiltered 8 spp, and each filter at 8 spp.
        let small: Vec<(String, RgbImage)> = tiles
            .iter()
            .filter(|(l, _)| l.starts_with("reference") || l.ends_with(" 8 spp"))
            .map(|(l, i)| (l.clone(), half_size(i)))
            .collect();
        let small_refs: Vec<(String, &RgbImage)> =
            small.iter().map(|(l, i)| (l.clone(), i)).collect();
        contact_sheet(
            &ctx.out.join(format!("quality-{name}-small.png")),
            &small_refs,
            small.len(),
            0.0,
        )?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mut md = String::from(
        "# Quality against the reference (thesis §7.3, Fig. 7.18)\n\n\
         Every method on every scene, against the cached reference; MSE in CIELUV is the thesis's\n\
         metric. `filter_s` is the filter's wall-clock time on this machine.\n\n",
    );
    md.push_str(&methods_markdown());
    // Every scene the CSV holds: runs over a few scenes at a time add up to one report.
    for name in distinct(&t.records(), "scene") {
        md.push_str(&format!(
            "![{name}](quality-{name}-small.png)\n\nFull size, with every spp: \
             `images/quality-{name}.png` (written by the run, not kept in git).\n\n"
        ));
    }
    md.push_str(&t.markdown());
    std::fs::write(ctx.out.join("quality.md"), md)?;
    Ok(())
}
