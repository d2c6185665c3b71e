//! Hard cases, bad input at the command line (tests/cli_errors.rs has the scene-file errors,
//! a missing or directory scene, a --out in a missing folder and bad device numbers): sizes
//! whose buffers cannot be allocated, zero samples or pixels, directories and missing folders
//! as outputs, bad inputs to `filter` and `compare`, filter settings out of range and the flags
//! that the filter registry renamed. Every case must exit with the status the CLI gives for
//! errors (1; 2 for arguments the parser refuses), must not panic or abort, must leave no
//! output behind, and its message must name the flag or the file at fault.

mod common;

use std::path::{Path, PathBuf};

use common::{MINIMAL_SCENE, fails, noisefree, tempdir, usage_fails, write_scene};

/// A small sphere light for the minimal scene.
const LIGHT: &str = r#"
[[light]]
type = "sphere"
center = [0, 3, 3]
radius = 0.5
emission = [10, 10, 10]
"#;

/// The minimal scene with [`LIGHT`], written to `dir`/scene.toml.
fn scene(dir: &Path) -> PathBuf {
    write_scene(dir, &format!("{MINIMAL_SCENE}{LIGHT}"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// No file in `dir` other than those named in `keep`.
fn nothing_written(dir: &Path, keep: &[&str]) {
    let extra: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect();
    assert!(extra.is_empty(), "files were written: {extra:?}");
}

#[test]
fn a_resolution_beyond_device_memory_is_refused_before_allocating() {
    let dir = tempdir("hard-cli-huge");
    let sc = scene(&dir);
    let png = dir.join("x.png");
    // 200000 x 200000 pixels: 4e10, far past any device's memory (and any host's).
    for extra in [
        &[][..],
        &["--filter", "ddf"][..],
        &["--aovs", s(&dir.join("a.exr"))][..],
    ] {
        let mut args = vec![
            "render",
            s(&sc),
            "--width",
            "200000",
            "--height",
            "200000",
            "--spp",
            "1",
            "--out",
            s(&png),
            "--no-exr",
            "-q",
        ];
        args.extend_from_slice(extra);
        let err = fails(&args, &[]);
        assert!(
            err.contains("--width") || err.contains("resolution"),
            "the message must say that the resolution is too large: {err}"
        );
        nothing_written(&dir, &["scene.toml"]);
    }
    // Wide and flat: a row count that fits, a pixel count that does not.
    let err = fails(
        &[
            "render",
            s(&sc),
            "--width",
            "4000000000",
            "--height",
            "4",
            "--out",
            s(&png),
            "--no-exr",
            "-q",
        ],
        &[],
    );
    assert!(
        err.contains("--width") || err.contains("resolution"),
        "{err}"
    );
    nothing_written(&dir, &["scene.toml"]);
}

#[test]
fn zero_samples_name_the_flag_and_bad_numbers_are_refused() {
    let dir = tempdir("hard-cli-zero");
    let sc = scene(&dir);
    let png = dir.join("x.png");
    let base = ["render", s(&sc), "--out", s(&png), "--no-exr", "-q"];
    let mut args = base.to_vec();
    args.extend_from_slice(&["--spp", "0"]);
    fails(&args, &["--spp"]);
    nothing_written(&dir, &["scene.toml"]);
    // Zero pixels: refused before rendering (that the message names the flag is checked by
    // `zero_width_or_height_names_the_flag`).
    for flag in ["--width", "--height"] {
        let mut args = base.to_vec();
        args.extend_from_slice(&[flag, "0"]);
        fails(&args, &[]);
        nothing_written(&dir, &["scene.toml"]);
    }
    // Negative and non-numeric values are refused by the argument parser, naming the flag.
    for (flag, value) in [("--spp", "-1"), ("--width", "x"), ("--height", "1e3")] {
        let mut args = base.to_vec();
        let arg = format!("{flag}={value}");
        args.push(&arg);
        usage_fails(&args, &[flag]);
    }
}

#[test]
fn zero_width_or_height_names_the_flag() {
    let dir = tempdir("hard-cli-zero-wh");
    let sc = scene(&dir);
    let png = dir.join("x.png");
    for flag in ["--width", "--height"] {
        let args = [
            "render",
            s(&sc),
            "--out",
            s(&png),
            "--no-exr",
            "-q",
            flag,
            "0",
        ];
        fails(&args, &[flag]);
    }
}

#[test]
fn a_directory_as_an_output_is_refused_before_rendering() {
    let dir = tempdir("hard-cli-dirout");
    let sc = scene(&dir);
    let sub = dir.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let png = dir.join("x.png");
    for flag in ["--out", "--exr", "--aovs", "--exr-unfiltered"] {
        let mut args = vec!["render", s(&sc), "-q", flag, s(&sub)];
        if flag != "--out" {
            args.extend_from_slice(&["--out", s(&png)]);
        }
        if flag == "--exr-unfiltered" {
            args.extend_from_slice(&["--filter", "ddf"]);
        }
        if flag != "--exr" {
            args.push("--no-exr");
        }
        fails(&args, &["sub", "is a directory"]);
        nothing_written(&dir, &["scene.toml", "sub"]);
    }
}

#[test]
fn outputs_in_a_missing_folder_are_refused_before_rendering() {
    let dir = tempdir("hard-cli-nofolder");
    let sc = scene(&dir);
    let missing = dir.join("no/such");
    let png = dir.join("x.png");
    for (flag, file) in [
        ("--aovs", "a.exr"),
        ("--exr-unfiltered", "u.exr"),
        ("--exr", "x.exr"),
        ("--aov-png", "pngs"),
    ] {
        let target = missing.join(file);
        let mut args = vec!["render", s(&sc), "-q", "--out", s(&png), flag, s(&target)];
        if flag == "--exr-unfiltered" {
            args.extend_from_slice(&["--filter", "ddf"]);
        }
        if flag != "--exr" {
            args.push("--no-exr");
        }
        if flag == "--aov-png" {
            // A missing folder for the PNGs is created (documented), so this one succeeds.
            let out = noisefree().args(&args).output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(out.status.success(), "{err}");
            assert!(target.join("beauty.png").is_file());
            continue;
        }
        fails(&args, &[file, "does not exist"]);
        assert!(
            !dir.join("x.png").exists(),
            "{flag}: the PNG was written anyway"
        );
    }
}

#[test]
fn filter_refuses_missing_directory_and_non_exr_inputs() {
    let dir = tempdir("hard-cli-filter");
    let out = dir.join("f.png");
    let missing = dir.join("absent.exr");
    fails(&["filter", s(&missing), "--out", s(&out)], &["absent.exr"]);
    let sub = dir.join("aovs_dir.exr");
    std::fs::create_dir_all(&sub).unwrap();
    fails(&["filter", s(&sub), "--out", s(&out)], &["aovs_dir.exr"]);
    let text = dir.join("notes.exr");
    std::fs::write(&text, "this is not an image\n").unwrap();
    fails(&["filter", s(&text), "--out", s(&out)], &["notes.exr"]);
    let empty = dir.join("empty.exr");
    std::fs::write(&empty, b"").unwrap();
    fails(&["filter", s(&empty), "--out", s(&out)], &["empty.exr"]);
    // A real EXR that is not an AOV file: the missing channel is named.
    let rgb = dir.join("rgb.exr");
    noisefree::imaging::write_exr(
        &rgb,
        &noisefree::imaging::RgbImage {
            width: 2,
            height: 2,
            pixels: vec![[0.5; 3]; 4],
        },
    )
    .unwrap();
    fails(
        &["filter", s(&rgb), "--out", s(&out)],
        &["rgb.exr", "channel"],
    );
    // An EXR header claiming 2^29 x 2^29 pixels: refused from the header, not an abort.
    let mut huge = std::fs::read(&rgb).unwrap();
    for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
        let at = huge.windows(name.len()).position(|w| w == name).unwrap() + name.len() + 4;
        huge[at + 8..at + 16].copy_from_slice(&[0, 0, 0, 0x20, 0, 0, 0, 0x20]);
    }
    let huge_path = dir.join("huge.exr");
    std::fs::write(&huge_path, &huge).unwrap();
    fails(
        &["filter", s(&huge_path), "--out", s(&out)],
        &["huge.exr", "would take"],
    );
    // RPF on a file that is not a samples file (`--method` is an alias of `--filter`).
    for flag in ["--filter", "--method"] {
        fails(
            &["filter", s(&text), flag, "rpf", "--out", s(&out)],
            &["notes.exr"],
        );
    }
    // A directory as the output of a good input.
    fails(&["filter", s(&rgb), "--out", s(&dir)], &["is a directory"]);
    assert!(!out.exists());
}

fn write_rgb(path: &Path, w: u32, h: u32) {
    let img = noisefree::imaging::RgbImage {
        width: w,
        height: h,
        pixels: vec![[0.25, 0.5, 0.75]; (w * h) as usize],
    };
    noisefree::imaging::write_exr(path, &img).unwrap();
}

#[test]
fn compare_refuses_mismatched_sizes_and_bad_files() {
    let dir = tempdir("hard-cli-compare");
    let small = dir.join("small.exr");
    let large = dir.join("large.exr");
    write_rgb(&small, 4, 4);
    write_rgb(&large, 8, 4);
    // (That the message names both files is checked by `compare_mismatch_names_both_files`.)
    fails(&["compare", s(&small), s(&large)], &["4×4", "8×4"]);
    fails(
        &["compare", s(&small), s(&dir.join("absent.exr"))],
        &["absent.exr"],
    );
    fails(&["compare", s(&dir), s(&small)], &[s(&dir)]);
    let text = dir.join("text.exr");
    std::fs::write(&text, "not an image").unwrap();
    fails(&["compare", s(&small), s(&text)], &["text.exr"]);
    // An error map in a missing folder is refused before reading anything.
    fails(
        &[
            "compare",
            s(&small),
            s(&small),
            "--error-map",
            s(&dir.join("no/such/map.png")),
        ],
        &["map.png", "does not exist"],
    );
    // The same image passes, as a control.
    let out = noisefree()
        .args(["compare", s(&small), s(&small)])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn compare_mismatch_names_both_files() {
    let dir = tempdir("hard-cli-compare-names");
    let small = dir.join("small.exr");
    let large = dir.join("large.exr");
    write_rgb(&small, 4, 4);
    write_rgb(&large, 8, 4);
    fails(
        &["compare", s(&small), s(&large)],
        &["small.exr", "large.exr"],
    );
}

#[test]
fn filter_settings_out_of_range_and_unknown_filters_name_the_flag() {
    let dir = tempdir("hard-cli-settings");
    let sc = scene(&dir);
    let png = dir.join("x.png");
    let base = ["render", s(&sc), "--out", s(&png), "--no-exr", "-q"];
    for (extra, needles) in [
        (
            &["--filter", "nope"][..],
            &["--filter", "\"nope\"", "ddf, rpf, atrous"][..],
        ),
        (&["--filter", "ddf", "--kw", "4"][..], &["--kw", "odd"][..]),
        (
            &["--filter", "atrous", "--atrous-iterations", "99"][..],
            &["--atrous-iterations", "at most 15"][..],
        ),
        (
            &["--filter", "atrous", "--atrous-sigma-color", "-1"][..],
            &["--atrous-sigma-color", "positive"][..],
        ),
        (
            &["--filter", "rpf", "--rpf-sigma2-8", "-1"][..],
            &["--rpf-sigma2-8", "positive"][..],
        ),
        (&["--texture2=maybe"][..], &["--texture2", "auto"][..]),
        // A setting of a filter that is not chosen is still checked.
        (&["--kw", "4"][..], &["--kw"][..]),
    ] {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        fails(&args, needles);
        nothing_written(&dir, &["scene.toml"]);
    }
}

#[test]
fn renamed_filter_flags_are_refused_naming_the_new_one() {
    // The flags before the filter registry: the parser refuses them and points at the flag
    // that replaced each.
    let dir = tempdir("hard-cli-renamed");
    let sc = scene(&dir);
    let png = dir.join("x.png");
    let base = ["render", s(&sc), "--out", s(&png), "--no-exr", "-q"];
    for (old, new) in [
        (&["--atrous-beauty"][..], "--atrous-demodulate"),
        (&["--rpf-sigma8", "0.002"][..], "--rpf-sigma2-8"),
        (&["--no-texture2"][..], "--texture2"),
    ] {
        let mut args = base.to_vec();
        args.extend_from_slice(old);
        usage_fails(&args, &[old[0], new]);
        nothing_written(&dir, &["scene.toml"]);
    }
    // `filter --outdoor` is gone too (σ²_8 is --rpf-sigma2-8 0.002).
    usage_fails(
        &["filter", s(&sc), "--outdoor", "--out", s(&png)],
        &["--outdoor"],
    );
}
