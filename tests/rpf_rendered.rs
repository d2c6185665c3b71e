//! Random Parameter Filtering on real renders (the sample vectors the megakernel writes): on
//! the bundled Cornell diffuse scene it lowers the error against a high-spp reference, and a
//! scene scaled by 1000 (same image) filters to the same error within 1% (the thesis's scale
//! experiment, Table 5.4, allows 10%).

mod common;

use common::*;
use noisefree::filters::rpf::{self, RpfSettings, SampleSet};
use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::metrics::mse_luv;
use noisefree::scene::Scene;

fn rendered_samples(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> (SampleSet, RgbImage) {
    let mut o = options(scene, w, h, seed);
    o.outputs = OutputSet::of(&[Output::Samples]);
    o.sample_capacity = spp;
    let frame = render_frame(scene, &o, spp);
    (
        SampleSet::from_frame(&frame, Default::default()).unwrap(),
        frame.beauty().unwrap(),
    )
}

#[test]
fn rpf_lowers_the_error_on_cornell_diffuse_and_ignores_the_scene_scale() {
    let scene = bundled_scene("cornell_diffuse");
    let (w, h) = (64, 64);
    let truth = reference_image(&scene, w, h, 1024, 1000);
    let settings = RpfSettings::default();
    let (set, noisy) = rendered_samples(&scene, w, h, 8, 7);
    let filtered = rpf::filter(&set, &settings).unwrap();
    let (before, after) = (
        mse_luv(&noisy, &truth).unwrap(),
        mse_luv(&filtered, &truth).unwrap(),
    );
    eprintln!("Cornell diffuse 64x64, 8 spp: MSE-LUV {before:.2} unfiltered, {after:.2} RPF");
    // RPF's weighted means do not keep the image's mean: measured, the filtered image is
    // brighter than the reference by 2.0 % (red), 3.7 % (green), 4.6 % (blue), while the
    // unfiltered one is within 0.3 %. Not a property the thesis claims; this bound (7 %,
    // 1.5 x the largest) only keeps it from growing unnoticed.
    let (mt, mf) = (mean_rgb(&truth.pixels), mean_rgb(&filtered.pixels));
    eprintln!("mean colour: reference {mt:.4?}, RPF {mf:.4?}");
    for c in 0..3 {
        assert!(
            (mf[c] / mt[c] - 1.0).abs() < 0.07,
            "channel {c}: RPF's mean {} vs the reference's {}",
            mf[c],
            mt[c]
        );
    }
    // RPF's parameters are the thesis's (§5.1), not tuned on this scene. Measured (PoCL,
    // seed 7): 33.82 -> 24.53, a ratio of 0.725 (the pre-redesign binary measured the same).
    // The bound keeps about two thirds of that 27.5 % reduction: 0.82.
    assert!(
        after < 0.82 * before,
        "RPF did not lower the error: {after} vs {before}"
    );

    // The same scene at 1000 times its size renders the same image; RPF's world-position
    // features scale with it and its normalisation (§5.1.2) must take that out.
    let (set_big, _) = rendered_samples(&scene.scaled(1000.0), w, h, 8, 7);
    let filtered_big = rpf::filter(&set_big, &settings).unwrap();
    let after_big = mse_luv(&filtered_big, &truth).unwrap();
    eprintln!("scaled x1000: MSE-LUV {after_big:.3} RPF (unscaled {after:.3})");
    // Measured: 24.519 vs 24.526, 0.03 % apart. The thesis's Table 5.4 allows 10 %; the bound
    // is 1 %, which leaves room for the renderer itself (its scale-1000 image is up to ~0.8 %
    // darker, tests/atrous.rs) but not for a normalisation that misses the scale.
    assert!(
        (after_big - after).abs() < 0.01 * after,
        "scale changed RPF's error: {after_big} vs {after}"
    );
}
