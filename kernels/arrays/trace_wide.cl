// The walks of the eight-wide BVH (issue 14; not in the thesis, whose Algorithm 4 walks the
// binary skip-index tree): each node holds the boxes of up to eight children as float8 lanes
// (WideBvhNode, collapsed from the binary tree by src/bvh/wide.rs), so one slab test (Alg. 2)
// in eight lanes replaces eight scalar ones, and a ray enters a third as many nodes. The
// nearest-hit walk goes front to back with a stack (Wald, Benthin & Boulos 2008; Embree's
// BVH8 walk), taking the nearest child first and dropping a kept child once the nearest hit
// lies before it.
//
// Same answers as the skip-index walk, whatever the order of the leaves (src/arrays/
// trace_wide.rs, the Rust reference, says why): among triangles at the same distance the one
// first in leaf order wins, which is the one the skip-index walk meets first; the robust slab
// test never drops a box holding a triangle before the nearest hit so far.
// Included by arrays/trace.cl when BVH_WIDE is 1; defines nearest_triangle, any_triangle and
// triangle_range for it.
#ifndef NOISEFREE_TRACE_WIDE_CL
#define NOISEFREE_TRACE_WIDE_CL

// The children of n that the ray enters in (0, t_far), one bit per lane, and every lane's
// entry distance. Each lane is Alg. 2 as ray_aabb computes it (geometry.cl).
inline uint wide_children_hit(__global const WideBvhNode* n, float3 o, float3 inv_d,
                              float t_far, float8* entry) {
    float8 l1x = (vload8(0, n->min_x) - o.x) * inv_d.x;
    float8 l2x = (vload8(0, n->max_x) - o.x) * inv_d.x;
    float8 l1y = (vload8(0, n->min_y) - o.y) * inv_d.y;
    float8 l2y = (vload8(0, n->max_y) - o.y) * inv_d.y;
    float8 l1z = (vload8(0, n->min_z) - o.z) * inv_d.z;
    float8 l2z = (vload8(0, n->max_z) - o.z) * inv_d.z;
    float8 t0 = max8_nonan(max8_nonan(min8_nonan(l1x, l2x), min8_nonan(l1y, l2y)),
                           max8_nonan(min8_nonan(l1z, l2z), (float8)(0.0f)));
    float8 t1 = min8_nonan(min8_nonan(max8_nonan(l1x, l2x), max8_nonan(l1y, l2y)),
                           min8_nonan(max8_nonan(l1z, l2z), (float8)(t_far)));
    int8 bits = (t1 * ROBUST_FAR_SCALE >= t0) & (int8)(1, 2, 4, 8, 16, 32, 64, 128);
    int4 b4 = bits.lo | bits.hi;
    int2 b2 = b4.lo | b4.hi;
    *entry = t0;
    return (uint)(b2.x | b2.y) & ((1u << n->child_count) - 1u);
}

inline uint lowest_lane(uint mask) { return 31u - clz(mask & (0u - mask)); }
inline uint highest_lane(uint mask) { return 31u - clz(mask); }

