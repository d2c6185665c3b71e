//! `airplane`: a medium-complexity airliner for the thesis's "Cornell plane" scene (ch. 7,
//! Fig. 7.1c). Nose towards +x, up +y, wings along z; about 2 units long and 1.8 units in
//! span, centred near the origin, its lowest point (the engines) about 0.2 below the origin.
//!
//! Every part is a closed surface wound outwards (smooth normals), so the mesh can be glass:
//! a fuselage of revolution with an upswept tail cone, swept and tapered wings with NACA
//! sections, dihedral and rounded tips, a horizontal and a vertical tail, two engine
//! nacelles on pylons, and a band of cabin windows.

use std::f32::consts::{PI, TAU};

use glam::{Mat3, Vec2, Vec3};

use super::builder::{PartBuilder, Rng, Xf, diffuse};
use crate::scene::mesh::MeshPart;

const BODY_R: f32 = 0.1;
const NOSE_X: f32 = 1.0;
const TAIL_X: f32 = -1.0;

/// The airplane. The seed varies the livery colour slightly; the shape is fixed.
pub fn airplane(seed: u64) -> Vec<MeshPart> {
    let mut rng = Rng::new(seed);
    let tint = [
        rng.range(0.55, 0.75),
        rng.range(0.1, 0.25),
        rng.range(0.1, 0.2),
    ];
    vec![fuselage(), windows(), wings(), tail(tint), engines()]
}

/// Fuselage centre-line height and radius at x.
fn body_section(x: f32) -> (f32, f32) {
    let nose_start = 0.7;
    let tail_start = -0.35;
    if x >= nose_start {
        // Blunt elliptic nose, slightly drooped.
        let s = ((x - nose_start) / (NOSE_X - nose_start)).clamp(0.0, 1.0);
        let r = BODY_R * (1.0 - s.powf(2.2)).max(0.0).sqrt();
        (-0.025 * s * s, r)
    } else if x <= tail_start {
        // Tail cone: tapers and sweeps up.
        let s = ((tail_start - x) / (tail_start - TAIL_X)).clamp(0.0, 1.0);
        let r = BODY_R * (1.0 - s.powf(1.6)).max(0.0).powf(0.6) * (1.0 - 0.75 * s);
        (0.07 * s.powf(1.5), r)
    } else {
        (0.0, BODY_R)
    }
}

fn fuselage() -> MeshPart {
    let mut b = PartBuilder::new("fuselage", diffuse("airplane_body", [0.85, 0.85, 0.85]));
    // u along the body (tail to nose, cosine-spaced so both ends get rows), v around.
    let f = |u: f32, v: f32| {
        let t = 0.5 - 0.5 * (PI * u).cos();
        let x = TAIL_X + (NOSE_X - TAIL_X) * t;
        let (cy, r) = body_section(x);
        let a = v * TAU;
        // Slightly taller than wide, like a double-bubble section.
        Vec3::new(x, cy + 1.06 * r * a.sin(), r * a.cos())
    };
    b.parametric(&Xf::IDENTITY, 128, 72, Vec2::new(1.0, 1.0), false, false, f);
    b.finish()
}

/// A row of dark cabin windows on each side: flattened discs just proud of the skin, and the
/// cockpit windscreen.
fn windows() -> MeshPart {
    let mut b = PartBuilder::new("windows", diffuse("airplane_windows", [0.05, 0.06, 0.08]));
    let n = 22;
    for side in [-1.0f32, 1.0] {
        for k in 0..n {
            let x = -0.3 + 0.045 * k as f32;
            let y = 0.035;
            let a = (y / (1.06 * BODY_R)).asin();
            let z = side * BODY_R * a.cos();
            let normal = Vec3::new(0.0, a.sin(), side * a.cos());
            window_pane(&mut b, Vec3::new(x, y, z), normal, 0.012, 0.016);
        }
    }
    // Windscreen panes on the nose.
    for side in [-1.0f32, 1.0] {
        for k in 0..2 {
            let x = 0.86 + 0.04 * k as f32;
            let (cy, r) = body_section(x);
            let a: f32 = 0.55;
            let p = Vec3::new(x, cy + 1.06 * r * a.sin(), side * r * a.cos());
            let normal = Vec3::new(0.35, a.sin(), side * a.cos()).normalize();
            window_pane(&mut b, p, normal, 0.016, 0.012);
        }
    }
    b.finish()
}

