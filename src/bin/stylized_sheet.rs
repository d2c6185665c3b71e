//! The contact sheet of the stylized-shadows filter's four controls (DeCoro 2009 ch. 3,
//! Figs. 3.5, 3.8, 3.9): `cargo run --release --bin stylized_sheet -- [OUT_DIR] [SCENE]`
//! (defaults results/stylized and scenes/grids.toml).
//!
//! One render of the scene with the shadow output, then the filter's stages run as an artist's
//! edits would run them: the contour and the distance of eq. 3.2 once, the blur again only
//! when α changes, the compose alone when i, s or b change. Rows: inflation i, brightness b,
//! softness s, abstraction α, each varied with the others at 0 (the first cell of each row is
//! the hard shadow of the light's centre, the identity), and softness proportional to the
//! occluder distance. Writes contact-sheet.png (rows top to
//! bottom, cells left to right as listed in `ROWS`), unfiltered.png (the path tracer's soft
//! shadow) and timings.md (kernel times of each kind of edit).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context as _, Result};
use noisefree::filters::stylized::{Controls, StylizedKernel, StylizedSettings};
use noisefree::gpu::Gpu;
use noisefree::imaging::{to_srgb8, write_png, write_rgb8_png};
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::{RenderOptions, Renderer};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 192;
const SPP: u32 = 16;
const BORDER: u32 = 4;

/// Each row: the control varied and its values (i and s in the L8-averaged world distance of
/// eq. 3.2, the scene's units; b in [0, 1]; α in pixels).
/// The last row makes softness grow with the occluder distance d (s = c1·d, §3.3.2's
/// "hardening" near the occluder, Fig. 3.8): c1 per cell.
const ROWS: [(&str, [f32; 5]); 5] = [
    ("inflation", [0.0, -0.1, 0.1, 0.2, 0.4]),
    ("brightness", [0.0, 0.2, 0.4, 0.6, 0.8]),
    ("softness", [0.0, 0.1, 0.2, 0.4, 0.8]),
    ("abstraction", [0.0, 2.0, 4.0, 8.0, 16.0]),
    ("softness per unit d", [0.0, 0.1, 0.2, 0.4, 0.8]),
];

fn controls(row: &str, v: f32) -> Controls {
    let mut c = Controls::default();
    let q = [v, 0.0, 0.0];
    match row {
        "inflation" => c.inflation = q,
        "brightness" => c.brightness = q,
        "softness" => c.softness = q,
        "abstraction" => c.abstraction = q,
        _ => c.softness = [0.0, v, 0.0],
    }
    c
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
        .unwrap_or_else(|| "results/stylized".into());
    let scene_path = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| "scenes/grids.toml".into());
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let scene = noisefree::scene::load_scene(&scene_path)?;
    let gpu = Gpu::open(None)?;
    let settings = StylizedSettings::default();
    let mut o = RenderOptions::for_scene(&scene);
    o.frame.width = WIDTH;
    o.frame.height = HEIGHT;
    o.outputs = OutputSet::of(&[Output::Shadows]);
    o.shadows = settings.sampling();
    let mut renderer = Renderer::new(gpu.clone(), &scene, &o)?;
    renderer.render_samples(SPP)?;
    let frame = renderer.frame();
    write_png(&out.join("unfiltered.png"), &frame.beauty()?, 0.0)?;

    let device = gpu.summary.name.clone();
    let mut k = StylizedKernel::new(gpu, &settings, &settings.stylized_lights(), WIDTH, HEIGHT)?;
    let distance = k.distance(&frame)?;
    let (mut blur_times, mut compose_times) = (Vec::new(), Vec::new());
    let cols = ROWS[0].1.len() as u32;
    let (sw, sh) = (
        cols * WIDTH + (cols + 1) * BORDER,
        ROWS.len() as u32 * HEIGHT + (ROWS.len() as u32 + 1) * BORDER,
    );
    let mut sheet = vec![255u8; (sw * sh * 3) as usize];
    for (r, (row, values)) in ROWS.iter().enumerate() {
        for (c, &v) in values.iter().enumerate() {
            k.set_controls(&controls(row, v))?;
            // Only α needs the blur again; the first cell of a row blurs with α = 0 (a copy),
            // so that the rows other than abstraction start from the unblurred distance.
            if *row == "abstraction" || c == 0 {
                let t = k.blur(&frame)?;
                if v > 0.0 && *row == "abstraction" {
                    blur_times.push(t);
                }
            }
            let (image, t) = k.compose(&frame)?;
            compose_times.push(t);
            let rgb = to_srgb8(&image, 0.0);
            let (x0, y0) = (
                BORDER + c as u32 * (WIDTH + BORDER),
                BORDER + r as u32 * (HEIGHT + BORDER),
            );
            for y in 0..HEIGHT {
                let src = (y * WIDTH * 3) as usize;
                let dst = (((y0 + y) * sw + x0) * 3) as usize;
                sheet[dst..dst + (WIDTH * 3) as usize]
                    .copy_from_slice(&rgb[src..src + (WIDTH * 3) as usize]);
            }
        }
    }
    write_rgb8_png(&out.join("contact-sheet.png"), &sheet, sw, sh)?;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let mut md = format!(
        "# Stylized shadows: kernel times of the contact sheet's edits\n\n\
         `cargo run --release --bin stylized_sheet -- {} {}`: {} at {WIDTH} x {HEIGHT}, \
         {SPP} spp, default sampling ({} contour samples, {} Halton points per blur pass), \
         on {}. Kernel times from OpenCL profiling events; the machine was shared, so only \
         the ratios within this run mean anything.\n\n\
         | stage (re-run when) | runs | median ms |\n|---|---|---|\n",
        out.display(),
        scene_path.display(),
        scene_path.display(),
        settings.contour_samples,
        settings.blur_samples,
        device,
    );
    md += &format!(
        "| contour + distance (camera or light moves) | 1 | {:.2} |\n",
        ms(distance)
    );
    md += &format!(
        "| blur, two passes (α changes; α > 0) | {} | {:.2} |\n",
        blur_times.len(),
        ms(median(blur_times))
    );
    md += &format!(
        "| compose (i, s or b change) | {} | {:.2} |\n",
        compose_times.len(),
        ms(median(compose_times))
    );
    std::fs::write(out.join("timings.md"), &md)?;
    print!("{md}");
    Ok(())
}
