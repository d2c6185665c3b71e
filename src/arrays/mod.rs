//! The scene as flat arrays in the shared layout (src/layout.rs): exactly what is uploaded to
//! the device, and what the CPU mirror of the kernels (src/render/cpu) reads, so both trace the
//! same data; and the ray queries over them ([`trace`], the mirror of kernels/arrays/trace.cl;
//! [`trace_wide`], of kernels/arrays/trace_wide.cl).

pub mod texels;
pub mod trace;
pub mod trace_wide;

use anyhow::{Result, bail};
use glam::Vec3;

use crate::bvh::wide::WideBvh;
use crate::bvh::{self, BuildQuality, BvhStats};
use crate::layout::{
    BvhNode, Float2, Float4, LIGHT_SPHERE, LIGHT_TRIANGLE, Light, MATERIAL_DIFFUSE,
    MATERIAL_EMITTER, MATERIAL_GLASS, MATERIAL_METAL, MATERIAL_SPECULAR, Material, SceneParams,
    Sphere, TextureInfo, TriangleGeom, TriangleShading,
};
use crate::scene::{MaterialKind, Scene};

/// Per-render settings that are not part of the scene file, or override it.
#[derive(Clone, Debug)]
pub struct FrameSettings {
    pub width: u32,
    pub height: u32,
    pub seed: u32,
    pub max_depth: u32,
    pub bvh_quality: BuildQuality,
    /// Per-sample colour clamp (0: none).
    pub sample_clamp: f32,
}

impl FrameSettings {
    pub fn from_scene(scene: &Scene) -> Self {
        FrameSettings {
            width: scene.render.width,
            height: scene.render.height,
            seed: scene.render.seed,
            max_depth: scene.render.max_depth,
            bvh_quality: BuildQuality::default(),
            sample_clamp: scene.render.clamp,
        }
    }
}

/// Hard cap on path vertices. With Russian roulette (survival <= 0.95) a path reaches it with
/// probability below 0.95^(1024 - max_depth), so it only guards against runaway loops.
pub const MAX_PATH_VERTICES: u32 = 1024;

#[derive(Clone, Debug, Default)]
pub struct SceneArrays {
    pub params: SceneParams,
    pub nodes: Vec<BvhNode>,
    /// The same tree collapsed to eight children per node (src/bvh/wide.rs), for the wide
    /// walk of kernels/arrays/trace_wide.cl.
    pub wide_bvh: WideBvh,
    pub tri_geom: Vec<TriangleGeom>,
    pub tri_shading: Vec<TriangleShading>,
    pub spheres: Vec<Sphere>,
    pub materials: Vec<Material>,
    pub textures: Vec<TextureInfo>,
    pub texels: Vec<Float4>,
    pub lights: Vec<Light>,
    /// light_cdf[i] = pmf[0] + ... + pmf[i]; the last entry is exactly 1.
    pub light_cdf: Vec<f32>,
    pub bvh_stats: BvhStats,
    /// Focal distance actually used, and how it was found.
    pub focus_note: String,
}

fn f4(v: Vec3, w: f32) -> Float4 {
    Float4::from_vec3(v, w)
}

fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl SceneArrays {
    pub fn build(scene: &Scene, frame: &FrameSettings) -> Result<SceneArrays> {
        if frame.width == 0 || frame.height == 0 {
            bail!(
                "the image must be at least 1x1 pixels, got {}x{}",
                frame.width,
                frame.height
            );
        }
        let mut a = SceneArrays::default();

        // Triangles in BVH leaf order (§4.2.2, Fig. 4.6).
        let verts: Vec<[Vec3; 3]> = scene.triangles.iter().map(|t| t.p).collect();
        let flat = bvh::build(&verts, frame.bvh_quality)?;
        a.nodes = flat.nodes;
        a.bvh_stats = flat.stats;

        for &i in &flat.triangle_order {
            let t = &scene.triangles[i as usize];
            a.tri_geom.push(TriangleGeom {
                v0: f4(t.p[0], 0.0),
                v1: f4(t.p[1], 0.0),
                v2: f4(t.p[2], 0.0),
            });
            a.tri_shading.push(TriangleShading {
                n0: f4(t.n[0], 0.0),
                n1: f4(t.n[1], 0.0),
                n2: f4(t.n[2], 0.0),
                uv0: Float2::from_vec2(t.uv[0]),
                uv1: Float2::from_vec2(t.uv[1]),
                uv2: Float2::from_vec2(t.uv[2]),
                material: t.material,
                light: -1,
                object: t.object,
                ..Default::default()
            });
        }
        a.wide_bvh = bvh::wide::collapse(&a.nodes, &a.tri_geom);
        #[cfg(debug_assertions)]
        bvh::wide::validate(&a.wide_bvh, &a.nodes);

        for m in &scene.materials {
            let mut d = Material {
                emission: f4(m.emission, 0.0),
                texture: -1,
                ..Default::default()
            };
            match &m.kind {
                MaterialKind::Diffuse { color, texture } => {
                    d.kind = MATERIAL_DIFFUSE;
                    d.color = f4(*color, 0.0);
                    d.texture = texture.map_or(-1, |t| t as i32);
                }
                MaterialKind::Specular { color } => {
                    d.kind = MATERIAL_SPECULAR;
                    d.color = f4(*color, 0.0);
                }
                MaterialKind::Glass {
                    reflect_color,
                    refract_color,
                    ior_outside,
                    ior_inside,
                } => {
                    d.kind = MATERIAL_GLASS;
                    d.color = f4(*reflect_color, 0.0);
                    d.color2 = f4(*refract_color, 0.0);
                    d.ior_outside = *ior_outside;
                    d.ior_inside = *ior_inside;
                }
                MaterialKind::Metal { color, exponent } => {
                    d.kind = MATERIAL_METAL;
                    d.color = f4(*color, 0.0);
                    d.exponent = *exponent;
                }
                MaterialKind::Emitter => d.kind = MATERIAL_EMITTER,
            }
            // Anything that emits is a light: it ends paths like an emitter (Alg. 1, implicit
            // connection), and is sampled by explicit connections.
            if m.is_emissive() {
                d.kind = MATERIAL_EMITTER;
            }
            a.materials.push(d);
        }

        (a.texels, a.textures) = texels::pack(&scene.textures);
        if a.texels.len() > u32::MAX as usize {
            bail!("the scene's textures hold more than 2^32 texels");
        }

        // Lights: every emissive sphere and triangle, chosen with probability proportional to
        // its power (luminance of the emitted radiance times area).
        let mut weights = Vec::new();
        for (i, s) in scene.spheres.iter().enumerate() {
            let m = &scene.materials[s.material as usize];
            let mut sphere = Sphere {
                center: s.center.to_array(),
                radius: s.radius,
                material: s.material,
                light: -1,
                ..Default::default()
            };
            if m.is_emissive() {
                sphere.light = a.lights.len() as i32;
                a.lights.push(Light {
                    kind: LIGHT_SPHERE,
                    primitive: i as u32,
                    emission: f4(m.emission, 0.0),
                    p0: f4(s.center, s.radius),
                    ..Default::default()
                });
                weights.push(
                    luminance(m.emission) as f64
                        * 4.0
                        * std::f64::consts::PI
                        * (s.radius as f64).powi(2),
                );
            }
            a.spheres.push(sphere);
        }
        let mut is_light = vec![false; scene.triangles.len()];
        for (k, &i) in flat.triangle_order.iter().enumerate() {
            let t = &scene.triangles[i as usize];
            let m = &scene.materials[t.material as usize];
            // With pre-split BVHs a triangle can appear in several leaves; it is one light.
            if !m.is_emissive() || is_light[i as usize] {
                continue;
            }
            is_light[i as usize] = true;
            a.tri_shading[k].light = a.lights.len() as i32;
            let area = t.area();
            a.lights.push(Light {
                kind: LIGHT_TRIANGLE,
                primitive: k as u32,
                area,
                emission: f4(m.emission, 0.0),
                p0: f4(t.p[0], 0.0),
                p1: f4(t.p[1], 0.0),
                p2: f4(t.p[2], 0.0),
                ..Default::default()
            });
            weights.push(luminance(m.emission) as f64 * area as f64);
        }
        let total: f64 = weights.iter().sum();
        let mut acc = 0.0f64;
        for (light, w) in a.lights.iter_mut().zip(&weights) {
            // Lights with zero luminance (e.g. pure blue) still get a share so they are sampled.
            let p = if total > 0.0 {
                w / total
            } else {
                1.0 / weights.len() as f64
            };
            light.pmf = p as f32;
            acc += p;
            a.light_cdf.push(acc as f32);
        }
        if let Some(last) = a.light_cdf.last_mut() {
            *last = 1.0;
        }
        if a.lights.iter().any(|l| !(l.pmf > 0.0)) {
            // A light too dim to be chosen in float32: share uniformly instead.
            let n = a.lights.len();
            for (i, l) in a.lights.iter_mut().enumerate() {
                l.pmf = 1.0 / n as f32;
                a.light_cdf[i] = (i + 1) as f32 / n as f32;
            }
        }

        a.params = scene_params(scene, frame, &a)?;
        a.focus(scene);
        Ok(a)
    }
}

