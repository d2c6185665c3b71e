//! Random Parameter Filtering on real renders (the sample vectors the megakernel writes): on
//! the bundled Cornell diffuse scene it lowers the error against a high-spp reference, and a
//! scene scaled by 1000 (same image) filters to the same error within 10% (the thesis's scale
//! experiment, Table 5.4).

mod common;

use common::*;
use noisefree::filters::rpf::{self, RpfSettings, SampleSet};
use noisefree::imaging::RgbImage;
use noisefree::metrics::mse_luv;
use noisefree::render::Renderer;
use noisefree::scene::Scene;

fn rendered_samples(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> (SampleSet, RgbImage) {
    let mut o = options(scene, w, h, seed);
    o.outputs.sample_vectors = Some(spp);
    let mut r = Renderer::new(gpu(), scene, &o).unwrap();
    r.render_samples(spp).unwrap();
    let (n, samples) = r.read_sample_vectors().unwrap();
    (
        SampleSet::new(w, h, n, samples).unwrap(),
        r.read_buffers().unwrap().beauty(),
    )
}

fn reference(scene: &Scene, w: u32, h: u32) -> RgbImage {
    let o = options(scene, w, h, 1000);
    let mut r = Renderer::new(gpu(), scene, &o).unwrap();
    r.render_samples(1024).unwrap();
    r.read_buffers().unwrap().beauty()
}

#[test]
fn rpf_lowers_the_error_on_cornell_diffuse_and_ignores_the_scene_scale() {
    let scene = noisefree::scene::load_scene(&repo_path("scenes/cornell_diffuse.toml")).unwrap();
    let (w, h) = (64, 64);
    let truth = reference(&scene, w, h);
    let settings = RpfSettings::default();
    let (set, noisy) = rendered_samples(&scene, w, h, 8, 7);
    let filtered = rpf::filter(&set, &settings).unwrap();
    let (before, after) = (
        mse_luv(&noisy, &truth).unwrap(),
        mse_luv(&filtered, &truth).unwrap(),
    );
    eprintln!("Cornell diffuse 64x64, 8 spp: MSE-LUV {before:.2} unfiltered, {after:.2} RPF");
    assert!(
        after < 0.9 * before,
        "RPF did not lower the error: {after} vs {before}"
    );

    // The same scene at 1000 times its size renders the same image; RPF's world-position
    // features scale with it and its normalisation (§5.1.2) must take that out.
    let (set_big, _) = rendered_samples(&scene.scaled(1000.0), w, h, 8, 7);
    let filtered_big = rpf::filter(&set_big, &settings).unwrap();
    let after_big = mse_luv(&filtered_big, &truth).unwrap();
    assert!(
        (after_big - after).abs() < 0.1 * after,
        "scale changed RPF's error: {after_big} vs {after}"
    );
}
