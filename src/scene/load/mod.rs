//! Reads a scene file and resolves it: names to indices, relative paths to the scene's folder,
//! meshes to world-space triangles. Every problem becomes a [`SceneError`] naming the file
//! and, where the problem sits in the scene file, the line and column.
//!
//! This file holds the entry points, the line:column bookkeeping and the walk over the file;
//! the sections are resolved next to it: `[render]` and `[camera]` in `render`, textures and
//! materials in `materials`, meshes in `meshes`, lights in `lights`.

mod lights;
mod materials;
mod meshes;
mod render;

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::Vec3;
use toml::Spanned;

use super::file::SceneFile;
use super::texture::Texture;
use super::{Scene, SceneError, SphereObject};

/// The scene file's text, for turning byte spans into line:column.
struct Source<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Source<'_> {
    fn position(&self, offset: usize) -> (usize, usize) {
        let before = &self.text[..offset.min(self.text.len())];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, col)
    }

    /// An error at `span`; a default value has the empty span 0..0 and then only `field` names it.
    fn error(&self, span: Range<usize>, field: &str, message: impl Into<String>) -> SceneError {
        let message = message.into();
        if span == (0..0) {
            SceneError {
                path: self.path.to_path_buf(),
                position: None,
                message: format!("{field}: {message}"),
            }
        } else {
            SceneError {
                path: self.path.to_path_buf(),
                position: Some(self.position(span.start)),
                message,
            }
        }
    }

    fn at<T>(&self, value: &Spanned<T>, field: &str, message: impl Into<String>) -> SceneError {
        self.error(value.span(), field, message)
    }
}

/// Loads and resolves a scene file.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    let meta = std::fs::metadata(path)
        .map_err(|e| SceneError::new(path, format!("cannot open scene file: {e}")))?;
    if meta.is_dir() {
        return Err(SceneError::new(
            path,
            "is a directory, expected a scene file (.toml)",
        ));
    }
    super::check_file_kind(path, &meta, "a scene file (.toml)")?;
    let bytes = std::fs::read(path)
        .map_err(|e| SceneError::new(path, format!("cannot read scene file: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let offset = e.utf8_error().valid_up_to();
        let text = String::from_utf8_lossy(e.as_bytes()).into_owned();
        Source { path, text: &text }.error(
            offset..offset + 1,
            "",
            "the scene file is not valid UTF-8 text",
        )
    })?;
    load_scene_str(path, &text)
}

/// Resolves scene text as if it had been read from `path` (relative paths resolve against
/// `path`'s folder).
pub fn load_scene_str(path: &Path, text: &str) -> Result<Scene, SceneError> {
    let src = Source { path, text };
    let raw: SceneFile = toml::from_str(text).map_err(|e| {
        let message = e.message().trim().to_string();
        match e.span() {
            Some(span) => SceneError {
                path: path.to_path_buf(),
                position: Some(src.position(span.start)),
                message,
            },
            None => SceneError::new(path, message),
        }
    })?;
    let folder = path.parent().map(Path::to_path_buf).unwrap_or_default();
    Resolver {
        src,
        folder,
        warnings: Vec::new(),
        scene_texture_count: 0,
        mtl_textures: Vec::new(),
        mtl_texture_index: HashMap::new(),
    }
    .resolve(raw)
}

struct Resolver<'a> {
    src: Source<'a>,
    folder: PathBuf,
    warnings: Vec<String>,
    /// Textures named by `[[texture]]`; MTL `map_Kd` images are numbered after them.
    scene_texture_count: usize,
    mtl_textures: Vec<Texture>,
    mtl_texture_index: HashMap<PathBuf, u32>,
}

