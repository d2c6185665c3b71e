//! Partial renders and their merge (src/stats/partial/, src/stats/merge/): sample ranges and
//! tiles merged equal the one-machine render to float rounding, every output buffer compared
//! lane by lane (the bound: tests/common/merge.rs), and so do their filtered images; a single
//! part merges to its own bytes. The command line (`render --samples`, `merge`, bad parts):
//! tests/merge_cli.rs.

mod common;

use std::path::PathBuf;

use common::merge::*;
use common::*;
use noisefree::filters::{FilterRequest, Registry};
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::render::{Frame, RenderOptions, Renderer, Tile};
use noisefree::stats::merge::Plan;
use noisefree::stats::partial::{self, Piece, PieceInfo, RenderIdentity};

const W: u32 = 40;
const H: u32 = 30;
const SPP: u32 = 24;
const SEED: u32 = 5;

fn options_for(scene: &noisefree::scene::Scene) -> RenderOptions {
    let mut o = options(scene, W, H, SEED);
    o.outputs = OutputSet::of(&[
        Output::Variance,
        Output::Position,
        Output::Samples,
        Output::Halves,
    ]);
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
    let record = noisefree::stats::RenderRecord {
        scene: Some(noisefree::render::SceneInfo::new(scene, &arrays)),
        ..Default::default()
    };
    RenderIdentity {
        scene: "test".into(),
        scene_hash: noisefree::render::scene_hash(&arrays),
        kernel_hash: noisefree::render::kernel_hash(),
        width: W,
        height: H,
        seed: SEED,
        spp: SPP,
        outputs: o.outputs.closed(),
        shadow_lights: if o.outputs.closed().contains(Output::Shadows) {
            o.shadows.lights.lights()
        } else {
            Vec::new()
        },
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

    assert_outputs_within_bound(&one, &merged);
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
    exact(BufferId::OddHalves, &[3]);

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

/// AAF's shadow output from sample ranges: its passes depend on the pixel alone, so every part
/// holds the same shadow pixels (merged as `Merge::Identical`: bit for bit), the replaced
/// light is a mean over the path samples like F, and the filtered image is the one machine's.
/// Tiles are refused (the slope fill reaches across them).
#[test]
fn shadow_output_merges_from_sample_ranges_and_refuses_tiles() {
    let scene = bundled_scene("grids");
    let shadows = |o: &mut RenderOptions| {
        o.outputs = OutputSet::of(&[Output::Variance, Output::Shadows]);
    };
    let render = |range: std::ops::Range<u32>| {
        let mut o = options_for(&scene);
        shadows(&mut o);
        o.first_sample = range.start;
        let mut r = Renderer::new(gpu(), &scene, &o).unwrap_or_else(|e| panic!("{e:#}"));
        r.render_samples(range.end - range.start).unwrap();
        let info = PieceInfo {
            tile: Tile::whole(W, H),
            samples: range,
            rays: r.rays_total,
            seconds: 0.0,
            device: "test".into(),
        };
        (r.frame(), info)
    };
    let (one, _) = render(0..SPP);
    let mut id = identity(&scene);
    id.outputs = one.outputs();
    id.shadow_lights = one.info().shadow_lights.clone();
    let dir = tempdir("partial-shadows");
    let paths: Vec<PathBuf> = [0..7, 7..SPP]
        .into_iter()
        .map(|range| {
            let (frame, info) = render(range.clone());
            let path = dir.join(format!("{}.nfp", range.start));
            let piece = Piece::of_frame(&frame, info).unwrap();
            partial::write(&path, &id, std::slice::from_ref(&piece)).unwrap();
            path
        })
        .collect();
    let merged = Plan::new(&paths).unwrap().merge(|_| {}).unwrap().frame;
    assert_outputs_within_bound(&one, &merged);
    let (a, b) = (
        one.host(BufferId::ShadowPixels).unwrap().floats(),
        merged.host(BufferId::ShadowPixels).unwrap().floats(),
    );
    assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
    let pixels: &[noisefree::layout::ShadowPixel] = one.host_slice(BufferId::ShadowPixels).unwrap();
    let receivers = pixels.iter().filter(|p| p.weight > 0.0).count();
    assert!(receivers * 2 > pixels.len(), "{receivers} receivers");

    let aaf = |frame: &Frame| {
        let r = Registry::builtin();
        let c = r
            .configure(
                r.get("aaf-shadows").unwrap(),
                &FilterRequest::default(),
                &frame.info().scene,
            )
            .unwrap();
        c.prepare(frame.info(), &gpu())
            .unwrap()
            .run(frame)
            .unwrap()
            .image
    };
    let (i1, i2) = (aaf(&one), aaf(&merged));
    let (d, compared) = filtered_difference(&one, &i1, &i2);
    eprintln!(
        "aaf-shadows image: merged within {d:.2e} of the one-machine render ({compared} pixels)"
    );
    assert!(d <= 1e-5, "{d:e}");

    let mut o = options_for(&scene);
    shadows(&mut o);
    o.tile = Some(Tile::parse("20x30+0+0").unwrap());
    let e = format!(
        "{:#}",
        Renderer::new(gpu(), &scene, &o)
            .err()
            .expect("a tile is refused")
    );
    assert!(e.contains("whole image") && e.contains("--samples"), "{e}");
}

/// The kernel hash that keys partial renders and the reference cache covers the megakernel's
/// program (render/pathtrace.cl and its includes) and nothing else: a filter's or a
/// benchmark's kernel can change without invalidating them.
#[test]
fn kernel_hash_covers_the_megakernel_program_only() {
    let program = noisefree::kernels::assemble("render/pathtrace.cl", "").unwrap();
    for part in ["render/outputs.cl", "render/shadows.cl", "layout.cl"] {
        assert!(program.contains(&format!("#line 1 \"{part}\"")), "{part}");
    }
    for other in ["filters/", "bench/", "render/subtractive.cl", "test/"] {
        assert!(!program.contains(&format!("#line 1 \"{other}")), "{other}");
    }
    assert_eq!(
        noisefree::render::kernel_hash(),
        noisefree::gpu::fnv1a(&[program.as_bytes()])
    );
}
