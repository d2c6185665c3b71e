//! `conference_room`: the thesis's "Conference room" test scene (ch. 7, Fig. 7.1e): high
//! geometric complexity, low material complexity. A 10 x 3 x 6 room (x in [-5, 5], y in
//! [0, 3], z in [-3, 3]) with a long table, swivel chairs, sideboards, wall panels, a
//! projection screen and rectangular ceiling light panels.
//!
//! Every surface that is not a light shares one plain diffuse material and nothing is
//! textured, so the filters' *texture* buffers carry no edges (thesis §7, "There is no edge
//! information in the texture and texture2 buffers"). The triangles go into the rounded,
//! smoothly shaded chairs.

use std::f32::consts::{PI, TAU};

use glam::{Mat3, Vec2, Vec3};

use super::builder::{PartBuilder, Rng, Xf, bend_about_y, diffuse, emissive, no_deform};
use crate::scene::mesh::{MeshPart, MtlMaterial};

/// The one diffuse reflectance of the room.
pub const ALBEDO: [f32; 3] = [0.7, 0.7, 0.7];
/// Emission of the ceiling panels.
pub const LIGHT: [f32; 3] = [8.0, 8.0, 8.0];

fn surface() -> MtlMaterial {
    diffuse("conference_diffuse", ALBEDO)
}

/// The room; the seed turns the chairs a little, as people left them.
pub fn conference_room(seed: u64) -> Vec<MeshPart> {
    let mut rng = Rng::new(seed);
    let (frames, lights) = ceiling_lights();
    vec![
        shell(),
        table(),
        chairs(&mut rng),
        furniture(),
        frames,
        lights,
    ]
}

const HX: f32 = 5.0;
const HY: f32 = 3.0;
const HZ: f32 = 3.0;

/// Floor, ceiling and walls, facing into the room, with skirting boards and a wainscot rail.
fn shell() -> MeshPart {
    let mut b = PartBuilder::new("room", surface());
    let id = Xf::IDENTITY;
    let v = Vec3::new;
    // Floor (up), ceiling (down).
    b.flat_quad(
        &id,
        [
            v(-HX, 0.0, -HZ),
            v(-HX, 0.0, HZ),
            v(HX, 0.0, HZ),
            v(HX, 0.0, -HZ),
        ],
        Vec3::Y,
        Vec2::new(6.0, 10.0),
    );
    b.flat_quad(
        &id,
        [
            v(-HX, HY, -HZ),
            v(HX, HY, -HZ),
            v(HX, HY, HZ),
            v(-HX, HY, HZ),
        ],
        -Vec3::Y,
        Vec2::new(10.0, 6.0),
    );
    // Walls, normals inwards.
    b.flat_quad(
        &id,
        [
            v(-HX, 0.0, -HZ),
            v(HX, 0.0, -HZ),
            v(HX, HY, -HZ),
            v(-HX, HY, -HZ),
        ],
        Vec3::Z,
        Vec2::new(10.0, 3.0),
    );
    b.flat_quad(
        &id,
        [
            v(HX, 0.0, HZ),
            v(-HX, 0.0, HZ),
            v(-HX, HY, HZ),
            v(HX, HY, HZ),
        ],
        -Vec3::Z,
        Vec2::new(10.0, 3.0),
    );
    b.flat_quad(
        &id,
        [
            v(-HX, 0.0, HZ),
            v(-HX, 0.0, -HZ),
            v(-HX, HY, -HZ),
            v(-HX, HY, HZ),
        ],
        Vec3::X,
        Vec2::new(6.0, 3.0),
    );
    b.flat_quad(
        &id,
        [
            v(HX, 0.0, -HZ),
            v(HX, 0.0, HZ),
            v(HX, HY, HZ),
            v(HX, HY, -HZ),
        ],
        -Vec3::X,
        Vec2::new(6.0, 3.0),
    );
    // Skirting boards and a rail at 0.9 m on the long walls; skirting on the short walls.
    let t = 0.02;
    for (y0, y1) in [(0.0, 0.1), (0.88, 0.92)] {
        b.cuboid(&id, v(-HX + t, y0, -HZ), v(HX - t, y1, -HZ + t));
        b.cuboid(&id, v(-HX + t, y0, HZ - t), v(HX - t, y1, HZ));
    }
    b.cuboid(&id, v(-HX, 0.0, -HZ), v(-HX + t, 0.1, HZ));
    b.cuboid(&id, v(HX - t, 0.0, -HZ), v(HX, 0.1, HZ));
    // Vertical wall panels (pilasters) along the long walls.
    for k in 0..9 {
        let x = -4.0 + k as f32;
        b.rounded_box(
            &Xf::translate(v(x, 1.5, -HZ + 0.03)),
            v(0.08, 1.5, 0.03),
            0.02,
            2,
            1,
            &no_deform,
        );
        b.rounded_box(
            &Xf::translate(v(x, 1.5, HZ - 0.03)),
            v(0.08, 1.5, 0.03),
            0.02,
            2,
            1,
            &no_deform,
        );
    }
    // A door in the far short wall's corner and a cornice along the ceiling.
    b.rounded_box(
        &Xf::translate(v(HX - 0.03, 1.05, 2.0)),
        v(0.03, 1.05, 0.5),
        0.015,
        2,
        2,
        &no_deform,
    );
    b.cylinder(
        &Xf {
            linear: Mat3::from_rotation_z(PI / 2.0),
            offset: v(HX - 0.06, 1.0, 1.65),
        },
        0.02,
        -0.05,
        0.05,
        16,
        1,
    );
    for (a, c) in [
        (v(-HX, HY - 0.08, -HZ), v(HX, HY, -HZ + 0.08)),
        (v(-HX, HY - 0.08, HZ - 0.08), v(HX, HY, HZ)),
        (v(-HX, HY - 0.08, -HZ), v(-HX + 0.08, HY, HZ)),
        (v(HX - 0.08, HY - 0.08, -HZ), v(HX, HY, HZ)),
    ] {
        b.cuboid(&id, a, c);
    }
    b.finish()
}

