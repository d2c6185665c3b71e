//! `box`: the unit cube centred at the origin, flat outward normals, each face's uvs over
//! [0,1]^2 (so a texture covers every face once).

use glam::{Vec2, Vec3};

use super::builder::{PartBuilder, Xf, diffuse};
use crate::scene::mesh::MeshPart;

pub fn unit_box() -> MeshPart {
    let mut b = PartBuilder::new("box", diffuse("box", [0.8, 0.8, 0.8]));
    let h = Vec3::splat(0.5);
    b.cuboid(&Xf::IDENTITY, -h, h);
    let mut part = b.finish();
    // `cuboid` gives uvs in world units (1 x 1 here), which is already [0,1]^2 per face.
    for uv in &mut part.uvs {
        *uv = uv.clamp(Vec2::ZERO, Vec2::ONE);
    }
    part
}
