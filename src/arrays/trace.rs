//! kernels/arrays/trace.cl in Rust: skip-index BVH traversal (Alg. 4, nearest hit) and any-hit, plus
//! a brute-force search over every primitive to check them against.

use glam::Vec3;

use super::SceneArrays;
use crate::geometry::{ray_aabb, ray_sphere, ray_triangle, safe_inverse};
use crate::layout::{LEAF_COUNT_SHIFT, LEAF_FIRST_MASK};

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prim {
    Triangle(u32),
    Sphere(u32),
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub prim: Prim,
}

pub(super) fn v3(a: &[f32; 3]) -> Vec3 {
    Vec3::from_array(*a)
}

/// Nearest hit in (0, t_max).
pub fn intersect_closest(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
    nearest_sphere(s, o, d, t_max, nearest_triangle(s, o, d, t_max))
}

/// The nearest triangle hit in (0, t_max), by the skip-index walk (Alg. 4).
fn nearest_triangle(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    let mut t_best = t_max;
    let inv_d = safe_inverse(d);
    let n = s.params.node_count as usize;
    let mut current = 0usize;
    while current < n {
        let node = &s.nodes[current];
        if ray_aabb(
            o,
            inv_d,
            0.0,
            t_best,
            v3(&node.bounds_min),
            v3(&node.bounds_max),
        ) {
            if node.leaf != 0 {
                let first = (node.leaf & LEAF_FIRST_MASK) as usize;
                let count = (node.leaf >> LEAF_COUNT_SHIFT) as usize;
                for k in first..first + count {
                    let g = &s.tri_geom[k];
                    if let Some((t, u, v)) = ray_triangle(o, d, g.v0.xyz(), g.v1.xyz(), g.v2.xyz())
                        && t > 0.0
                        && t < t_best
                    {
                        t_best = t;
                        best = Some(Hit {
                            t,
                            u,
                            v,
                            prim: Prim::Triangle(k as u32),
                        });
                    }
                }
                current = node.skip as usize;
            } else {
                current += 1;
            }
        } else {
            current = node.skip as usize;
        }
    }
    best
}

/// The spheres after the triangles (as the kernels test them): a sphere replaces `best` only
/// when strictly nearer.
pub(super) fn nearest_sphere(
    s: &SceneArrays,
    o: Vec3,
    d: Vec3,
    t_max: f32,
    mut best: Option<Hit>,
) -> Option<Hit> {
    let mut t_best = best.map_or(t_max, |h| h.t);
    for (i, sp) in s
        .spheres
        .iter()
        .enumerate()
        .take(s.params.sphere_count as usize)
    {
        if let Some(t) = ray_sphere(o, d, v3(&sp.center), sp.radius, 0.0, t_best)
            && t > 0.0
        {
            t_best = t;
            best = Some(Hit {
                t,
                u: 0.0,
                v: 0.0,
                prim: Prim::Sphere(i as u32),
            });
        }
    }
    best
}

/// Visits the distance of every triangle hit in (0, t_max), in BVH order, until `visit` says
/// stop (returns true); returns whether it stopped. The traversal of [`occluded`] and
/// [`occluder_range`] (kernels/arrays/trace.cl writes it twice: OpenCL C has no closures).
fn triangle_hits(
    s: &SceneArrays,
    o: Vec3,
    d: Vec3,
    t_max: f32,
    mut visit: impl FnMut(f32) -> bool,
) -> bool {
    let inv_d = safe_inverse(d);
    let n = s.params.node_count as usize;
    let mut current = 0usize;
    while current < n {
        let node = &s.nodes[current];
        if ray_aabb(
            o,
            inv_d,
            0.0,
            t_max,
            v3(&node.bounds_min),
            v3(&node.bounds_max),
        ) {
            if node.leaf != 0 {
                let first = (node.leaf & LEAF_FIRST_MASK) as usize;
                let count = (node.leaf >> LEAF_COUNT_SHIFT) as usize;
                for g in &s.tri_geom[first..first + count] {
                    if let Some((t, _, _)) = ray_triangle(o, d, g.v0.xyz(), g.v1.xyz(), g.v2.xyz())
                        && t > 0.0
                        && t < t_max
                        && visit(t)
                    {
                        return true;
                    }
                }
                current = node.skip as usize;
            } else {
                current += 1;
            }
        } else {
            current = node.skip as usize;
        }
    }
    false
}

/// Any hit in (0, t_max).
pub fn occluded(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> bool {
    triangle_hits(s, o, d, t_max, |_| true) || any_sphere(s, o, d, t_max)
}

pub(super) fn any_sphere(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> bool {
    s.spheres
        .iter()
        .take(s.params.sphere_count as usize)
        .any(|sp| ray_sphere(o, d, v3(&sp.center), sp.radius, 0.0, t_max).is_some_and(|t| t > 0.0))
}

/// Every hit in (0, t_max), nearest and farthest (kernels/arrays/trace.cl `occluder_range`):
/// AAF's any-hit shadow rays that record the distance and go on. None when nothing is hit.
pub fn occluder_range(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, f32)> {
    range_of_hits(s, o, d, t_max, |visit| triangle_hits(s, o, d, t_max, visit))
}

/// The occluder range of the triangle hits a walk visits (`walk` calls its argument with each
/// distance), then of both crossings of every sphere in range; None when nothing is hit.
pub(super) fn range_of_hits(
    s: &SceneArrays,
    o: Vec3,
    d: Vec3,
    t_max: f32,
    walk: impl FnOnce(&mut dyn FnMut(f32) -> bool) -> bool,
) -> Option<(f32, f32)> {
    let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
    walk(&mut |t| {
        lo = lo.min(t);
        hi = hi.max(t);
        false
    });
    for sp in s.spheres.iter().take(s.params.sphere_count as usize) {
        let c = v3(&sp.center);
        if let Some(t0) = ray_sphere(o, d, c, sp.radius, 0.0, t_max).filter(|&t| t > 0.0) {
            lo = lo.min(t0);
            hi = hi.max(t0);
            if let Some(t1) = ray_sphere(o, d, c, sp.radius, t0, t_max).filter(|&t| t > 0.0) {
                hi = hi.max(t1);
            }
        }
    }
    (hi > 0.0).then_some((lo, hi))
}

/// Every primitive, no BVH: the ground truth for traversal tests.
pub fn brute_force_closest(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    let mut t_best = t_max;
    for (k, g) in s.tri_geom.iter().enumerate() {
        if let Some((t, u, v)) = ray_triangle(o, d, g.v0.xyz(), g.v1.xyz(), g.v2.xyz())
            && t > 0.0
            && t < t_best
        {
            t_best = t;
            best = Some(Hit {
                t,
                u,
                v,
                prim: Prim::Triangle(k as u32),
            });
        }
    }
    for (i, sp) in s.spheres.iter().enumerate() {
        if let Some(t) = ray_sphere(o, d, v3(&sp.center), sp.radius, 0.0, t_best)
            && t > 0.0
        {
            t_best = t;
            best = Some(Hit {
                t,
                u: 0.0,
                v: 0.0,
                prim: Prim::Sphere(i as u32),
            });
        }
    }
    best
}
