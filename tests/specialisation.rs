//! "Simulate only the effects a scene calls for": kernels specialised to each scene render
//! the same bytes as the generic kernel, code for absent effects never runs, and kernel builds
//! are cached on disk.

mod common;

use common::*;
use noisefree::gpu::{BuildSource, Gpu};
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::{DEBUG_COUNTERS, Renderer};

#[test]
fn specialised_kernels_render_the_generic_kernels_bytes() {
    let scenes = bundled_scenes();
    assert!(scenes.len() >= 10, "the five scenes and their DOF variants");
    for path in scenes {
        let scene = noisefree::scene::load_scene(&path).unwrap();
        let mut o = options(&scene, 24, 16, 3);
        o.outputs = OutputSet::of(&[Output::Features, Output::Variance]);
        let specialised = film_bytes(&render_film(&scene, &o, 3, 3));
        o.all_features = true;
        let generic = film_bytes(&render_film(&scene, &o, 3, 3));
        assert!(
            specialised == generic,
            "{}: the specialised kernel's image differs from the generic one",
            path.display()
        );
    }
}

fn counters(text: &str, all_features: bool) -> std::collections::BTreeMap<&'static str, u32> {
    counters_with(text, all_features, OutputSet::colour())
}

fn counters_with(
    text: &str,
    all_features: bool,
    outputs: OutputSet,
) -> std::collections::BTreeMap<&'static str, u32> {
    let scene = scene_from_toml(text);
    let mut o = options(&scene, 16, 16, 1);
    o.debug_counters = true;
    o.all_features = all_features;
    o.outputs = outputs;
    let mut r = Renderer::new(gpu(), &scene, &o).unwrap();
    r.render_samples(2).unwrap();
    DEBUG_COUNTERS
        .iter()
        .copied()
        .zip(r.read_debug_counters().unwrap())
        .collect()
}

#[test]
fn absent_effects_never_run() {
    let glass = "[[material]]\nname = \"glass\"\ntype = \"glass\"\n\n[[sphere]]\ncenter = [0, 0.5, 0]\nradius = 0.4\nmaterial = \"glass\"\n";
    let pinhole_no_glass = cornell("max_depth = 3", "");
    let dof_with_glass = cornell("max_depth = 3", glass).replace(
        "fov = 40",
        "fov = 40\nlens_radius = 0.05\nfocal_distance = 3",
    );
    let mut seen = Vec::new();
    for all in [false, true] {
        let c = counters(&pinhole_no_glass, all);
        eprintln!("{c:?}");
        let which = if all { "generic" } else { "specialised" };
        assert_eq!(
            c["lens samples"], 0,
            "{which}: a pinhole camera sampled its lens"
        );
        assert_eq!(
            c["glass scatters"], 0,
            "{which}: a scene without glass evaluated glass"
        );
        assert_eq!(c["metal scatters"], 0, "{which}");
        assert_eq!(c["sphere light samples"], 0, "{which}");
        assert_eq!(c["surface texture lookups"], 0, "{which}");
        if !all {
            // The generic kernel cannot know these are empty; the specialised one has no code.
            assert_eq!(
                c["environment lookups"], 0,
                "{which}: no environment light, yet it was looked up"
            );
            assert_eq!(
                c["sphere list tests"], 0,
                "{which}: a scene without spheres tested its sphere list"
            );
        }
        // Measured (both kernels): 1664 BVH traversals, 1505 diffuse scatters and as many
        // triangle light samples (one per diffuse vertex), for 512 camera rays. Bounds:
        // measured / 1.5.
        assert!(
            c["BVH traversals"] > 1100 && c["diffuse scatters"] > 1000,
            "{which}: {c:?}"
        );
        assert_eq!(
            c["triangle light samples"], c["diffuse scatters"],
            "{which}: one light sample per diffuse vertex"
        );
        seen.push(c);
    }
    // Both kernels trace the same paths: every effect the scene has ran exactly as often.
    // (Only the environment lookups of escaping rays, 117 here, and the sphere list tests
    // differ: the generic kernel cannot know they find nothing.)
    for (name, count) in &seen[0] {
        if !["environment lookups", "sphere list tests"].contains(name) {
            assert_eq!(*count, seen[1][name], "{name}: specialised vs generic");
        }
    }
    assert_eq!(seen[1]["sphere list tests"], seen[1]["BVH traversals"]);
    // The counters do count: the same code runs when the scene calls for it.
    let c = counters(&dof_with_glass, false);
    eprintln!("{c:?}");
    assert_eq!(c["lens samples"], 16 * 16 * 2);
    // Every closest-hit query tests the sphere list once (measured: 1846 each). Measured: 255
    // glass scatters; bound 170 (measured / 1.5).
    assert_eq!(c["sphere list tests"], c["BVH traversals"], "{c:?}");
    assert!(c["glass scatters"] > 170, "{c:?}");
    // And the feature set says why.
    let scene = scene_from_toml(&pinhole_no_glass);
    let set = noisefree::render::FeatureSet::for_scene(&scene, OutputSet::colour());
    for off in [
        "HAS_GLASS",
        "HAS_DOF",
        "HAS_ENV",
        "HAS_SPHERES",
        "OUTPUT_FEATURES",
        "OUTPUT_VARIANCE",
        "OUTPUT_POSITION",
        "OUTPUT_SAMPLES",
    ] {
        assert!(!set.is_on(off), "{off} should be off");
    }
}