// The nearest triangle hit before hit->t (which starts at the query's t_max), into *hit.
inline void nearest_triangle(const SceneRefs* s, float3 o, float3 d, Hit* out) {
    Hit hit = *out;
    float3 inv_d = safe_inverse(d);
    uint stack_word[BVH_STACK];
    float stack_entry[BVH_STACK];
    uint top = 0u;
    uint word = 0u;   // the root, always an inner node
    for (;;) {
        if ((word >> LEAF_COUNT_SHIFT) == 0u) {
            __global const WideBvhNode* n = s->nodes + word;
            float8 entry;
            uint mask = wide_children_hit(n, o, inv_d, hit.t, &entry);
            if (mask != 0u) {
                uint lane = lowest_lane(mask);
                mask &= mask - 1u;
                if (mask == 0u) {   // one child hit: no stack, no sorting
                    word = n->child[lane];
                    continue;
                }
                // Several: nearest entry first (insertion sort, stable in lane order); the
                // others onto the stack, farthest deepest.
                float lane_entry[BVH_WIDTH];
                vstore8(entry, 0, lane_entry);
                uint w[BVH_WIDTH];
                float e[BVH_WIDTH];
                w[0] = n->child[lane];
                e[0] = lane_entry[lane];
                uint m = 1u;
                while (mask != 0u) {
                    lane = lowest_lane(mask);
                    mask &= mask - 1u;
                    float te = lane_entry[lane];
                    uint j = m;
                    while (j > 0u && e[j - 1u] > te) {
                        e[j] = e[j - 1u];
                        w[j] = w[j - 1u];
                        --j;
                    }
                    e[j] = te;
                    w[j] = n->child[lane];
                    ++m;
                }
                for (uint j = m - 1u; j > 0u; --j) {
                    stack_word[top] = w[j];
                    stack_entry[top] = e[j];
                    ++top;
                }
                word = w[0];
                continue;
            }
        } else {
            uint first = word & LEAF_FIRST_MASK;
            uint count = word >> LEAF_COUNT_SHIFT;
            for (uint k = first; k < first + count; ++k) {
                __global const TriangleGeom* tri = s->tri_geom + k;
                float u, v;
                float t = ray_triangle(o, d, tri->v0.xyz, tri->v1.xyz, tri->v2.xyz, &u, &v);
                // A tie goes to the triangle first in leaf order (the skip-index walk's pick).
                if (t > 0.0f && (t < hit.t || (t == hit.t && hit.kind == HIT_TRIANGLE
                                                && k < hit.prim))) {
                    hit.t = t;
                    hit.u = u;
                    hit.v = v;
                    hit.prim = k;
                    hit.kind = HIT_TRIANGLE;
                }
            }
        }
        // The next kept child that the ray still enters before the nearest hit.
        for (;;) {
            if (top == 0u) {
                *out = hit;
                return;
            }
            --top;
            if (hit.t * ROBUST_FAR_SCALE >= stack_entry[top]) {
                word = stack_word[top];
                break;
            }
        }
    }
}

// Every triangle hit in (0, t_max), in no particular order: stops at the first one when
// first_only (shadow rays), else widens [*lo, *hi] by each (AAF's occluder range). Returns
// whether anything was hit.
inline bool wide_triangle_hits(const SceneRefs* s, float3 o, float3 d, float t_max,
                               bool first_only, float* lo, float* hi) {
    float3 inv_d = safe_inverse(d);
    uint stack[BVH_STACK];
    uint top = 0u;
    uint word = 0u;
    bool any = false;
    for (;;) {
        if ((word >> LEAF_COUNT_SHIFT) == 0u) {
            __global const WideBvhNode* n = s->nodes + word;
            float8 entry;
            uint mask = wide_children_hit(n, o, inv_d, t_max, &entry);
            if (mask != 0u) {
                uint lane = lowest_lane(mask);
                mask &= mask - 1u;
                while (mask != 0u) {   // the others, the lowest lane on top
                    uint l = highest_lane(mask);
                    mask &= ~(1u << l);
                    stack[top++] = n->child[l];
                }
                word = n->child[lane];
                continue;
            }
        } else {
            uint first = word & LEAF_FIRST_MASK;
            uint count = word >> LEAF_COUNT_SHIFT;
            for (uint k = first; k < first + count; ++k) {
                __global const TriangleGeom* tri = s->tri_geom + k;
                float u, v;
                float t = ray_triangle(o, d, tri->v0.xyz, tri->v1.xyz, tri->v2.xyz, &u, &v);
                if (t > 0.0f && t < t_max) {
                    if (first_only) return true;
                    any = true;
                    *lo = fmin(*lo, t);
                    *hi = fmax(*hi, t);
                }
            }
        }
        if (top == 0u) return any;
        word = stack[--top];
    }
}

inline bool any_triangle(const SceneRefs* s, float3 o, float3 d, float t_max) {
    float lo, hi;
    return wide_triangle_hits(s, o, d, t_max, true, &lo, &hi);
}

inline void triangle_range(const SceneRefs* s, float3 o, float3 d, float t_max, float* lo,
                           float* hi) {
    wide_triangle_hits(s, o, d, t_max, false, lo, hi);
}

#endif
