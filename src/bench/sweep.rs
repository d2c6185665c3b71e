//! Parameter sweep of Table 7.1 (one parameter at a time from its base values) at each kernel
//! width of the thesis (11, 15, 21; Figs. 7.13-7.15, Appendix B), the three readings of the
//! direction factor of eq. 6.14, the variance scales s_f the thesis leaves open, and hypothesis
//! 3 (kernel size, Fig. 7.17) with the final parameters of Table 7.2 on the thesis's three
//! scenes and every depth-of-field variant. The report and the rule that derives our defaults
//! from these rows are in `sweep_report.rs`.

use anyhow::Result;

use super::Context;
use super::study::{STUDY_SEED, StudyScene, metric_cells, reference_image, sizes};
use super::table::num;
use crate::filters::Configured;
use crate::filters::ddf::{Ddf, DdfSettings, DirectionTerm};
use crate::layout::outputs::{Output, OutputSet};

/// How a row changes the base settings.
type Set = fn(&mut DdfSettings, f64);

/// A parameter of the sweep: its name, the values tried and how it is set.
pub(super) struct Param {
    pub name: &'static str,
    pub values: &'static [f64],
    set: Set,
}

/// Table 7.1's base values at kernel width `kw`; every variance scale at the neutral 1 (the
/// thesis gives none) and the direction factor as printed.
pub(super) fn sweep_base(kw: u32) -> DdfSettings {
    DdfSettings {
        kw,
        sigma_dc: 0.5,
        sigma_ic: 0.3,
        sigma_f: [1.0, 0.1, 0.1, 0.5, 0.1],
        variance_scale: [1.0; 5],
        direction: DirectionTerm::Thesis,
        ..Default::default()
    }
}

/// The scales tried for each s_f.
const SCALES: &[f64] = &[0.0, 0.1, 1.0, 10.0, 100.0];

/// Table 7.1's rows (the base value among the experimentation values), then the variance
/// scales s_f.
pub(super) fn sweep_params() -> Vec<Param> {
    vec![
        Param {
            name: "sigma_dc",
            values: &[0.10, 0.25, 0.5, 1.00, 2.50],
            set: |s, x| s.sigma_dc = x as f32,
        },
        Param {
            name: "sigma_ic",
            values: &[0.10, 0.25, 0.3, 1.00, 2.50],
            set: |s, x| s.sigma_ic = x as f32,
        },
        Param {
            name: "sigma_depth",
            values: &[0.25, 0.50, 1.0, 2.50, 5.00],
            set: |s, x| s.sigma_f[0] = x as f32,
        },
        Param {
            name: "sigma_normal",
            values: &[0.05, 0.1, 0.25, 0.50, 1.00],
            set: |s, x| s.sigma_f[1] = x as f32,
        },
        Param {
            name: "sigma_texture",
            values: &[0.05, 0.1, 0.25, 0.50, 1.00],
            set: |s, x| s.sigma_f[2] = x as f32,
        },
        Param {
            name: "sigma_direction",
            values: &[0.10, 0.25, 0.5, 1.00, 2.50],
            set: |s, x| s.sigma_f[3] = x as f32,
        },
        // The same row with the other two readings of eq. 6.14's direction factor.
        Param {
            name: "sigma_direction@neighbour",
            values: &[0.10, 0.25, 0.5, 1.00, 2.50],
            set: |s, x| {
                s.direction = DirectionTerm::Neighbour;
                s.sigma_f[3] = x as f32;
            },
        },
        Param {
            name: "sigma_direction@difference",
            values: &[0.10, 0.25, 0.5, 1.00, 2.50],
            set: |s, x| {
                s.direction = DirectionTerm::Difference;
                s.sigma_f[3] = x as f32;
            },
        },
        Param {
            name: "sigma_texture2",
            values: &[0.05, 0.1, 0.25, 0.50, 1.00],
            set: |s, x| s.sigma_f[4] = x as f32,
        },
        Param {
            name: "scale_depth",
            values: SCALES,
            set: |s, x| s.variance_scale[0] = x as f32,
        },
        Param {
            name: "scale_normal",
            values: SCALES,
            set: |s, x| s.variance_scale[1] = x as f32,
        },
        Param {
            name: "scale_texture",
            values: SCALES,
            set: |s, x| s.variance_scale[2] = x as f32,
        },
        Param {
            name: "scale_direction",
            values: SCALES,
            set: |s, x| s.variance_scale[3] = x as f32,
        },
        Param {
            name: "scale_texture2",
            values: SCALES,
            set: |s, x| s.variance_scale[4] = x as f32,
        },
    ]
}

/// The parameters that concern reflections (§7.3: swept on the glossy and outside scenes).
pub(super) const REFLECTION_PARAMS: &[&str] = &[
    "sigma_direction",
    "sigma_direction@neighbour",
    "sigma_direction@difference",
    "sigma_texture2",
    "scale_direction",
    "scale_texture2",
];

/// What the sweep measures on one scene.
struct PlanEntry {
    scene: &'static str,
    /// 8, or 16 with depth of field (§7.3).
    spp: u32,
    /// Table 7.1 rows: all, the reflection ones, or none.
    rows: Rows,
    /// Hypothesis 3 with the final parameters (kw 11, 15, 21, 55).
    hypothesis3: bool,
}