impl SceneArrays {
    /// The camera the megakernel renders with (after autofocus).
    pub fn camera(&self) -> crate::scene::CameraBasis {
        let p = &self.params;
        crate::scene::CameraBasis {
            origin: p.camera_origin.xyz(),
            forward: p.camera_forward.xyz(),
            right: p.camera_right.xyz(),
            up: p.camera_up.xyz(),
            tan_half_fov: p.tan_half_fov,
            lens_radius: p.lens_radius,
            focal_distance: p.focal_distance,
        }
    }

    /// Moves the camera to `scene.camera` (the rest of `scene` must be what the arrays were
    /// built from): the thesis's camera update (§4.2.2 "Camera"), without rebuilding the BVH.
    /// The parameters are then exactly those [`SceneArrays::build`] gives for `scene`.
    pub fn set_camera(&mut self, scene: &Scene) {
        set_camera_params(&mut self.params, &scene.camera);
        self.focus(scene);
    }

    /// Autofocus (§4.2.2 "Camera"): the focal distance is the distance to the first hit along
    /// the view direction. When that ray hits nothing, the explicit focal_distance is kept if
    /// there is one, else the camera focuses on the centre of the scene's bounds.
    fn focus(&mut self, scene: &Scene) {
        let cam = &scene.camera;
        if cam.lens_radius <= 0.0 {
            self.focus_note = "pinhole camera".into();
            return;
        }
        if !cam.autofocus {
            self.focus_note = format!(
                "focal distance {} (from the scene)",
                self.params.focal_distance
            );
            return;
        }
        let origin = self.params.camera_origin.xyz();
        let forward = self.params.camera_forward.xyz();
        match crate::arrays::trace::intersect_closest(self, origin, forward, f32::INFINITY) {
            Some(hit) => {
                self.params.focal_distance = hit.t;
                self.focus_note =
                    format!("autofocus: {} (first hit along the view direction)", hit.t);
            }
            None => {
                let fallback = cam.focal_distance.unwrap_or_else(|| {
                    let (lo, hi) = scene_bounds(scene);
                    ((lo + hi) * 0.5 - origin).dot(forward).abs().max(1e-3)
                });
                self.params.focal_distance = fallback;
                self.focus_note = format!(
                    "autofocus ray hit nothing; focal distance {fallback} ({})",
                    if cam.focal_distance.is_some() {
                        "from the scene"
                    } else {
                        "centre of the scene bounds"
                    }
                );
            }
        }
    }
}

/// Axis-aligned bounds of all geometry (the camera position when there is none).
pub fn scene_bounds(scene: &Scene) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for t in &scene.triangles {
        for p in t.p {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    for s in &scene.spheres {
        lo = lo.min(s.center - s.radius);
        hi = hi.max(s.center + s.radius);
    }
    if lo.x > hi.x {
        return (scene.camera.origin, scene.camera.origin);
    }
    (lo, hi)
}

/// Writes the camera of `camera` into the megakernel's parameters (before autofocus).
fn set_camera_params(p: &mut SceneParams, camera: &crate::scene::Camera) {
    let cam = crate::scene::CameraBasis::new(camera);
    p.camera_origin = f4(cam.origin, 0.0);
    p.camera_forward = f4(cam.forward, 0.0);
    p.camera_right = f4(cam.right, 0.0);
    p.camera_up = f4(cam.up, 0.0);
    p.tan_half_fov = cam.tan_half_fov;
    p.lens_radius = cam.lens_radius;
    p.focal_distance = cam.focal_distance;
}

fn scene_params(scene: &Scene, frame: &FrameSettings, a: &SceneArrays) -> Result<SceneParams> {
    let mut p = SceneParams {
        image_width: frame.width,
        image_height: frame.height,
        node_count: a.nodes.len() as u32,
        sphere_count: a.spheres.len() as u32,
        light_count: a.lights.len() as u32,
        env_texture: -1,
        rr_depth: frame.max_depth,
        max_vertices: MAX_PATH_VERTICES,
        seed: frame.seed,
        sample_clamp: frame.sample_clamp,
        scene_size: {
            let (lo, hi) = scene_bounds(scene);
            let size = (hi - lo).max_element();
            if size.is_finite() && size > 0.0 {
                size
            } else {
                1.0
            }
        },
        env_uv: Float4::new(1.0, 1.0, 0.0, 0.0),
        ..Default::default()
    };
    set_camera_params(&mut p, &scene.camera);
    if let Some(env) = &scene.environment {
        p.env_radiance = f4(env.radiance, 0.0);
        p.env_texture = env.texture.map_or(-1, |t| t as i32);
        p.env_uv = Float4::new(
            env.uv_scale.x,
            env.uv_scale.y,
            env.uv_shift.x,
            env.uv_shift.y,
        );
    }
    Ok(p)
}
