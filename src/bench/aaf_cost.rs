//! `aaf-cost` (issue 15; only when asked): the AAF filters' cost against the scene's geometry.
//! The seed (Wang 2013 §3.6) reports the soft-shadow filter at ≈ 5 ms for 640 × 480 on a
//! GTX 570 "whether 0.2K or 309K vertices": the filter works on image-space buffers only, so
//! its cost should not follow the triangle count, while the sampling passes and the path
//! tracer, which trace rays through the BVH, should.
//!
//! The scene: Grids (scenes/grids.toml: its camera, sphere light and ground plane) with the
//! three grids replaced by one UV sphere tessellated in code ([`occluder_scene`]) at 0.2K to
//! 200K triangles (a 1000× range), and up to three bounces so that the diffuse ground plane has
//! indirect light for `aaf-indirect`. For each triangle count and each filter, at 256² (quick:
//! 64²), with 16 path samples per pixel and the filter's default sampling:
//!
//! - `filter_ms`: the filter's kernel time (OpenCL profiling events), best of several runs
//!   after a warm-up, on the same frame;
//! - `passes_ms`: the sampling passes' kernel time (the shadow passes for aaf-shadows, the
//!   indirect passes for aaf-indirect), best of the same number of renders;
//! - `path_ms`: the path tracer's kernel time for the 16 samples, best of those renders;
//! - `average_spp`: the passes' average samples per pixel (Σn / N²), which the adaptive pass
//!   sets from the geometry (it changes the passes' time as well as the triangle count does).
//!
//! Everything is measured anew on every run (nothing resumed), so the rows are side by side.

use std::time::Duration;

use anyhow::{Result, bail};
use glam::{Vec2, Vec3};

use super::plot::{Chart, Series, line_chart};
use super::study::{STUDY_SEED, StudyScene, options, sizes};
use super::table::{ResultTable, num};
use super::{Context, bar};
use crate::filters::Configured;
use crate::filters::aaf_indirect::{AafIndirect, AafIndirectSettings};
use crate::filters::aaf_shadows::{AafShadowSettings, AafShadows};
use crate::layout::outputs::OutputSet;
use crate::render::Renderer;
use crate::scene::assets::builder::{PartBuilder, Xf, diffuse};
use crate::scene::{Scene, Triangle};

/// Occluder triangle counts asked for (the sphere's tessellation gets within a few per cent).
pub const TRIANGLES: [usize; 4] = [200, 2_000, 20_000, 200_000];

/// Path samples per pixel of every render (as the aaf-shadows study's AAF rows).
const PATH_SPP: u32 = 16;

/// Bounces of the study scene (Grids has 1: direct light only); 3 gives the ground plane
/// indirect light from the sphere for aaf-indirect.
const MAX_DEPTH: u32 = 3;

/// The sphere occluder: centre and radius, under Grids' light (centre (0.5, 4.5, −0.8),
/// radius 0.8) and over its ground plane (y = 0, side 8), so its penumbra falls in view.
const SPHERE_CENTRE: Vec3 = Vec3::new(0.0, 1.2, 0.0);
const SPHERE_RADIUS: f32 = 0.7;

pub const COLUMNS: [&str; 8] = [
    "size",
    "triangles",
    "filter",
    "filter_ms",
    "passes_ms",
    "path_ms",
    "average_spp",
    "runs",
];

/// A UV sphere of about `triangles` triangles: nv ≈ √(n/4) rings of nu ≈ 2 nv segments,
/// 2 nu nv triangles less the 2 nu degenerate ones at the poles (the builder drops them), so
/// nu = n / (2 (nv − 1)).
pub fn sphere_part(triangles: usize) -> crate::scene::mesh::MeshPart {
    let nv = ((triangles as f64 / 4.0).sqrt().round() as usize).max(3);
    let nu = ((triangles as f64 / (2.0 * (nv - 1) as f64)).round() as usize).max(3);
    let mut b = PartBuilder::new("occluder", diffuse("occluder", [0.7, 0.45, 0.3]));
    let xf = Xf::translate(SPHERE_CENTRE);
    b.grid(&xf, nu, nv, Vec2::ONE, |u, v| {
        let (phi, theta) = (std::f32::consts::TAU * u, std::f32::consts::PI * v);
        let n = Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        );
        (SPHERE_RADIUS * n, n)
    });
    b.finish()
}

