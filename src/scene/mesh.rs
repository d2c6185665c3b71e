//! Triangle meshes: Wavefront OBJ files with their MTL materials (via `tobj`), or procedural
//! meshes from src/assets, in one in-memory form.

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::SceneError;

/// The MTL statements noisefree reads (see scenes/README.md for how they map to materials).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MtlMaterial {
    pub name: String,
    pub kd: Option<[f32; 3]>,
    /// Absolute path of `map_Kd`.
    pub map_kd: Option<PathBuf>,
    pub ks: Option<[f32; 3]>,
    pub ns: Option<f32>,
    pub ni: Option<f32>,
    pub d: Option<f32>,
    pub ke: Option<[f32; 3]>,
}

/// One part of a mesh with one material.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshPart {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Per-vertex normals, or empty (flat shading).
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates, or empty.
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    pub material: Option<MtlMaterial>,
}

impl MeshPart {
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
}

/// Loads an OBJ file, triangulating polygons. Missing MTL files are reported, not ignored.
pub fn load_obj(path: &Path) -> Result<Vec<MeshPart>, SceneError> {
    let meta = std::fs::metadata(path)
        .map_err(|e| SceneError::new(path, format!("cannot open mesh file: {e}")))?;
    if meta.is_dir() {
        return Err(SceneError::new(
            path,
            "is a directory, expected an OBJ mesh file",
        ));
    }
    let text = std::fs::read(path)
        .map_err(|e| SceneError::new(path, format!("cannot read mesh file: {e}")))?;
    let folder = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    load_obj_bytes(path, &text, &|name: &Path| {
        let mtl_path = folder.join(name);
        let file = std::fs::File::open(&mtl_path).map_err(|e| {
            SceneError::new(
                &mtl_path,
                format!(
                    "cannot open material library named by {}: {e}",
                    path.display()
                ),
            )
        })?;
        Ok((mtl_path, std::io::BufReader::new(file)))
    })
}

type MtlOpener<'a> =
    dyn Fn(&Path) -> Result<(PathBuf, std::io::BufReader<std::fs::File>), SceneError> + 'a;

