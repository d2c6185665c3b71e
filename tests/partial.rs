//! Partial renders and their merge (src/stats/partial.rs, src/stats/merge.rs,
//! `render --samples A..B --partial`, `noisefree merge`): sample ranges and tiles merged equal
//! the one-machine render to float rounding, every output buffer compared lane by lane; the
//! same parts in any order or grouping give the same bytes; parts that do not make up one
//! render are refused with the files named, and nothing is written.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use noisefree::filters::{FilterRequest, Registry};
use noisefree::layout::outputs::{BUFFERS, BufferId, Output, OutputSet};
use noisefree::layout::{SKY_DEPTH, WelfordState};
use noisefree::render::{Frame, RenderOptions, Renderer, Tile};
use noisefree::stats::merge::Plan;
use noisefree::stats::partial::{self, Piece, PieceInfo, RenderIdentity};

const W: u32 = 40;
const H: u32 = 30;
const SPP: u32 = 24;
const SEED: u32 = 5;

/// Merged against one-machine renders: every lane of every output buffer agrees within this,
/// relative to the larger magnitude (absolute below 1e-3). Both sides round: the one-machine
/// render its float running means and Kahan-summed S_n over all samples, the merge the parts'
/// float running means, combined in double precision. Measured (PoCL): 1.5e-5 on the mean
/// first-bounce direction (a component near 0, so absolute: 1.5e-8), at most 5.0e-6 on every
/// other lane (F's normal, S_n of the direction), on cornell_plane_dof (DOF, textures), 40 x
/// 30, 24 spp, ranges 0..5, 5..11 in four tiles, 11..24; 1.05e-5 and 1.6e-6 on
/// cornell_diffuse 24 x 20 through the command line. Bound 3e-5 (2x).
const MERGE_BOUND: f64 = 3e-5;

fn options_for(scene: &noisefree::scene::Scene) -> RenderOptions {
    let mut o = options(scene, W, H, SEED);
    o.outputs = OutputSet::of(&[Output::Variance, Output::Position, Output::Samples]);
    o
}

/// Samples `range` of `tile`, rendered in launches of at most 4 samples.
fn piece(scene: &noisefree::scene::Scene, range: std::ops::Range<u32>, tile: Tile) -> Piece {
    let mut o = options_for(scene);
    o.first_sample = range.start;
    o.tile = Some(tile);
    o.sample_capacity = range.end - range.start;
    let mut r = Renderer::new(gpu(), scene, &o).unwrap_or_else(|e| panic!("{e:#}"));
    while r.samples_done() < range.end - range.start {
        r.render_samples(4.min(range.end - range.start - r.samples_done()))
            .unwrap();
    }
    let info = PieceInfo {
        tile,
        samples: range,
        rays: r.rays_total,
        seconds: r.kernel_time_total.as_secs_f64(),
        device: "test".into(),
    };
    Piece::of_frame(&r.frame(), info).unwrap()
}

fn identity(scene: &noisefree::scene::Scene) -> RenderIdentity {
    let o = options_for(scene);
    let arrays = noisefree::render::SceneArrays::build(scene, &o.frame).unwrap();
    let mut record = noisefree::stats::RenderRecord::default();
    record.scene = Some(noisefree::render::SceneInfo::new(scene, &arrays));
    RenderIdentity {
        scene: "test".into(),
        scene_hash: noisefree::render::scene_hash(&arrays),
        kernel_hash: noisefree::render::kernel_hash(),
        width: W,
        height: H,
        seed: SEED,
        spp: SPP,
        outputs: o.outputs.closed(),
        record,
    }
}

/// The one-machine render: all samples, in two launches.
fn one_machine(scene: &noisefree::scene::Scene) -> Frame {
    let mut o = options_for(scene);
    o.sample_capacity = SPP;
    let mut r = Renderer::new(gpu(), scene, &o).unwrap();
    r.render_samples(9).unwrap();
    r.render_samples(SPP - 9).unwrap();
    r.frame()
}