/// Grids with its grids replaced by [`sphere_part`] of about `triangles` triangles (in the
/// grids' material and the first grid's object id), and [`MAX_DEPTH`] bounces.
pub fn occluder_scene(grids: &Scene, triangles: usize) -> Result<Scene> {
    let Some(floor) = grids.materials.iter().position(|m| m.name == "floor") else {
        bail!("grids.toml has no `floor` material: the aaf-cost study keeps its ground plane");
    };
    let Some(occluder) = grids.triangles.iter().find(|t| t.material != floor as u32) else {
        bail!("grids.toml has no occluder: the aaf-cost study replaces its grids");
    };
    let (material, object) = (occluder.material, occluder.object);
    let mut s = grids.clone();
    s.triangles.retain(|t| t.material == floor as u32);
    let part = sphere_part(triangles);
    s.triangles.extend(part.indices.iter().map(|idx| Triangle {
        p: idx.map(|i| part.positions[i as usize]),
        n: idx.map(|i| part.normals[i as usize]),
        uv: idx.map(|i| part.uvs[i as usize]),
        material,
        object,
    }));
    s.render.max_depth = MAX_DEPTH;
    Ok(s)
}

/// What one filter's renders and runs measured (best of each).
struct Measured {
    filter: Duration,
    passes: Duration,
    path: Duration,
    average_spp: f64,
}

/// Renders `study` `runs` times with `c`'s sampling (each render: the passes, then
/// [`PATH_SPP`] path samples) and runs `c` on the last frame once to warm up and `runs` times.
fn measure(ctx: &Context, study: &StudyScene, c: &Configured, runs: usize) -> Result<Measured> {
    let s = sizes_of(ctx);
    let mut o = options(&study.scene, &s, study.arrays.params.seed);
    o.outputs = OutputSet::colour().union(c.needs());
    c.adjust_render(&mut o);
    let mut r = Renderer::with_arrays(ctx.gpu.clone(), &study.scene, study.arrays.clone(), &o)?;
    let mut m = Measured {
        filter: Duration::MAX,
        passes: Duration::MAX,
        path: Duration::MAX,
        average_spp: 0.0,
    };
    for _ in 0..runs {
        r.reset()?;
        let launch = r.render_samples(PATH_SPP)?;
        let (passes, spp) = match (r.shadow_stats(), r.indirect_stats()) {
            (Some((_, st)), _) => (st.kernel_time, st.average_spp),
            (None, Some((_, st))) => (st.kernel_time, st.average_spp),
            (None, None) => bail!("{}: the render has no sampling passes", c.name()),
        };
        m.passes = m.passes.min(passes);
        m.path = m.path.min(launch.kernel_time);
        m.average_spp = spp;
    }
    let frame = r.frame();
    let mut prepared = c.prepare(frame.info(), &ctx.gpu)?;
    prepared.run(&frame)?;
    for _ in 0..runs {
        m.filter = m.filter.min(prepared.run(&frame)?.time());
    }
    Ok(m)
}

/// The study's image size: 256² (quick: 64²), or `--size`.
fn sizes_of(ctx: &Context) -> super::study::Sizes {
    let mut s = sizes(ctx);
    let side = ctx.size.unwrap_or(if ctx.quick { 64 } else { 256 });
    (s.width, s.height) = (side, side);
    s
}