fn finite3(v: [f32; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

impl Resolver<'_> {
    fn resolve(mut self, raw: SceneFile) -> Result<Scene, SceneError> {
        let render = self.render(&raw.render)?;
        let camera = self.camera(&raw.camera)?;
        let (textures, texture_index) = self.textures(&raw.textures)?;
        self.scene_texture_count = textures.len();
        let (mut materials, material_index) = self.materials(&raw.materials, &texture_index)?;
        let mut spheres = Vec::new();
        for s in &raw.spheres {
            let s = s.get_ref();
            let r = *s.radius.get_ref();
            if !(r > 0.0 && r.is_finite()) {
                return Err(self.src.at(
                    &s.radius,
                    "sphere.radius",
                    format!("sphere radius must be a positive number, got {r}"),
                ));
            }
            if !finite3(s.center) {
                return Err(self.src.at(
                    &s.radius,
                    "sphere.center",
                    "sphere centre must be finite",
                ));
            }
            spheres.push(SphereObject {
                center: Vec3::from(s.center),
                radius: r,
                material: self.lookup_material(&material_index, &s.material, "sphere.material")?,
            });
        }

        let mut triangles = Vec::new();
        for m in &raw.meshes {
            let override_material = match &m.get_ref().material {
                Some(name) => Some(self.lookup_material(&material_index, name, "mesh.material")?),
                None => None,
            };
            self.mesh(m, override_material, &mut materials, &mut triangles)?;
        }

        let mut environment = None;
        for l in &raw.lights {
            match l.get_ref().kind.get_ref().as_str() {
                "sphere" => spheres.push(self.sphere_light(l, &mut materials)?),
                "infinite" => {
                    if environment.is_some() {
                        return Err(self.src.at(
                            l,
                            "light",
                            "only one infinite (environment) light is allowed",
                        ));
                    }
                    environment = Some(self.environment(l, &texture_index)?);
                }
                other => {
                    return Err(self.src.at(
                        &l.get_ref().kind,
                        "light.type",
                        format!(
                            "unknown light type {other:?}; expected \"sphere\" or \"infinite\""
                        ),
                    ));
                }
            }
        }

        let textures = [textures, std::mem::take(&mut self.mtl_textures)].concat();
        Ok(Scene {
            path: self.src.path.to_path_buf(),
            render,
            camera,
            textures,
            materials,
            spheres,
            triangles,
            environment,
            filter: self.filter_config(raw.filter)?,
            warnings: self.warnings,
        })
    }

    fn lookup_material(
        &self,
        index: &HashMap<String, u32>,
        name: &Spanned<String>,
        field: &str,
    ) -> Result<u32, SceneError> {
        index.get(name.get_ref().as_str()).copied().ok_or_else(|| {
            let mut known: Vec<&str> = index.keys().map(|s| s.as_str()).collect();
            known.sort();
            self.src.at(
                name,
                field,
                format!(
                    "unknown material {:?}; the scene defines: {}",
                    name.get_ref(),
                    if known.is_empty() {
                        "no materials".to_string()
                    } else {
                        known.join(", ")
                    }
                ),
            )
        })
    }

    fn positive_int(
        &self,
        v: &Spanned<i64>,
        field: &str,
        min: i64,
        max: i64,
    ) -> Result<u32, SceneError> {
        let x = *v.get_ref();
        if x < min || x > max {
            return Err(self.src.at(
                v,
                field,
                format!("{field} must be between {min} and {max}, got {x}"),
            ));
        }
        Ok(x as u32)
    }

    fn asset_path(&self, p: &str) -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.folder.join(p)
        }
    }
}

impl Resolver<'_> {
    /// `[filter]`: `method` names the filter to run, every other key is a table of one
    /// filter's settings. The names and settings are checked by the filter registry.
    fn filter_config(
        &self,
        table: Option<Spanned<toml::Table>>,
    ) -> Result<super::FilterConfig, SceneError> {
        let mut config = super::FilterConfig::default();
        let Some(table) = table else {
            return Ok(config);
        };
        let span = table.span();
        let header = self.src.position(span.start).0;
        for (key, value) in table.into_inner() {
            match (key.as_str(), value) {
                ("method", toml::Value::String(m)) => {
                    config.method = Some(m);
                    config.method_line = self.key_line("filter", "method");
                }
                ("method", other) => {
                    return Err(self.src.error(
                        span.clone(),
                        "[filter] method",
                        format!(
                            "[filter] method must be a filter name, got {}",
                            other.type_str()
                        ),
                    ));
                }
                (name, toml::Value::Table(t)) => {
                    let line = self.table_line(&format!("filter.{name}")).unwrap_or(header);
                    config.lines.insert(name.to_string(), line);
                    config.settings.insert(name.to_string(), t);
                }
                (name, _) => {
                    return Err(self.src.error(
                        span.clone(),
                        "[filter]",
                        format!(
                            "[filter] {name}: a filter's settings live in its own table, e.g. \
                             [filter.ddf] {name} = ... (see scenes/README.md)"
                        ),
                    ));
                }
            }
        }
        Ok(config)
    }

    /// The 1-based line of `key = ...` in the table `[table]` (written as a header and a key
    /// line, the usual form).
    fn key_line(&self, table: &str, key: &str) -> Option<usize> {
        let start = self.table_line(table)?;
        self.src
            .text
            .lines()
            .enumerate()
            .skip(start)
            .take_while(|(_, l)| !l.trim_start().starts_with('['))
            .find(|(_, l)| {
                l.trim_start()
                    .strip_prefix(key)
                    .is_some_and(|r| r.trim_start().starts_with('='))
            })
            .map(|(i, _)| i + 1)
    }

    /// The 1-based line of the table header `[name]` in the scene file.
    fn table_line(&self, name: &str) -> Option<usize> {
        self.src
            .text
            .lines()
            .position(|l| {
                l.trim()
                    .strip_prefix('[')
                    .and_then(|r| r.strip_suffix(']'))
                    .is_some_and(|inner| inner.trim() == name)
            })
            .map(|i| i + 1)
    }
}