const TABLE_HALF: Vec3 = Vec3::new(3.0, 0.03, 0.8);
const TABLE_TOP: f32 = 0.75;

/// The long table: a thick top with rounded edges on two pedestals joined by a beam.
fn table() -> MeshPart {
    let mut b = PartBuilder::new("table", surface());
    let v = Vec3::new;
    b.rounded_box(
        &Xf::translate(v(0.0, TABLE_TOP - TABLE_HALF.y, 0.0)),
        TABLE_HALF,
        0.03,
        8,
        12,
        &no_deform,
    );
    for x in [-2.0, 0.0, 2.0] {
        // Pedestal: a rounded panel standing on a foot.
        b.rounded_box(
            &Xf::translate(v(x, 0.375, 0.0)),
            v(0.06, 0.33, 0.45),
            0.04,
            4,
            4,
            &no_deform,
        );
        b.rounded_box(
            &Xf::translate(v(x, 0.025, 0.0)),
            v(0.12, 0.025, 0.6),
            0.02,
            4,
            4,
            &no_deform,
        );
    }
    // Cable beam under the top.
    b.rounded_box(
        &Xf::translate(v(0.0, 0.55, 0.0)),
        v(2.1, 0.06, 0.08),
        0.03,
        4,
        6,
        &no_deform,
    );
    b.finish()
}

/// Seats around the table; each chair turned a little at random.
fn chairs(rng: &mut Rng) -> MeshPart {
    let mut b = PartBuilder::new("chairs", surface());
    let mut placements = Vec::new();
    for k in 0..7 {
        let x = -2.55 + 0.85 * k as f32;
        placements.push((x, -1.15, 0.0)); // south side, facing +z (the table)
        placements.push((x, 1.15, PI)); // north side, facing -z
    }
    placements.push((-3.55, 0.0, PI / 2.0)); // heads of the table, facing the table
    placements.push((3.55, 0.0, -PI / 2.0));
    for (x, z, facing) in placements {
        let turn = rng.range(-0.35, 0.35);
        let dx = rng.range(-0.08, 0.08);
        let dz = rng.range(-0.1, 0.1);
        let xf = Xf::rot_y(facing + turn, Vec3::new(x + dx, 0.0, z + dz));
        chair(&mut b, &xf);
    }
    b.finish()
}

