//! kernels/geometry.cl in Rust.

use glam::Vec3;

pub const ROBUST_FAR_SCALE: f32 = 1.000_000_4;

pub fn safe_inverse(d: Vec3) -> Vec3 {
    let tiny = 1.0e-30f32;
    let f = |c: f32| if c.abs() < tiny { tiny.copysign(c) } else { c };
    Vec3::ONE / Vec3::new(f(d.x), f(d.y), f(d.z))
}

/// Algorithm 2 (see the kernel for the NaN-free inverse and the robust far scale).
pub fn ray_aabb(
    o: Vec3,
    inv_d: Vec3,
    t_near_plane: f32,
    t_far_plane: f32,
    bmin: Vec3,
    bmax: Vec3,
) -> bool {
    let (t0, t1) = slab_interval(o, inv_d, t_near_plane, t_far_plane, bmin, bmax);
    t1 * ROBUST_FAR_SCALE >= t0
}

/// The entry and exit distances of Alg. 2's slab test, clipped to the planes; the box is hit
/// when `t1 * ROBUST_FAR_SCALE >= t0` ([`ray_aabb`]). The wide walk sorts children by `t0`.
pub fn slab_interval(
    o: Vec3,
    inv_d: Vec3,
    t_near_plane: f32,
    t_far_plane: f32,
    bmin: Vec3,
    bmax: Vec3,
) -> (f32, f32) {
    let l1 = (bmin - o) * inv_d;
    let l2 = (bmax - o) * inv_d;
    let t_near = l1.min(l2);
    let t_far = l1.max(l2);
    let t0 = t_near.x.max(t_near.y).max(t_near.z.max(t_near_plane));
    let t1 = t_far.x.min(t_far.y).min(t_far.z.min(t_far_plane));
    (t0, t1)
}

/// Algorithm 3 (Möller-Trumbore): Some((t, u, v)) or None.
pub fn ray_triangle(o: Vec3, d: Vec3, p1: Vec3, p2: Vec3, p3: Vec3) -> Option<(f32, f32, f32)> {
    ray_triangle_edges(o, d, p1, p2 - p1, p3 - p1)
}

/// [`ray_triangle`] from the first vertex and the two edges (a wide BVH leaf's
/// [`crate::layout::TrianglePack`] stores them).
pub fn ray_triangle_edges(
    o: Vec3,
    d: Vec3,
    p1: Vec3,
    e1: Vec3,
    e2: Vec3,
) -> Option<(f32, f32, f32)> {
    let c = d.cross(e2);
    let det = e1.dot(c);
    if det == 0.0 {
        return None;
    }
    let vec1 = o - p1;
    let u = vec1.dot(c) / det;
    // Written as in kernels/geometry.cl: a NaN u passes here as it does there.
    #[allow(clippy::manual_range_contains)]
    if u < 0.0 || u > 1.0 {
        return None;
    }
    let vec2 = vec1.cross(e1);
    let v = d.dot(vec2) / det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((e2.dot(vec2) / det, u, v))
}

/// Nearest root in (t_min, t_max), Haines et al.'s careful form.
pub fn ray_sphere(
    o: Vec3,
    d: Vec3,
    center: Vec3,
    radius: f32,
    t_min: f32,
    t_max: f32,
) -> Option<f32> {
    let f = o - center;
    let b = -f.dot(d);
    let l = f + b * d;
    let r2 = radius * radius;
    let disc = r2 - l.dot(l);
    if disc < 0.0 {
        return None;
    }
    let c = f.dot(f) - r2;
    let q = b + disc.sqrt().copysign(b);
    let t0 = if q != 0.0 { c / q } else { 0.0 };
    let t1 = q;
    let (lo, hi) = (t0.min(t1), t0.max(t1));
    if lo > t_min && lo < t_max {
        Some(lo)
    } else if hi > t_min && hi < t_max {
        Some(hi)
    } else {
        None
    }
}

fn offset_component(p: f32, n: f32, scale: f32) -> f32 {
    let origin = scale * (1.0 / 32.0);
    let float_scale = scale * (1.0 / 65536.0);
    const INT_SCALE: f32 = 256.0;
    let of_i = (INT_SCALE * n) as i32;
    let p_i = f32::from_bits(
        (p.to_bits() as i32).wrapping_add(if p < 0.0 { -of_i } else { of_i }) as u32,
    );
    if p.abs() < origin {
        p + float_scale * n
    } else {
        p_i
    }
}

/// Wächter & Binder's origin offset, its absolute part in units of the scene size `scale`.
pub fn offset_ray_origin(p: Vec3, n: Vec3, scale: f32) -> Vec3 {
    Vec3::new(
        offset_component(p.x, n.x, scale),
        offset_component(p.y, n.y, scale),
        offset_component(p.z, n.z, scale),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_parallel_rays_inside_or_outside_a_slab() {
        // Zero direction components: classified by the origin, never NaN.
        let d = Vec3::new(0.0, 0.0, 1.0);
        let inside = Vec3::new(0.3, 0.5, -5.0);
        let outside = Vec3::new(-0.1, 0.5, -5.0);
        for d in [d, Vec3::new(-0.0, -0.0, 1.0)] {
            assert!(ray_aabb(
                inside,
                safe_inverse(d),
                0.0,
                f32::INFINITY,
                Vec3::ZERO,
                Vec3::ONE
            ));
            assert!(!ray_aabb(
                outside,
                safe_inverse(d),
                0.0,
                f32::INFINITY,
                Vec3::ZERO,
                Vec3::ONE
            ));
        }
        // (Origins exactly on a face plane are handled by padding the BVH's boxes, src/bvh/mod.rs.)
    }

    #[test]
    fn offset_leaves_the_surface_at_any_scale() {
        for scale in [1e-3f32, 1.0, 1e3, 1e5] {
            let center = Vec3::splat(0.37) * scale;
            let r = 0.5 * scale;
            let n = Vec3::new(0.3, 0.8, -0.52).normalize();
            let p = center + n * r;
            let o = offset_ray_origin(p, n, scale);
            // A ray leaving outwards along a tangent-ish direction must not re-hit the sphere.
            let d = (n + Vec3::new(0.9, -0.3, 0.1).normalize() * 3.0).normalize();
            let d = if d.dot(n) > 0.0 { d } else { -d };
            assert!(
                ray_sphere(o, d, center, r, 0.0, f32::INFINITY).is_none(),
                "scale {scale}"
            );
        }
    }
}
