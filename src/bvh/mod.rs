//! The bounding volume hierarchy (thesis §4.2.2 "BVH construction", Figs. 4.4-4.6).
//!
//! The tree is built by `obvhs` (PLOC clustering, SAH reinsertion and leaf collapse; the thesis
//! split at the mean triangle centre, which gives slower trees), then flattened depth-first into
//! the thesis's node array: each node stores its box, its leaf triangle range and a *skip index*,
//! the next node to visit when a ray misses the node's whole subtree. Triangles are reordered
//! into leaf order, so the device reads a leaf's triangles contiguously, without indirection.

pub mod wide;

use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use glam::Vec3A;
use obvhs::BvhBuildParams;
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::triangle::Triangle as ObvhsTriangle;

use crate::layout::{BvhNode, LEAF_COUNT_SHIFT, LEAF_FIRST_MASK};

/// Which obvhs preset builds the tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BuildQuality {
    Fast,
    #[default]
    Medium,
    /// Uses obvhs's pre-splitting: a large triangle may sit in several leaves and is then
    /// duplicated in the reordered triangle list.
    Slow,
}

/// Which tree the kernels walk (`render --bvh`). Both give every ray query the same answer,
/// so the image is the same bytes (tests/wide_bvh.rs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum BvhLayout {
    /// The thesis's binary tree with skip indices (§4.2.2, Alg. 4), walked without a stack.
    Skip,
    /// Eight children per node ([`wide`]), tested in float8 lanes, walked front to back.
    #[default]
    Wide,
}

/// Most triangles a leaf may hold; the count must fit in the node's top 4 bits.
pub const MAX_LEAF_TRIANGLES: u32 = 4;

/// A flattened BVH over triangles whose order is given by `triangle_order`.
#[derive(Clone, Debug, Default)]
pub struct FlatBvh {
    pub nodes: Vec<BvhNode>,
    /// `triangle_order[k]` is the input index of the k-th triangle in leaf order. With
    /// pre-splitting an input triangle can appear more than once.
    pub triangle_order: Vec<u32>,
    pub stats: BvhStats,
}

#[derive(Clone, Debug, Default)]
pub struct BvhStats {
    pub input_triangles: usize,
    pub leaf_triangles: usize,
    pub nodes: usize,
    pub leaves: usize,
    pub max_depth: usize,
    pub build_time: Duration,
}

/// Builds and flattens the BVH over triangles given by their three vertices.
pub fn build(triangles: &[[glam::Vec3; 3]], quality: BuildQuality) -> Result<FlatBvh> {
    let start = Instant::now();
    if triangles.is_empty() {
        return Ok(FlatBvh::default());
    }
    if triangles.len() as u64 > LEAF_FIRST_MASK as u64 / 2 {
        bail!(
            "{} triangles is more than the BVH layout can index",
            triangles.len()
        );
    }
    let tris: Vec<ObvhsTriangle> = triangles
        .iter()
        .map(|t| ObvhsTriangle {
            v0: Vec3A::from(t[0]),
            v1: Vec3A::from(t[1]),
            v2: Vec3A::from(t[2]),
        })
        .collect();
    let mut params = match quality {
        BuildQuality::Fast => BvhBuildParams::fast_build(),
        BuildQuality::Medium => BvhBuildParams::medium_build(),
        BuildQuality::Slow => BvhBuildParams::slow_build(),
    };
    params.max_prims_per_leaf = MAX_LEAF_TRIANGLES;
    let bvh = build_bvh2_from_tris(&tris, params, &mut Duration::default());
    let mut flat = flatten(&bvh.nodes, &bvh.primitive_indices)?;
    flat.stats.input_triangles = triangles.len();
    flat.stats.build_time = start.elapsed();
    Ok(flat)
}

/// Relative and absolute outward padding of node boxes.
const PAD_RELATIVE: f32 = 1.0 / (1 << 20) as f32;
const PAD_ABSOLUTE: f32 = 1.0e-20;