/// A swivel chair facing +z with its centre on the floor at the origin.
fn chair(b: &mut PartBuilder, xf: &Xf) {
    let v = Vec3::new;
    // Five-star base with casters.
    for k in 0..5 {
        let a = k as f32 * TAU / 5.0 + 0.3;
        let spoke = xf.then(Xf::rot_y(a, v(0.0, 0.0, 0.0)));
        b.rounded_box(
            &spoke.then(Xf::translate(v(0.15, 0.09, 0.0))),
            v(0.15, 0.022, 0.025),
            0.018,
            2,
            3,
            &no_deform,
        );
        // Caster: a small wheel (torus-like lathe) on a fork.
        let wheel = spoke.then(Xf {
            linear: Mat3::from_rotation_x(PI / 2.0),
            offset: v(0.29, 0.03, 0.0),
        });
        let profile: Vec<(f32, f32)> = (0..=8)
            .map(|i| {
                let t = PI * i as f32 / 8.0 - PI / 2.0;
                (0.012 + 0.018 * t.cos(), 0.014 * t.sin())
            })
            .collect();
        b.lathe(
            &wheel,
            &[&[(0.0, -0.014)], &profile[..], &[(0.0, 0.014)]].concat(),
            14,
            1,
        );
        b.rounded_box(
            &spoke.then(Xf::translate(v(0.29, 0.065, 0.0))),
            v(0.022, 0.02, 0.02),
            0.008,
            2,
            1,
            &no_deform,
        );
    }
    // Hub, gas spring and column.
    b.lathe(
        xf,
        &[
            (0.0, 0.07),
            (0.05, 0.07),
            (0.06, 0.09),
            (0.06, 0.11),
            (0.045, 0.125),
            (0.0, 0.125),
        ],
        24,
        1,
    );
    b.cylinder(xf, 0.032, 0.12, 0.28, 24, 1);
    b.cylinder(xf, 0.022, 0.28, 0.42, 24, 1);
    // Seat mechanism and the seat cushion, slightly dished by a gentle bend.
    b.rounded_box(
        &xf.then(Xf::translate(v(0.0, 0.415, 0.0))),
        v(0.1, 0.02, 0.12),
        0.01,
        2,
        2,
        &no_deform,
    );
    b.rounded_box(
        &xf.then(Xf::translate(v(0.0, 0.47, 0.02))),
        v(0.245, 0.04, 0.235),
        0.035,
        6,
        6,
        &no_deform,
    );
    // Back support bar from under the seat up behind the back rest.
    b.rounded_box(
        &xf.then(Xf {
            linear: Mat3::from_rotation_x(-0.12),
            offset: v(0.0, 0.62, -0.245),
        }),
        v(0.035, 0.2, 0.015),
        0.012,
        3,
        3,
        &no_deform,
    );
    // Curved, reclined back rest.
    let bend = bend_about_y(0.55);
    b.rounded_box(
        &xf.then(Xf {
            linear: Mat3::from_rotation_x(-0.15),
            offset: v(0.0, 0.86, -0.25),
        }),
        v(0.225, 0.24, 0.028),
        0.026,
        6,
        8,
        &bend,
    );
    // Armrests: a post and a pad on each side.
    for side in [-1.0f32, 1.0] {
        b.rounded_box(
            &xf.then(Xf::translate(v(side * 0.26, 0.57, -0.02))),
            v(0.014, 0.09, 0.03),
            0.012,
            3,
            2,
            &no_deform,
        );
        b.rounded_box(
            &xf.then(Xf::translate(v(side * 0.26, 0.665, 0.0))),
            v(0.035, 0.016, 0.13),
            0.015,
            3,
            3,
            &no_deform,
        );
    }
}

