//! The wavefront tracer (kernels/render/wavefront.cl, src/render/wavefront.rs) against the
//! megakernel, which stays the reference (itself checked against the Rust path tracer by
//! tests/reference.rs): every output buffer, the ray counts and the debug counters must be the
//! same bytes, on every bundled scene, with every output the filters ask for, over bands of
//! rows, tiles, sample ranges and launches of several samples.

mod common;

use common::*;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::{RenderOptions, Tile, Tracer};
use noisefree::scene::Scene;

/// Renders `scene` with both tracers in launches of `batches` samples and asserts the same
/// buffers, rays and debug counters ([`render_in_launches`], [`assert_same_render`]).
fn assert_tracers_agree(scene: &Scene, options: &RenderOptions, batches: &[u32], what: &str) {
    let (mut mega, mut wave) = (options.clone(), options.clone());
    mega.tracer = Tracer::Megakernel;
    wave.tracer = Tracer::Wavefront;
    let what = format!("{what}: the wavefront against the megakernel");
    assert_options_agree(scene, &mega, &wave, batches, &what);
}

#[test]
fn every_bundled_scene_gives_the_megakernels_bytes() {
    for path in bundled_scenes() {
        let scene = noisefree::scene::load_scene(&path).unwrap();
        let mut o = options(&scene, 21, 13, 3);
        o.outputs = OutputSet::of(&[
            Output::Features,
            Output::Variance,
            Output::Position,
            Output::Samples,
            Output::Halves,
            Output::Emission,
        ]);
        o.sample_capacity = 3;
        // Waves of three rows: a launch traces five waves one after the other.
        o.wave_paths = Some(3 * 21);
        assert_tracers_agree(&scene, &o, &[2, 1], &path.display().to_string());
    }
}

#[test]
fn mirrors_glass_and_clamped_samples_give_the_megakernels_bytes() {
    let scene = cornell_with_spheres();
    let mut o = options(&scene, 19, 17, 7);
    o.outputs = OutputSet::of(&[Output::Features, Output::Variance, Output::Samples]);
    o.sample_capacity = 4;
    assert_tracers_agree(&scene, &o, &[1, 2, 1], "Cornell box with spheres");
    o.frame.sample_clamp = 0.5;
    assert_tracers_agree(&scene, &o, &[3], "clamped samples");
    // A work-group size of its own, waves of a few rows (4: a multiple of the work-group's
    // height), and paths cut at depth 2 without Russian roulette.
    o.local_size = Some([4, 2]);
    o.wave_paths = Some(3 * 19 + 1);
    o.frame.sample_clamp = 0.0;
    let shallow = scene_from_toml(&cornell("max_depth = 2\nrussian_roulette = false", ""));
    assert_tracers_agree(&shallow, &o, &[2], "depth 2, work-group 4 x 2");
}

#[test]
fn the_shadow_light_field_and_indirect_outputs_give_the_megakernels_bytes() {
    // Soft shadows of two sphere lights (AAF and sheared filtering's outputs), depth of field
    // with the lens field, and AAF's indirect output.
    let shadows = bundled_scene("two_lights_shadows");
    let mut o = options(&shadows, 24, 18, 5);
    o.outputs = OutputSet::of(&[Output::Shadows, Output::LightField]);
    assert_tracers_agree(&shadows, &o, &[2, 1], "shadows and their light field");
    let mut lens = bundled_scene("two_lights_shadows");
    lens.camera.lens_radius = 0.2;
    let mut o = options(&lens, 24, 18, 5);
    o.outputs = OutputSet::of(&[Output::Shadows, Output::LightField, Output::LensShadows]);
    assert_tracers_agree(&lens, &o, &[2], "shadows through a lens");
    o.outputs = OutputSet::of(&[Output::LightField]);
    assert_tracers_agree(&lens, &o, &[1, 1], "the lens field");
    let room = bundled_scene("room_gi");
    let mut o = options(&room, 24, 18, 5);
    o.outputs = OutputSet::of(&[Output::Indirect]);
    assert_tracers_agree(&room, &o, &[2], "indirect light");
}

#[test]
fn tiles_and_sample_ranges_give_the_megakernels_bytes() {
    let scene = bundled_scene("cornell_glossy");
    let mut o = options(&scene, 30, 22, 9);
    o.outputs = OutputSet::of(&[Output::Variance, Output::Samples, Output::Halves]);
    o.sample_capacity = 3;
    o.tile = Some(Tile {
        x: 7,
        y: 5,
        width: 13,
        height: 11,
    });
    o.first_sample = 5;
    o.wave_paths = Some(2 * 13);
    assert_tracers_agree(&scene, &o, &[2, 1], "a tile of samples 5..8");
}
