//! Shared tools of the mesh generators: a small deterministic PRNG, a part builder that keeps
//! every triangle non-degenerate and wound to agree with its vertex normals, and the shapes
//! the generators are assembled from (boxes, rounded boxes, parametric grids, cylinders).

use glam::{Mat3, Vec2, Vec3};

use crate::scene::mesh::{MeshPart, MtlMaterial};

/// SplitMix64: a tiny, well-mixed generator, so that a seed always gives the same asset.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
}

/// A diffuse MTL material (`Kd` only).
pub fn diffuse(name: &str, kd: [f32; 3]) -> MtlMaterial {
    MtlMaterial {
        name: name.into(),
        kd: Some(kd),
        ..Default::default()
    }
}

/// An emissive MTL material (`Ke`; the loader makes it a light).
pub fn emissive(name: &str, ke: [f32; 3]) -> MtlMaterial {
    MtlMaterial {
        name: name.into(),
        kd: Some([0.0; 3]),
        ke: Some(ke),
        ..Default::default()
    }
}

/// An affine placement: `p -> linear * p + offset`; normals use the inverse transpose.
#[derive(Clone, Copy, Debug)]
pub struct Xf {
    pub linear: Mat3,
    pub offset: Vec3,
}

impl Xf {
    pub const IDENTITY: Xf = Xf {
        linear: Mat3::IDENTITY,
        offset: Vec3::ZERO,
    };

    pub fn translate(t: Vec3) -> Xf {
        Xf {
            linear: Mat3::IDENTITY,
            offset: t,
        }
    }

    /// Rotation about y (radians), then translation.
    pub fn rot_y(angle: f32, t: Vec3) -> Xf {
        Xf {
            linear: Mat3::from_rotation_y(angle),
            offset: t,
        }
    }

    /// `self` applied after `inner`.
    pub fn then(self, inner: Xf) -> Xf {
        Xf {
            linear: self.linear * inner.linear,
            offset: self.linear * inner.offset + self.offset,
        }
    }

    pub fn point(&self, p: Vec3) -> Vec3 {
        self.linear * p + self.offset
    }

    pub fn normal(&self, n: Vec3) -> Vec3 {
        (self.linear.inverse().transpose() * n).normalize_or_zero()
    }
}

/// Collects the triangles of one part.
pub struct PartBuilder {
    part: MeshPart,
}

impl PartBuilder {
    pub fn new(name: &str, material: MtlMaterial) -> Self {
        PartBuilder {
            part: MeshPart {
                name: name.into(),
                material: Some(material),
                ..Default::default()
            },
        }
    }

    pub fn vertex(&mut self, p: Vec3, n: Vec3, uv: Vec2) -> u32 {
        self.part.positions.push(p);
        self.part.normals.push(n.normalize_or_zero());
        self.part.uvs.push(uv);
        (self.part.positions.len() - 1) as u32
    }

    /// Adds a triangle unless its area is (nearly) zero. The winding is turned, if needed, so
    /// that the face normal agrees with the vertex normals: every surface built from outward
    /// normals is then consistently wound outward.
    pub fn tri(&mut self, a: u32, b: u32, c: u32) {
        let p = &self.part.positions;
        let (pa, pb, pc) = (p[a as usize], p[b as usize], p[c as usize]);
        let face = (pb - pa).cross(pc - pa);
        let scale = (pb - pa)
            .length_squared()
            .max((pc - pa).length_squared())
            .max((pc - pb).length_squared());
        // Also rejects NaN: the comparison is false for it.
        let big_enough = face.length_squared() > 1e-12 * scale * scale;
        if !big_enough {
            return;
        }
        let n = &self.part.normals;
        let avg = n[a as usize] + n[b as usize] + n[c as usize];
        if face.dot(avg) < 0.0 {
            self.part.indices.push([a, c, b]);
        } else {
            self.part.indices.push([a, b, c]);
        }
    }

    /// A quad a-b-c-d (in order around its edge) as two triangles.
    pub fn quad(&mut self, a: u32, b: u32, c: u32, d: u32) {
        self.tri(a, b, c);
        self.tri(a, c, d);
    }

