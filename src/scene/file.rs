//! The scene description file (thesis §4.2.2 "Scene"), in TOML. Every field is documented in
//! `scenes/README.md`. Unknown fields are errors, so a typo is reported instead of ignored.
//!
//! Fields that are checked after parsing carry their source span (`Spanned`), so that every
//! error can name the file, line and column.

use serde::Deserialize;
use toml::Spanned;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    #[serde(default)]
    pub render: RenderSection,
    pub camera: Spanned<CameraSection>,
    #[serde(default, rename = "texture")]
    pub textures: Vec<Spanned<TextureSection>>,
    #[serde(default, rename = "material")]
    pub materials: Vec<Spanned<MaterialSection>>,
    #[serde(default, rename = "sphere")]
    pub spheres: Vec<Spanned<SphereSection>>,
    #[serde(default, rename = "mesh")]
    pub meshes: Vec<Spanned<MeshSection>>,
    #[serde(default, rename = "light")]
    pub lights: Vec<Spanned<LightSection>>,
    /// `[filter]`: `method = "<name>"` and one `[filter.<name>]` table of settings per filter
    /// (the command line wins over them). Checked against the filter registry when a command
    /// runs a filter (src/filters/registry.rs), since the scene does not know the filters.
    #[serde(default)]
    pub filter: Option<Spanned<toml::Table>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSection {
    #[serde(default = "default_width")]
    pub width: Spanned<i64>,
    #[serde(default = "default_height")]
    pub height: Spanned<i64>,
    #[serde(default = "default_spp")]
    pub spp: Spanned<i64>,
    /// Path depth at which Russian roulette starts (eq. 2.9; Alg. 1 line 5).
    #[serde(default = "default_max_depth")]
    pub max_depth: Spanned<i64>,
    #[serde(default = "zero_i64")]
    pub seed: Spanned<i64>,
    /// false: no Russian roulette, paths end at max_depth (biased, for comparisons).
    #[serde(default = "yes")]
    pub russian_roulette: bool,
    /// false: no explicit light connections, lights are found by BSDF sampling only.
    #[serde(default = "yes")]
    pub next_event_estimation: bool,
    /// "indoor" or "outdoor": the RPF sigma^2_8 choice of thesis §5.1.4.
    #[serde(default)]
    pub setting: Option<Spanned<String>>,
    /// Largest colour component one path sample may carry (0 or absent: no clamp).
    #[serde(default)]
    pub clamp: Option<Spanned<f32>>,
}

impl Default for RenderSection {
    fn default() -> Self {
        RenderSection {
            width: default_width(),
            height: default_height(),
            spp: default_spp(),
            max_depth: default_max_depth(),
            seed: zero_i64(),
            russian_roulette: true,
            next_event_estimation: true,
            setting: None,
            clamp: None,
        }
    }
}

fn default_width() -> Spanned<i64> {
    Spanned::new(0..0, 512)
}
fn default_height() -> Spanned<i64> {
    Spanned::new(0..0, 512)
}
fn default_spp() -> Spanned<i64> {
    Spanned::new(0..0, 8)
}
fn default_max_depth() -> Spanned<i64> {
    Spanned::new(0..0, 4)
}
fn zero_i64() -> Spanned<i64> {
    Spanned::new(0..0, 0)
}
fn zero_f32() -> Spanned<f32> {
    Spanned::new(0..0, 0.0)
}
fn yes() -> bool {
    true
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    pub origin: [f32; 3],
    pub target: [f32; 3],
    #[serde(default = "default_up")]
    pub up: Spanned<[f32; 3]>,
    /// Vertical field of view in degrees.
    #[serde(default = "default_fov")]
    pub fov: Spanned<f32>,
    #[serde(default = "zero_f32")]
    pub lens_radius: Spanned<f32>,
    #[serde(default)]
    pub focal_distance: Option<Spanned<f32>>,
    #[serde(default)]
    pub autofocus: bool,
}

fn default_up() -> Spanned<[f32; 3]> {
    Spanned::new(0..0, [0.0, 1.0, 0.0])
}
fn default_fov() -> Spanned<f32> {
    Spanned::new(0..0, 45.0)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextureSection {
    pub name: String,
    pub file: Spanned<String>,
    #[serde(default = "one2")]
    pub uv_scale: [f32; 2],
    #[serde(default)]
    pub uv_shift: [f32; 2],
}

fn one2() -> [f32; 2] {
    [1.0, 1.0]
}

/// One `[[material]]`. The fields a type allows are checked after parsing (src/scene/load.rs),
/// so that a misplaced field is reported with its position. (serde's tagged enums would lose
/// the positions.)
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSection {
    pub name: String,
    /// diffuse | specular | glass | metal | emitter
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    #[serde(default)]
    pub color: Option<Spanned<[f32; 3]>>,
    #[serde(default)]
    pub texture: Option<Spanned<String>>,
    #[serde(default)]
    pub reflect_color: Option<Spanned<[f32; 3]>>,
    #[serde(default)]
    pub refract_color: Option<Spanned<[f32; 3]>>,
    #[serde(default)]
    pub ior_outside: Option<Spanned<f32>>,
    #[serde(default)]
    pub ior_inside: Option<Spanned<f32>>,
    #[serde(default)]
    pub exponent: Option<Spanned<f32>>,
    /// Emitted radiance; non-zero makes every surface with this material a light.
    #[serde(default)]
    pub emission: Option<Spanned<[f32; 3]>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSection {
    pub center: [f32; 3],
    pub radius: Spanned<f32>,
    pub material: Spanned<String>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum Scale {
    Uniform(f32),
    PerAxis([f32; 3]),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSection {
    /// An OBJ file (with its MTL materials).
    #[serde(default)]
    pub file: Option<Spanned<String>>,
    /// A built-in procedural mesh instead of a file (see src/scene/assets/).
    #[serde(default)]
    pub generator: Option<Spanned<String>>,
    /// Seed of a procedural mesh.
    #[serde(default)]
    pub seed: u64,
    /// Overrides every material of the mesh.
    #[serde(default)]
    pub material: Option<Spanned<String>>,
    #[serde(default)]
    pub scale: Option<Spanned<Scale>>,
    /// Rotation in degrees about x, then y, then z.
    #[serde(default)]
    pub rotate: [f32; 3],
    #[serde(default)]
    pub translate: [f32; 3],
}

/// One `[[light]]`: `type = "sphere"` or `type = "infinite"`, fields checked after parsing.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightSection {
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    #[serde(default)]
    pub center: Option<Spanned<[f32; 3]>>,
    #[serde(default)]
    pub radius: Option<Spanned<f32>>,
    #[serde(default)]
    pub emission: Option<Spanned<[f32; 3]>>,
    #[serde(default)]
    pub texture: Option<Spanned<String>>,
    #[serde(default)]
    pub color: Option<Spanned<[f32; 3]>>,
    #[serde(default)]
    pub gain: Option<Spanned<f32>>,
    #[serde(default)]
    pub uv_scale: Option<Spanned<[f32; 2]>>,
    #[serde(default)]
    pub uv_shift: Option<Spanned<[f32; 2]>>,
}
