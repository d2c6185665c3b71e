//! Reads a scene file and resolves it: names to indices, relative paths to the scene's folder,
//! meshes to world-space triangles. Every problem becomes a [`SceneError`] naming the file
//! and, where the problem sits in the scene file, the line and column.

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec2, Vec3};
use toml::Spanned;

use super::file::{self, SceneFile};
use super::mesh::{self, MeshPart, MtlMaterial};
use super::texture::{self, Texture};
use super::{
    Camera, Environment, Material, MaterialKind, RenderSettings, Scene, SceneError, Setting,
    SphereObject, Triangle,
};

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
            filter: raw.filter,
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

    fn render(&self, r: &file::RenderSection) -> Result<RenderSettings, SceneError> {
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

    fn camera(&self, c: &Spanned<file::CameraSection>) -> Result<Camera, SceneError> {
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

    fn asset_path(&self, p: &str) -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.folder.join(p)
        }
    }

    fn textures(
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

    fn color(
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

    fn materials(
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

    fn mesh(
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
            let (s, r) = append_part(
                part,
                material,
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

    fn sphere_light(
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

    fn environment(
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

    /// The material an MTL entry describes (rules in scenes/README.md): `Ke` > 0 makes a light,
    /// dissolve `d` < 1 makes glass with index `Ni`, a specular colour `Ks` brighter than `Kd`
    /// makes a Phong metal with exponent `Ns`, anything else is diffuse `Kd` with `map_Kd`.
    fn material_from_mtl(&mut self, m: &MtlMaterial) -> Result<Material, SceneError> {
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

/// Transforms a mesh part into world space and appends its triangles. Triangles with a
/// non-finite vertex, zero area or an area too large for f32 are skipped; non-finite or zero
/// normals are replaced by the face normal. Returns (skipped, repaired).
fn append_part(
    part: &MeshPart,
    material: u32,
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
        if !p.iter().all(|v| v.is_finite()) || !(area2 > 0.0 && area2.is_finite()) {
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
        out.push(Triangle { p, n, uv, material });
    }
    (skipped, repaired)
}
