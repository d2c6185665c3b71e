//! The eight-wide BVH (issue 14; not in the thesis): the binary tree of [`super::flatten`]
//! collapsed so that each node holds up to eight children, whose boxes one float8 slab test
//! checks at once (kernels/arrays/trace_wide.cl). A ray tracer on a CPU spends most of its time
//! walking boxes one at a time with a scalar ray (Wald, Benthin & Boulos 2008, "Getting rid of
//! packets"); eight children per node make one box test of eight lanes out of eight scalar
//! ones, over far fewer nodes (the conference room: 34,444 wide nodes for 227,927 binary ones).
//!
//! The collapse keeps the leaves and the triangles' leaf order of the binary tree: a wide node
//! takes the two children of a binary node and opens its largest inner child (by surface area,
//! the SAH's measure of how often a ray enters it) into its two children until it holds eight
//! or only leaves (Wald et al. 2008 §3; Ylitie, Karras & Laine 2017 collapse by cost). The
//! children stay in depth-first order. Each leaf's triangles are stored once more as a
//! [`TrianglePack`], four triangles in float4 lanes, which one vector Möller-Trumbore test
//! checks at once.

use super::MAX_LEAF_TRIANGLES;
use crate::layout::{
    BVH_WIDTH, BvhNode, LEAF_COUNT_SHIFT, LEAF_FIRST_MASK, TriangleGeom, TrianglePack, WideBvhNode,
};

/// The wide tree and what its walk needs.
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    pub nodes: Vec<WideBvhNode>,
    /// One per leaf, in the order the leaves were met; a leaf's child word holds its index.
    pub packs: Vec<TrianglePack>,
    /// Most stack entries a walk can hold ([`stack_need`]).
    pub stack_need: usize,
}

/// The largest stack a wide walk may be built with (the kernels' `-D BVH_STACK`): 2 KiB of
/// private memory per work-item. A tree that could need more is walked by the skip-index
/// walk, which needs no stack (src/render/mod.rs `bvh_walked`).
pub const MAX_BVH_STACK: usize = 256;

impl WideBvh {
    /// Whether a walk's stack of [`MAX_BVH_STACK`] entries holds every walk of this tree.
    pub fn fits_stack(&self) -> bool {
        self.stack_need <= MAX_BVH_STACK
    }

    /// The stack the kernels are built with for this tree (`-D BVH_STACK`): its need rounded
    /// up to a multiple of 8, so that similar scenes share a build.
    pub fn stack_entries(&self) -> usize {
        self.stack_need.max(1).next_multiple_of(8)
    }
}

fn surface_area(n: &BvhNode) -> f32 {
    let e = [0, 1, 2].map(|k| n.bounds_max[k] - n.bounds_min[k]);
    e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
}

/// The two children of the inner binary node `i` (left after its parent, right at the left
/// subtree's skip index).
fn binary_children(nodes: &[BvhNode], i: usize) -> [usize; 2] {
    [i + 1, nodes[i + 1].skip as usize]
}

/// Collapses a flattened binary tree (skip-index layout) over `triangles` (leaf order) into
/// eight-wide nodes. Node 0 is the root and always an inner node: a tree that is a single leaf
/// becomes a root with one child.
pub fn collapse(nodes: &[BvhNode], triangles: &[TriangleGeom]) -> WideBvh {
    if nodes.is_empty() {
        return WideBvh::default();
    }
    let width = BVH_WIDTH as usize;
    let mut out: Vec<WideBvhNode> = Vec::new();
    let mut packs: Vec<TrianglePack> = Vec::new();
    let mut leaf_word = |leaf: u32| {
        let index = packs.len() as u32;
        packs.push(pack(leaf, triangles));
        index | (leaf & !LEAF_FIRST_MASK)
    };
    // (binary node, wide index): binary inner nodes whose wide node is still to be filled.
    let mut todo: Vec<(usize, usize)> = Vec::new();
    out.push(WideBvhNode::default());
    if nodes[0].leaf != 0 {
        set_child(&mut out[0], 0, &nodes[0], leaf_word(nodes[0].leaf));
        out[0].child_count = 1;
    } else {
        todo.push((0, 0));
    }
    while let Some((b, w)) = todo.pop() {
        let mut slots: Vec<usize> = binary_children(nodes, b).to_vec();
        while slots.len() < width {
            // Open the inner child a ray enters most often.
            let widest = slots
                .iter()
                .enumerate()
                .filter(|&(_, &c)| nodes[c].leaf == 0)
                .max_by(|a, b| surface_area(&nodes[*a.1]).total_cmp(&surface_area(&nodes[*b.1])));
            let Some((at, &c)) = widest else { break };
            slots.splice(at..=at, binary_children(nodes, c));
        }
        for (lane, &c) in slots.iter().enumerate() {
            let word = if nodes[c].leaf != 0 {
                leaf_word(nodes[c].leaf)
            } else {
                let index = out.len();
                out.push(WideBvhNode::default());
                todo.push((c, index));
                index as u32
            };
            set_child(&mut out[w], lane, &nodes[c], word);
        }
        out[w].child_count = slots.len() as u32;
    }
    let stack_need = stack_need(&out);
    WideBvh {
        nodes: out,
        packs,
        stack_need,
    }
}