/// A thin closed lens-shaped pane centred at `p` facing `normal`.
fn window_pane(b: &mut PartBuilder, p: Vec3, normal: Vec3, w: f32, h: f32) {
    let side = Vec3::X.cross(normal).normalize_or(Vec3::Y);
    let along = normal.cross(side).normalize();
    let rot = Mat3::from_cols(along * w, normal, side * h);
    let xf = Xf {
        linear: rot,
        offset: p,
    };
    // A flattened ellipsoid: 2 units of thickness scale to ~0.003.
    b.parametric(&xf, 12, 6, Vec2::ONE, true, false, |u, v| {
        let a = u * TAU;
        let e = (v - 0.5) * PI;
        Vec3::new(e.cos() * a.cos(), 0.003 * e.sin(), -e.cos() * a.sin())
    });
}

/// One lifting surface: NACA 00xx sections, linear taper and sweep, rounded root and tip.
struct Surface {
    /// Leading edge at the root.
    root: Vec3,
    /// Span direction (unit) and length.
    span_dir: Vec3,
    span: f32,
    /// Thickness direction (unit), perpendicular to the chord (-x).
    thick_dir: Vec3,
    root_chord: f32,
    tip_chord: f32,
    /// Leading-edge offset at the tip, towards -x.
    sweep: f32,
    thickness: f32,
}

impl Surface {
    /// Position at u (around the section: trailing edge, upper side, leading edge, lower side,
    /// trailing edge) and w (root cap, span, tip cap).
    fn point(&self, u: f32, w: f32) -> Vec3 {
        // Rounded caps: the first and last 8% of w turn the section down to a line.
        let cap = 0.08;
        let cap_len = 0.04;
        let (s, k) = if w < cap {
            let th = (1.0 - w / cap) * PI / 2.0;
            (cap_len * (1.0 - th.sin()), th.cos())
        } else if w > 1.0 - cap {
            let th = (w - (1.0 - cap)) / cap * PI / 2.0;
            (1.0 - cap_len + cap_len * th.sin(), th.cos())
        } else {
            let t = (w - cap) / (1.0 - 2.0 * cap);
            (cap_len + (1.0 - 2.0 * cap_len) * t, 1.0)
        };
        let x = 0.5 + 0.5 * (TAU * u).cos(); // 1 at the TE, 0 at the LE
        let side = if u < 0.5 { 1.0 } else { -1.0 };
        let yt = 5.0
            * self.thickness
            * (0.2969 * x.sqrt() - 0.1260 * x - 0.3516 * x * x + 0.2843 * x.powi(3)
                - 0.1036 * x.powi(4));
        let chord = self.root_chord + (self.tip_chord - self.root_chord) * s;
        let le = self.root + self.span_dir * (s * self.span) - Vec3::X * (self.sweep * s);
        le - Vec3::X * (x * chord) + self.thick_dir * (side * yt * chord * k)
    }

    fn build(&self, b: &mut PartBuilder, nu: usize, nv: usize) {
        // du x dw points along span_dir x thick_dir-ish; pick the sign from a probe.
        let e = 1e-3;
        let (u, w) = (0.25, 0.5);
        let du = self.point(u + e, w) - self.point(u - e, w);
        let dw = self.point(u, w + e) - self.point(u, w - e);
        let flip = du.cross(dw).dot(self.thick_dir) < 0.0;
        b.parametric(&Xf::IDENTITY, nu, nv, Vec2::ONE, false, flip, |u, w| {
            self.point(u, w)
        });
    }
}

