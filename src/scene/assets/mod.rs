//! Procedural assets made by the project's own code: meshes named by `[[mesh]] generator = ...`
//! in scene files, and the bundled texture images (`textures`, written by
//! `cargo run --release --bin make_assets -- scenes/textures`). Deterministic for a seed.
//!
//! Every generator returns parts with an MTL-style default material (`Kd`, or `Ke` for the
//! parts that emit light), so a scene can use them as they are or override them all with
//! `[[mesh]] material = ...`.

pub mod airplane;
pub mod builder;
pub mod conference;
pub mod cube;
pub mod grid;
pub mod textures;

use glam::{Vec2, Vec3};

use crate::scene::mesh::MeshPart;

/// Names accepted by `[[mesh]] generator`.
pub const MESH_GENERATORS: &[&str] = &["quad", "box", "grid", "airplane", "conference_room"];

/// The mesh a generator makes, or None for an unknown name.
pub fn generate_mesh(name: &str, seed: u64) -> Option<Vec<MeshPart>> {
    match name {
        "quad" => Some(vec![quad()]),
        "box" => Some(vec![cube::unit_box()]),
        "grid" => Some(vec![grid::grid()]),
        "airplane" => Some(airplane::airplane(seed)),
        "conference_room" => Some(conference::conference_room(seed)),
        _ => None,
    }
}

/// The unit square in the xz plane, facing +y, uv over [0,1]^2.
fn quad() -> MeshPart {
    MeshPart {
        name: "quad".into(),
        positions: vec![
            Vec3::new(-0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(-0.5, 0.0, 0.5),
        ],
        normals: vec![Vec3::Y; 4],
        uvs: vec![
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 0.0),
        ],
        indices: vec![[0, 2, 1], [0, 3, 2]],
        material: None,
    }
}