/// The triangles of the binary leaf `leaf` (first | count << 28) in float4 lanes; unused lanes
/// are zero (the walk never reads their answers).
fn pack(leaf: u32, triangles: &[TriangleGeom]) -> TrianglePack {
    let first = leaf & LEAF_FIRST_MASK;
    let count = leaf >> LEAF_COUNT_SHIFT;
    assert!(
        count <= MAX_LEAF_TRIANGLES,
        "a leaf of {count} triangles does not fit a pack"
    );
    let mut p = TrianglePack {
        first,
        count,
        ..Default::default()
    };
    for lane in 0..count as usize {
        let t = &triangles[first as usize + lane];
        let (v0, e1, e2) = (t.v0.xyz(), t.v1.xyz() - t.v0.xyz(), t.v2.xyz() - t.v0.xyz());
        [p.v0_x[lane], p.v0_y[lane], p.v0_z[lane]] = v0.to_array();
        [p.e1_x[lane], p.e1_y[lane], p.e1_z[lane]] = e1.to_array();
        [p.e2_x[lane], p.e2_y[lane], p.e2_z[lane]] = e2.to_array();
    }
    p
}

fn set_child(w: &mut WideBvhNode, lane: usize, n: &BvhNode, word: u32) {
    w.min_x[lane] = n.bounds_min[0];
    w.min_y[lane] = n.bounds_min[1];
    w.min_z[lane] = n.bounds_min[2];
    w.max_x[lane] = n.bounds_max[0];
    w.max_y[lane] = n.bounds_max[1];
    w.max_z[lane] = n.bounds_max[2];
    w.child[lane] = word;
}

/// Whether a child word names an inner node (the top four bits hold a leaf's count).
pub fn is_inner(word: u32) -> bool {
    word >> LEAF_COUNT_SHIFT == 0
}

/// The most entries a walk's stack can hold: at a node it enters, a walk keeps all but one of
/// the children it hits and goes on into that one, so along a path from the root the stack
/// grows by at most (children - 1) per node.
pub fn stack_need(nodes: &[WideBvhNode]) -> usize {
    if nodes.is_empty() {
        return 0;
    }
    // Children come after their parent in `collapse`'s order: walk backwards.
    let mut need = vec![0usize; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = &nodes[i];
        let count = n.child_count as usize;
        let below = n.child[..count]
            .iter()
            .filter(|&&w| is_inner(w))
            .map(|&w| need[w as usize])
            .max()
            .unwrap_or(0);
        need[i] = count.saturating_sub(1) + below;
    }
    need[0]
}