    /// A flat quad with corners in order around its edge, facing `normal`.
    pub fn flat_quad(&mut self, xf: &Xf, corners: [Vec3; 4], normal: Vec3, uv_size: Vec2) {
        let n = xf.normal(normal);
        let uvs = [
            Vec2::ZERO,
            Vec2::new(uv_size.x, 0.0),
            uv_size,
            Vec2::new(0.0, uv_size.y),
        ];
        let i: Vec<u32> = (0..4)
            .map(|k| self.vertex(xf.point(corners[k]), n, uvs[k]))
            .collect();
        self.quad(i[0], i[1], i[2], i[3]);
    }

    /// A parametric surface sampled on an (nu+1) x (nv+1) grid; `f(u, v)` gives the position
    /// and outward normal at (u, v) in [0,1]^2. Collapsed rows (poles) lose their degenerate
    /// triangles in `tri`.
    pub fn grid(
        &mut self,
        xf: &Xf,
        nu: usize,
        nv: usize,
        uv_scale: Vec2,
        f: impl Fn(f32, f32) -> (Vec3, Vec3),
    ) {
        let base = self.part.positions.len() as u32;
        for j in 0..=nv {
            for i in 0..=nu {
                let (u, v) = (i as f32 / nu as f32, j as f32 / nv as f32);
                let (p, n) = f(u, v);
                self.vertex(xf.point(p), xf.normal(n), Vec2::new(u, v) * uv_scale);
            }
        }
        let row = (nu + 1) as u32;
        for j in 0..nv as u32 {
            for i in 0..nu as u32 {
                let a = base + j * row + i;
                self.quad(a, a + 1, a + row + 1, a + row);
            }
        }
    }

    /// A parametric surface given by its position alone; the normals come from the partial
    /// derivatives (central differences). `periodic_u` surfaces wrap around in u (no clamping),
    /// and near a collapsed row (a pole) the normal is taken just inside the domain. `flip`
    /// reverses the normal, for parametrisations whose du x dv points inwards.
    #[allow(clippy::too_many_arguments)]
    pub fn parametric(
        &mut self,
        xf: &Xf,
        nu: usize,
        nv: usize,
        uv_scale: Vec2,
        periodic_u: bool,
        flip: bool,
        f: impl Fn(f32, f32) -> Vec3,
    ) {
        const E: f32 = 1e-3;
        let normal = |u: f32, v: f32| -> Vec3 {
            let mut best = Vec3::ZERO;
            // Try the point itself, then points slightly further into the domain.
            for inset in [0.0, 2.0 * E, 6.0 * E] {
                let uu = if periodic_u {
                    u
                } else {
                    u.clamp(inset, 1.0 - inset)
                };
                let vv = v.clamp(inset, 1.0 - inset);
                let (u0, u1) = if periodic_u {
                    (uu - E, uu + E)
                } else {
                    ((uu - E).max(0.0), (uu + E).min(1.0))
                };
                let (v0, v1) = ((vv - E).max(0.0), (vv + E).min(1.0));
                let du = f(u1, vv) - f(u0, vv);
                let dv = f(uu, v1) - f(uu, v0);
                let n = du.cross(dv);
                let scale = du.length() * dv.length();
                if n.length() > 1e-3 * scale && scale > 0.0 {
                    best = n.normalize();
                    break;
                }
            }
            if flip { -best } else { best }
        };
        self.grid(xf, nu, nv, uv_scale, |u, v| (f(u, v), normal(u, v)));
    }

