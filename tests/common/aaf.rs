//! Helpers of the AAF soft-shadow tests (tests/aaf_*.rs).

use noisefree::filters::Configured;
use noisefree::filters::aaf_shadows::{AafShadowSettings, AafShadows};
use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::{Frame, Renderer, ShadowSampling};
use noisefree::scene::Scene;

use super::{gpu, options, scene_from_toml};

/// A sphere light of radius 0.3 three metres above the floor's centre.
pub const OVERHEAD: &str = "center = [0, 3, 0]\nradius = 0.3";

/// A 6 × 6 floor (material "floor") seen from (0, 3, 3) under a sphere light (`light`: its
/// centre and radius lines), with `extra` appended; direct light only.
pub fn floor_scene(light: &str, extra: &str) -> Scene {
    scene_from_toml(&format!(
        r#"
[render]
max_depth = 1
russian_roulette = false

[camera]
origin = [0, 3, 3]
target = [0, 0, 0]
fov = 40

[[material]]
name = "floor"
type = "diffuse"
color = [0.8, 0.8, 0.8]

[[mesh]]
generator = "quad"
material = "floor"
scale = 6

[[light]]
type = "sphere"
{light}
emission = [20, 20, 20]
{extra}
"#
    ))
}

/// `spp` path samples of `scene` at w × h with the shadow output sampled as `sampling`.
pub fn shadow_renderer(
    scene: &Scene,
    w: u32,
    h: u32,
    spp: u32,
    seed: u32,
    sampling: ShadowSampling,
) -> Renderer {
    let mut o = options(scene, w, h, seed);
    o.outputs = OutputSet::of(&[Output::Shadows]);
    o.shadows = sampling;
    let mut r = Renderer::new(gpu(), scene, &o).unwrap_or_else(|e| panic!("{e:#}"));
    r.render_samples(spp).unwrap();
    r
}

/// The filter as `render --filter aaf-shadows` runs it (configured, specialised, prepared).
pub fn aaf_filtered(frame: &Frame, settings: &AafShadowSettings) -> RgbImage {
    Configured::typed::<AafShadows>(settings.clone(), &frame.info().scene)
        .unwrap()
        .prepare(frame.info(), &gpu())
        .unwrap()
        .run(frame)
        .unwrap()
        .image
}