fn wings() -> MeshPart {
    let mut b = PartBuilder::new("wings", diffuse("airplane_wings", [0.7, 0.72, 0.75]));
    let dihedral: f32 = 6f32.to_radians();
    for side in [-1.0f32, 1.0] {
        let span_dir = Vec3::new(0.0, dihedral.sin(), side * dihedral.cos());
        let thick_dir = Vec3::new(0.0, dihedral.cos(), -side * dihedral.sin());
        Surface {
            root: Vec3::new(0.25, -0.05, 0.0),
            span_dir,
            span: 0.95,
            thick_dir,
            root_chord: 0.45,
            tip_chord: 0.11,
            sweep: 0.5,
            thickness: 0.12,
        }
        .build(&mut b, 64, 40);
        // Winglet: a small near-vertical fin at the tip.
        let tip = Vec3::new(0.25 - 0.5, -0.05, 0.0) + span_dir * 0.93;
        let up = Vec3::new(0.0, 0.97, side * 0.25).normalize();
        Surface {
            root: tip - Vec3::X * 0.0,
            span_dir: up,
            span: 0.1,
            thick_dir: up.cross(Vec3::X).normalize(),
            root_chord: 0.1,
            tip_chord: 0.05,
            sweep: 0.06,
            thickness: 0.1,
        }
        .build(&mut b, 32, 16);
    }
    // Wing-to-body fairing: a flattened ellipsoid under the wing root.
    b.parametric(&Xf::IDENTITY, 48, 24, Vec2::ONE, true, false, |u, v| {
        let a = u * TAU;
        let e = (v - 0.5) * PI;
        Vec3::new(
            0.06 + 0.36 * e.cos() * a.cos(),
            -0.06 + 0.055 * e.sin(),
            -0.105 * e.cos() * a.sin(),
        )
    });
    b.finish()
}

fn tail(tint: [f32; 3]) -> MeshPart {
    let mut b = PartBuilder::new("tail", diffuse("airplane_tail", tint));
    for side in [-1.0f32, 1.0] {
        Surface {
            root: Vec3::new(-0.72, 0.05, 0.0),
            span_dir: Vec3::new(0.0, 0.12, side).normalize(),
            span: 0.36,
            thick_dir: Vec3::new(0.0, 1.0, -side * 0.12).normalize(),
            root_chord: 0.22,
            tip_chord: 0.08,
            sweep: 0.2,
            thickness: 0.1,
        }
        .build(&mut b, 48, 24);
    }
    Surface {
        root: Vec3::new(-0.6, 0.04, 0.0),
        span_dir: Vec3::Y,
        span: 0.36,
        thick_dir: Vec3::Z,
        root_chord: 0.32,
        tip_chord: 0.12,
        sweep: 0.3,
        thickness: 0.1,
    }
    .build(&mut b, 48, 24);
    b.finish()
}

fn engines() -> MeshPart {
    let mut b = PartBuilder::new("engines", diffuse("airplane_engines", [0.4, 0.42, 0.45]));
    let r = 0.046;
    // Nacelle profile about the y axis, counterclockwise in (radius, y): from the exhaust cone
    // tip (aft, on the axis) out over the nozzle and the cowling to the intake lip, down the
    // inlet duct to the fan face and its spinner, which ends on the axis.
    let profile = [
        (0.0, -0.22),
        (0.35 * r, -0.18),
        (0.6 * r, -0.16),
        (0.8 * r, -0.16),
        (0.92 * r, -0.1),
        (r, 0.0),
        (r, 0.12),
        (0.97 * r, 0.15),
        (0.9 * r, 0.16),
        (0.82 * r, 0.155),
        (0.78 * r, 0.1),
        (0.3 * r, 0.1),
        (0.0, 0.14),
    ];
    for side in [-1.0f32, 1.0] {
        let z = side * 0.33;
        // Turn +y (the intake) to +x, the flight direction.
        let xf = Xf {
            linear: Mat3::from_rotation_z(-PI / 2.0),
            offset: Vec3::new(0.3, -0.13, z),
        };
        b.lathe(&xf, &profile, 48, 2);
        // Pylon joining the nacelle to the wing.
        Surface {
            root: Vec3::new(0.32, -0.105, z),
            span_dir: Vec3::Y,
            span: 0.085,
            thick_dir: Vec3::Z,
            root_chord: 0.3,
            tip_chord: 0.26,
            sweep: 0.03,
            thickness: 0.14,
        }
        .build(&mut b, 32, 12);
    }
    b.finish()
}
