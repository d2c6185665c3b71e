//! Quality study (thesis §7.3, Fig. 7.18): every scene, unfiltered and with each filter, against
//! the ground truth, with contact sheets.

use anyhow::Result;

use super::plot::{contact_sheet, half_size};
use super::study::{
    STUDY_SEED, methods, metric_cells, reference_image, renderer_for, scene_name, sizes,
};
use super::table::{distinct, num};
use super::{Context, bar};
use crate::filters::method::Method;
use crate::imaging::{RgbImage, write_exr, write_png};
use crate::render::Outputs;
use crate::scene;

/// Study 2 (thesis §7.3, Fig. 7.18): every scene, unfiltered and filtered, against the
/// reference; a contact sheet per scene.
pub fn quality(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let columns = [
        "scene", "method", "spp", "mse_luv", "rel_mse", "mse_rgb", "ssim", "filter_s",
    ];
    let mut t = ctx.table("quality", &columns, 3, fresh)?;
    let images = ctx.out.join("images");
    std::fs::create_dir_all(&images)?;
    let ddf_spp: &[u32] = if ctx.quick { &[8] } else { &[8, 16, 32] };
    let pb = bar(ctx, ctx.scenes.len() as u64, "quality");
    for path in &ctx.scenes {
        let name = scene_name(path);
        pb.set_message(format!("quality: {name}"));
        let scene = scene::load_scene(path)?;
        let reference = reference_image(ctx, path, &s)?;
        let mut tiles: Vec<(String, RgbImage)> = vec![(
            format!("reference {} spp", s.reference_spp),
            reference.clone(),
        )];
        // (method, spp) cells: unfiltered at 8, ours at 8/16/32, RPF and à-trous at 8.
        let mut cells: Vec<(Option<Method>, u32)> = vec![(None, 8)];
        for m in methods(&scene) {
            let spps: Vec<u32> = if m.name() == "ddf" {
                ddf_spp.to_vec()
            } else {
                vec![8]
            };
            for spp in spps {
                cells.push((Some(m.clone()), spp));
            }
        }
        for (method, spp) in cells {
            let label = method.as_ref().map_or("unfiltered", |m| m.name());
            let key = vec![name.clone(), label.to_string(), spp.to_string()];
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
            let outputs = method
                .as_ref()
                .map_or(Outputs::default(), |m| m.outputs(spp));
            let mut r = renderer_for(ctx, &scene, &s, STUDY_SEED, outputs)?;
            r.render_samples(spp)?;
            let (img, secs) = match &method {
                None => (r.read_buffers()?.beauty(), 0.0),
                Some(m) => {
                    let mut f = m.prepare(&ctx.gpu, &scene, &r)?;
                    f.show_progress(!ctx.quiet);
                    let run = f.run(&r)?;
                    (run.image, run.wall_time.as_secs_f64())
                }
            };
            write_png(&png, &img, 0.0)?;
            write_exr(&exr, &img)?;
            if !t.has(&key) {
                let mut row = key;
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
