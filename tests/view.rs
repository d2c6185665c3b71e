//! `noisefree view` driven by scripts under a virtual X server (Xvfb; scripts/test.sh installs
//! it): a scripted run shows exactly what `render` gives for the same camera and spp, moving
//! the camera empties the film, the heads-up line is drawn, and without a display the viewer
//! says what to do.

mod common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use common::*;

/// A virtual X server on a free display, stopped when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Xvfb {
        // -displayfd: Xvfb picks a free display and writes its number once it accepts clients.
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "640x480x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| {
                panic!("cannot start Xvfb ({e}): scripts/test.sh installs it (apt install xvfb)")
            });
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let n: u32 = line
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("Xvfb said {line:?}"));
        Xvfb {
            child,
            display: format!(":{n}"),
        }
    }

    /// `noisefree view SCENE` at 64 × 48 on this display, with `args`.
    fn view(&self, scene: &Path, args: &[&str]) -> std::process::Output {
        let out = noisefree()
            .env("DISPLAY", &self.display)
            .arg("view")
            .arg(scene)
            .args(["--width", "64", "--height", "48"])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "view {args:?} failed: {err}");
        out
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn script(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// The PNG and EXR bytes of `stem`.png/.exr.
fn images(png: &Path) -> (Vec<u8>, Vec<u8>) {
    (
        std::fs::read(png).unwrap(),
        std::fs::read(png.with_extension("exr")).unwrap(),
    )
}

/// `noisefree render` of `scene` with `args` into `png` (and its EXR).
fn render(scene: &Path, png: &Path, args: &[&str]) -> (Vec<u8>, Vec<u8>) {
    let out = noisefree()
        .arg("render")
        .arg(scene)
        .args(["-q", "--out", png.to_str().unwrap()])
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    images(png)
}

fn spp_at_end(out: &std::process::Output) -> u32 {
    let text = String::from_utf8_lossy(&out.stdout);
    let (_, rest) = text
        .split_once("frames, ")
        .unwrap_or_else(|| panic!("{text}"));
    rest.split_whitespace().next().unwrap().parse().unwrap()
}

#[test]
fn a_still_camera_shows_what_render_gives_at_the_same_spp() {
    let x = Xvfb::start();
    let dir = tempdir("view-still");
    let scene = bundled_scene_path("cornell_glossy");
    let shot = dir.join("view.png");
    let out = x.view(
        &scene,
        &[
            "--frames",
            "4",
            "--filter",
            "ddf",
            "--screenshot",
            shot.to_str().unwrap(),
        ],
    );
    assert_eq!(spp_at_end(&out), 4, "one sample per pixel a frame");
    let want = render(
        &scene,
        &dir.join("render.png"),
        &[
            "--spp", "4", "--width", "64", "--height", "48", "--filter", "ddf",
        ],
    );
    assert!(
        images(&shot) == want,
        "the viewer's 4 spp differ from render --spp 4"
    );
    // The window's picture carries the heads-up line over the image: its top rows differ.
    let window = image::open(dir.join("view-window.png")).unwrap().to_rgb8();
    let image = image::open(&shot).unwrap().to_rgb8();
    assert_eq!(window.dimensions(), image.dimensions());
    let top = |i: &image::RgbImage| i.rows().take(14).flatten().map(|p| p.0).collect::<Vec<_>>();
    let bottom = |i: &image::RgbImage| i.rows().skip(20).flatten().map(|p| p.0).collect::<Vec<_>>();
    assert!(
        top(&window) != top(&image),
        "no heads-up line in the window"
    );
    assert!(
        bottom(&window) == bottom(&image),
        "the window shows the image below it"
    );
}

#[test]
fn moving_the_camera_empties_the_film_and_the_saved_scene_renders_the_screenshot() {
    let x = Xvfb::start();
    let dir = tempdir("view-moved");
    let scene = bundled_scene_path("cornell_glossy");
    // Frames 0-2 on the scene's camera; then walk (faster with Shift), look, open the lens,
    // focus on a pixel (when the click's button comes up, frame 10) and widen the kernel: each
    // change empties the film. The last change is at frame 10, so frames 10-13 leave 4 spp.
    let events = script(
        &dir,
        "events.txt",
        "# walk, look, focus\n3 press W\n4 press LeftShift\n5 release W\n5 release LeftShift\n\
         6 move 32 24\n6 drag 12 -5\n8 tap RightBracket\n9 click 20 30\n10 tap K\n",
    );
    let shot = dir.join("moved.png");
    let saved = dir.join("moved.toml");
    let out = x.view(
        &scene,
        &[
            "--script",
            events.to_str().unwrap(),
            "--frames",
            "14",
            "--screenshot",
            shot.to_str().unwrap(),
            "--save-scene",
            saved.to_str().unwrap(),
        ],
    );
    assert_eq!(spp_at_end(&out), 4, "the film restarts at every change");
    let text = std::fs::read_to_string(&saved).unwrap();
    assert!(
        text.contains("spp = 4") && text.contains("holes = false"),
        "{text}"
    );
    assert!(
        text.contains("lens_radius") && text.contains("focal_distance"),
        "{text}"
    );
    // `render` of the saved file (from another folder: its asset paths were made absolute).
    let got = render(&saved, &dir.join("saved-render.png"), &[]);
    assert!(
        images(&shot) == got,
        "render of the saved scene differs from the screenshot"
    );
    // The camera did move: the scene's own camera at 4 spp, with the kernel width the viewer
    // ended with, is another image.
    let kw = text
        .lines()
        .find_map(|l| l.strip_prefix("kw = "))
        .unwrap_or_else(|| panic!("no kw in {text}"));
    let still = render(
        &scene,
        &dir.join("still.png"),
        &[
            "--spp", "4", "--width", "64", "--height", "48", "--filter", "ddf", "--kw", kw,
        ],
    );
    assert!(still.0 != got.0, "the script did not move the camera");
}

#[test]
fn without_a_display_the_viewer_says_what_to_do() {
    let scene = bundled_scene_path("cornell_glossy");
    let mut cmd = noisefree();
    cmd.env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .arg("view")
        .arg(&scene);
    fails_with(ERROR, &mut cmd, &["DISPLAY is not set", "Xvfb"]);
    // A display that is not there: the error names it and the fix.
    let mut cmd = noisefree();
    cmd.env("DISPLAY", ":987").arg("view").arg(&scene);
    fails_with(ERROR, &mut cmd, &["DISPLAY=:987", "Xvfb"]);
    // A bad script is reported before any window opens, with its line.
    let dir = tempdir("view-bad-script");
    let bad = script(&dir, "bad.txt", "0 tap W\n2 press Whoops\n");
    let mut cmd = noisefree();
    cmd.env_remove("DISPLAY")
        .arg("view")
        .arg(&scene)
        .arg("--script")
        .arg(&bad);
    fails_with(
        ERROR,
        &mut cmd,
        &["bad.txt", "line 2", "no key named \"Whoops\""],
    );
}

#[test]
fn a_focus_click_on_a_shadow_film_gathers_the_lens_field_for_sheared_depth_of_field() {
    // Sheared filtering of a scene's sphere lights gathers their shadow fields (as the filter
    // samples them: every light of two_lights_shadows, a plane each). A click focuses there
    // and gives the pinhole camera a lens, so the filter specialises to depth of field, which
    // reads the lens field: the viewer gathers it (before, it kept the shadow film, and the
    // filter's refusal ended the viewer on Grids; on two_lights_shadows it ended at once, the
    // film holding light 0 alone). What it shows after 4 spp is what `render` of the saved
    // scene gives.
    let x = Xvfb::start();
    for name in ["grids", "two_lights_shadows"] {
        let dir = tempdir(&format!("view-field-kind-{name}"));
        let scene = bundled_scene_path(name);
        let events = script(&dir, "events.txt", "2 click 32 30\n");
        let (shot, saved) = (dir.join("focused.png"), dir.join("focused.toml"));
        let out = x.view(
            &scene,
            &[
                "--filter",
                "sheared",
                "--script",
                events.to_str().unwrap(),
                "--frames",
                "7",
                "--screenshot",
                shot.to_str().unwrap(),
                "--save-scene",
                saved.to_str().unwrap(),
            ],
        );
        assert_eq!(
            spp_at_end(&out),
            4,
            "{name}: the film restarts at the focus"
        );
        let text = std::fs::read_to_string(&saved).unwrap();
        assert!(text.contains("lens_radius"), "{name}: {text}");
        let got = render(&saved, &dir.join("saved-render.png"), &[]);
        assert!(
            images(&shot) == got,
            "{name}: render of the saved scene differs from the screenshot"
        );
    }
}

#[test]
fn the_film_is_gathered_again_when_the_filter_reads_another_light_field() {
    use noisefree::filters::sheared::{Effect, Sheared, ShearedSettings};
    use noisefree::filters::{Auto, Configured};
    use noisefree::layout::outputs::{FieldKind, Output, OutputSet};
    use noisefree::view::session::film_must_change;
    let scene = bundled_scene("two_lights_shadows");
    let info = scene_info(&scene, 16, 16);
    // The options of a film gathered for the sheared filter with `effect` (the viewer adds
    // the features and variances for its AOV pictures).
    let film_for = |effect: Option<Effect>| {
        let mut o = options(&scene, 16, 16, 1);
        o.outputs = OutputSet::of(&[Output::Features, Output::Variance]);
        if let Some(effect) = effect {
            let s = ShearedSettings {
                effect: Auto::Set(effect),
                light: Auto::Set(if effect == Effect::Shadows { 0 } else { -1 }),
                ..Default::default()
            };
            let c = Configured::typed::<Sheared>(s, &info).unwrap();
            o.outputs = o.outputs.union(c.needs());
            c.adjust_render(&mut o);
        }
        o
    };
    let [none, shadows, dof, gi] = [
        None,
        Some(Effect::Shadows),
        Some(Effect::Dof),
        Some(Effect::Gi),
    ]
    .map(film_for);
    // The same film serves the same filter, and one without a light field serves none.
    for o in [&none, &shadows, &dof, &gi] {
        assert!(!film_must_change(o, o));
        assert!(!film_must_change(o, &none));
    }
    // A film with every output but another field: gathered again, each way round.
    for (a, b) in [(&shadows, &dof), (&dof, &gi), (&gi, &dof), (&shadows, &gi)] {
        assert!(film_must_change(a, b));
        assert!(film_must_change(b, a));
    }
    // The lens and v-plane films gather the same outputs; what they record differs.
    assert_eq!(dof.outputs.names(), gi.outputs.names());
    assert_eq!(dof.recorded_outputs().light_field(), Some(FieldKind::Lens));
    assert_eq!(gi.recorded_outputs().light_field(), Some(FieldKind::Gi));
    assert!(film_must_change(&none, &dof));
}
