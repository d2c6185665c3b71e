//! Triangle meshes: Wavefront OBJ files with their MTL materials (via `tobj`), or procedural
//! meshes from src/scene/assets, in one in-memory form.

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
    super::check_file_kind(path, &meta, "an OBJ mesh file")?;
    let text = std::fs::read(path)
        .map_err(|e| SceneError::new(path, format!("cannot read mesh file: {e}")))?;
    let folder = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    load_obj_bytes(path, &text, &|name: &Path| {
        let mtl_path = folder.join(name);
        if let Ok(meta) = std::fs::metadata(&mtl_path) {
            super::check_file_kind(&mtl_path, &meta, "a material library (.mtl)").map_err(|e| {
                SceneError {
                    message: format!("{} (named by {})", e.message, path.display()),
                    ..e
                }
            })?;
        }
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
///
/// The text is checked first (UTF-8, face indices; MTL statements before tobj reads them), so
/// that errors name the offending line and so that input tobj mishandles never reaches it:
/// tobj 4.0.5 panics on an MTL colour with fewer than three numbers (`Kd 1 1`), and computes
/// `3 * index` without an overflow check for texture-coordinate and normal indices, which
/// panics in debug builds and wraps to a wrong but valid-looking index in release builds.
pub fn load_obj_bytes(
    path: &Path,
    text: &[u8],
    open_mtl: &MtlOpener,
) -> Result<Vec<MeshPart>, SceneError> {
    check_obj_text(text).map_err(|(line, message)| SceneError {
        path: path.to_path_buf(),
        position: Some((line, 1)),
        message: format!("invalid OBJ: {message}"),
    })?;
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        // Points and two-vertex lines would become degenerate triangles.
        ignore_points: true,
        ignore_lines: true,
    };
    let mtl_error: std::cell::RefCell<Option<SceneError>> = Default::default();
    let mtl_folder: std::cell::RefCell<Option<PathBuf>> = Default::default();
    // Polylines (`l`) and points (`p`) are not surfaces, but tobj turns an `l` with three
    // vertices into a triangle (ignore_lines drops only two-vertex lines): blank them out,
    // keeping the line numbers.
    let not_surface = |l: &str| matches!(l.split_whitespace().next(), Some("l" | "p"));
    let surfaces: Vec<u8>;
    let text = match std::str::from_utf8(text) {
        Ok(t) if t.lines().any(not_surface) => {
            let kept: Vec<&str> = t
                .split('\n')
                .map(|l| if not_surface(l) { "" } else { l })
                .collect();
            surfaces = kept.join("\n").into_bytes();
            &surfaces[..]
        }
        _ => text,
    };
    let mut reader = std::io::BufReader::new(text);
    let (models, materials) =
        tobj::load_obj_buf(&mut reader, &options, |name| match open_mtl(name) {
            Ok((mtl_path, mut r)) => {
                *mtl_folder.borrow_mut() = mtl_path.parent().map(Path::to_path_buf);
                let mtl_err = |position: Option<usize>, what: String| {
                    *mtl_error.borrow_mut() = Some(SceneError {
                        path: mtl_path.clone(),
                        position: position.map(|l| (l, 1)),
                        message: format!(
                            "invalid material library (named by {}): {what}",
                            path.display()
                        ),
                    });
                    Err(tobj::LoadError::MaterialParseError)
                };
                let mut bytes = Vec::new();
                if let Err(e) = std::io::Read::read_to_end(&mut r, &mut bytes) {
                    return mtl_err(None, format!("cannot read it: {e}"));
                }
                if let Err((line, what)) = check_mtl_text(&bytes) {
                    return mtl_err(Some(line), what);
                }
                let result = tobj::load_mtl_buf(&mut std::io::Cursor::new(&bytes));
                if let Err(e) = &result {
                    return mtl_err(None, e.to_string());
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

/// The 1-based line of byte `offset`.
fn line_of(text: &[u8], offset: usize) -> usize {
    text[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// The text of an OBJ or MTL file, or the line of its first byte that is not UTF-8.
fn utf8_lines<'a>(text: &'a [u8], what: &str) -> Result<&'a str, (usize, String)> {
    std::str::from_utf8(text).map_err(|e| {
        (
            line_of(text, e.valid_up_to()),
            format!("the {what} is not valid UTF-8 text"),
        )
    })
}

/// Checks every statement tobj reads, with tobj's rules, before tobj sees the text: UTF-8;
/// `v` (x y z, then nothing, w != 0, or r g b), `vt` (u v), `vn` (x y z); `usemtl` and `mtllib`
/// with a name; and every face corner of `f` (and `l`) lines: whole numbers, at most v/vt/vn,
/// no index 0, none past the end of its list or, counted back, before its start. Vertex colours
/// must be given for every vertex or for none (tobj fails on faces that mix them). Returns the
/// first offending line and what is wrong with it.
fn check_obj_text(text: &[u8]) -> Result<(), (usize, String)> {
    let text = utf8_lines(text, "OBJ file")?;
    const KINDS: [&str; 3] = ["v", "vt", "vn"];
    const NAMES: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let kind = |line: &str| {
        let first = line.split_whitespace().next();
        KINDS.iter().position(|k| first == Some(*k))
    };
    let mut total = [0i64; 3];
    for line in text.lines() {
        if let Some(k) = kind(line) {
            total[k] += 1;
        }
    }
    let number = |w: &&str| w.parse::<f32>().is_ok();
    let mut seen = [0i64; 3];
    // Whether the vertices so far have colours (None before the first vertex).
    let mut coloured: Option<bool> = None;
    for (i, line) in text.lines().enumerate() {
        let bad = |m: String| Err((i + 1, m));
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let rest: Vec<&str> = words.collect();
        match key {
            "v" => {
                seen[0] += 1;
                if rest.len() < 3 || !rest[..3].iter().all(number) {
                    return bad("a vertex needs three numbers: v x y z".into());
                }
                let colour = match rest.len() {
                    3 => false,
                    4 => {
                        if rest[3].parse::<f32>().map_or(true, |w| w == 0.0) {
                            return bad("the vertex weight w must be a non-zero number".into());
                        }
                        false
                    }
                    6 if rest[3..].iter().all(number) => true,
                    _ => {
                        return bad(
                            "a vertex is v x y z, v x y z w or v x y z r g b (numbers)".into()
                        );
                    }
                };
                if coloured.is_some_and(|c| c != colour) {
                    return bad("vertex colours must be given for every vertex or for none".into());
                }
                coloured = Some(colour);
            }
            "vt" => {
                seen[1] += 1;
                if rest.len() < 2 || !rest[..2].iter().all(number) {
                    return bad("a texture coordinate needs two numbers: vt u v".into());
                }
            }
            "vn" => {
                seen[2] += 1;
                if rest.len() < 3 || !rest[..3].iter().all(number) {
                    return bad("a normal needs three numbers: vn x y z".into());
                }
            }
            "usemtl" | "mtllib" if rest.is_empty() => {
                return bad(format!("{key} needs a name"));
            }
            "f" | "l" => {
                let min = if key == "f" { 3 } else { 2 };
                if rest.len() < min {
                    return bad(format!(
                        "`{key}` needs at least {min} corners, this one has {}",
                        rest.len()
                    ));
                }
                for word in &rest {
                    let parts: Vec<&str> = word.split('/').collect();
                    if parts.len() > 3 {
                        return bad(format!(
                            "corner {word:?} has more than three indices (v/vt/vn)"
                        ));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            if k == 0 {
                                return bad(format!("corner {word:?} has no vertex index"));
                            }
                            continue;
                        }
                        let Ok(x) = part.parse::<i64>() else {
                            return bad(format!(
                                "corner {word:?} is not v, v/vt, v//vn or v/vt/vn in whole numbers"
                            ));
                        };
                        let name = NAMES[k];
                        if x == 0 {
                            return bad(format!(
                                "corner {word:?} has {name} index 0 (indices start at 1)"
                            ));
                        }
                        if x > total[k] {
                            return bad(format!(
                                "corner {word:?} refers to {name} {x}, but the file has {} \
                                 {name}(s)",
                                total[k]
                            ));
                        }
                        if x < 0 && x.unsigned_abs() > seen[k] as u64 {
                            return bad(format!(
                                "corner {word:?} refers to {name} {x} (counted back), but only \
                                 {} come before this line",
                                seen[k]
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Checks the MTL statements tobj parses: colours (Ka, Kd, Ks, Ke) need three numbers (tobj
/// 4.0.5 panics on fewer), Ns, Ni and d one number, illum a whole number, newmtl and the texture
/// maps a name. Returns the first offending line and what is wrong with it.
fn check_mtl_text(text: &[u8]) -> Result<(), (usize, String)> {
    let text = utf8_lines(text, "material library")?;
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let rest: Vec<&str> = words.collect();
        let number = |w: &&str| w.parse::<f32>().is_ok();
        let problem = match key {
            "Ka" | "Kd" | "Ks" | "Ke" => (rest.len() < 3 || !rest[..3].iter().all(number))
                .then(|| format!("{key} needs three numbers (r g b)")),
            "Ns" | "Ni" | "d" => {
                (!rest.first().is_some_and(number)).then(|| format!("{key} needs a number"))
            }
            "illum" => rest
                .first()
                .is_none_or(|w| w.parse::<u8>().is_err())
                .then(|| "illum needs a whole number from 0 to 255".to_string()),
            "newmtl" | "map_Ka" | "map_Kd" | "map_Ks" | "map_Bump" | "map_bump" | "map_Ns"
            | "map_ns" | "map_NS" | "bump" | "map_d" => {
                rest.is_empty().then(|| format!("{key} needs a name"))
            }
            _ => None,
        };
        if let Some(p) = problem {
            return Err((i + 1, p));
        }
    }
    Ok(())
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
        let first = l.split_whitespace().next().unwrap_or("");
        if first == "v" {
            vertex_count += 1;
        }
        if first != prefix.trim_end() {
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
