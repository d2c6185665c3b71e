//! Writes a bundled scene as Mitsuba 3 inputs, for issue 14's anchor: the same geometry,
//! camera, diffuse materials and lights rendered by Mitsuba 3's `path` integrator beside
//! `noisefree render` (scripts/mitsuba/anchor.sh runs both and prints the ratios).
//!
//! `cargo run --release --example mitsuba_scene -- SCENE.toml OUT_DIR` writes
//! OUT_DIR/scene.json (camera, render settings, materials, spheres), one binary PLY per
//! material (the loaded scene's world-space triangles with their shading normals and uvs,
//! three vertices each, as the renderer holds them) and each texture as a linear EXR of the
//! floats the renderer samples, times the material's colour. What Mitsuba cannot be given
//! the same way is refused with a message: non-diffuse materials, the infinite light,
//! autofocus. Sphere texture coordinates are Mitsuba's own (a textured sphere shows its
//! texture turned; the work per sample is the same).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use noisefree::imaging::{RgbImage, write_exr};
use noisefree::scene::{MaterialKind, Scene, Triangle, load_scene};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [scene_path, out] = args.as_slice() else {
        bail!("usage: mitsuba_scene SCENE.toml OUT_DIR");
    };
    let scene = load_scene(Path::new(scene_path))?;
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    check_supported(&scene)?;

    let mut materials = Vec::new();
    for (m, material) in scene.materials.iter().enumerate() {
        let (color, texture) = match &material.kind {
            MaterialKind::Diffuse { color, texture } => (*color, *texture),
            MaterialKind::Emitter => (glam::Vec3::ZERO, None),
            _ => unreachable!("refused by check_supported"),
        };
        let texture_file = match texture {
            Some(t) => Some(write_texture(&scene, t as usize, color, &out, m)?),
            None => None,
        };
        let triangles: Vec<&Triangle> = scene
            .triangles
            .iter()
            .filter(|t| t.material as usize == m)
            .collect();
        let uv_transform = texture.map(|t| {
            let tex = &scene.textures[t as usize];
            (tex.uv_scale, tex.uv_shift)
        });
        let mesh_file = if triangles.is_empty() {
            None
        } else {
            let name = format!("mesh{m}.ply");
            write_ply(&out.join(&name), &triangles, uv_transform)?;
            Some(name)
        };
        materials.push(serde_json::json!({
            "name": material.name,
            "emitter": matches!(material.kind, MaterialKind::Emitter),
            "color": color.to_array(),
            "texture": texture_file,
            "emission": material.emission.to_array(),
            "mesh": mesh_file,
        }));
    }
    let spheres: Vec<_> = scene
        .spheres
        .iter()
        .map(|s| {
            serde_json::json!({
                "center": s.center.to_array(),
                "radius": s.radius,
                "material": s.material,
            })
        })
        .collect();
    let c = &scene.camera;
    let r = &scene.render;
    let json = serde_json::json!({
        "scene": scene_path,
        "camera": {
            "origin": c.origin.to_array(),
            "target": c.target.to_array(),
            "up": c.up.to_array(),
            "fov_degrees": c.fov_degrees,
            "lens_radius": c.lens_radius,
            "focal_distance": c.focal_distance,
        },
        "render": {
            "width": r.width,
            "height": r.height,
            "max_depth": r.max_depth,
            "russian_roulette": r.russian_roulette,
        },
        "materials": materials,
        "spheres": spheres,
    });
    let path = out.join("scene.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("writing {}", path.display()))?;
    println!(
        "{}: {} triangles, {} spheres, {} materials -> {}",
        scene_path,
        scene.triangles.len(),
        scene.spheres.len(),
        scene.materials.len(),
        out.display()
    );
    Ok(())
}

/// Refuses what the Mitsuba scene would not reproduce.
fn check_supported(scene: &Scene) -> Result<()> {
    for m in &scene.materials {
        match m.kind {
            MaterialKind::Diffuse { .. } | MaterialKind::Emitter => {}
            _ => bail!(
                "{}: material {:?} is not diffuse; the Mitsuba anchor takes diffuse scenes only",
                scene.path.display(),
                m.name
            ),
        }
    }
    if scene.environment.is_some() {
        bail!(
            "{}: has an infinite light; the Mitsuba anchor takes scenes without one",
            scene.path.display()
        );
    }
    if scene.camera.autofocus {
        bail!(
            "{}: autofocus is not reproduced; give focal_distance instead",
            scene.path.display()
        );
    }
    if !scene.render.next_event_estimation || scene.render.clamp > 0.0 {
        bail!(
            "{}: the Mitsuba anchor takes next event estimation on and no clamp",
            scene.path.display()
        );
    }
    Ok(())
}

/// The texture's floats times the material's colour, as a linear RGB EXR (rows top to
/// bottom, as the renderer holds them).
fn write_texture(
    scene: &Scene,
    t: usize,
    color: glam::Vec3,
    out: &Path,
    material: usize,
) -> Result<String> {
    let tex = &scene.textures[t];
    let pixels = tex
        .texels
        .iter()
        .map(|p| [p[0] * color.x, p[1] * color.y, p[2] * color.z])
        .collect();
    let img = RgbImage {
        width: tex.width,
        height: tex.height,
        pixels,
    };
    let name = format!("texture{material}.exr");
    write_exr(&out.join(&name), &img)?;
    Ok(name)
}

/// A binary little-endian PLY of unshared vertices (position, normal, uv). The renderer's uv
/// (0, 0) is an image's bottom-left corner; Mitsuba's is its top-left, so v is flipped after
/// the texture's scale and shift (both wrap by repetition).
fn write_ply(
    path: &Path,
    triangles: &[&Triangle],
    uv_transform: Option<(glam::Vec2, glam::Vec2)>,
) -> Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let n = triangles.len();
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property float u\nproperty float v\n\
         element face {n}\nproperty list uchar int vertex_indices\nend_header\n",
        3 * n
    )?;
    for t in triangles {
        for k in 0..3 {
            let uv = match uv_transform {
                Some((scale, shift)) => t.uv[k] * scale + shift,
                None => t.uv[k],
            };
            for v in [
                t.p[k].x,
                t.p[k].y,
                t.p[k].z,
                t.n[k].x,
                t.n[k].y,
                t.n[k].z,
                uv.x,
                1.0 - uv.y,
            ] {
                w.write_all(&v.to_le_bytes())?;
            }
        }
    }
    for i in 0..n as i32 {
        w.write_all(&[3u8])?;
        for k in 0..3 {
            w.write_all(&(3 * i + k).to_le_bytes())?;
        }
    }
    w.flush()?;
    Ok(())
}