    /// An axis-aligned box from `min` to `max`, flat faces, uvs in world units.
    pub fn cuboid(&mut self, xf: &Xf, min: Vec3, max: Vec3) {
        let c = |x: bool, y: bool, z: bool| {
            Vec3::new(
                if x { max.x } else { min.x },
                if y { max.y } else { min.y },
                if z { max.z } else { min.z },
            )
        };
        let s = max - min;
        let (t, f) = (true, false);
        self.flat_quad(
            xf,
            [c(t, f, f), c(t, t, f), c(t, t, t), c(t, f, t)],
            Vec3::X,
            Vec2::new(s.y, s.z),
        );
        self.flat_quad(
            xf,
            [c(f, f, t), c(f, t, t), c(f, t, f), c(f, f, f)],
            -Vec3::X,
            Vec2::new(s.y, s.z),
        );
        self.flat_quad(
            xf,
            [c(f, t, f), c(f, t, t), c(t, t, t), c(t, t, f)],
            Vec3::Y,
            Vec2::new(s.z, s.x),
        );
        self.flat_quad(
            xf,
            [c(f, f, t), c(f, f, f), c(t, f, f), c(t, f, t)],
            -Vec3::Y,
            Vec2::new(s.z, s.x),
        );
        self.flat_quad(
            xf,
            [c(f, f, t), c(t, f, t), c(t, t, t), c(f, t, t)],
            Vec3::Z,
            Vec2::new(s.x, s.y),
        );
        self.flat_quad(
            xf,
            [c(t, f, f), c(f, f, f), c(f, t, f), c(t, t, f)],
            -Vec3::Z,
            Vec2::new(s.x, s.y),
        );
    }

    /// A box of half extents `half` centred at the origin with edges and corners rounded to
    /// `radius`: `bevel` segments per quarter round, `flat` segments across each flat part.
    /// Smooth normals. `deform` bends the result (position and normal) before `xf` places it.
    pub fn rounded_box(
        &mut self,
        xf: &Xf,
        half: Vec3,
        radius: f32,
        bevel: usize,
        flat: usize,
        deform: &dyn Fn(Vec3, Vec3) -> (Vec3, Vec3),
    ) {
        let r = radius.min(half.x).min(half.y).min(half.z) * 0.999;
        let inner = half - Vec3::splat(r);
        // Sample coordinates along an axis of half extent h: tan-spaced in the bevels so the
        // angles of the round are uniform, uniform across the flat middle.
        let coords = |i: f32| -> Vec<f32> {
            let mut v = Vec::new();
            for k in 0..bevel {
                let a = std::f32::consts::FRAC_PI_4 * (1.0 - k as f32 / bevel as f32);
                v.push(-i - r * a.tan());
            }
            let flat = if i > 1e-6 { flat.max(1) } else { 0 };
            for k in 0..=flat {
                v.push(-i + 2.0 * i * k as f32 / flat.max(1) as f32);
            }
            if flat == 0 {
                v.pop();
                v.push(0.0);
            }
            for k in (0..bevel).rev() {
                let a = std::f32::consts::FRAC_PI_4 * (1.0 - k as f32 / bevel as f32);
                v.push(i + r * a.tan());
            }
            v
        };
        let cx = coords(inner.x);
        let cy = coords(inner.y);
        let cz = coords(inner.z);
        let map = |q: Vec3| -> (Vec3, Vec3) {
            let c = q.clamp(-inner, inner);
            let d = q - c;
            let n = d.normalize_or_zero();
            deform(c + n * r, n)
        };
        // Each face: axis a is the normal, (b, c) span the face.
        for (axis, sign) in [
            (0, 1.0f32),
            (0, -1.0),
            (1, 1.0),
            (1, -1.0),
            (2, 1.0),
            (2, -1.0),
        ] {
            let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
            let all = [&cx, &cy, &cz];
            let (cb, cc) = (all[b], all[c]);
            let hv = [half.x, half.y, half.z];
            let base = self.part.positions.len() as u32;
            for j in 0..cc.len() {
                for i in 0..cb.len() {
                    let mut q = [0.0f32; 3];
                    q[axis] = sign * hv[axis];
                    q[b] = cb[i];
                    q[c] = cc[j];
                    let (p, n) = map(Vec3::from(q));
                    let uv = Vec2::new(cb[i] - cb[0], cc[j] - cc[0]);
                    self.vertex(xf.point(p), xf.normal(n), uv);
                }
            }
            let row = cb.len() as u32;
            for j in 0..(cc.len() - 1) as u32 {
                for i in 0..(cb.len() - 1) as u32 {
                    let a = base + j * row + i;
                    self.quad(a, a + 1, a + row + 1, a + row);
                }
            }
        }
    }

