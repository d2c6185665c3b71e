//! `render --samples A..B --tile WxH+X+Y --partial` and `noisefree merge` on the command
//! line: the same parts in any order or grouping give the same bytes and equal the one-machine
//! render (the bound: tests/common/merge.rs); tiles merge like ranges; parts that do not make
//! up one render are refused with the files named, and nothing is written; partial-render
//! flags are checked before rendering.

mod common;

use std::path::Path;

use common::merge::*;
use common::*;

fn scene_path() -> String {
    bundled_scene_path("cornell_diffuse").display().to_string()
}

/// Runs noisefree and asserts success; returns stdout.
fn ok(args: &[&str]) -> String {
    let out = noisefree().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The render of the command-line tests: `(flag, value)` pairs, any replaced by `changes`.
fn render_args(changes: &[(&str, &str)]) -> Vec<String> {
    let scene = scene_path();
    let base = [
        ("--spp", "16"),
        ("--width", "24"),
        ("--height", "20"),
        ("--seed", "3"),
        ("--filter", "ddf"),
    ];
    let mut v = vec!["render".to_string(), scene, "-q".into()];
    for (flag, value) in base {
        let value = changes.iter().find(|c| c.0 == flag).map_or(value, |c| c.1);
        v.extend([flag.to_string(), value.to_string()]);
    }
    v
}

/// `render --partial dir/name` of the test render with `changes`, and `extra` flags.
fn render_part(dir: &Path, name: &str, changes: &[(&str, &str)], extra: &[&str]) -> String {
    let path = dir.join(name).display().to_string();
    let mut args = render_args(changes);
    args.extend(["--partial".to_string(), path.clone()]);
    args.extend(extra.iter().map(|s| s.to_string()));
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    path
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn merge_gives_the_same_bytes_in_any_order_or_grouping_and_equals_the_one_machine_render() {
    let dir = tempdir("partial-cli");
    let d = |n: &str| dir.join(n).display().to_string();
    let ranges = ["0..3", "3..8", "8..13", "13..16"];
    let parts: Vec<String> = ranges
        .iter()
        .map(|r| render_part(&dir, &format!("p{r}.nfp"), &[], &["--samples", r]))
        .collect();
    let merge = |name: &str, inputs: &[&str]| -> [Vec<u8>; 3] {
        let (png, exr, aovs) = (
            d(&format!("{name}.png")),
            d(&format!("{name}.exr")),
            d(&format!("{name}-aovs.exr")),
        );
        let mut args = vec!["merge", "-q", "--out", &png, "--exr", &exr, "--aovs", &aovs];
        args.extend_from_slice(inputs);
        let stdout = ok(&args);
        assert!(stdout.contains("filtered with ddf"), "{stdout}");
        [png, exr, aovs].map(|p| bytes(Path::new(&p)))
    };
    let p: Vec<&str> = parts.iter().map(String::as_str).collect();
    let forward = merge("forward", &p);
    let backward = merge("backward", &[p[3], p[2], p[1], p[0]]);
    // Grouped: two bundles of pieces, merged together.
    let (ab, cd) = (d("ab.nfp"), d("cd.nfp"));
    ok(&["merge", "-q", "--partial", &ab, p[1], p[0]]);
    ok(&["merge", "-q", "--partial", &cd, p[3], p[2]]);
    let grouped = merge("grouped", &[&cd, &ab]);
    let mixed = merge("mixed", &[p[2], &ab, p[3]]);
    for (name, other) in [
        ("backward", &backward),
        ("grouped", &grouped),
        ("mixed", &mixed),
    ] {
        for (k, what) in ["PNG", "EXR", "AOV file"].iter().enumerate() {
            assert!(forward[k] == other[k], "{name}: the {what} differs");
        }
    }

    // Against `render` on one machine, through the files: the AOVs to the merge bound, and the
    // filtered image (the data-driven filter, the render's choice) to float rounding where it
    // is continuous (see filtered_difference).
    let (one_png, one_aovs) = (d("one.png"), d("one-aovs.exr"));
    let mut one_args = render_args(&[]);
    one_args.extend(["--out".into(), one_png, "--aovs".into(), one_aovs.clone()]);
    ok(&one_args.iter().map(String::as_str).collect::<Vec<_>>());
    let (one, _) = noisefree::stats::aov::read_aov_exr(Path::new(&one_aovs)).unwrap();
    let (merged, record) =
        noisefree::stats::aov::read_aov_exr(&dir.join("forward-aovs.exr")).unwrap();
    assert_eq!(record.filter.as_deref(), Some("ddf"));
    assert_outputs_within_bound(&one, &merged);
    let exr = |p: &str| noisefree::imaging::read_exr_rgb(Path::new(p)).unwrap();
    let (one_img, merged_img) = (exr(&d("one.exr")), exr(&d("forward.exr")));
    let (d_img, compared) = filtered_difference(&one, &one_img, &merged_img);
    // Measured 2.3e-6 (PoCL, 440 of 480 pixels); bound 1e-5, as for the merged frames.
    eprintln!("filtered image: within {d_img:.2e} ({compared} pixels compared)");
    assert!(d_img <= 1e-5, "filtered images differ by {d_img:e}");
}

#[test]
fn tiles_merge_like_ranges() {
    let dir = tempdir("partial-tiles");
    let d = |n: &str| dir.join(n).display().to_string();
    // Unequal left and right halves for samples 0..16, a whole-image part for 16..24.
    let spp = [("--spp", "24")];
    let left = render_part(
        &dir,
        "l.nfp",
        &spp,
        &["--tile", "10x20+0+0", "--samples", "0..16"],
    );
    let right = render_part(
        &dir,
        "r.nfp",
        &spp,
        &["--tile", "14x20+10+0", "--samples", "0..16"],
    );
    let rest = render_part(&dir, "rest.nfp", &spp, &["--samples", "16..24"]);
    ok(&[
        "merge",
        "-q",
        "--aovs",
        &d("tiles.exr"),
        &right,
        &rest,
        &left,
    ]);
    let mut one = render_args(&spp);
    one.extend(["--out".into(), d("one.png"), "--aovs".into(), d("one.exr")]);
    ok(&one.iter().map(String::as_str).collect::<Vec<_>>());
    let read = |n: &str| {
        noisefree::stats::aov::read_aov_exr(Path::new(&d(n)))
            .unwrap()
            .0
    };
    let (one, tiles) = (read("one.exr"), read("tiles.exr"));
    assert_outputs_within_bound(&one, &tiles);
}

/// Replaces `from` by `to` (the same length) in the header of a partial file.
fn edit_header(path: &str, from: &str, to: &str) {
    assert_eq!(from.len(), to.len());
    let mut b = std::fs::read(path).unwrap();
    let at = b
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap_or_else(|| panic!("{from:?} is not in {path}"));
    b[at..at + from.len()].copy_from_slice(to.as_bytes());
    std::fs::write(path, b).unwrap();
}

#[test]
fn parts_that_do_not_make_up_one_render_are_refused_and_nothing_is_written() {
    let dir = tempdir("partial-bad");
    let d = |n: &str| dir.join(n).display().to_string();
    let part = |name: &str, changes: &[(&str, &str)], extra: &[&str]| {
        render_part(&dir, name, changes, extra)
    };
    let second = ["--samples", "8..16"];
    let a = part("a.nfp", &[], &["--samples", "0..8"]);
    let b = part("b.nfp", &[], &second);
    let (png, aovs) = (d("out.png"), d("aovs.exr"));
    let refused = |parts: &[&str], needles: &[&str]| {
        let mut args = vec!["merge", "-q", "--out", &png, "--aovs", &aovs];
        args.extend_from_slice(parts);
        fails(&args, needles);
        assert!(!Path::new(&png).exists() && !Path::new(&aovs).exists());
    };
    // Missing, duplicate and overlapping ranges.
    refused(
        &[&a],
        &["missing samples 8..16 of the whole image", "16 spp"],
    );
    refused(&[&a, &a], &["given twice"]);
    let copy = d("copy.nfp");
    std::fs::copy(&a, &copy).unwrap();
    refused(
        &[&a, &b, &copy],
        &["duplicate pieces", "a.nfp", "copy.nfp", "samples 0..8"],
    );
    let over = part("over.nfp", &[], &["--samples", "4..12"]);
    refused(
        &[&a, &over, &b],
        &["overlapping pieces", "over.nfp", "samples 4..12"],
    );
    let tl = part(
        "tl.nfp",
        &[],
        &["--tile", "12x20+0+0", "--samples", "8..16"],
    );
    refused(&[&a, &tl], &["missing samples 8..16 of tile 12x20+12+0"]);
    // Parts of other renders: the message names both files and what differs.
    let seed = part("seed.nfp", &[("--seed", "4")], &second);
    refused(
        &[&a, &seed],
        &["a.nfp", "seed.nfp", "different seeds (3 and 4)"],
    );
    let size = part("size.nfp", &[("--width", "20")], &second);
    refused(&[&a, &size], &["different resolutions (24x20 and 20x20)"]);
    let length = part("length.nfp", &[("--spp", "32")], &second);
    refused(&[&a, &length], &["different lengths (16 and 32 spp)"]);
    let glossy = bundled_scene_path("cornell_glossy").display().to_string();
    let mut args = render_args(&[]);
    args[1] = glossy;
    args.extend([
        "--partial".into(),
        d("glossy.nfp"),
        "--samples".into(),
        "8..16".into(),
    ]);
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    refused(
        &[&a, &d("glossy.nfp")],
        &[
            "different scenes",
            "cornell_diffuse.toml",
            "cornell_glossy.toml",
        ],
    );
    let none = part("none.nfp", &[("--filter", "none")], &second);
    refused(&[&a, &none], &["gathered different outputs", "none.nfp"]);
    let kernel = d("kernel.nfp");
    std::fs::copy(&b, &kernel).unwrap();
    let text = String::from_utf8_lossy(&bytes(Path::new(&kernel))).into_owned();
    let at = text.find("kernel_hash = \"").unwrap() + 15;
    edit_header(&kernel, &text[at..at + 16], "0123456789abcdef");
    refused(&[&a, &kernel], &["different kernels", "kernel.nfp"]);
    // Damaged files.
    let full = bytes(Path::new(&b));
    std::fs::write(d("trunc.nfp"), &full[..full.len() - 100]).unwrap();
    refused(&[&a, &d("trunc.nfp")], &["trunc.nfp", "truncated file"]);
    let mut flipped = full.clone();
    let last = flipped.len() - 5;
    flipped[last] ^= 0x40;
    std::fs::write(d("damaged.nfp"), &flipped).unwrap();
    refused(
        &[&a, &d("damaged.nfp")],
        &["damaged.nfp", "does not match its checksum"],
    );
    refused(&[&a, &d("nothing.nfp")], &["nothing.nfp", "cannot open it"]);
    std::fs::write(d("text.nfp"), "not a partial render at all").unwrap();
    refused(&[&a, &d("text.nfp")], &["text.nfp", "not a partial render"]);
    // The good parts still merge.
    ok(&["merge", "-q", "--out", &png, &b, &a]);
    assert!(Path::new(&png).exists());
}

#[test]
fn partial_render_flags_are_checked_before_rendering() {
    let dir = tempdir("partial-flags");
    let scene = scene_path();
    let part = dir.join("p.nfp").display().to_string();
    fails(&["render", &scene, "--samples", "0..4"], &["--partial"]);
    fails(&["render", &scene, "--tile", "4x4+0+0"], &["--partial"]);
    fails(
        &[
            "render",
            &scene,
            "--spp",
            "8",
            "--samples",
            "4..12",
            "--partial",
            &part,
        ],
        &["--samples 4..12 runs past the render's 8 samples"],
    );
    fails(
        &[
            "render",
            &scene,
            "--width",
            "16",
            "--height",
            "16",
            "--tile",
            "8x8+12+0",
            "--partial",
            &part,
        ],
        &["tile 8x8+12+0 does not lie inside the 16x16 image"],
    );
    fails(
        &["render", &scene, "--partial", &part, "--out", "x.png"],
        &["--out does not go with --partial"],
    );
    usage_fails(&["render", &scene, "--samples", "4..4"], &["empty"]);
    usage_fails(&["render", &scene, "--tile", "4x4"], &["WxH+X+Y"]);
    usage_fails(
        &["render", &scene, "--gather", "colours"],
        &["no output named"],
    );
    fails(&["merge", &part], &["nothing to write"]);
    assert!(!Path::new(&part).exists());
}