/// The lanes of a buffer as values: S_n as s − c (its Kahan compensation taken out, film.cl),
/// the compensations themselves as 0 (they are compared inside S_n), everything else as stored.
fn values(f: &Frame, id: BufferId) -> Vec<f64> {
    let floats = f.host(id).unwrap().floats();
    let state: &[WelfordState] = match id {
        BufferId::WelfordSums | BufferId::WelfordState => {
            f.host_slice(BufferId::WelfordState).unwrap()
        }
        _ => return floats.iter().map(|&v| v as f64).collect(),
    };
    if id == BufferId::WelfordState {
        return state
            .iter()
            .flat_map(|c| {
                let mut v = [0f64; 20];
                for (i, d) in c.direction_mean.iter().enumerate() {
                    v[i] = *d as f64;
                }
                v
            })
            .collect();
    }
    floats
        .chunks(16)
        .zip(state)
        .flat_map(|(s, c)| (0..16).map(move |i| s[i] as f64 - c.s_compensation[i] as f64))
        .collect()
}

/// The largest difference of two buffers relative to the larger magnitude (absolute below
/// 1e-3), with where it is: (difference, element, lane).
fn worst(a: &[f64], b: &[f64], floats: usize) -> (f64, usize, usize) {
    assert_eq!(a.len(), b.len());
    let mut w = (0.0, 0, 0);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        let d = (x - y).abs() / x.abs().max(y.abs()).max(1e-3);
        if d > w.0 {
            w = (d, i / floats, i % floats);
        }
    }
    w
}

fn ddf_image(frame: &Frame) -> noisefree::imaging::RgbImage {
    let r = Registry::builtin();
    let ddf = r.get("ddf").unwrap();
    let c = r
        .configure(ddf, &FilterRequest::default(), &frame.info().scene)
        .unwrap();
    c.prepare(frame.info(), &gpu())
        .unwrap()
        .run(frame)
        .unwrap()
        .image
}

#[test]
fn merged_ranges_and_tiles_equal_the_one_machine_render() {
    let scene = bundled_scene("cornell_plane_dof");
    let one = one_machine(&scene);
    let dir = tempdir("partial-merge");
    let whole = Tile::whole(W, H);
    // Three ranges, the middle one in four unequal tiles.
    let quarters = ["17x13+0+0", "23x13+17+0", "17x17+0+13", "23x17+17+13"];
    let mut pieces = vec![("a.nfp".to_string(), piece(&scene, 0..5, whole))];
    for (i, t) in quarters.iter().enumerate() {
        let t = Tile::parse(t).unwrap();
        pieces.push((format!("b{i}.nfp"), piece(&scene, 5..11, t)));
    }
    pieces.push(("c.nfp".into(), piece(&scene, 11..SPP, whole)));
    let paths: Vec<PathBuf> = pieces
        .iter()
        .map(|(name, p)| {
            let path = dir.join(name);
            partial::write(&path, &identity(&scene), std::slice::from_ref(p)).unwrap();
            path
        })
        .collect();
    let merged = Plan::new(&paths).unwrap().merge(|_| {}).unwrap().frame;
    assert_eq!(merged.info().spp, SPP);

    for b in BUFFERS {
        let (x, y) = (values(&one, b.id), values(&merged, b.id));
        let (d, element, lane) = worst(&x, &y, b.element_bytes / 4);
        eprintln!(
            "{}: merged within {d:.2e} of the one-machine render (element {element}, lane {lane})",
            b.name
        );
        assert!(
            d <= MERGE_BOUND,
            "{}: element {element} lane {lane} differs by {d:e}",
            b.name
        );
    }
    // What is not rounded is equal: the sample vectors (the same samples), the depth shift K
    // (sample 0's depth, as in one render) and the hit counts.
    let exact = |id: BufferId, lanes: &[usize]| {
        let floats = id.decl().element_bytes / 4;
        let (x, y) = (values(&one, id), values(&merged, id));
        for (i, (a, b)) in x.iter().zip(&y).enumerate() {
            if lanes.is_empty() || lanes.contains(&(i % floats)) {
                assert_eq!(a.to_bits(), b.to_bits(), "{} value {i}", id.decl().name);
            }
        }
    };
    exact(BufferId::SampleVectors, &[]);
    exact(BufferId::DepthShifts, &[0]);
    exact(BufferId::Positions, &[3]);

    // The filter sees the difference as float rounding too, except where it is not continuous
    // in its input: a pixel whose samples hit both surfaces and the sky has F.depth = a mean
    // of SKY_DEPTH (1e9) and surface depths, ~1e8, whose float rounding (measured: up to 64,
    // 7.6e-7 relative, the one-machine render's running mean) flips the data-driven filter's
    // depth weight (measured: 0.47 at such pixels). Elsewhere measured 3.6e-6 relative
    // (absolute below 1e-3); bound 1e-5.
    let (i1, i2) = (ddf_image(&one), ddf_image(&merged));
    let (d, compared) = filtered_difference(&one, &i1, &i2);
    eprintln!(
        "ddf image: merged within {d:.2e} of the one-machine render ({compared} of {} pixels)",
        i1.pixels.len()
    );
    assert!(d <= 1e-5, "{d:e}");
}