    /// A closed cylinder along y from `y0` to `y1` with radius `r`, `segments` around and
    /// `rows` along; smooth sides and flat caps.
    pub fn cylinder(&mut self, xf: &Xf, r: f32, y0: f32, y1: f32, segments: usize, rows: usize) {
        self.lathe(
            xf,
            &[(0.0, y0), (r, y0), (r, y1), (0.0, y1)],
            segments,
            rows,
        );
    }

    /// A surface of revolution about y from a profile of (radius, y) points, listed
    /// counterclockwise in the (r, y) plane (from the axis at the bottom, outwards, up, and
    /// back to the axis), so that the outward normal of each profile segment is on its right.
    /// Each segment becomes `rows` rings; where the profile turns gently the normals are
    /// averaged (smooth), where it turns sharply each segment keeps its own (crisp edges).
    pub fn lathe(&mut self, xf: &Xf, profile: &[(f32, f32)], segments: usize, rows: usize) {
        let n = profile.len();
        for s in 0..n - 1 {
            let (r0, y0) = profile[s];
            let (r1, y1) = profile[s + 1];
            let dir = Vec2::new(r1 - r0, y1 - y0);
            if dir.length_squared() == 0.0 {
                continue;
            }
            // Outward normal of a profile walked from bottom-axis, out, up, back to the axis.
            let seg_n = Vec2::new(dir.y, -dir.x).normalize();
            let smooth_n = |k: usize| -> Vec2 {
                // Average with the neighbour segment when the turn is gentle.
                let neighbour = if k == s && s > 0 {
                    Some((profile[s - 1], profile[s]))
                } else if k == s + 1 && s + 2 < n {
                    Some((profile[s + 1], profile[s + 2]))
                } else {
                    None
                };
                match neighbour {
                    Some(((ra, ya), (rb, yb))) => {
                        let d = Vec2::new(rb - ra, yb - ya);
                        if d.length_squared() == 0.0 {
                            return seg_n;
                        }
                        let other = Vec2::new(d.y, -d.x).normalize();
                        if other.dot(seg_n) > 0.8 {
                            (other + seg_n).normalize()
                        } else {
                            seg_n
                        }
                    }
                    None => seg_n,
                }
            };
            let n0 = smooth_n(s);
            let n1 = smooth_n(s + 1);
            self.grid(xf, segments, rows, Vec2::ONE, |u, v| {
                let a = u * std::f32::consts::TAU;
                let (sa, ca) = a.sin_cos();
                let r = r0 + (r1 - r0) * v;
                let y = y0 + (y1 - y0) * v;
                let nn = (n0 * (1.0 - v) + n1 * v).normalize();
                (
                    Vec3::new(r * ca, y, -r * sa),
                    Vec3::new(nn.x * ca, nn.y, -nn.x * sa),
                )
            });
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.part.indices.len()
    }

    pub fn finish(self) -> MeshPart {
        self.part
    }
}

/// Identity deformation for [`PartBuilder::rounded_box`].
pub fn no_deform(p: Vec3, n: Vec3) -> (Vec3, Vec3) {
    (p, n)
}

/// Bends a shape lying in the xy plane around a vertical axis at distance `radius` in front
/// (+z), so that a flat panel becomes a section of a cylinder curving towards +z.
pub fn bend_about_y(radius: f32) -> impl Fn(Vec3, Vec3) -> (Vec3, Vec3) {
    move |p: Vec3, n: Vec3| {
        let a = p.x / radius;
        let (sa, ca) = a.sin_cos();
        let d = radius - p.z;
        let q = Vec3::new(d * sa, p.y, radius - d * ca);
        let rot = Mat3::from_rotation_y(-a);
        (q, rot * n)
    }
}