/// Sideboards with doors and handles along the south wall, a projection screen on the west
/// wall and a lectern.
fn furniture() -> MeshPart {
    let mut b = PartBuilder::new("furniture", surface());
    let v = Vec3::new;
    for k in 0..3 {
        let x = -3.0 + 3.0 * k as f32;
        let z = -HZ + 0.25;
        b.rounded_box(
            &Xf::translate(v(x, 0.42, z)),
            v(0.9, 0.42, 0.22),
            0.015,
            3,
            4,
            &no_deform,
        );
        for d in 0..3 {
            let dx = x - 0.6 + 0.6 * d as f32;
            // Door panel, proud of the carcass.
            b.rounded_box(
                &Xf::translate(v(dx, 0.44, z + 0.225)),
                v(0.28, 0.36, 0.012),
                0.008,
                3,
                3,
                &no_deform,
            );
            // Bar handle on two stand-offs.
            let handle = Xf {
                linear: Mat3::IDENTITY,
                offset: v(dx + 0.2, 0.44, z + 0.26),
            };
            b.cylinder(&handle, 0.008, -0.1, 0.1, 12, 1);
            for hy in [-0.08, 0.08] {
                b.cylinder(
                    &Xf {
                        linear: Mat3::from_rotation_x(PI / 2.0),
                        offset: v(dx + 0.2, 0.44 + hy, z + 0.245),
                    },
                    0.005,
                    -0.016,
                    0.016,
                    8,
                    1,
                );
            }
        }
    }
    // Projection screen: a housing and the screen itself on the west wall.
    b.rounded_box(
        &Xf::translate(v(-HX + 0.02, 1.65, 0.0)),
        v(0.02, 0.8, 1.3),
        0.01,
        2,
        2,
        &no_deform,
    );
    b.cylinder(
        &Xf {
            linear: Mat3::from_rotation_x(PI / 2.0),
            offset: v(-HX + 0.08, 2.5, 0.0),
        },
        0.05,
        -1.4,
        1.4,
        24,
        1,
    );
    // Lectern in the corner.
    b.rounded_box(
        &Xf::translate(v(-4.3, 0.55, -2.2)),
        v(0.25, 0.55, 0.2),
        0.03,
        4,
        4,
        &no_deform,
    );
    b.rounded_box(
        &Xf {
            linear: Mat3::from_rotation_z(0.25),
            offset: v(-4.3, 1.14, -2.2),
        },
        v(0.3, 0.02, 0.25),
        0.015,
        3,
        3,
        &no_deform,
    );
    b.finish()
}

/// Rectangular ceiling panels: the emitting surfaces (facing down, just below the ceiling)
/// and their diffuse frames.
fn ceiling_lights() -> (MeshPart, MeshPart) {
    let mut frames = PartBuilder::new("light_frames", surface());
    let mut lights = PartBuilder::new("ceiling_lights", emissive("conference_light", LIGHT));
    let v = Vec3::new;
    let (hw, hd) = (0.6, 0.3);
    for i in 0..4 {
        for j in 0..2 {
            let x = -3.0 + 2.0 * i as f32;
            let z = -1.2 + 2.4 * j as f32;
            let y = HY - 0.03;
            lights.flat_quad(
                &Xf::IDENTITY,
                [
                    v(x - hw, y, z - hd),
                    v(x + hw, y, z - hd),
                    v(x + hw, y, z + hd),
                    v(x - hw, y, z + hd),
                ],
                -Vec3::Y,
                Vec2::ONE,
            );
            let f = 0.04;
            for (a, c) in [
                (
                    v(x - hw - f, y - 0.005, z - hd - f),
                    v(x + hw + f, HY, z - hd),
                ),
                (
                    v(x - hw - f, y - 0.005, z + hd),
                    v(x + hw + f, HY, z + hd + f),
                ),
                (v(x - hw - f, y - 0.005, z - hd), v(x - hw, HY, z + hd)),
                (v(x + hw, y - 0.005, z - hd), v(x + hw + f, HY, z + hd)),
            ] {
                frames.cuboid(&Xf::IDENTITY, a, c);
            }
        }
    }
    (frames.finish(), lights.finish())
}