/// A path's last possible vertex (the fixed depth without Russian roulette) draws no BSDF
/// sample (kernels/render/path.cl, path_vertex): nothing reads it, except the features'
/// first-bounce direction. The images are the same bytes either way (the random numbers are
/// counters); scripts/render-ab.sh measured 1.06-1.14x on the scenes without Russian roulette.
#[test]
fn the_last_vertex_draws_no_bsdf_sample() {
    for all in [false, true] {
        // Direct light only: one vertex, whose light sample is all the image needs.
        let direct = cornell("max_depth = 1\nrussian_roulette = false", "");
        let c = counters_with(&direct, all, OutputSet::colour());
        eprintln!("{c:?}");
        // Measured: 501 of the 512 camera rays hit a diffuse wall (the rest the light).
        assert!(c["triangle light samples"] >= 490, "{c:?}");
        assert_eq!(c["diffuse scatters"], 0, "all {all}: {c:?}");
        // With the features, the first vertex's direction is recorded, so it is drawn.
        let f = counters_with(&direct, all, OutputSet::of(&[Output::Features]));
        assert_eq!(f["diffuse scatters"], f["triangle light samples"], "{f:?}");
        assert_eq!(f["triangle light samples"], c["triangle light samples"]);
        // Two vertices: only the first one's BSDF sample is drawn.
        let two = cornell("max_depth = 2\nrussian_roulette = false", "");
        let c2 = counters_with(&two, all, OutputSet::colour());
        eprintln!("{c2:?}");
        assert_eq!(
            c2["diffuse scatters"], c["triangle light samples"],
            "{c2:?}"
        );
        assert!(
            c2["triangle light samples"] > c2["diffuse scatters"],
            "{c2:?}"
        );
    }
}

#[test]
fn kernel_binaries_are_cached_on_disk_and_invalidated_by_changes() {
    let dir = tempdir("kcache");
    let defines = generic_defines();
    let source_of = |gpu: &Gpu| gpu.builds().last().unwrap().source;
    let first = Gpu::open_with_cache(None, Some(dir.clone())).unwrap();
    first.program("render/pathtrace.cl", &defines, "").unwrap();
    assert_eq!(source_of(&first), BuildSource::Compiled);
    first.program("render/pathtrace.cl", &defines, "").unwrap();
    assert_eq!(
        source_of(&first),
        BuildSource::Memory,
        "the same run reuses the program"
    );
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        1,
        "one binary stored"
    );

    // A second run (a new context) loads the binary instead of compiling.
    let second = Gpu::open_with_cache(None, Some(dir.clone())).unwrap();
    second.program("render/pathtrace.cl", &defines, "").unwrap();
    assert_eq!(source_of(&second), BuildSource::Disk);
    // A program from the disk cache works: it renders like a compiled one.
    let scene = scene_from_toml(&cornell("max_depth = 2", ""));
    let o = options(&scene, 8, 8, 1);
    let mut a = Renderer::new(first.clone(), &scene, &o).unwrap();
    let mut b = Renderer::new(second.clone(), &scene, &o).unwrap();
    a.render_samples(2).unwrap();
    b.render_samples(2).unwrap();
    assert_eq!(
        film_bytes(a.frame().filter_vectors().unwrap()),
        film_bytes(b.frame().filter_vectors().unwrap())
    );

    // Another option or another source text is another program.
    let mut other = defines.clone();
    other.retain(|d| d.0 != "HAS_GLASS");
    other.push(("HAS_GLASS".into(), "0".into()));
    second.program("render/pathtrace.cl", &other, "").unwrap();
    assert_eq!(source_of(&second), BuildSource::Compiled);
    second
        .program("render/pathtrace.cl", &defines, "// changed source\n")
        .unwrap();
    assert_eq!(source_of(&second), BuildSource::Compiled);
    let _ = std::fs::remove_dir_all(&dir);
}
