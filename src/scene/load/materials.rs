//! Textures, colours and materials named in the scene file, and the rules that turn an MTL
//! entry into a material (with its `map_Kd` image as a texture).

use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

use glam::{Vec2, Vec3};
use toml::Spanned;

use super::Resolver;
use crate::scene::mesh::MtlMaterial;
use crate::scene::texture::{self, Texture};
use crate::scene::{Material, MaterialKind, SceneError, file};

impl Resolver<'_> {
    pub(super) fn textures(
        &self,
        list: &[Spanned<file::TextureSection>],
    ) -> Result<(Vec<Texture>, HashMap<String, u32>), SceneError> {
        let mut textures = Vec::new();
        let mut index = HashMap::new();
        for t in list {
            let sec = t.get_ref();
            if index.contains_key(&sec.name) {
                return Err(self.src.at(
                    t,
                    "texture.name",
                    format!("texture {:?} is defined twice", sec.name),
                ));
            }
            let path = self.asset_path(sec.file.get_ref());
            let (width, height, texels) = texture::load_image(&path).map_err(|e| {
                self.src.at(
                    &sec.file,
                    "texture.file",
                    format!("texture {:?}: {e}", sec.name),
                )
            })?;
            if !sec
                .uv_scale
                .iter()
                .chain(sec.uv_shift.iter())
                .all(|v| v.is_finite())
            {
                return Err(self
                    .src
                    .at(t, "texture", "uv_scale and uv_shift must be finite"));
            }
            index.insert(sec.name.clone(), textures.len() as u32);
            textures.push(Texture {
                name: sec.name.clone(),
                width,
                height,
                texels,
                uv_scale: Vec2::from(sec.uv_scale),
                uv_shift: Vec2::from(sec.uv_shift),
            });
        }
        Ok((textures, index))
    }

    pub(super) fn color(
        &self,
        c: &Option<Spanned<[f32; 3]>>,
        field: &str,
        default: Option<[f32; 3]>,
    ) -> Result<Vec3, SceneError> {
        match c {
            Some(v) => {
                let x = *v.get_ref();
                if !x.iter().all(|c| c.is_finite() && *c >= 0.0) {
                    return Err(self.src.at(
                        v,
                        field,
                        format!("{field} must be three non-negative numbers, got {x:?}"),
                    ));
                }
                Ok(Vec3::from(x))
            }
            None => default
                .map(Vec3::from)
                .ok_or_else(|| SceneError::new(self.src.path, format!("{field} is required"))),
        }
    }

    pub(super) fn materials(
        &self,
        list: &[Spanned<file::MaterialSection>],
        textures: &HashMap<String, u32>,
    ) -> Result<(Vec<Material>, HashMap<String, u32>), SceneError> {
        let mut materials = Vec::new();
        let mut index = HashMap::new();
        for m in list {
            let sec = m.get_ref();
            if index.contains_key(&sec.name) {
                return Err(self.src.at(
                    m,
                    "material.name",
                    format!("material {:?} is defined twice", sec.name),
                ));
            }
            let kind_name = sec.kind.get_ref().as_str();
            let allowed: &[&str] = match kind_name {
                "diffuse" => &["color", "texture"],
                "specular" => &["color"],
                "glass" => &[
                    "reflect_color",
                    "refract_color",
                    "ior_outside",
                    "ior_inside",
                ],
                "metal" => &["color", "exponent"],
                "emitter" => &[],
                other => {
                    return Err(self.src.at(&sec.kind, "material.type", format!(
                        "unknown material type {other:?}; expected diffuse, specular, glass, metal or emitter"
                    )));
                }
            };
            let present: [(&str, Option<Range<usize>>); 7] = [
                ("color", sec.color.as_ref().map(|v| v.span())),
                ("texture", sec.texture.as_ref().map(|v| v.span())),
                (
                    "reflect_color",
                    sec.reflect_color.as_ref().map(|v| v.span()),
                ),
                (
                    "refract_color",
                    sec.refract_color.as_ref().map(|v| v.span()),
                ),
                ("ior_outside", sec.ior_outside.as_ref().map(|v| v.span())),
                ("ior_inside", sec.ior_inside.as_ref().map(|v| v.span())),
                ("exponent", sec.exponent.as_ref().map(|v| v.span())),
            ];
            for (name, span) in present {
                if let Some(span) = span
                    && !allowed.contains(&name)
                {
                    return Err(self.src.error(
                        span,
                        name,
                        format!(
                            "a {kind_name} material has no field `{name}` (it takes: {})",
                            if allowed.is_empty() {
                                "emission only".to_string()
                            } else {
                                allowed.join(", ")
                            }
                        ),
                    ));
                }
            }
            let f = |v: &Option<Spanned<f32>>,
                     field: &str,
                     default: f32,
                     min_exclusive: f32|
             -> Result<f32, SceneError> {
                match v {
                    Some(x) => {
                        let val = *x.get_ref();
                        if !(val > min_exclusive && val.is_finite()) {
                            return Err(self.src.at(
                                x,
                                field,
                                format!("{field} must be a number > {min_exclusive}, got {val}"),
                            ));
                        }
                        Ok(val)
                    }
                    None => Ok(default),
                }
            };
            let kind = match kind_name {
                "diffuse" => {
                    let texture = match &sec.texture {
                        Some(t) => Some(*textures.get(t.get_ref()).ok_or_else(|| {
                            self.src.at(
                                t,
                                "material.texture",
                                format!("unknown texture {:?}", t.get_ref()),
                            )
                        })?),
                        None => None,
                    };
                    MaterialKind::Diffuse {
                        color: self.color(&sec.color, "color", Some([1.0; 3]))?,
                        texture,
                    }
                }
                "specular" => MaterialKind::Specular {
                    color: self.color(&sec.color, "color", Some([1.0; 3]))?,
                },
                "glass" => MaterialKind::Glass {
                    reflect_color: self.color(
                        &sec.reflect_color,
                        "reflect_color",
                        Some([1.0; 3]),
                    )?,
                    refract_color: self.color(
                        &sec.refract_color,
                        "refract_color",
                        Some([1.0; 3]),
                    )?,
                    ior_outside: f(&sec.ior_outside, "ior_outside", 1.0, 0.0)?,
                    ior_inside: f(&sec.ior_inside, "ior_inside", 1.5, 0.0)?,
                },
                "metal" => MaterialKind::Metal {
                    color: self.color(&sec.color, "color", Some([1.0; 3]))?,
                    exponent: match &sec.exponent {
                        // A cos^n lobe needs n >= 0 (negative n is infinite at grazing angles).
                        Some(x) if !(*x.get_ref() >= 0.0 && x.get_ref().is_finite()) => {
                            return Err(self.src.at(
                                x,
                                "exponent",
                                format!("exponent must be a number >= 0, got {}", x.get_ref()),
                            ));
                        }
                        Some(x) => *x.get_ref(),
                        None => 100.0,
                    },
                },
                _ => MaterialKind::Emitter,
            };
            let emission = self.color(&sec.emission, "emission", Some([0.0; 3]))?;
            if kind == MaterialKind::Emitter && emission.max_element() <= 0.0 {
                return Err(self.src.at(
                    m,
                    "material.emission",
                    "an emitter material needs a positive emission",
                ));
            }
            index.insert(sec.name.clone(), materials.len() as u32);
            materials.push(Material {
                name: sec.name.clone(),
                kind,
                emission,
            });
        }
        Ok((materials, index))
    }

    /// The material an MTL entry describes (rules in scenes/README.md): `Ke` > 0 makes a light,
    /// dissolve `d` < 1 makes glass with index `Ni`, a specular colour `Ks` brighter than `Kd`
    /// makes a Phong metal with exponent `Ns`, anything else is diffuse `Kd` with `map_Kd`.
    pub(super) fn material_from_mtl(&mut self, m: &MtlMaterial) -> Result<Material, SceneError> {
        let v = |c: Option<[f32; 3]>| c.map(Vec3::from).filter(|v| v.is_finite());
        let kd = v(m.kd);
        let ks = v(m.ks);
        let ke = v(m.ke).unwrap_or(Vec3::ZERO).max(Vec3::ZERO);
        let kind = if ke.max_element() > 0.0 {
            MaterialKind::Emitter
        } else if m.d.is_some_and(|d| d < 1.0) {
            MaterialKind::Glass {
                reflect_color: Vec3::ONE,
                refract_color: Vec3::ONE,
                ior_outside: 1.0,
                ior_inside: m.ni.filter(|n| n.is_finite() && *n > 0.0).unwrap_or(1.5),
            }
        } else if let Some(ks) =
            ks.filter(|ks| ks.max_element() > kd.unwrap_or(Vec3::ZERO).max_element())
        {
            MaterialKind::Metal {
                color: ks.clamp(Vec3::ZERO, Vec3::ONE),
                exponent: m.ns.filter(|n| n.is_finite() && *n >= 0.0).unwrap_or(100.0),
            }
        } else {
            let texture = match &m.map_kd {
                Some(path) => Some(self.mtl_texture(path, &m.name)?),
                None => None,
            };
            MaterialKind::Diffuse {
                color: kd.unwrap_or(Vec3::splat(0.8)).clamp(Vec3::ZERO, Vec3::ONE),
                texture,
            }
        };
        Ok(Material {
            name: m.name.clone(),
            kind,
            emission: ke,
        })
    }

    fn mtl_texture(&mut self, path: &Path, material: &str) -> Result<u32, SceneError> {
        if let Some(&i) = self.mtl_texture_index.get(path) {
            return Ok(i);
        }
        let (width, height, texels) = texture::load_image(path).map_err(|e| SceneError {
            message: format!("map_Kd of MTL material {material:?}: {}", e.message),
            ..e
        })?;
        let index = (self.scene_texture_count + self.mtl_textures.len()) as u32;
        self.mtl_textures.push(Texture {
            name: path.display().to_string(),
            width,
            height,
            texels,
            uv_scale: Vec2::ONE,
            uv_shift: Vec2::ZERO,
        });
        self.mtl_texture_index.insert(path.to_path_buf(), index);
        Ok(index)
    }
}
