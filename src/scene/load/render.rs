//! The `[render]` and `[camera]` sections: render settings and the camera, checked.

use glam::Vec3;
use toml::Spanned;

use super::{Resolver, finite3};
use crate::scene::{Camera, RenderSettings, SceneError, Setting, file};

impl Resolver<'_> {
    pub(super) fn render(&self, r: &file::RenderSection) -> Result<RenderSettings, SceneError> {
        let setting = match &r.setting {
            None => Setting::Indoor,
            Some(s) => match s.get_ref().as_str() {
                "indoor" => Setting::Indoor,
                "outdoor" => Setting::Outdoor,
                other => {
                    return Err(self.src.at(
                        s,
                        "render.setting",
                        format!("setting must be \"indoor\" or \"outdoor\", got {other:?}"),
                    ));
                }
            },
        };
        Ok(RenderSettings {
            width: self.positive_int(&r.width, "render.width", 1, 1 << 15)?,
            height: self.positive_int(&r.height, "render.height", 1, 1 << 15)?,
            spp: self.positive_int(&r.spp, "render.spp", 1, 1 << 24)?,
            max_depth: self.positive_int(&r.max_depth, "render.max_depth", 0, 1024)?,
            seed: self.positive_int(&r.seed, "render.seed", 0, u32::MAX as i64)?,
            russian_roulette: r.russian_roulette,
            next_event_estimation: r.next_event_estimation,
            setting,
            clamp: match &r.clamp {
                None => 0.0,
                Some(c) => {
                    let v = *c.get_ref();
                    if !(v >= 0.0 && v.is_finite()) {
                        return Err(self.src.at(
                            c,
                            "render.clamp",
                            format!("clamp must be >= 0 (0 = off), got {v}"),
                        ));
                    }
                    v
                }
            },
        })
    }

    pub(super) fn camera(&self, c: &Spanned<file::CameraSection>) -> Result<Camera, SceneError> {
        let cam = c.get_ref();
        if !finite3(cam.origin) || !finite3(cam.target) || !finite3(*cam.up.get_ref()) {
            return Err(self.src.at(
                c,
                "camera",
                "camera origin, target and up must be finite numbers",
            ));
        }
        let origin = Vec3::from(cam.origin);
        let target = Vec3::from(cam.target);
        let up = Vec3::from(*cam.up.get_ref());
        let forward = target - origin;
        if forward.length_squared() == 0.0 || !forward.normalize().is_finite() {
            return Err(self.src.at(
                c,
                "camera",
                "camera target equals its origin: there is no view direction",
            ));
        }
        if forward.normalize().cross(up).length() < 1e-6 {
            // `up` may be the default, which has no place in the text: then point at the camera.
            let span = if cam.up.span() == (0..0) {
                c.span()
            } else {
                cam.up.span()
            };
            return Err(self.src.error(
                span,
                "camera.up",
                format!("camera up {up} is parallel to the view direction (or zero)"),
            ));
        }
        let fov = *cam.fov.get_ref();
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.src.at(
                &cam.fov,
                "camera.fov",
                format!("fov must be between 0 and 180 degrees, got {fov}"),
            ));
        }
        let lens = *cam.lens_radius.get_ref();
        if !(lens >= 0.0 && lens.is_finite()) {
            return Err(self.src.at(
                &cam.lens_radius,
                "camera.lens_radius",
                format!("lens_radius must be >= 0, got {lens}"),
            ));
        }
        let focal = match &cam.focal_distance {
            Some(f) => {
                let v = *f.get_ref();
                if !(v > 0.0 && v.is_finite()) {
                    return Err(self.src.at(
                        f,
                        "camera.focal_distance",
                        format!("focal_distance must be > 0, got {v}"),
                    ));
                }
                Some(v)
            }
            None => None,
        };
        if lens > 0.0 && focal.is_none() && !cam.autofocus {
            return Err(self.src.at(
                c,
                "camera",
                "a camera with lens_radius > 0 needs focal_distance or autofocus = true",
            ));
        }
        Ok(Camera {
            origin,
            target,
            up,
            fov_degrees: fov,
            lens_radius: lens,
            focal_distance: focal,
            autofocus: cam.autofocus,
        })
    }
}
