//! The light-field pass of sheared soft shadows (Yan et al. 2015 §3.1, issue 16): l × l
//! visibility samples per pixel on a jittered grid over each filtered sphere light's square
//! [−R, R]², in one global frame per light ([`light_frame`]), kept per pixel and light
//! ([`crate::layout::LightFieldPixel`], the output [`crate::layout::outputs::Output::LightField`]).
//! The kernel is kernels/render/light_field.cl, run by [`super::ShadowPasses`] between the AAF
//! sparse pass (receiver, d1, r(x), first slopes) and the slope fill.

use glam::Vec3;

/// Largest grid side l: the seed's l ≤ 4 (§3.1, "4–16 spp"), and the 16 sample lanes of
/// [`crate::layout::LightFieldPixel`].
pub const MAX_SIDE: u32 = 4;

/// The frame of the light's square: unit e1, e2 perpendicular to e3 = (scene centre → light
/// centre) and to each other. One frame for every pixel, because steps 1b and 2b of the
/// sheared filter shift samples of neighbours along the same (y1, y2) axes (digest §3.4);
/// e3 = +y when the light sits at the scene's centre. e1 comes from the world axis least
/// aligned with e3, so it does not flip between nearby lights.
pub fn light_frame(light_centre: Vec3, scene_centre: Vec3) -> [Vec3; 3] {
    let d = light_centre - scene_centre;
    let e3 = if d.length_squared() > 0.0 && d.is_finite() {
        d.normalize()
    } else {
        Vec3::Y
    };
    let a = if e3.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let e2 = e3.cross(a).normalize();
    let e1 = e2.cross(e3);
    [e1, e2, e3]
}

/// [`light_frame`] of a sphere light (centre xyz, radius) in a scene centred at
/// `scene_centre`: e1 and e2, as the light-field pass and the sheared filter take them.
pub fn sphere_frame(sphere: [f32; 4], scene_centre: [f32; 3]) -> [Vec3; 2] {
    let [e1, e2, _] = light_frame(
        Vec3::new(sphere[0], sphere[1], sphere[2]),
        Vec3::from(scene_centre),
    );
    [e1, e2]
}

/// The light coordinate of grid point `a` of a side-`side` grid with jitter `j`, for a light
/// of radius `radius`: R (2 (a + j) / l − 1) (kernels/render/light_field.cl).
pub fn grid_coordinate(a: u32, jitter: f32, side: u32, radius: f32) -> f32 {
    radius * (2.0 * (a as f32 + jitter) * (1.0 / side as f32) - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_is_orthonormal_and_perpendicular_to_the_light_direction() {
        for (l, c) in [
            (Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO),
            (Vec3::new(3.0, 0.1, 0.0), Vec3::ZERO),
            (Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 2.0, 3.0)),
            (Vec3::new(-4.0, 1.0, 7.0), Vec3::new(0.5, -0.5, 0.0)),
        ] {
            let [e1, e2, e3] = light_frame(l, c);
            for (u, v) in [(e1, e2), (e1, e3), (e2, e3)] {
                assert!(u.dot(v).abs() < 1e-6);
            }
            for e in [e1, e2, e3] {
                assert!((e.length() - 1.0).abs() < 1e-6);
            }
            assert!((e1.cross(e2) - e3).length() < 1e-6, "right-handed");
        }
    }

    #[test]
    fn grid_points_cover_the_square() {
        assert_eq!(grid_coordinate(0, 0.0, 3, 1.5), -1.5);
        assert!((grid_coordinate(2, 1.0, 3, 1.5) - 1.5).abs() < 1e-6);
        assert!((grid_coordinate(1, 0.5, 3, 1.5)).abs() < 1e-6);
    }
}
