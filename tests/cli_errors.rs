//! Bad input gets a clear error: the file, the line and column (or the field), what was
//! expected, the exit status of an error (1), and no panic. Outputs that exist are left
//! untouched.

mod common;

use std::path::Path;
use std::process::Command;

use common::{ERROR, fails, fails_with, noisefree, tempdir, write_scene};

/// The scene the cases below change: line and column numbers refer to it.
const GOOD: &str = common::MINIMAL_SCENE;

/// Renders `text` as a scene file and returns (exit code, None for a signal; stderr).
fn render_text(dir: &Path, text: &str) -> (Option<i32>, String) {
    let path = write_scene(dir, text);
    let out = noisefree()
        .args([
            "render",
            path.to_str().unwrap(),
            "--out",
            dir.join("x.png").to_str().unwrap(),
            "--no-exr",
            "-q",
        ])
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn each_bad_scene_names_file_position_and_problem() {
    let dir = tempdir("cli-errors");
    // (what to change, text that must appear in the message, line:col it must point at)
    let cases: Vec<(String, &str, Option<&str>)> = vec![
        (
            GOOD.replace("material = \"white\"\n", "material = \"whte\"\n"),
            "unknown material \"whte\"",
            Some(":18:12:"),
        ),
        (
            GOOD.replace("radius = 1", "radius = -2"),
            "radius must be a positive number",
            Some(":17:10:"),
        ),
        (
            GOOD.replace("width = 8", "width = 0"),
            "render.width must be between 1",
            Some(":2:9:"),
        ),
        (
            GOOD.replace("height = 8", "height = -3"),
            "render.height must be between 1",
            Some(":3:10:"),
        ),
        (
            GOOD.replace("spp = 1", "spp = 0"),
            "render.spp must be between 1",
            Some(":4:7:"),
        ),
        (
            format!("{GOOD}\n[[mesh]]\nfile = \"missing.obj\"\n"),
            "missing.obj",
            Some(":21:8:"),
        ),
        (
            format!("{GOOD}\n[[texture]]\nname = \"t\"\nfile = \"nope.png\"\n"),
            "nope.png",
            Some(":22:8:"),
        ),
        (
            GOOD.replace("color = [0.8, 0.8, 0.8]", "color = [0.8, 0.8]"),
            "expected",
            Some(":13:9:"),
        ),
        (
            GOOD.replace("radius = 1", "radius = 1\nradiuss = 2"),
            "unknown field `radiuss`",
            Some(":18:1:"),
        ),
        (GOOD.replace("[camera]", "[camera"), "", Some(":6:")),
        (
            GOOD.replace("type = \"diffuse\"", "type = \"plastic\""),
            "unknown material type \"plastic\"",
            Some(":12:8:"),
        ),
        (
            GOOD.replace("target = [0, 0, 0]", "target = [0, 0, 5]"),
            "no view direction",
            None,
        ),
        (
            GOOD.replace("type = \"diffuse\"", "type = \"diffuse\"\nexponent = 3"),
            "has no field `exponent`",
            Some(":13:12:"),
        ),
        // Filter settings: each filter has its own [filter.<name>] table (line 20 here),
        // checked by the filter registry before anything renders.
        (
            format!("{GOOD}\n[filter]\nmethod = \"ddf\"\nkw = 7\n"),
            "a filter's settings live in its own table, e.g. [filter.ddf] kw",
            Some(":20:1:"),
        ),
        (
            format!("{GOOD}\n[filter.nope]\nkw = 7\n"),
            "[filter.nope]: no filter of that name",
            Some(":20:"),
        ),
        (
            format!("{GOOD}\n[filter.atrous]\niterations = 99\n"),
            "at most 15 iterations",
            Some(":20:"),
        ),
        (
            format!("{GOOD}\n[filter.ddf]\nkww = 3\n"),
            "unknown field `kww`",
            Some(":20:"),
        ),
        // The method is checked when the command runs; its message has no line (yet).
        (
            format!("{GOOD}\n[filter]\nmethod = \"nope\"\n"),
            "no filter named \"nope\"",
            None,
        ),
    ];
    for (text, needle, position) in cases {
        let (code, stderr) = render_text(&dir, &text);
        assert_eq!(
            code,
            Some(ERROR),
            "expected an error for:\n{text}\n{stderr}"
        );
        assert!(
            !stderr.contains("panicked"),
            "a panic instead of an error: {stderr}"
        );
        assert!(
            stderr.contains("scene.toml"),
            "the message must name the file: {stderr}"
        );
        assert!(stderr.contains(needle), "expected {needle:?} in: {stderr}");
        if let Some(pos) = position {
            assert!(stderr.contains(pos), "expected position {pos} in: {stderr}");
        }
    }
}

#[test]
fn missing_and_directory_scene_paths() {
    let dir = tempdir("cli-paths");
    fails(
        &["render", dir.join("absent.toml").to_str().unwrap()],
        &["absent.toml: cannot open scene file"],
    );
    fails(&["render", dir.to_str().unwrap()], &["is a directory"]);
}

#[test]
fn failed_render_leaves_existing_output_untouched() {
    let dir = tempdir("cli-keep");
    let png = dir.join("x.png");
    std::fs::write(&png, b"precious").unwrap();
    let (code, _) = render_text(&dir, &GOOD.replace("radius = 1", "radius = 0"));
    assert_eq!(code, Some(ERROR));
    assert_eq!(std::fs::read(&png).unwrap(), b"precious");
    // A good render replaces it with a real PNG, and leaves no temporary files behind.
    let (code, stderr) = render_text(&dir, GOOD);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(leftovers.is_empty());
}

#[test]
fn output_in_a_missing_folder_is_refused_before_rendering() {
    let dir = tempdir("cli-nofolder");
    let scene = write_scene(&dir, GOOD);
    fails(
        &[
            "render",
            scene.to_str().unwrap(),
            "--out",
            dir.join("no/such/x.png").to_str().unwrap(),
            "--no-exr",
        ],
        &["does not exist"],
    );
}

#[test]
fn wave_paths_without_the_wavefront_tracer_is_refused() {
    let dir = tempdir("cli-wave-paths");
    let scene = write_scene(&dir, GOOD);
    let out = dir.join("x.png");
    fails(
        &[
            "render",
            scene.to_str().unwrap(),
            "--wave-paths",
            "64",
            "--out",
            out.to_str().unwrap(),
        ],
        &["--wave-paths", "--tracer wavefront"],
    );
    assert!(!out.exists(), "nothing is written");
}

#[test]
fn no_opencl_platform_says_how_to_install_pocl() {
    let dir = tempdir("cli-noicd");
    // The ICD loader reads vendor files from OCL_ICD_VENDORS; an empty folder means no platform.
    fails_with(
        ERROR,
        noisefree().arg("devices").env("OCL_ICD_VENDORS", &dir),
        &["pocl-opencl-icd"],
    );
}

#[test]
fn devices_lists_the_device_and_bad_device_numbers_are_explained() {
    let out = noisefree().arg("devices").output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("[0]") && text.contains("compute units") && text.contains("local memory"),
        "{text}"
    );
    let dir = tempdir("cli-baddev");
    let scene = write_scene(&dir, GOOD);
    fails(
        &[
            "render",
            scene.to_str().unwrap(),
            "--out",
            dir.join("x.png").to_str().unwrap(),
            "--device",
            "99",
        ],
        &["device 99 does not exist"],
    );
}

