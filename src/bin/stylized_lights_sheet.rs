//! The contact sheet of the stylized-shadows filter on two sphere lights stylized apart
//! (DeCoro 2009 eq. 3.1: each light has its own S_l):
//! `cargo run --release --bin stylized_lights_sheet -- [OUT_DIR] [SCENE]` (defaults
//! results/stylized-lights and scenes/decoro/stylized_two_lights.toml).
//!
//! One render with the shadow output's two planes, then the filter's stages as edits: each
//! light's contour and distance once, a light's blur again only when its α changes, the
//! compose alone for i, s and b. Cells left to right, as listed in `CELLS`; writes
//! contact-sheet.png, unfiltered.png (the path tracer's soft shadows) and timings.md.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context as _, Result};
use noisefree::filters::stylized::{Controls, StylizedKernel, StylizedSettings};
use noisefree::gpu::Gpu;
use noisefree::imaging::{to_srgb8, write_png, write_rgb8_png};
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::{LightPlanes, RenderOptions, Renderer};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 192;
const SPP: u32 = 16;
const BORDER: u32 = 4;

/// Constant controls (i, s, b, α): i and s in the L8-averaged world distance of eq. 3.2 (the
/// scene's metres), b in [0, 1], α in pixels.
fn c(i: f32, s: f32, b: f32, a: f32) -> Controls {
    Controls {
        inflation: [i, 0.0, 0.0],
        softness: [s, 0.0, 0.0],
        brightness: [b, 0.0, 0.0],
        abstraction: [a, 0.0, 0.0],
    }
}

/// Each cell: its caption and the controls of light 0 (warm, left) and light 1 (cool, right).
fn cells() -> [(&'static str, Controls, Controls); 5] {
    let id = c(0.0, 0.0, 0.0, 0.0);
    [
        ("both hard (identity)", id, id),
        ("warm inflated + soft", c(0.15, 0.3, 0.0, 0.0), id),
        ("cool abstracted + bright", id, c(0.0, 0.0, 0.5, 8.0)),
        (
            "warm deflated, cool soft",
            c(-0.08, 0.0, 0.0, 0.0),
            c(0.05, 0.5, 0.0, 0.0),
        ),
        (
            "both: blobs",
            c(0.1, 0.1, 0.3, 12.0),
            c(0.1, 0.1, 0.3, 12.0),
        ),
    ]
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn main() -> Result<()> {
    let mut args = std::env::args_os().skip(1);
    let out = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| "results/stylized-lights".into());
    let scene_path = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| "scenes/decoro/stylized_two_lights.toml".into());
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let scene = noisefree::scene::load_scene(&scene_path)?;
    let gpu = Gpu::open(None)?;
    let settings = StylizedSettings {
        light_count: 2,
        ..Default::default()
    };
    let mut o = RenderOptions::for_scene(&scene);
    o.frame.width = WIDTH;
    o.frame.height = HEIGHT;
    o.outputs = OutputSet::of(&[Output::Shadows]);
    o.shadows = settings.sampling();
    assert_eq!(o.shadows.lights, LightPlanes::of(&[0, 1]));
    let mut renderer = Renderer::new(gpu.clone(), &scene, &o)?;
    renderer.render_samples(SPP)?;
    let frame = renderer.frame();
    write_png(&out.join("unfiltered.png"), &frame.beauty()?, 0.0)?;

    let device = gpu.summary.name.clone();
    let mut k = StylizedKernel::new(gpu, &settings, &[0, 1], WIDTH, HEIGHT)?;
    let first = k.filter(&frame)?;
    let distance = first.kernel_time.unwrap_or_default();
    let cells = cells();
    let cols = cells.len() as u32;
    let sw = cols * WIDTH + (cols + 1) * BORDER;
    let sh = HEIGHT + 2 * BORDER;
    let mut sheet = vec![255u8; (sw * sh * 3) as usize];
    let mut edits = Vec::new();
    for (n, (_, c0, c1)) in cells.iter().enumerate() {
        k.set_light_controls(0, c0)?;
        k.set_light_controls(1, c1)?;
        // `filter` re-runs a light's blur only when its α changed, and the compose.
        let run = k.filter(&frame)?;
        edits.push(run.kernel_time.unwrap_or_default());
        let rgb = to_srgb8(&run.image, 0.0);
        let x0 = BORDER + n as u32 * (WIDTH + BORDER);
        for y in 0..HEIGHT {
            let src = (y * WIDTH * 3) as usize;
            let dst = (((BORDER + y) * sw + x0) * 3) as usize;
            sheet[dst..dst + (WIDTH * 3) as usize]
                .copy_from_slice(&rgb[src..src + (WIDTH * 3) as usize]);
        }
    }
    write_rgb8_png(&out.join("contact-sheet.png"), &sheet, sw, sh)?;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let mut md = format!(
        "# Stylized shadows of two lights: kernel times\n\n\
         `cargo run --release --bin stylized_lights_sheet -- {} {}`: {WIDTH} x {HEIGHT}, {SPP} \
         spp, default sampling, on {device}. Kernel times from OpenCL profiling events; the \
         machine was shared, so only the ratios within this run mean anything.\n\n\
         | run | ms |\n|---|---|\n\
         | first filter: both lights' contour, distance, blur, compose | {:.2} |\n",
        out.display(),
        scene_path.display(),
        ms(distance),
    );
    for ((caption, _, _), t) in cells.iter().zip(&edits) {
        md += &format!("| edit to \"{caption}\" | {:.2} |\n", ms(*t));
    }
    md += &format!("\nmedian edit: {:.2} ms\n", ms(median(edits)));
    std::fs::write(out.join("timings.md"), &md)?;
    print!("{md}");
    Ok(())
}