/// Parses OBJ text (from `path`, for messages); `open_mtl` opens the libraries it names.
pub fn load_obj_bytes(
    path: &Path,
    text: &[u8],
    open_mtl: &MtlOpener,
) -> Result<Vec<MeshPart>, SceneError> {
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ..Default::default()
    };
    let mtl_error: std::cell::RefCell<Option<SceneError>> = Default::default();
    let mtl_folder: std::cell::RefCell<Option<PathBuf>> = Default::default();
    let mut reader = std::io::BufReader::new(text);
    let (models, materials) =
        tobj::load_obj_buf(&mut reader, &options, |name| match open_mtl(name) {
            Ok((mtl_path, mut r)) => {
                *mtl_folder.borrow_mut() = mtl_path.parent().map(Path::to_path_buf);
                let result = tobj::load_mtl_buf(&mut r);
                if let Err(e) = &result {
                    *mtl_error.borrow_mut() = Some(SceneError::new(
                        &mtl_path,
                        format!("cannot parse material library: {e}"),
                    ));
                }
                result
            }
            Err(e) => {
                *mtl_error.borrow_mut() = Some(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        })
        .map_err(|e| obj_error(path, text, e))?;
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let materials = materials.unwrap_or_default();
    let folder = mtl_folder
        .into_inner()
        .unwrap_or_else(|| path.parent().unwrap_or(Path::new(".")).to_path_buf());
    let mut parts = Vec::with_capacity(models.len());
    for model in models {
        let m = &model.mesh;
        if m.indices.len() % 3 != 0 {
            return Err(SceneError::new(
                path,
                format!("object {:?} has a face that is not a polygon", model.name),
            ));
        }
        let positions: Vec<Vec3> = m
            .positions
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect();
        let normals: Vec<Vec3> = if m.normals.len() == m.positions.len() {
            m.normals
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect()
        } else {
            Vec::new()
        };
        let uvs: Vec<Vec2> = if m.texcoords.len() / 2 == positions.len() {
            m.texcoords
                .chunks_exact(2)
                .map(|c| Vec2::new(c[0], c[1]))
                .collect()
        } else {
            Vec::new()
        };
        let indices: Vec<[u32; 3]> = m
            .indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        if let Some(bad) = indices
            .iter()
            .flatten()
            .find(|&&i| i as usize >= positions.len())
        {
            return Err(SceneError::new(
                path,
                format!(
                    "object {:?} refers to vertex {} which does not exist",
                    model.name,
                    bad + 1
                ),
            ));
        }
        let material = m
            .material_id
            .and_then(|id| materials.get(id))
            .map(|mat| mtl_material(mat, &folder));
        parts.push(MeshPart {
            name: model.name.clone(),
            positions,
            normals,
            uvs,
            indices,
            material,
        });
    }
    Ok(parts)
}

fn parse3(s: Option<&String>) -> Option<[f32; 3]> {
    let v: Vec<f32> = s?
        .split_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect();
    (v.len() == 3).then(|| [v[0], v[1], v[2]])
}

fn mtl_material(m: &tobj::Material, folder: &Path) -> MtlMaterial {
    MtlMaterial {
        name: m.name.clone(),
        kd: m.diffuse,
        map_kd: m.diffuse_texture.as_ref().map(|t| folder.join(t.trim())),
        ks: m.specular,
        ns: m.shininess,
        ni: m.optical_density,
        d: m.dissolve,
        ke: m.emissive.or_else(|| parse3(m.unknown_param.get("Ke"))),
    }
}

/// tobj reports what went wrong but not where; find the first line of the kind it names so the
/// message can point at it.
fn obj_error(path: &Path, text: &[u8], e: tobj::LoadError) -> SceneError {
    use tobj::LoadError as E;
    let prefix = match e {
        E::PositionParseError | E::ScalingByZeroError => Some("v "),
        E::NormalParseError => Some("vn "),
        E::TexcoordParseError => Some("vt "),
        E::FaceParseError
        | E::InvalidPolygon
        | E::FaceVertexOutOfBounds
        | E::FaceTexCoordOutOfBounds
        | E::FaceNormalOutOfBounds
        | E::FaceColorOutOfBounds => Some("f "),
        E::MaterialParseError => Some("usemtl"),
        _ => None,
    };
    let text = String::from_utf8_lossy(text);
    let line = prefix.and_then(|p| first_bad_line(&text, p));
    SceneError {
        path: path.to_path_buf(),
        position: line.map(|l| (l, 1)),
        message: format!("invalid OBJ: {e}"),
    }
}

/// The first line starting with `prefix` that fails a basic check for the error kind.
fn first_bad_line(text: &str, prefix: &str) -> Option<usize> {
    let mut vertex_count = 0i64;
    let mut first_with_prefix = None;
    for (i, line) in text.lines().enumerate() {
        let l = line.trim_start();
        if l.starts_with("v ") {
            vertex_count += 1;
        }
        if !l.starts_with(prefix) {
            continue;
        }
        first_with_prefix.get_or_insert(i + 1);
        let fields: Vec<&str> = l.split_whitespace().skip(1).collect();
        let bad = match prefix {
            "v " | "vn " | "vt " => {
                fields.is_empty()
                    || fields.iter().any(|f| f.parse::<f32>().is_err())
                    || (prefix == "v "
                        && fields.get(3).is_some_and(|w| w.parse::<f32>() == Ok(0.0)))
            }
            "f " => {
                fields.len() < 3
                    || fields.iter().any(|f| {
                        let idx = f.split('/').next().unwrap_or("");
                        match idx.parse::<i64>() {
                            Ok(v) => v == 0 || v > vertex_count || -v > vertex_count,
                            Err(_) => true,
                        }
                    })
            }
            _ => false,
        };
        if bad {
            return Some(i + 1);
        }
    }
    // tobj can also reject a face by its vt/vn indices; point at the first such line then.
    first_with_prefix
}