/// Ctrl-C during a render: without --save-partial nothing is written (existing files stay);
/// with it, the samples rendered so far are written.
#[test]
fn ctrl_c_keeps_outputs_or_saves_partial() {
    let dir = tempdir("cli-ctrlc");
    let scene = write_scene(
        &dir,
        &GOOD
            .replace("width = 8", "width = 64")
            .replace("height = 8", "height = 64"),
    );
    let png = dir.join("x.png");
    for save_partial in [false, true] {
        std::fs::write(&png, b"precious").unwrap();
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "--out",
            png.to_str().unwrap(),
            "--spp",
            "100000000",
            "-q",
        ];
        if save_partial {
            args.push("--save-partial");
        }
        let child = noisefree()
            .args(&args)
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Give it time to build its kernels and start rendering.
        std::thread::sleep(std::time::Duration::from_secs(4));
        let status = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{stderr}");
        if save_partial {
            assert_eq!(out.status.code(), Some(0), "{stderr}");
            assert_eq!(
                &std::fs::read(&png).unwrap()[1..4],
                b"PNG",
                "the partial image was not written"
            );
            assert!(png.with_extension("exr").exists());
        } else {
            assert_eq!(out.status.code(), Some(130), "{stderr}");
            assert_eq!(
                std::fs::read(&png).unwrap(),
                b"precious",
                "an interrupted render overwrote its output"
            );
        }
    }
}

/// Runs `args` with stdout a pipe whose reader has gone (`noisefree ... | head -0`); returns
/// (exit code, stderr).
fn run_with_closed_stdout(args: &[&str]) -> (Option<i32>, String) {
    let mut child = noisefree()
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_reader_that_closed_the_pipe_does_not_stop_the_command() {
    // Before: `println!` panicked on the broken pipe (exit 101) before `filter` wrote its image.
    let dir = tempdir("cli-pipe");
    let scene = write_scene(&dir, GOOD);
    let (aovs, png, exr) = (dir.join("a.exr"), dir.join("x.png"), dir.join("b.exr"));
    let render = [
        "render",
        scene.to_str().unwrap(),
        "--out",
        png.to_str().unwrap(),
        "--aovs",
        aovs.to_str().unwrap(),
        "--no-exr",
    ];
    let filter = [
        "filter",
        aovs.to_str().unwrap(),
        "--filter",
        "atrous",
        "--exr",
        exr.to_str().unwrap(),
    ];
    for (args, file) in [(&render[..], &aovs), (&filter[..], &exr)] {
        let (code, stderr) = run_with_closed_stdout(args);
        assert_eq!(code, Some(0), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(file.is_file(), "{args:?} wrote no {}", file.display());
    }
}
