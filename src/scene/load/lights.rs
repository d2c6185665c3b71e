//! Lights: a sphere light (an emitter sphere with a material of its own) and the one
//! infinite (environment) light.

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use toml::Spanned;

use super::{Resolver, finite3};
use crate::scene::{Environment, Material, MaterialKind, SceneError, SphereObject, file};

impl Resolver<'_> {
    pub(super) fn sphere_light(
        &self,
        l: &Spanned<file::LightSection>,
        materials: &mut Vec<Material>,
    ) -> Result<SphereObject, SceneError> {
        let sec = l.get_ref();
        for (name, present) in [
            ("texture", sec.texture.is_some()),
            ("color", sec.color.is_some()),
            ("gain", sec.gain.is_some()),
            ("uv_scale", sec.uv_scale.is_some()),
            ("uv_shift", sec.uv_shift.is_some()),
        ] {
            if present {
                return Err(self.src.at(
                    l,
                    name,
                    format!(
                        "a sphere light has no field `{name}` (it takes center, radius, emission)"
                    ),
                ));
            }
        }
        let center = sec.center.as_ref().ok_or_else(|| {
            self.src
                .at(l, "light.center", "a sphere light needs `center`")
        })?;
        let radius = sec.radius.as_ref().ok_or_else(|| {
            self.src
                .at(l, "light.radius", "a sphere light needs `radius`")
        })?;
        let r = *radius.get_ref();
        if !(r > 0.0 && r.is_finite()) {
            return Err(self.src.at(
                radius,
                "light.radius",
                format!("light radius must be a positive number, got {r}"),
            ));
        }
        if !finite3(*center.get_ref()) {
            return Err(self
                .src
                .at(center, "light.center", "light centre must be finite"));
        }
        if sec.emission.is_none() {
            return Err(self
                .src
                .at(l, "light.emission", "a sphere light needs `emission`"));
        }
        let emission = self.color(&sec.emission, "emission", None)?;
        // Like an emitter material: a light that emits nothing is a mistake, not a light.
        if let Some(e) = &sec.emission
            && emission.max_element() <= 0.0
        {
            return Err(self.src.at(
                e,
                "light.emission",
                "a sphere light needs a positive emission",
            ));
        }
        let id = materials.len() as u32;
        materials.push(Material {
            name: format!("sphere light {id}"),
            kind: MaterialKind::Emitter,
            emission,
        });
        Ok(SphereObject {
            center: Vec3::from(*center.get_ref()),
            radius: r,
            material: id,
        })
    }

    pub(super) fn environment(
        &self,
        l: &Spanned<file::LightSection>,
        textures: &HashMap<String, u32>,
    ) -> Result<Environment, SceneError> {
        let sec = l.get_ref();
        for (name, present) in [
            ("center", sec.center.is_some()),
            ("radius", sec.radius.is_some()),
            ("emission", sec.emission.is_some()),
        ] {
            if present {
                return Err(self.src.at(l, name, format!(
                    "an infinite light has no field `{name}` (it takes texture or color, gain, uv_scale, uv_shift)"
                )));
            }
        }
        let gain = match &sec.gain {
            Some(g) => {
                let v = *g.get_ref();
                if !(v >= 0.0 && v.is_finite()) {
                    return Err(self.src.at(
                        g,
                        "light.gain",
                        format!("gain must be >= 0, got {v}"),
                    ));
                }
                v
            }
            None => 1.0,
        };
        let texture = match &sec.texture {
            Some(t) => Some(*textures.get(t.get_ref()).ok_or_else(|| {
                self.src.at(
                    t,
                    "light.texture",
                    format!("unknown texture {:?}", t.get_ref()),
                )
            })?),
            None => None,
        };
        let color = self.color(&sec.color, "color", Some([1.0; 3]))?;
        if texture.is_none() && sec.color.is_none() {
            return Err(self.src.at(
                l,
                "light",
                "an infinite light needs a `texture` or a `color`",
            ));
        }
        let v2 =
            |v: &Option<Spanned<[f32; 2]>>, d: [f32; 2], field: &str| -> Result<Vec2, SceneError> {
                match v {
                    Some(x) if !x.get_ref().iter().all(|c| c.is_finite()) => {
                        Err(self.src.at(x, field, "must be finite"))
                    }
                    Some(x) => Ok(Vec2::from(*x.get_ref())),
                    None => Ok(Vec2::from(d)),
                }
            };
        Ok(Environment {
            radiance: color * gain,
            texture,
            uv_scale: v2(&sec.uv_scale, [1.0, 1.0], "uv_scale")?,
            uv_shift: v2(&sec.uv_shift, [0.0, 0.0], "uv_shift")?,
        })
    }
}