#[derive(PartialEq)]
enum Rows {
    All,
    Reflections,
    None,
}

fn plan(quick: bool) -> Vec<PlanEntry> {
    let e = |scene, spp, rows, hypothesis3| PlanEntry {
        scene,
        spp,
        rows,
        hypothesis3,
    };
    if quick {
        return vec![e("cornell_diffuse", 8, Rows::All, true)];
    }
    vec![
        // The thesis's parameter scenes (§7.3): Cornell diffuse with and without depth of
        // field for every parameter, Cornell glossy and Outside for the reflection ones.
        e("cornell_diffuse", 8, Rows::All, true),
        e("cornell_diffuse_dof", 16, Rows::All, true),
        e("cornell_glossy", 8, Rows::Reflections, true),
        e("outside", 8, Rows::Reflections, true),
        // Hypothesis 3 on every depth-of-field variant.
        e("cornell_glossy_dof", 16, Rows::None, true),
        e("cornell_plane_dof", 16, Rows::None, true),
        e("outside_dof", 16, Rows::None, true),
        e("conference_dof", 16, Rows::None, true),
    ]
}

/// The bundled scenes the sweep renders (and compares with their references).
pub fn sweep_scenes(quick: bool) -> Vec<&'static str> {
    plan(quick).into_iter().map(|e| e.scene).collect()
}

/// The kernel widths of the Table 7.1 sweep (Appendix B: 11 × 11, 15 × 15, 21 × 21).
pub(super) const SWEEP_WIDTHS: &[u32] = &[11, 15, 21];
/// The kernel widths of hypothesis 3 (Fig. 7.17).
pub(super) const HYPOTHESIS3_WIDTHS: &[u32] = &[11, 15, 21, 55];

/// Study 4: the Table 7.1 sweep at each width and hypothesis 3. Rows are keyed (scene, kw,
/// parameter, value); `base` rows hold the base settings at each width.
pub fn sweep(ctx: &Context, fresh: bool) -> Result<()> {
    let s = sizes(ctx);
    let columns = ["scene", "kw", "parameter", "value", "mse_luv", "rel_mse"];
    let mut t = ctx.table("sweep", &columns, 4, fresh)?;
    let widths: &[u32] = if ctx.quick { &[21] } else { SWEEP_WIDTHS };
    // `--scene` narrows the plan to the named scenes (by file name); by default every scene of
    // the plan is a bundled one, so nothing is left out.
    let chosen = |name: &str| {
        ctx.scenes
            .iter()
            .any(|p| p.file_stem().is_some_and(|s| s == name))
    };
    for entry in plan(ctx.quick).into_iter().filter(|e| chosen(e.scene)) {
        let mut runs: Vec<(u32, String, String, DdfSettings)> = Vec::new();
        if entry.rows != Rows::None {
            for &kw in widths {
                runs.push((kw, "base".into(), "-".into(), sweep_base(kw)));
                for p in sweep_params() {
                    if entry.rows == Rows::Reflections && !REFLECTION_PARAMS.contains(&p.name) {
                        continue;
                    }
                    let values = if ctx.quick { &p.values[..2] } else { p.values };
                    for &v in values {
                        let mut st = sweep_base(kw);
                        (p.set)(&mut st, v);
                        runs.push((kw, p.name.to_string(), num(v), st));
                    }
                }
            }
        }
        if entry.hypothesis3 {
            let kws: &[u32] = if ctx.quick {
                &[11, 21]
            } else {
                HYPOTHESIS3_WIDTHS
            };
            for &kw in kws {
                let st = DdfSettings {
                    kw,
                    ..Default::default()
                };
                runs.push((kw, "kw_final".into(), kw.to_string(), st));
            }
        }
        let key = |kw: u32, p: &str, v: &str| {
            vec![
                entry.scene.to_string(),
                kw.to_string(),
                p.to_string(),
                v.to_string(),
            ]
        };
        runs.retain(|(kw, p, v, _)| !t.has(&key(*kw, p, v)));
        if runs.is_empty() {
            continue;
        }
        let path = ctx.scene_file(entry.scene)?;
        let study = StudyScene::load(&path, &s, STUDY_SEED)?;
        let reference = reference_image(ctx, &path, &s)?;
        let outputs = OutputSet::of(&[Output::Colour, Output::Features, Output::Variance]);
        let mut r = study.renderer(ctx, &s, outputs, entry.spp)?;
        ctx.say(&format!(
            "sweep: {} ({} spp, {} cells)",
            entry.scene,
            entry.spp,
            runs.len()
        ));
        r.render_samples(entry.spp)?;
        let frame = r.frame();
        let pb = super::bar(ctx, runs.len() as u64, &format!("sweep: {}", entry.scene));
        for (kw, param, value, st) in runs {
            let m = Configured::typed::<Ddf>(st, &study.info)?;
            let img = m.prepare(frame.info(), &ctx.gpu)?.run(&frame)?.image;
            let cells = metric_cells(&img, &reference)?;
            let mut row = key(kw, &param, &value);
            row.extend([cells[0].clone(), cells[1].clone()]);
            t.push(row)?;
            pb.inc(1);
        }
        pb.finish_and_clear();
    }
    super::sweep_report::write(ctx, &t)
}
