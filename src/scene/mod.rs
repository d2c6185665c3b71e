//! The scene: what the file describes, resolved into flat lists of triangles, spheres,
//! materials, textures and lights (thesis §4.2.2).

pub mod assets;
pub mod file;
mod load;
pub mod mesh;
pub mod texture;

use std::fmt;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

pub use load::{load_scene, load_scene_str};
pub use texture::Texture;

/// An error in a scene file or an asset it names, with the position when there is one.
#[derive(Debug, Clone)]
pub struct SceneError {
    pub path: PathBuf,
    /// 1-based line and column in `path`.
    pub position: Option<(usize, usize)>,
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.position {
            Some((line, col)) => {
                write!(f, "{}:{line}:{col}: {}", self.path.display(), self.message)
            }
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for SceneError {}

impl SceneError {
    pub fn new(path: &Path, message: impl Into<String>) -> Self {
        SceneError {
            path: path.to_path_buf(),
            position: None,
            message: message.into(),
        }
    }
}

/// Refuses inputs that are not files to read: devices and sockets, which can be endless
/// (`file = "/dev/zero"` would be read until memory runs out) or block. Regular files and
/// pipes (`<(...)`) pass; directories are refused by the callers with their own message.
pub(crate) fn check_file_kind(
    path: &Path,
    meta: &std::fs::Metadata,
    what: &str,
) -> Result<(), SceneError> {
    #[cfg(unix)]
    let pipe = std::os::unix::fs::FileTypeExt::is_fifo(&meta.file_type());
    #[cfg(not(unix))]
    let pipe = false;
    if meta.is_file() || meta.is_dir() || pipe {
        Ok(())
    } else {
        Err(SceneError::new(
            path,
            format!("is not a regular file (a device or a socket), expected {what}"),
        ))
    }
}

/// "indoor" or "outdoor" (RPF's sigma^2_8, thesis §5.1.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Setting {
    Indoor,
    Outdoor,
}

#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Depth at which Russian roulette starts (eq. 2.9).
    pub max_depth: u32,
    pub seed: u32,
    pub russian_roulette: bool,
    pub next_event_estimation: bool,
    pub setting: Setting,
    /// Per-sample clamp of the colour (0: none).
    pub clamp: f32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub origin: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_degrees: f32,
    pub lens_radius: f32,
    /// Explicit focal distance; with `autofocus` it is found by tracing the view direction.
    pub focal_distance: Option<f32>,
    pub autofocus: bool,
}

/// The camera as the renderer and the filters use it: an orthonormal basis, the field of view
/// and the thin lens (thesis §4.2.2 "Camera", Fig. 4.8). One type for the megakernel's
/// parameters (src/arrays) and for filters that turn depths back into positions.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CameraBasis {
    pub origin: Vec3,
    /// Unit view direction, target − origin.
    pub forward: Vec3,
    /// Unit right vector of the image plane.
    pub right: Vec3,
    /// Unit up vector of the image plane.
    pub up: Vec3,
    /// tan(vertical fov / 2).
    pub tan_half_fov: f32,
    /// Thin-lens radius, 0 for a pinhole.
    pub lens_radius: f32,
    /// Distance from the lens to the plane in focus (after autofocus, where the renderer ran
    /// it; the scene's value or 1 otherwise).
    pub focal_distance: f32,
}

impl CameraBasis {
    /// The basis of a scene's camera: forward = normalize(target − origin), right =
    /// normalize(forward × up), up = right × forward.
    pub fn new(camera: &Camera) -> CameraBasis {
        let forward = (camera.target - camera.origin).normalize();
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        CameraBasis {
            origin: camera.origin,
            forward,
            right,
            up,
            tan_half_fov: (camera.fov_degrees.to_radians() * 0.5).tan(),
            lens_radius: camera.lens_radius,
            focal_distance: camera.focal_distance.unwrap_or(1.0),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum MaterialKind {
    Diffuse {
        color: Vec3,
        texture: Option<u32>,
    },
    Specular {
        color: Vec3,
    },
    Glass {
        reflect_color: Vec3,
        refract_color: Vec3,
        ior_outside: f32,
        ior_inside: f32,
    },
    Metal {
        color: Vec3,
        exponent: f32,
    },
    /// A light surface: emits `emission`, reflects nothing.
    Emitter,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub kind: MaterialKind,
    pub emission: Vec3,
}

impl Material {
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereObject {
    pub center: Vec3,
    pub radius: f32,
    pub material: u32,
}

/// A world-space triangle with its shading data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub p: [Vec3; 3],
    pub n: [Vec3; 3],
    pub uv: [Vec2; 3],
    pub material: u32,
    /// The object the triangle belongs to: one number per part of each `[[mesh]]`, in file
    /// order (filters that must not mix surfaces, e.g. AAF's slope fill, compare it).
    pub object: u32,
}

impl Triangle {
    pub fn area(&self) -> f32 {
        0.5 * (self.p[1] - self.p[0])
            .cross(self.p[2] - self.p[0])
            .length()
    }
}

/// The infinite light (the thesis's sky-box / environment map).
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// colour x gain, or gain alone when textured.
    pub radiance: Vec3,
    pub texture: Option<u32>,
    pub uv_scale: Vec2,
    pub uv_shift: Vec2,
}

/// The scene file's `[filter]` table as written: the filter to run and one table of settings
/// per filter. The filter registry checks names and settings (src/filters/registry.rs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FilterConfig {
    /// `method = "<name>"`: the filter `render` runs when the command line names none.
    pub method: Option<String>,
    /// 1-based line of `method`, for messages.
    pub method_line: Option<usize>,
    /// `[filter.<name>]` tables.
    pub settings: std::collections::BTreeMap<String, toml::Table>,
    /// 1-based line of each `[filter.<name>]` table (or of `[filter]` when written inline).
    pub lines: std::collections::BTreeMap<String, usize>,
}

#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene file; relative asset paths were resolved against its folder.
    pub path: PathBuf,
    pub render: RenderSettings,
    pub camera: Camera,
    pub textures: Vec<Texture>,
    pub materials: Vec<Material>,
    pub spheres: Vec<SphereObject>,
    pub triangles: Vec<Triangle>,
    pub environment: Option<Environment>,
    /// The `[filter]` table, for the filters.
    pub filter: FilterConfig,
    /// Problems repaired while loading (degenerate triangles, bad normals), reported once.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Scales the whole scene about the origin: geometry, camera and lights move together and
    /// emission keeps its radiance, so the image is unchanged in exact arithmetic.
    pub fn scaled(&self, factor: f32) -> Scene {
        let mut s = self.clone();
        for t in &mut s.triangles {
            for p in &mut t.p {
                *p *= factor;
            }
        }
        for sp in &mut s.spheres {
            sp.center *= factor;
            sp.radius *= factor;
        }
        s.camera.origin *= factor;
        s.camera.target *= factor;
        s.camera.lens_radius *= factor;
        s.camera.focal_distance = s.camera.focal_distance.map(|f| f * factor);
        s
    }

    pub fn emissive_triangle_count(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| self.materials[t.material as usize].is_emissive())
            .count()
    }

    pub fn emissive_sphere_count(&self) -> usize {
        self.spheres
            .iter()
            .filter(|s| self.materials[s.material as usize].is_emissive())
            .count()
    }
}