/// The largest difference of two filtered images of `one` relative to the larger magnitude
/// (absolute below 1e-3), leaving out the pixels whose samples hit both surfaces and the sky
/// (see above); and how many pixels it compared, at least 85% of them.
fn filtered_difference(
    one: &Frame,
    a: &noisefree::imaging::RgbImage,
    b: &noisefree::imaging::RgbImage,
) -> (f32, usize) {
    let f = one.filter_vectors().unwrap();
    let mut d = 0f32;
    let mut compared = 0;
    for (p, (x, y)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if f[p].depth > 1e6 && f[p].depth != SKY_DEPTH {
            continue;
        }
        compared += 1;
        for c in 0..3 {
            d = d.max((x[c] - y[c]).abs() / x[c].abs().max(y[c].abs()).max(1e-3));
        }
    }
    assert!(compared * 100 >= a.pixels.len() * 85, "{compared} pixels");
    (d, compared)
}

#[test]
fn a_single_part_merges_to_exactly_its_own_bytes() {
    // Nothing to combine, so nothing may round: a merge of one whole render is that render.
    let scene = bundled_scene("cornell_diffuse");
    let p = piece(&scene, 0..SPP, Tile::whole(W, H));
    let dir = tempdir("partial-single");
    let path = dir.join("all.nfp");
    partial::write(&path, &identity(&scene), std::slice::from_ref(&p)).unwrap();
    let merged = Plan::new(&[path]).unwrap().merge(|_| {}).unwrap().frame;
    for (id, buffer) in &p.buffers {
        let (a, b) = (merged.host(*id).unwrap().floats(), buffer.floats());
        let floats = id.decl().element_bytes / 4;
        if let Some(i) = (0..a.len()).find(|&i| a[i].to_bits() != b[i].to_bits()) {
            panic!(
                "{}: element {} lane {}: merged {:e}, rendered {:e}",
                id.decl().name,
                i / floats,
                i % floats,
                a[i],
                b[i]
            );
        }
    }
}

// ---- The command line ----

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
    assert_eq!(merged.outputs(), one.outputs());
    for id in one.outputs().buffers().map(|b| b.id) {
        let floats = id.decl().element_bytes / 4;
        let (x, y) = (values(&one, id), values(&merged, id));
        let (w, element, lane) = worst(&x, &y, floats);
        eprintln!(
            "{}: within {w:.2e} (pixel {element}, lane {lane})",
            id.decl().name
        );
        assert!(
            w <= MERGE_BOUND,
            "{}: pixel {element} lane {lane}: {w:e}",
            id.decl().name
        );
    }
    let exr = |p: &str| noisefree::imaging::read_exr_rgb(Path::new(p)).unwrap();
    let (d_img, compared) = filtered_difference(&one, &exr(&d("one.exr")), &exr(&d("forward.exr")));
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
    for id in one.outputs().buffers().map(|b| b.id) {
        let floats = id.decl().element_bytes / 4;
        let (w, element, lane) = worst(&values(&one, id), &values(&tiles, id), floats);
        eprintln!(
            "{}: within {w:.2e} (pixel {element}, lane {lane})",
            id.decl().name
        );
        assert!(
            w <= MERGE_BOUND,
            "{}: pixel {element} lane {lane}: {w:e}",
            id.decl().name
        );
    }
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
