//! kernels/arrays/trace_wide.cl in Rust: the walks of the eight-wide BVH (src/bvh/wide.rs).
//!
//! They answer every query exactly as the skip-index walks of [`super::trace`] do, whatever
//! order they visit the leaves in:
//! - the nearest hit is the triangle with the smallest t, and among triangles at the same t
//!   the one first in leaf order, which the skip-index walk meets first (it visits leaves in
//!   leaf order and keeps a hit only when strictly nearer);
//! - a box is passed over only when the slab test (Alg. 2, with its robust far bound) says
//!   that no point of it lies before the nearest hit so far, so no nearer triangle is lost;
//! - any-hit and the occluder range do not depend on the order at all.

use glam::Vec3;

use super::SceneArrays;
use super::trace::{Hit, Prim, any_sphere, nearest_sphere, range_of_hits};
use crate::bvh::wide::is_inner;
use crate::geometry::{ROBUST_FAR_SCALE, ray_triangle_edges, safe_inverse, slab_interval};
use crate::layout::{LEAF_FIRST_MASK, TrianglePack, WideBvhNode};

/// The children of `n` whose boxes the ray enters before `t_far`, with their entry distances,
/// in lane order.
fn children_hit(n: &WideBvhNode, o: Vec3, inv_d: Vec3, t_far: f32) -> Vec<(u32, f32)> {
    (0..n.child_count as usize)
        .filter_map(|k| {
            let lo = Vec3::new(n.min_x[k], n.min_y[k], n.min_z[k]);
            let hi = Vec3::new(n.max_x[k], n.max_y[k], n.max_z[k]);
            let (t0, t1) = slab_interval(o, inv_d, 0.0, t_far, lo, hi);
            (t1 * ROBUST_FAR_SCALE >= t0).then_some((n.child[k], t0))
        })
        .collect()
}

/// A leaf's triangles as the kernel's four-lane test sees them: (triangle index, t, u, v) of
/// every lane the test passes, in lane order (triangle order).
fn pack_hits(
    s: &SceneArrays,
    word: u32,
    o: Vec3,
    d: Vec3,
) -> impl Iterator<Item = (u32, f32, f32, f32)> {
    let p: &TrianglePack = &s.wide_bvh.packs[(word & LEAF_FIRST_MASK) as usize];
    (0..p.count as usize).filter_map(move |l| {
        let v0 = Vec3::new(p.v0_x[l], p.v0_y[l], p.v0_z[l]);
        let e1 = Vec3::new(p.e1_x[l], p.e1_y[l], p.e1_z[l]);
        let e2 = Vec3::new(p.e2_x[l], p.e2_y[l], p.e2_z[l]);
        ray_triangle_edges(o, d, v0, e1, e2).map(|(t, u, v)| (p.first + l as u32, t, u, v))
    })
}

/// Nearest hit in (0, t_max).
pub fn intersect_closest(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
    nearest_sphere(s, o, d, t_max, nearest_triangle(s, o, d, t_max))
}

/// Front to back: the children a node's test hits are taken nearest entry first, the others
/// kept on the stack with their entry distance and dropped when popped behind the nearest hit.
fn nearest_triangle(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
    let nodes = &s.wide_bvh.nodes;
    if nodes.is_empty() {
        return None;
    }
    let inv_d = safe_inverse(d);
    let mut best: Option<Hit> = None;
    let mut t_best = t_max;
    let mut stack: Vec<(u32, f32)> = Vec::new();
    let mut word = 0u32;
    loop {
        if is_inner(word) {
            let mut hits = children_hit(&nodes[word as usize], o, inv_d, t_best);
            // Stable: children at the same entry distance stay in lane order (as the kernel's
            // insertion sort keeps them).
            hits.sort_by(|a, b| a.1.total_cmp(&b.1));
            if let Some(&(near, _)) = hits.first() {
                stack.extend(hits[1..].iter().rev());
                debug_assert!(stack.len() <= s.wide_bvh.stack_need);
                word = near;
                continue;
            }
        } else {
            for (k, t, u, v) in pack_hits(s, word, o, d) {
                if t > 0.0
                    && (t < t_best
                        || (t == t_best
                            && matches!(best, Some(Hit { prim: Prim::Triangle(b), .. }) if k < b)))
                {
                    t_best = t;
                    best = Some(Hit {
                        t,
                        u,
                        v,
                        prim: Prim::Triangle(k),
                    });
                }
            }
        }
        // The next kept box that still starts before the nearest hit.
        match std::iter::from_fn(|| stack.pop()).find(|&(_, t0)| t_best * ROBUST_FAR_SCALE >= t0) {
            Some((next, _)) => word = next,
            None => return best,
        }
    }
}

/// Visits the distance of every triangle hit in (0, t_max), in no particular order, until
/// `visit` says stop (returns true); returns whether it stopped.
fn triangle_hits(
    s: &SceneArrays,
    o: Vec3,
    d: Vec3,
    t_max: f32,
    mut visit: impl FnMut(f32) -> bool,
) -> bool {
    let nodes = &s.wide_bvh.nodes;
    if nodes.is_empty() {
        return false;
    }
    let inv_d = safe_inverse(d);
    let mut stack: Vec<u32> = vec![0];
    while let Some(word) = stack.pop() {
        if is_inner(word) {
            let hits = children_hit(&nodes[word as usize], o, inv_d, t_max);
            // Lane 0 next, as the kernel does.
            stack.extend(hits.iter().rev().map(|h| h.0));
        } else {
            for (_, t, _, _) in pack_hits(s, word, o, d) {
                if t > 0.0 && t < t_max && visit(t) {
                    return true;
                }
            }
        }
    }
    false
}

/// Any hit in (0, t_max).
pub fn occluded(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> bool {
    triangle_hits(s, o, d, t_max, |_| true) || any_sphere(s, o, d, t_max)
}

/// Every hit in (0, t_max), nearest and farthest; None when nothing is hit.
pub fn occluder_range(s: &SceneArrays, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, f32)> {
    range_of_hits(s, o, d, t_max, |visit| triangle_hits(s, o, d, t_max, visit))
}
