//! Meshes: parts from an OBJ file or a generator, placed by scale, rotate and translate and
//! appended as world-space triangles.

use std::collections::HashMap;

use glam::{Mat3, Vec2, Vec3};
use toml::Spanned;

use super::{Resolver, finite3};
use crate::scene::mesh::{self, MeshPart};
use crate::scene::{Material, SceneError, Triangle, file};

impl Resolver<'_> {
    pub(super) fn mesh(
        &mut self,
        m: &Spanned<file::MeshSection>,
        override_material: Option<u32>,
        materials: &mut Vec<Material>,
        triangles: &mut Vec<Triangle>,
    ) -> Result<(), SceneError> {
        let sec = m.get_ref();
        let (parts, origin) = match (&sec.file, &sec.generator) {
            (Some(f), None) => {
                let path = self.asset_path(f.get_ref());
                let parts = mesh::load_obj(&path).map_err(|e| {
                    // Name both the scene line and the mesh file's own position.
                    let (line, col) = self.src.position(f.span().start);
                    SceneError {
                        path: self.src.path.to_path_buf(),
                        position: Some((line, col)),
                        message: format!("mesh {e}"),
                    }
                })?;
                (parts, path.display().to_string())
            }
            (None, Some(g)) => {
                let parts = crate::scene::assets::generate_mesh(g.get_ref(), sec.seed).ok_or_else(
                    || {
                        self.src.at(
                            g,
                            "mesh.generator",
                            format!(
                                "unknown mesh generator {:?}; available: {}",
                                g.get_ref(),
                                crate::scene::assets::MESH_GENERATORS.join(", ")
                            ),
                        )
                    },
                )?;
                (parts, format!("generator {:?}", g.get_ref()))
            }
            _ => {
                return Err(self.src.at(
                    m,
                    "mesh",
                    "a mesh needs exactly one of `file` or `generator`",
                ));
            }
        };
        let scale = match &sec.scale {
            None => Vec3::ONE,
            Some(s) => match s.get_ref() {
                file::Scale::Uniform(v) => Vec3::splat(*v),
                file::Scale::PerAxis(v) => Vec3::from(*v),
            },
        };
        if !scale.is_finite() || scale.x * scale.y * scale.z == 0.0 {
            return Err(self.src.at(
                sec.scale.as_ref().unwrap(),
                "mesh.scale",
                "scale must be finite and non-zero",
            ));
        }
        if !finite3(sec.rotate) || !finite3(sec.translate) {
            return Err(self
                .src
                .at(m, "mesh", "rotate and translate must be finite"));
        }
        let r = sec.rotate.map(f32::to_radians);
        let rotation =
            Mat3::from_rotation_z(r[2]) * Mat3::from_rotation_y(r[1]) * Mat3::from_rotation_x(r[0]);
        let linear = rotation * Mat3::from_diagonal(scale);
        let normal_matrix = linear.inverse().transpose();
        let translate = Vec3::from(sec.translate);

        let mut skipped = 0usize;
        let mut repaired = 0usize;
        let mut mtl_cache: HashMap<String, u32> = HashMap::new();
        for part in &parts {
            let material = match override_material {
                Some(id) => id,
                None => match &part.material {
                    Some(mtl) => match mtl_cache.get(&mtl.name) {
                        Some(&id) => id,
                        None => {
                            let id = materials.len() as u32;
                            // A map_Kd image that cannot be loaded: name the scene line of
                            // this mesh, the mesh file and the image (in `e`).
                            let material = self.material_from_mtl(mtl).map_err(|e| {
                                let at = sec.file.as_ref().map_or(m.span(), |f| f.span());
                                self.src
                                    .error(at, "mesh.file", format!("mesh {origin}: {e}"))
                            })?;
                            materials.push(material);
                            mtl_cache.insert(mtl.name.clone(), id);
                            id
                        }
                    },
                    None => {
                        return Err(self.src.at(m, "mesh.material", format!(
                            "part {:?} of {origin} has no MTL material; give the mesh a `material`",
                            part.name
                        )));
                    }
                },
            };
            // Every part is an object of its own (AAF's slope fill stays within one).
            let object = triangles.last().map_or(0, |t| t.object + 1);
            let (s, r) = append_part(
                part,
                material,
                object,
                &linear,
                &normal_matrix,
                translate,
                triangles,
            );
            skipped += s;
            repaired += r;
        }
        if skipped > 0 {
            self.warnings.push(format!("{origin}: skipped {skipped} degenerate triangle(s) (zero or overflowing area, or non-finite vertices)"));
        }
        if repaired > 0 {
            self.warnings.push(format!(
                "{origin}: replaced {repaired} invalid vertex normal(s) by the face normal"
            ));
        }
        Ok(())
    }
}

/// Transforms a mesh part into world space and appends its triangles. Triangles with a
/// non-finite vertex, zero area or an area too large for f32 are skipped; non-finite or zero
/// normals are replaced by the face normal. Returns (skipped, repaired).
fn append_part(
    part: &MeshPart,
    material: u32,
    object: u32,
    linear: &Mat3,
    normal_matrix: &Mat3,
    translate: Vec3,
    out: &mut Vec<Triangle>,
) -> (usize, usize) {
    let mut skipped = 0;
    let mut repaired = 0;
    for idx in &part.indices {
        let p = idx.map(|i| *linear * part.positions[i as usize] + translate);
        let face = (p[1] - p[0]).cross(p[2] - p[0]);
        // |face|^2 must be finite too: with coordinates near 1e19 the cross product is finite
        // but its squared length overflows, and the normal would normalise to zero.
        let area2 = face.length_squared();
        if !(p.iter().all(|v| v.is_finite()) && area2 > 0.0 && area2.is_finite()) {
            skipped += 1;
            continue;
        }
        let face_n = face.normalize();
        let n = idx.map(|i| {
            let n = part
                .normals
                .get(i as usize)
                .map(|n| (*normal_matrix * *n).normalize_or_zero());
            match n {
                Some(n) if n.is_finite() && n != Vec3::ZERO => n,
                Some(_) => {
                    repaired += 1;
                    face_n
                }
                None => face_n,
            }
        });
        let uv = idx.map(|i| {
            part.uvs
                .get(i as usize)
                .copied()
                .filter(|u| u.is_finite())
                .unwrap_or(Vec2::ZERO)
        });
        out.push(Triangle {
            p,
            n,
            uv,
            material,
            object,
        });
    }
    (skipped, repaired)
}