/// Checks the invariants the walks rely on (debug builds and tests): children after their
/// parent, inner words in range, counts in 1..=8, and every leaf of the binary tree reached
/// exactly once (so every triangle, in its own leaf's box).
pub fn validate(wide: &WideBvh, binary: &[BvhNode]) {
    let mut leaves: Vec<u32> = Vec::new();
    let mut packs_met = vec![0u32; wide.packs.len()];
    for (i, n) in wide.nodes.iter().enumerate() {
        let count = n.child_count as usize;
        assert!(
            (1..=BVH_WIDTH as usize).contains(&count),
            "node {i}: {count} children"
        );
        for lane in 0..count {
            let w = n.child[lane];
            if is_inner(w) {
                let c = w as usize;
                assert!(
                    c > i && c < wide.nodes.len(),
                    "node {i} lane {lane}: child {c}"
                );
            } else {
                let p = &wide.packs[(w & LEAF_FIRST_MASK) as usize];
                assert_eq!(p.count, w >> LEAF_COUNT_SHIFT, "node {i} lane {lane}");
                packs_met[(w & LEAF_FIRST_MASK) as usize] += 1;
                leaves.push(p.first | p.count << LEAF_COUNT_SHIFT);
            }
        }
    }
    let mut expected: Vec<u32> = binary
        .iter()
        .filter(|n| n.leaf != 0)
        .map(|n| n.leaf)
        .collect();
    leaves.sort_unstable();
    expected.sort_unstable();
    assert_eq!(
        leaves, expected,
        "the wide tree's leaves are the binary tree's"
    );
    assert_eq!(wide.stack_need, stack_need(&wide.nodes));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::tests::soup;
    use crate::bvh::{BuildQuality, FlatBvh, build};
    use crate::layout::Float4;

    /// The triangles in the tree's leaf order, as the scene arrays hold them.
    fn leaf_order(bvh: &FlatBvh, tris: &[[glam::Vec3; 3]]) -> Vec<TriangleGeom> {
        bvh.triangle_order
            .iter()
            .map(|&i| {
                let [v0, v1, v2] = tris[i as usize].map(|v| Float4::from_vec3(v, 0.0));
                TriangleGeom { v0, v1, v2 }
            })
            .collect()
    }

    #[test]
    fn collapse_keeps_every_leaf_in_fewer_nodes() {
        for n in [1, 2, 3, 9, 500, 5000] {
            let binary = build(&soup(n), BuildQuality::Medium).unwrap();
            let wide = collapse(&binary.nodes, &leaf_order(&binary, &soup(n)));
            validate(&wide, &binary.nodes);
            assert!(wide.fits_stack(), "{n} triangles need {}", wide.stack_need);
            if n >= 500 {
                // The greedy collapse leaves nodes near the leaves part-full: measured 59 wide
                // nodes for 164 inner binary ones at 500 triangles.
                let inner = binary.nodes.iter().filter(|b| b.leaf == 0).count();
                assert!(
                    wide.nodes.len() * 5 < inner * 2,
                    "{} wide, {inner} inner",
                    wide.nodes.len()
                );
            }
        }
    }

    #[test]
    fn a_single_leaf_becomes_a_root_with_one_child() {
        let binary = build(&soup(1), BuildQuality::Medium).unwrap();
        let tris = leaf_order(&binary, &soup(1));
        let wide = collapse(&binary.nodes, &tris);
        assert_eq!(wide.nodes.len(), 1);
        assert_eq!(wide.nodes[0].child_count, 1);
        assert_eq!(
            wide.nodes[0].child[0],
            1 << LEAF_COUNT_SHIFT,
            "pack 0, one triangle"
        );
        assert_eq!(wide.stack_need, 0);
        // The pack holds the triangle's first vertex and its edges as the kernels form them.
        let p = &wide.packs[0];
        assert_eq!((p.first, p.count), (0, 1));
        assert_eq!(p.e1_y[0], tris[0].v1.0[1] - tris[0].v0.0[1]);
        assert_eq!(p.e2_z[0], tris[0].v2.0[2] - tris[0].v0.0[2]);
        assert_eq!(p.v0_x[1], 0.0);
        assert!(collapse(&[], &[]).nodes.is_empty());
    }

    #[test]
    fn stack_need_adds_the_siblings_along_the_deepest_path() {
        // Root with three children: a leaf, an inner node with two leaves, a leaf.
        let leaf = 1 << LEAF_COUNT_SHIFT;
        let mut root = WideBvhNode {
            child_count: 3,
            ..Default::default()
        };
        root.child[..3].copy_from_slice(&[leaf, 1, leaf]);
        let mut inner = WideBvhNode {
            child_count: 2,
            ..Default::default()
        };
        inner.child[..2].copy_from_slice(&[leaf, leaf]);
        assert_eq!(stack_need(&[root, inner]), 2 + 1);
    }
}
