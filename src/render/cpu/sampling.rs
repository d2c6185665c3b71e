//! kernels/render/sampling.cl and kernels/render/camera.cl in Rust.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::rng::{DIM_LENS_U, DIM_LENS_V, DIM_PIXEL_X, DIM_PIXEL_Y, rng_uniform};
use crate::layout::SceneParams;

pub fn tangent_frame(w: Vec3) -> (Vec3, Vec3) {
    let temp = if w.x.abs() > 0.1 { Vec3::Y } else { Vec3::X };
    let u = temp.cross(w).normalize();
    (u, w.cross(u))
}

/// Algorithm 5: cosine-weighted direction around `normal`.
pub fn sample_diffuse(r1: f32, r2: f32, normal: Vec3) -> Vec3 {
    let azimuthal = 2.0 * PI * r1;
    let (u, v) = tangent_frame(normal);
    let s = r2.sqrt();
    (u * (azimuthal.cos() * s) + v * (azimuthal.sin() * s) + normal * (1.0 - r2).sqrt()).normalize()
}

pub fn sample_phong_lobe(r1: f32, r2: f32, axis: Vec3, exponent: f32) -> Vec3 {
    let cos_t = r2.powf(1.0 / (exponent + 1.0));
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * r1;
    let (u, v) = tangent_frame(axis);
    (u * (phi.cos() * sin_t) + v * (phi.sin() * sin_t) + axis * cos_t).normalize()
}

pub fn sample_disk(r1: f32, r2: f32) -> Vec2 {
    let r = r1.sqrt();
    let phi = 2.0 * PI * r2;
    Vec2::new(r * phi.cos(), r * phi.sin())
}

pub fn sample_cone(r1: f32, r2: f32, axis: Vec3, one_minus_cos_max: f32) -> Vec3 {
    let one_minus_cos = r1 * one_minus_cos_max;
    let cos_t = 1.0 - one_minus_cos;
    let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = 2.0 * PI * r2;
    let (u, v) = tangent_frame(axis);
    (u * (phi.cos() * sin_t) + v * (phi.sin() * sin_t) + axis * cos_t).normalize()
}

pub fn sample_triangle(r1: f32, r2: f32) -> Vec2 {
    let s = r1.sqrt();
    Vec2::new(1.0 - s, r2 * s)
}

/// The unit direction from the lens centre through the point (x + jx, y + jy) of the image
/// (kernels/render/camera.cl `pinhole_direction`).
pub fn pinhole_direction(p: &SceneParams, x: u32, y: u32, jx: f32, jy: f32) -> Vec3 {
    let (w, h) = (p.image_width as f32, p.image_height as f32);
    let sx = (2.0 * (x as f32 + jx) / w - 1.0) * p.tan_half_fov * (w / h);
    let sy = (1.0 - 2.0 * (y as f32 + jy) / h) * p.tan_half_fov;
    let forward = p.camera_forward.xyz();
    (forward + sx * p.camera_right.xyz() + sy * p.camera_up.xyz()).normalize()
}

/// The camera ray of pixel (x, y) for the sample whose key is `key` (kernels/render/camera.cl).
pub fn camera_ray(p: &SceneParams, x: u32, y: u32, key: u32) -> (Vec3, Vec3) {
    let jx = rng_uniform(key, 0, DIM_PIXEL_X);
    let jy = rng_uniform(key, 0, DIM_PIXEL_Y);
    let forward = p.camera_forward.xyz();
    let mut dir = pinhole_direction(p, x, y, jx, jy);
    let mut o = p.camera_origin.xyz();
    if p.lens_radius > 0.0 {
        let focus = o + dir * (p.focal_distance / dir.dot(forward));
        let lens = p.lens_radius
            * sample_disk(
                rng_uniform(key, 0, DIM_LENS_U),
                rng_uniform(key, 0, DIM_LENS_V),
            );
        o = o + lens.x * p.camera_right.xyz() + lens.y * p.camera_up.xyz();
        dir = (focus - o).normalize();
    }
    (o, dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_sampling_has_the_right_mean_cosine() {
        // E[cos theta] under pdf cos/pi is 2/3.
        let n = Vec3::new(0.2, -0.9, 0.3).normalize();
        let mut sum = 0.0f64;
        let count = 200_000;
        for i in 0..count {
            let (a, b) = (
                ((i * 7919) % count) as f32 / count as f32,
                (i as f32 + 0.5) / count as f32,
            );
            let d = sample_diffuse(a, b, n);
            assert!(d.dot(n) >= -1e-6);
            sum += d.dot(n) as f64;
        }
        assert!((sum / count as f64 - 2.0 / 3.0).abs() < 2e-3);
    }

    #[test]
    fn cone_samples_stay_in_the_cone_even_when_tiny() {
        let axis = Vec3::new(0.0, 0.6, 0.8);
        for omc in [0.5f32, 1e-4, 1e-10] {
            for i in 0..100 {
                let d = sample_cone(i as f32 / 100.0, 0.37, axis, omc);
                assert!(d.is_finite());
                assert!(1.0 - d.dot(axis) <= omc * 1.01 + 1e-6);
            }
        }
    }
}
