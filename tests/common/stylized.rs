//! Helpers of the stylized-shadows tests (tests/stylized.rs, tests/stylized_distance.rs),
//! included by path from each: rendered and synthetic frames holding the shadow output.
#![allow(dead_code)]

use noisefree::filters::stylized::{DeviceStages, StylizedKernel, StylizedSettings};
use noisefree::layout::outputs::BufferId;
use noisefree::layout::{Float4, ShadowPixel};
use noisefree::render::Frame;

use crate::common::aaf::shadow_renderer;
use crate::common::{bundled_scene, gpu};

pub fn device(frame: &Frame, s: &StylizedSettings) -> (noisefree::imaging::RgbImage, DeviceStages) {
    let mut k = StylizedKernel::new(
        gpu(),
        s,
        &s.stylized_lights(),
        frame.width(),
        frame.height(),
    )
    .unwrap();
    let run = k.filter(frame).unwrap();
    (run.image, k.stages().unwrap())
}

pub fn grids_frame(s: &StylizedSettings) -> Frame {
    shadow_renderer(&bundled_scene("grids"), 64, 48, 2, 7, s.sampling()).frame()
}

pub fn pixels(frame: &Frame) -> &[ShadowPixel] {
    frame.host_slice(BufferId::ShadowPixels).unwrap()
}

/// Largest |a − b| / max(|a|, |b|, floor) over finite pairs; ±∞ must match exactly.
pub fn worst(a: &[f32], b: &[f32], floor: f32) -> f32 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            if !x.is_finite() || !y.is_finite() {
                assert_eq!(x, y, "an infinity differs");
                return 0.0;
            }
            (x - y).abs() / x.abs().max(y.abs()).max(floor)
        })
        .fold(0.0, f32::max)
}

pub fn styled() -> StylizedSettings {
    StylizedSettings {
        inflation: [0.02, 0.05, 0.0],
        softness: [0.05, 0.0, 0.02],
        brightness: [0.2, 0.05, 0.0],
        abstraction: [2.0, 1.0, 0.0],
        contour_samples: 64,
        blur_samples: 32,
        ..Default::default()
    }
}

/// Contour points along the line x = 0 from y = −ℓ/2 to ℓ/2 at `step`, normal +z.
pub fn line_contour(length: f32, step: f32) -> Vec<Float4> {
    let n = (length / step).round() as i32;
    (0..=n)
        .flat_map(|k| {
            let y = -length / 2.0 + k as f32 * step;
            [Float4([0.0, y, 0.0, 1.0]), Float4([0.0, 0.0, 1.0, 1.0])]
        })
        .collect()
}

/// A synthetic frame: a w × h grid of receivers on the plane z = 0 at spacing `step`
/// (normal +z, or +x where `wall` says so), V from `lit`, r = 1, nothing replaced.
pub fn plane_frame(
    w: u32,
    h: u32,
    step: f32,
    lit: &dyn Fn(u32, u32) -> bool,
    wall: &dyn Fn(u32, u32) -> bool,
) -> Frame {
    shadow_frame(w, h, plane_pixels(w, h, step, lit, wall))
}

pub fn plane_pixels(
    w: u32,
    h: u32,
    step: f32,
    lit: &dyn Fn(u32, u32) -> bool,
    wall: &dyn Fn(u32, u32) -> bool,
) -> Vec<ShadowPixel> {
    let n = (w * h) as usize;
    let mut pixels = vec![ShadowPixel::default(); n];
    for (i, p) in pixels.iter_mut().enumerate() {
        let (x, y) = (i as u32 % w, i as u32 / w);
        p.weight = 1.0;
        p.samples = 1.0;
        p.visible = lit(x, y) as u8 as f32;
        p.centre_visible = p.visible;
        p.occluder_distance = if p.visible == 0.0 { 1.0 } else { 0.0 };
        p.pixel_size = step;
        p.position = [x as f32 * step, y as f32 * step, 0.0];
        p.normal = if wall(x, y) {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 0.0, 1.0]
        };
        p.unshadowed = [1.0; 3];
    }
    pixels
}

/// A frame holding `pixels` as its shadow output (F and the replaced term 0), the light 10
/// above the origin.
pub fn shadow_frame(w: u32, h: u32, pixels: Vec<ShadowPixel>) -> Frame {
    crate::common::aaf::shadow_frame(w, h, pixels, [0.0, 0.0, 10.0, 0.5])
}

/// A disc of shadow with a notch, on a 48 × 40 plane.
pub fn notched_disc(x: u32, y: u32) -> bool {
    let (dx, dy) = (x as f32 - 20.0, y as f32 - 20.0);
    let inside = dx * dx + dy * dy < 100.0 && !(dx > 3.0 && dy.abs() < 2.0);
    !inside
}