/// Moves a box bound outward by a relative 2^-20 plus 1e-20. A ray lying exactly in the plane of
/// a box face (an axis-parallel ray, whose zero direction component the kernels replace by
/// +-1e-30) is classified by the sign of that zero, so it could miss a triangle touching the
/// face. After padding no triangle touches the box boundary, so that classification never
/// decides a hit; and 1e-20 * 1e30 keeps the slab distances of such rays far beyond any scene.
fn pad_bound(v: f32, outward: f32) -> f32 {
    v + outward * (v.abs() * PAD_RELATIVE + PAD_ABSOLUTE)
}

/// Depth-first flattening with skip indices, using explicit stacks (trees can be deeper than
/// any safe recursion depth).
///
/// Pass 1 emits nodes in pre-order (left child directly after its parent). Pass 2 walks the
/// output backwards, where both children of a node are already sized: the left child's subtree
/// starts at i + 1, the right one's after it. Then skip(i) = i + size(i), which for the last
/// subtree is the node count, the loop bound of Alg. 4.
pub fn flatten(
    nodes: &[obvhs::bvh2::node::Bvh2Node],
    primitive_indices: &[u32],
) -> Result<FlatBvh> {
    let mut out: Vec<BvhNode> = Vec::with_capacity(nodes.len());
    let mut is_leaf: Vec<bool> = Vec::with_capacity(nodes.len());
    let mut order: Vec<u32> = Vec::new();
    let mut stats = BvhStats::default();
    if nodes.is_empty() {
        return Ok(FlatBvh::default());
    }
    let mut stack: Vec<(usize, usize)> = vec![(0, 0)];
    while let Some((id, depth)) = stack.pop() {
        let n = &nodes[id];
        stats.max_depth = stats.max_depth.max(depth);
        let mut node = BvhNode {
            bounds_min: n.aabb.min.to_array().map(|v| pad_bound(v, -1.0)),
            bounds_max: n.aabb.max.to_array().map(|v| pad_bound(v, 1.0)),
            skip: 0,
            leaf: 0,
        };
        if n.prim_count > 0 {
            if n.prim_count >= 1 << (32 - LEAF_COUNT_SHIFT) {
                bail!(
                    "a BVH leaf holds {} triangles, more than the node layout allows",
                    n.prim_count
                );
            }
            let first = order.len() as u32;
            let range = n.first_index as usize..(n.first_index + n.prim_count) as usize;
            order.extend_from_slice(&primitive_indices[range]);
            node.leaf = first | (n.prim_count << LEAF_COUNT_SHIFT);
            stats.leaves += 1;
        } else {
            stack.push((n.first_index as usize + 1, depth + 1)); // right, visited second
            stack.push((n.first_index as usize, depth + 1)); // left, visited next
        }
        is_leaf.push(n.prim_count > 0);
        out.push(node);
    }
    let count = out.len();
    let mut size = vec![1usize; count];
    for i in (0..count).rev() {
        if !is_leaf[i] {
            let left = size[i + 1];
            size[i] = 1 + left + size[i + 1 + left];
        }
        out[i].skip = (i + size[i]) as u32;
    }
    debug_assert_eq!(size[0], count);
    stats.nodes = count;
    stats.leaf_triangles = order.len();
    Ok(FlatBvh {
        nodes: out,
        triangle_order: order,
        stats,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::Vec3;

    pub(crate) fn soup(n: usize) -> Vec<[Vec3; 3]> {
        let mut s = 12345u32;
        let mut r = move || {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            (s >> 8) as f32 / (1u32 << 24) as f32
        };
        (0..n)
            .map(|_| {
                let c = Vec3::new(r(), r(), r()) * 10.0;
                [
                    c,
                    c + Vec3::new(r(), r(), r()),
                    c + Vec3::new(r(), r(), r()),
                ]
            })
            .collect()
    }

    #[test]
    fn skip_indices_describe_a_preorder_tree() {
        let bvh = build(&soup(500), BuildQuality::Medium).unwrap();
        let n = bvh.nodes.len();
        assert_eq!(
            bvh.nodes[0].skip as usize, n,
            "the root's skip ends traversal"
        );
        for (i, node) in bvh.nodes.iter().enumerate() {
            let skip = node.skip as usize;
            assert!(skip > i && skip <= n);
            if node.leaf != 0 {
                assert_eq!(skip, i + 1, "a leaf's subtree is itself");
            } else {
                // Children: i+1 and the node after the left subtree; both inside our subtree,
                // and their boxes inside ours.
                let left = i + 1;
                let right = bvh.nodes[left].skip as usize;
                assert!(right < skip);
                assert_eq!(bvh.nodes[right].skip as usize, skip);
                for c in [left, right] {
                    for k in 0..3 {
                        // Children are padded as much as their parent: allow that slack.
                        let slack = 2.0
                            * (node.bounds_max[k].abs().max(node.bounds_min[k].abs())
                                * PAD_RELATIVE
                                + PAD_ABSOLUTE);
                        assert!(bvh.nodes[c].bounds_min[k] >= node.bounds_min[k] - slack);
                        assert!(bvh.nodes[c].bounds_max[k] <= node.bounds_max[k] + slack);
                    }
                }
            }
        }
    }

    #[test]
    fn every_triangle_lands_in_exactly_one_leaf_without_presplit() {
        let tris = soup(777);
        let bvh = build(&tris, BuildQuality::Medium).unwrap();
        let mut seen = vec![0; tris.len()];
        for &t in &bvh.triangle_order {
            seen[t as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1));
        // Leaf ranges tile the reordered list.
        let mut covered = 0;
        for node in &bvh.nodes {
            if node.leaf != 0 {
                assert_eq!((node.leaf & LEAF_FIRST_MASK) as usize, covered);
                let count = node.leaf >> LEAF_COUNT_SHIFT;
                assert!((1..=MAX_LEAF_TRIANGLES).contains(&count));
                covered += count as usize;
            }
        }
        assert_eq!(covered, tris.len());
    }

    #[test]
    fn ray_in_the_plane_of_a_box_face_still_reaches_the_leaf() {
        use crate::geometry::ray_aabb;
        use crate::geometry::{ray_triangle, safe_inverse};
        // A wall at z = 0 spanning x in [0, 1]: its box's min-x face is the plane x = 0.
        let tris = vec![
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            [
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
        ];
        let bvh = build(&tris, BuildQuality::Medium).unwrap();
        let o = Vec3::new(0.0, 0.5, -5.0);
        for d in [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(-0.0, 0.0, 1.0),
            Vec3::new(-0.0, -0.0, 1.0),
        ] {
            let inv = safe_inverse(d);
            for node in &bvh.nodes {
                let (lo, hi) = (Vec3::from(node.bounds_min), Vec3::from(node.bounds_max));
                assert!(
                    ray_aabb(o, inv, 0.0, f32::INFINITY, lo, hi),
                    "direction {d:?} misses a box"
                );
            }
            // And the triangle edge on x = 0 is hit (Möller-Trumbore's bounds are inclusive).
            assert!(tris.iter().any(|t| {
                ray_triangle(o, d, t[0], t[1], t[2]).is_some_and(|h| (h.0 - 5.0).abs() < 1e-6)
            }));
        }
    }

    #[test]
    fn single_triangle_and_empty_inputs() {
        assert!(build(&[], BuildQuality::Medium).unwrap().nodes.is_empty());
        let one = build(&soup(1), BuildQuality::Medium).unwrap();
        assert_eq!(one.nodes.len(), 1);
        assert_eq!(one.nodes[0].skip, 1);
        assert_eq!(one.nodes[0].leaf, 1 << LEAF_COUNT_SHIFT);
    }
}