/// `aaf-cost` (module docs).
pub fn aaf_cost(ctx: &Context) -> Result<()> {
    let path = ctx.scene_file("grids")?;
    if !path.exists() {
        bail!(
            "the aaf-cost study builds on {}, which is missing",
            path.display()
        );
    }
    let grids = crate::scene::load_scene(&path)?;
    let s = sizes_of(ctx);
    let size = format!("{}x{}", s.width, s.height);
    let runs = if ctx.quick { 2 } else { 5 };
    let mut t = ctx.table("aaf-cost", &COLUMNS, 3, true)?;
    let pb = bar(ctx, 2 * TRIANGLES.len() as u64, "aaf-cost");
    for &n in &TRIANGLES {
        let scene = occluder_scene(&grids, n)?;
        let triangles = scene.triangles.len();
        let study = StudyScene::from_scene("aaf-cost", scene, &s, STUDY_SEED)?;
        let filters = [
            Configured::typed::<AafShadows>(AafShadowSettings::default(), &study.info)?,
            Configured::typed::<AafIndirect>(AafIndirectSettings::default(), &study.info)?,
        ];
        for c in &filters {
            pb.set_message(format!("aaf-cost: {triangles} triangles, {}", c.name()));
            let m = measure(ctx, &study, c, runs)?;
            let ms = |d: Duration| num(d.as_secs_f64() * 1e3);
            t.push(vec![
                size.clone(),
                triangles.to_string(),
                c.name().to_string(),
                ms(m.filter),
                ms(m.passes),
                ms(m.path),
                num(m.average_spp),
                runs.to_string(),
            ])?;
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    report(ctx, &t, &size)
}

/// A column of one filter's rows as (triangles, value), by triangle count.
fn column(t: &ResultTable, filter: &str, name: &str) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = t
        .records()
        .iter()
        .filter(|r| r["filter"] == filter)
        .filter_map(|r| Some((r["triangles"].parse().ok()?, r[name].parse().ok()?)))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// Largest over smallest value of a column (how much it grew over the range).
fn spread(points: &[(f64, f64)]) -> f64 {
    let hi = points.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    let lo = points.iter().map(|p| p.1).fold(f64::MAX, f64::min);
    hi / lo
}

/// aaf-cost.md (the table, and each column's spread over the triangle range) and the figure.
fn report(ctx: &Context, t: &ResultTable, size: &str) -> Result<()> {
    let filters = ["aaf-shadows", "aaf-indirect"];
    let parts = [
        ("filter_ms", "filter"),
        ("passes_ms", "sampling passes"),
        ("path_ms", "path tracer (16 spp)"),
    ];
    let mut md = format!(
        "# AAF cost against the scene's geometry (issue 15)\n\n\
         `noisefree bench --study aaf-cost`: Grids' camera, sphere light and ground plane with \
         one UV sphere of {} to {} triangles (generated in code, src/bench/aaf_cost.rs) as the \
         occluder, {MAX_DEPTH} bounces, {size}, {PATH_SPP} path samples per pixel, each \
         filter's default sampling. Kernel times from OpenCL profiling events, best of `runs` \
         renders (passes, path tracer) and of `runs` filter runs after a warm-up. \
         `average_spp`: the sampling passes' Σn / N².\n\n{}\n\
         Largest over smallest time across the triangle counts:\n\n\
         | filter | filter | sampling passes | path tracer |\n|---|---|---|---|\n",
        TRIANGLES[0],
        TRIANGLES[TRIANGLES.len() - 1],
        t.markdown()
    );
    let mut series = Vec::new();
    for f in filters {
        md.push_str(&format!("| {f} |"));
        for (col, label) in parts {
            let points = column(t, f, col);
            md.push_str(&format!(" {:.2} |", spread(&points)));
            series.push(Series {
                label: format!("{f}: {label}"),
                points,
            });
        }
        md.push('\n');
    }
    md.push_str("\nFigure: `aaf-cost.png` (kernel ms against triangles, log-log).\n");
    std::fs::write(ctx.out.join("aaf-cost.md"), md)?;
    line_chart(
        &ctx.out.join("aaf-cost.png"),
        &Chart {
            title: format!("AAF cost against triangles ({size})"),
            x_label: "triangles".into(),
            y_label: "kernel ms".into(),
            log_x: true,
            log_y: true,
        },
        &series,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sphere_has_the_triangles_asked_for_within_a_few_per_cent() {
        for n in TRIANGLES {
            let got = sphere_part(n).indices.len() as f64;
            // 2 nu (nv − 1): 204, 2016, 20 020 and 199 808 (the rounding of nu and nv).
            assert!((got / n as f64 - 1.0).abs() < 0.025, "{n}: {got}");
        }
    }
}
