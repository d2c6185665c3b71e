//! `noisefree view SCENE.toml`: the thesis's interactive viewer (§4.2-4.2.2). A window shows
//! the progressive image, filtered every frame by the chosen filter; the keyboard and mouse
//! move the camera (src/view/controls.rs lists the keys, as README "Viewer keys" does); any
//! change of the camera or of the filter empties the film and rendering starts again from one
//! sample per pixel. With `--devices` every frame is shared among several devices
//! (src/render/split.rs). A heads-up line says fps, spp, samples/s, the filter's time and the
//! devices.
//!
//! `--script events.txt --frames N --screenshot out.png` replays input without a person
//! (src/view/input.rs), for tests and demos under Xvfb; `--save-scene` writes the camera as a
//! scene file that `noisefree render` reproduces exactly.
//!
//! The window is minifb's (src/view/window.rs says why). Nothing below `cli` imports this
//! module.

pub mod camera;
pub mod controls;
pub mod hud;
pub mod input;
pub mod save;
pub mod session;
pub mod window;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use clap::Args;

use crate::filters::{FilterRequest, MultiDeviceArgs, Registry};
use crate::render::RenderOptions;
use controls::{Command, Controls};
use session::{Shown, Viewer};
use window::ViewerWindow;

#[derive(Args, Debug, Clone)]
pub struct ViewArgs {
    /// The scene description (.toml).
    pub scene: PathBuf,
    /// Image width [default: the scene's].
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height [default: the scene's].
    #[arg(long)]
    pub height: Option<u32>,
    #[arg(long)]
    pub seed: Option<u32>,
    /// The filter to start with: a registered filter or none [default: the scene's [filter]
    /// method, else ddf]. Keys switch it (Tab, 0-9).
    #[arg(long, value_name = "NAME")]
    pub filter: Option<String>,
    /// The filter settings given on the command line, per filter (filled from the flags the
    /// registry adds, src/cli/mod.rs).
    #[arg(skip)]
    pub settings: BTreeMap<String, toml::Table>,
    /// Samples per pixel added each frame.
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub spf: u32,
    /// Stop adding samples at this many per pixel.
    #[arg(long, value_name = "N")]
    pub max_spp: Option<u32>,
    /// Replay the input events of this file instead of reading the keyboard and mouse
    /// (format: src/view/input.rs, README "Scripted viewer").
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Close after this many frames.
    #[arg(long, value_name = "N")]
    pub frames: Option<u32>,
    /// On closing, write the image shown as this PNG, its linear EXR beside it, and the window
    /// with its heads-up lines as <name>-window.png.
    #[arg(long, value_name = "FILE.png")]
    pub screenshot: Option<PathBuf>,
    /// On closing, write the camera, size, spp and filter as a scene file that `render`
    /// reproduces.
    #[arg(long, value_name = "FILE.toml")]
    pub save_scene: Option<PathBuf>,
    /// Where the P (screenshot) and O (scene file) keys write.
    #[arg(long, value_name = "DIR", default_value = "out")]
    pub out_dir: PathBuf,
    /// The reference cache the R key compares with [default: cache/references].
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// OpenCL device number from `noisefree devices` (or NOISEFREE_DEVICE).
    #[arg(long)]
    pub device: Option<usize>,
    #[command(flatten)]
    pub multi: MultiDeviceArgs,
}

/// Seconds one frame of held keys moves the camera by in a scripted run, so that a script
/// gives the same camera on any machine.
const SCRIPT_FRAME_SECONDS: f32 = 1.0 / 30.0;

pub fn run(args: &ViewArgs, registry: &Registry) -> Result<()> {
    let scene = crate::scene::load_scene(&args.scene)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let mut options = RenderOptions::for_scene(&scene);
    options.frame.width = args.width.unwrap_or(options.frame.width);
    options.frame.height = args.height.unwrap_or(options.frame.height);
    options.frame.seed = args.seed.unwrap_or(options.frame.seed);
    if options.frame.width == 0 || options.frame.height == 0 {
        bail!("--width and --height must be at least 1");
    }
    if args.spf == 0 || args.max_spp == Some(0) {
        bail!("--spf and --max-spp must be at least 1");
    }
    for p in [&args.screenshot, &args.save_scene].into_iter().flatten() {
        crate::imaging::check_output_path(p)?;
    }
    // Input errors before the window and the kernels.
    let mut script = args
        .script
        .as_deref()
        .map(input::Script::load)
        .transpose()?;
    let mut window = ViewerWindow::open(
        &format!("noisefree view {}", args.scene.display()),
        options.frame.width,
        options.frame.height,
    )?;
    let gpus = args.multi.open(args.device)?;
    let request = FilterRequest {
        scene: scene.filter.settings.clone(),
        scene_origin: args.scene.display().to_string(),
        scene_lines: scene.filter.lines.clone(),
        flags: args.settings.clone(),
        ..Default::default()
    };
    let first = args
        .filter
        .clone()
        .or_else(|| scene.filter.method.clone())
        .unwrap_or_else(|| registry.names().first().copied().unwrap_or("none").into());
    let mut viewer = Viewer::new(
        registry,
        scene,
        &args.scene,
        options,
        gpus,
        args.multi.clone(),
        request,
        &first,
    )?;
    viewer.spf = args.spf;
    viewer.max_spp = args.max_spp.or(viewer.max_spp);
    if let Some(c) = &args.cache {
        viewer.set_reference_cache(c.clone());
    }
    let hud = hud::Hud::default();
    let mut controls = Controls::default();
    let (mut frame, mut shots, mut help) = (0u32, 0u32, false);
    let mut last: Option<Shown> = None;
    let mut frame_time = Duration::from_millis(33);
    loop {
        let start = Instant::now();
        let input = match &mut script {
            Some(s) => s.input(frame),
            None => window.input(),
        };
        let requests = controls.read(&input);
        if !window.is_open() || requests.commands.contains(&Command::Quit) {
            break;
        }
        let dt = if script.is_some() {
            SCRIPT_FRAME_SECONDS
        } else {
            frame_time.as_secs_f32().min(0.1)
        };
        viewer.update(&requests.camera, dt, requests.focus_at)?;
        for &c in &requests.commands {
            viewer.command(c)?;
            help ^= c == Command::ToggleHelp;
        }
        let shown = viewer.step()?;
        window.set_rgb8(&shown.rgb8);
        let mut lines = vec![heads_up(&viewer, frame_time)];
        if !viewer.message.is_empty() {
            lines.push(viewer.message.clone());
        }
        if help {
            lines.extend(controls::HELP.iter().map(|s| s.to_string()));
        }
        hud.draw(&mut window.pixels, window.width, &lines);
        window.present()?;
        for c in &requests.commands {
            let n = shots;
            match c {
                Command::Screenshot => {
                    shots += 1;
                    let p = numbered(&args.out_dir, &args.scene, n, "png")?;
                    save::screenshot(&p, &shown.rgb8, &shown.linear, &window.rgb8())?;
                    viewer.message = format!("saved {} (+ .exr, -window.png)", p.display());
                }
                Command::SaveScene => {
                    shots += 1;
                    let p = numbered(&args.out_dir, &args.scene, n, "toml")?;
                    save_scene(&viewer, &p)?;
                    viewer.message = format!("saved {}", p.display());
                }
                _ => {}
            }
        }
        last = Some(shown);
        frame += 1;
        frame_time = start.elapsed();
        if args.frames.is_some_and(|n| frame >= n) {
            break;
        }
    }
    if let (Some(p), Some(shown)) = (&args.screenshot, &last) {
        save::screenshot(p, &shown.rgb8, &shown.linear, &window.rgb8())?;
    }
    if let Some(p) = &args.save_scene {
        save_scene(&viewer, p)?;
    }
    // A closed pipe is not an error (as the command line's `say!`).
    use std::io::Write as _;
    let _ = writeln!(
        std::io::stdout().lock(),
        "view: {frame} frames, {} spp at the end, {} x {}, filter {}, {}",
        viewer.film.samples_done(),
        viewer.film.width(),
        viewer.film.height(),
        viewer.filter_label(),
        viewer.film.describe()
    );
    Ok(())
}

/// "12.5 fps | 7 spp | 1.31 Msamples/s | ddf (kw 15) 21 ms | pthread 66 % + basic 34 %".
fn heads_up(v: &Viewer, frame_time: Duration) -> String {
    let s = &v.stats;
    let filter = match s.filter {
        Some(t) => format!("{} {}", v.filter_label(), milliseconds(t)),
        None if v.unfiltered => format!("{} off (U)", v.filter_label()),
        None => v.filter_label(),
    };
    let parts = v.film.parts();
    let devices = parts
        .iter()
        .zip(v.film.bands())
        .map(|(p, b)| {
            let name = short_name(&p.gpu.summary.name);
            if parts.len() == 1 {
                name
            } else {
                format!(
                    "{name} {:.0} %",
                    100.0 * b.len() as f64 / v.film.height() as f64
                )
            }
        })
        .collect::<Vec<_>>()
        .join(" + ");
    format!(
        "{:.1} fps | {} spp | {:.2} Msamples/s | {filter} | {devices}",
        1.0 / frame_time.as_secs_f64().max(1e-6),
        v.film.samples_done(),
        s.samples as f64 / s.render.as_secs_f64().max(1e-9) / 1e6,
    )
}

fn milliseconds(t: Duration) -> String {
    let ms = t.as_secs_f64() * 1e3;
    if ms >= 100.0 {
        format!("{ms:.0} ms")
    } else {
        format!("{ms:.1} ms")
    }
}

/// A device's name short enough for the heads-up line: PoCL's "pthread-skylake-…" → "pthread",
/// others cut at 24 characters.
fn short_name(name: &str) -> String {
    match name.split_once('-') {
        Some((driver, _)) if !driver.contains(' ') => driver.to_string(),
        _ => name.chars().take(24).collect(),
    }
}

/// out/<scene>-view-<n>.<ext>.
fn numbered(dir: &Path, scene: &Path, n: u32, ext: &str) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let stem = scene.file_stem().unwrap_or_default().to_string_lossy();
    Ok(dir.join(format!("{stem}-view-{n}.{ext}")))
}

fn save_scene(v: &Viewer, path: &Path) -> Result<()> {
    let text = save::scene_text(
        &v.scene_path,
        path,
        &save::SavedView {
            camera: &v.scene.camera,
            frame: &v.options.frame,
            spp: v.film.samples_done(),
            filter: v.filter_for_render(),
        },
    )?;
    crate::imaging::write_atomically(path, |tmp| {
        std::fs::write(tmp, &text).with_context(|| format!("writing {}", tmp.display()))
    })
}
