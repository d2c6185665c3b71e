//! Helpers of the AAF soft-shadow and indirect-light tests (tests/aaf_*.rs).

use noisefree::filters::aaf_indirect::{AafIndirect, AafIndirectSettings};
use noisefree::filters::aaf_shadows::{AafShadowSettings, AafShadows};
use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::layout::{FilterVector, IndirectPixel, ShadowPixel, ShadowTerms};
use noisefree::render::{
    Frame, FrameInfo, HostBuffer, IndirectSampling, Renderer, SceneInfo, ShadowSampling,
    VarianceForm,
};
use noisefree::scene::Scene;

use super::{options, rendered, scene_from_toml};

/// A sphere light of radius 0.3 three metres above the floor's centre.
pub const OVERHEAD: &str = "center = [0, 3, 0]\nradius = 0.3";

/// The floor material of [`floor_scene`]: a grey diffuse.
pub const GREY_DIFFUSE: &str = "type = \"diffuse\"\ncolor = [0.8, 0.8, 0.8]";

/// A 6 × 6 floor (material "floor") seen from (0, 3, 3) under a sphere light (`light`: its
/// centre and radius lines), with `extra` appended; direct light only.
pub fn floor_scene(light: &str, extra: &str) -> Scene {
    floor_scene_with(
        1,
        GREY_DIFFUSE,
        &format!("{light}\nemission = [20, 20, 20]\n{extra}"),
    )
}

/// The same floor with paths of `max_depth` (no Russian roulette), the floor's `material`
/// lines (type and parameters) and the sphere light's `light` lines (all but its type, then
/// anything appended).
pub fn floor_scene_with(max_depth: u32, material: &str, light: &str) -> Scene {
    scene_from_toml(&format!(
        r#"
[render]
max_depth = {max_depth}
russian_roulette = false

[camera]
origin = [0, 3, 3]
target = [0, 0, 0]
fov = 40

[[material]]
name = "floor"
{material}

[[mesh]]
generator = "quad"
material = "floor"
scale = 6

[[light]]
type = "sphere"
{light}
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
    rendered(scene, &o, spp)
}

/// The filter as `render --filter aaf-shadows` runs it (configured, specialised, prepared).
pub fn aaf_filtered(frame: &Frame, settings: &AafShadowSettings) -> RgbImage {
    super::filtered::<AafShadows>(frame, settings)
}

/// A host frame of one spp holding `pixels` as its shadow output, with F and the replaced
/// term 0 (so a shadow filter's image is r times its visibility), lit by one sphere light
/// `light` (centre xyz, radius).
pub fn shadow_frame(w: u32, h: u32, pixels: Vec<ShadowPixel>, light: [f32; 4]) -> Frame {
    let n = pixels.len();
    let mut scene = SceneInfo::unknown();
    scene.sphere_lights = vec![light];
    Frame::on_host(
        FrameInfo {
            width: w,
            height: h,
            spp: 1,
            sample_capacity: 0,
            shadow_lights: vec![0],
            scene,
        },
        OutputSet::of(&[Output::Colour, Output::Shadows]),
        VarianceForm::Variances,
        vec![
            (
                BufferId::FilterVectors,
                HostBuffer::from_slice(&vec![FilterVector::default(); n]),
            ),
            (
                BufferId::ShadowTerms,
                HostBuffer::from_slice(&vec![ShadowTerms::default(); n]),
            ),
            (BufferId::ShadowPixels, HostBuffer::from_slice(&pixels)),
        ],
    )
    .unwrap_or_else(|e| panic!("{e:#}"))
}

/// `spp` path samples of `scene` at w × h (seed 5) with the indirect output sampled as
/// `sampling`.
pub fn indirect_renderer(
    scene: &Scene,
    w: u32,
    h: u32,
    spp: u32,
    sampling: IndirectSampling,
) -> Renderer {
    let mut o = options(scene, w, h, 5);
    o.outputs = OutputSet::of(&[Output::Indirect]);
    o.indirect = sampling;
    rendered(scene, &o, spp)
}

/// The filter as `render --filter aaf-indirect` runs it (configured, specialised, prepared).
pub fn aaf_indirect_filtered(frame: &Frame, s: &AafIndirectSettings) -> RgbImage {
    super::filtered::<AafIndirect>(frame, s)
}

/// A host frame holding `pixels` as its indirect output and F = 0.
pub fn indirect_frame(w: u32, h: u32, pixels: &[IndirectPixel]) -> Frame {
    let n = pixels.len();
    Frame::on_host(
        FrameInfo {
            width: w,
            height: h,
            spp: 1,
            sample_capacity: 0,
            shadow_lights: Vec::new(),
            scene: SceneInfo::unknown(),
        },
        OutputSet::of(&[Output::Colour, Output::Indirect]),
        VarianceForm::Variances,
        vec![
            (
                BufferId::FilterVectors,
                HostBuffer::from_slice(&vec![FilterVector::default(); n]),
            ),
            (BufferId::IndirectPixels, HostBuffer::from_slice(pixels)),
        ],
    )
    .unwrap_or_else(|e| panic!("{e:#}"))
}
