// The walks of the eight-wide BVH (issue 14; not in the thesis, whose Algorithm 4 walks the
// binary skip-index tree): each node holds the boxes of up to eight children as float8 lanes
// (WideBvhNode, collapsed from the binary tree by src/bvh/wide.rs), so one slab test (Alg. 2)
// in eight lanes replaces eight scalar ones (the conference room: 34,444 wide nodes for
// 227,927 binary ones). The nearest-hit walk goes front to back with a stack (Wald, Benthin &
// Boulos 2008; Embree's BVH8 walk), taking the nearest child first and dropping a kept child
// once the nearest hit lies before it.
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

// Alg. 3 (Möller-Trumbore) in four lanes over a leaf's TrianglePack. Each lane runs exactly
// the float operations of ray_triangle (geometry.cl) in the same order, dot and cross written
// out as PoCL's builtins compute them (FP_CONTRACT OFF), so its t, u and v are that test's
// bits, and the nearest hit is the same float. Returns the lanes whose triangle the ray hits
// at t in (0, t_max] (t_max itself: a tie with the nearest hit so far), their t, u, v in the
// arrays. Unused lanes hold zero edges: a zero determinant, never a hit.
inline uint pack_hits(__global const TrianglePack* p, float3 o, float3 d, float t_max,
                      float* lane_t, float* lane_u, float* lane_v) {
    float4 e1x = vload4(0, p->e1_x), e1y = vload4(0, p->e1_y), e1z = vload4(0, p->e1_z);
    float4 e2x = vload4(0, p->e2_x), e2y = vload4(0, p->e2_y), e2z = vload4(0, p->e2_z);
    float4 cx = d.y * e2z - d.z * e2y;            // c = cross(d, e2)
    float4 cy = d.z * e2x - d.x * e2z;
    float4 cz = d.x * e2y - d.y * e2x;
    float4 det = e1x * cx + e1y * cy + e1z * cz;  // dot(e1, c)
    float4 ax = o.x - vload4(0, p->v0_x);         // vec1 = o - p1
    float4 ay = o.y - vload4(0, p->v0_y);
    float4 az = o.z - vload4(0, p->v0_z);
    float4 u = (ax * cx + ay * cy + az * cz) / det;
    float4 qx = ay * e1z - az * e1y;              // vec2 = cross(vec1, e1)
    float4 qy = az * e1x - ax * e1z;
    float4 qz = ax * e1y - ay * e1x;
    float4 v = (d.x * qx + d.y * qy + d.z * qz) / det;
    float4 t = (e2x * qx + e2y * qy + e2z * qz) / det;
    // ray_triangle's rejections, written as there (a NaN u or v passes them, as there).
    int4 hit = (det != 0.0f) & !(u < 0.0f) & !(u > 1.0f) & !(v < 0.0f) & !(u + v > 1.0f)
               & (t > 0.0f) & (t <= t_max);
    int4 bits = hit & (int4)(1, 2, 4, 8);
    int2 b2 = bits.lo | bits.hi;
    vstore4(t, 0, lane_t);
    vstore4(u, 0, lane_u);
    vstore4(v, 0, lane_v);
    return (uint)(b2.x | b2.y);
}

// The nearest triangle hit in (0, t_max) as (t, u, v, triangle index as bits), the index
// NO_TRIANGLE when there is none ([triangle_hit]). Returned in a register: a Hit written
// through a pointer and read back by the caller, its index and kind as one 8-byte load,
// stalled on store forwarding (28 % of trace_path_from's samples at Cornell diffuse).
inline float4 nearest_triangle(const SceneRefs* s, float3 o, float3 d, float t_max) {
    Hit hit = no_hit(t_max);
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
            __global const TrianglePack* p = s->tri_packs + (word & LEAF_FIRST_MASK);
            float lane_t[4], lane_u[4], lane_v[4];
            uint mask = pack_hits(p, o, d, hit.t, lane_t, lane_u, lane_v);
            while (mask != 0u) {   // in lane order, which is leaf order
                uint lane = lowest_lane(mask);
                mask &= mask - 1u;
                uint k = p->first + lane;
                float t = lane_t[lane];
                // A tie goes to the triangle first in leaf order (the skip-index walk's pick).
                if (t < hit.t || (hit.kind == HIT_TRIANGLE && k < hit.prim)) {
                    hit.t = t;
                    hit.u = lane_u[lane];
                    hit.v = lane_v[lane];
                    hit.prim = k;
                    hit.kind = HIT_TRIANGLE;
                }
            }
        }
        // The next kept child that the ray still enters before the nearest hit.
        for (;;) {
            if (top == 0u) {
                return triangle_hit(&hit);
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
            __global const TrianglePack* p = s->tri_packs + (word & LEAF_FIRST_MASK);
            float lane_t[4], lane_u[4], lane_v[4];
            uint mask = pack_hits(p, o, d, t_max, lane_t, lane_u, lane_v);
            while (mask != 0u) {
                uint lane = lowest_lane(mask);
                mask &= mask - 1u;
                float t = lane_t[lane];
                if (t < t_max) {
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
