// The scene as the kernels see it, and ray-scene queries: the thesis's stackless skip-index
// BVH traversal (Algorithm 4, Fig. 4.11) plus the analytic spheres.
#ifndef NOISEFREE_SCENE_CL
#define NOISEFREE_SCENE_CL

#include "layout.cl"
#include "render/features.cl"
#include "geometry.cl"

// Which tree the ray queries walk: the thesis's binary skip-index tree (Alg. 4; BVH_WIDE=0)
// or the eight-wide one (arrays/trace_wide.cl; BVH_WIDE=1), chosen by the host
// (src/render/mod.rs, RenderOptions::bvh). Both give every query the same answer. The wide
// walk's stack holds BVH_STACK entries, what the scene's tree can need (src/bvh/wide.rs).
#if !defined(BVH_WIDE)
#error "noisefree: BVH_WIDE is missing from the build options"
#endif
#if BVH_WIDE
#if !defined(BVH_STACK)
#error "noisefree: BVH_STACK (the wide walk's stack entries) is missing from the build options"
#endif
typedef WideBvhNode SceneNode;
#else
typedef BvhNode SceneNode;
#endif

// Pointers to the scene buffers, bundled so functions take one argument.
typedef struct {
    __constant const SceneParams* params;
    __global const SceneNode* nodes;   // BvhNode, or WideBvhNode with BVH_WIDE
    __global const TriangleGeom* tri_geom;
    __global const TrianglePack* tri_packs;   // the wide BVH's leaves (BVH_WIDE only)
    __global const TriangleShading* tri_shading;
    __global const Sphere* spheres;
    __global const Material* materials;
    __global const TextureInfo* textures;
    __global const float4* texels;
    __global const Light* lights;
    __global const float* light_cdf;
    __global uint* counters;   // debug counters (DEBUG_COUNTERS builds only)
} SceneRefs;

// A kernel's scene arguments, in the order the host binds them (src/render/mod.rs
// DeviceScene::bind, then the debug counters), and the SceneRefs made of them.
#define SCENE_PARAMS                                                                         \
    __constant const SceneParams *params, __global const SceneNode *nodes,                   \
        __global const TriangleGeom *tri_geom, __global const TrianglePack *tri_packs,       \
        __global const TriangleShading *tri_shading,                                         \
        __global const Sphere *spheres, __global const Material *materials,                  \
        __global const TextureInfo *textures, __global const float4 *texels,                 \
        __global const Light *lights, __global const float *light_cdf,                      \
        __global uint *debug_counters
#define SCENE_REFS                                                                           \
    {params, nodes, tri_geom, tri_packs, tri_shading, spheres, materials,                    \
     textures, texels, lights, light_cdf, debug_counters}

// Debug counters, compiled in only for tests (-D DEBUG_COUNTERS=1): how often each optional
// piece of code ran, so tests can show that a scene without, say, glass never runs glass
// code. Indices are mirrored in src/render/mod.rs (DebugCounter).
#define COUNT_LENS_SAMPLE 0
#define COUNT_DIFFUSE 1
#define COUNT_SPECULAR 2
#define COUNT_GLASS 3
#define COUNT_METAL 4
#define COUNT_ENV_LOOKUP 5
#define COUNT_ENV_TEXTURE 6
#define COUNT_SPHERE_LIGHT 7
#define COUNT_TRIANGLE_LIGHT 8
#define COUNT_TEXTURE 9
#define COUNT_SPHERE_TEST 10
#define COUNT_BVH_TRAVERSAL 11
#define DEBUG_COUNTER_COUNT 12
#if defined(DEBUG_COUNTERS) && DEBUG_COUNTERS
#define DEBUG_COUNT(s, what) atomic_inc((s)->counters + (what))
#else
#define DEBUG_COUNT(s, what) ((void)0)
#endif

#define HIT_NONE 0
#define HIT_TRIANGLE 1
#define HIT_SPHERE 2

typedef struct {
    float t;
    float u, v;      // barycentrics of a triangle hit (eq. 4.4)
    uint prim;       // triangle (leaf order) or sphere index
    int kind;        // HIT_NONE, HIT_TRIANGLE or HIT_SPHERE
} Hit;

#define NO_TRIANGLE 0xffffffffu

// What nearest_triangle returns for the walk's hit.
inline float4 triangle_hit(const Hit* hit) {
    uint index = hit->kind == HIT_TRIANGLE ? hit->prim : NO_TRIANGLE;
    return (float4)(hit->t, hit->u, hit->v, as_float(index));
}

inline Hit no_hit(float t_max) {
    Hit hit;
    hit.t = t_max;
    hit.u = 0.0f;
    hit.v = 0.0f;
    hit.prim = 0u;
    hit.kind = HIT_NONE;
    return hit;
}

#if BVH_WIDE
#include "arrays/trace_wide.cl"
#else
inline float3 node_min(__global const BvhNode* n) {
    return (float3)(n->bounds_min[0], n->bounds_min[1], n->bounds_min[2]);
}
inline float3 node_max(__global const BvhNode* n) {
    return (float3)(n->bounds_max[0], n->bounds_max[1], n->bounds_max[2]);
}

// The nearest triangle hit in (0, t_max) as (t, u, v, triangle index as bits), the index
// NO_TRIANGLE when there is none ([triangle_hit]). Returned in a register: a Hit written
// through a pointer and read back by the caller, its index and kind as one 8-byte load,
// stalled on store forwarding (28 % of trace_path_from's samples at Cornell diffuse).
//
// Algorithm 4 as printed keeps the *last* triangle it hits and never shortens the far plane,
// so it returns whichever intersected triangle comes last in node order, not the nearest one.
// Here a hit is kept only when it is nearer than the best so far, and the far plane passed to
// the box test (Alg. 2) is clipped to it, which also prunes boxes behind the nearest hit.
// A leaf holds several triangles (obvhs leaves); Alg. 4 line 9 tests one.
inline float4 nearest_triangle(const SceneRefs* s, float3 o, float3 d, float t_max) {
    Hit hit = no_hit(t_max);
    float3 inv_d = safe_inverse(d);
    uint node_count = s->params->node_count;
    uint current = 0u;
    while (current < node_count) {                       // Alg. 4 line 6 (stopNode = n)
        __global const BvhNode* node = s->nodes + current;
        if (ray_aabb(o, inv_d, 0.0f, hit.t, node_min(node), node_max(node))) {
            uint leaf = node->leaf;
            if (leaf != 0u) {
                uint first = leaf & LEAF_FIRST_MASK;
                uint count = leaf >> LEAF_COUNT_SHIFT;
                for (uint k = first; k < first + count; ++k) {
                    __global const TriangleGeom* tri = s->tri_geom + k;
                    float u, v;
                    float t = ray_triangle(o, d, tri->v0.xyz, tri->v1.xyz, tri->v2.xyz, &u, &v);
                    if (t > 0.0f && t < hit.t) {
                        hit.t = t;
                        hit.u = u;
                        hit.v = v;
                        hit.prim = k;
                        hit.kind = HIT_TRIANGLE;
                    }
                }
                current = node->skip;   // == current + 1 for a leaf
            } else {
                current += 1u;          // descend: the left child follows its parent
            }
        } else {
            current = node->skip;       // Alg. 4 line 21: skip the whole subtree
        }
    }
    return triangle_hit(&hit);
}

// Any triangle hit in (0, t_max).
inline bool any_triangle(const SceneRefs* s, float3 o, float3 d, float t_max) {
    float3 inv_d = safe_inverse(d);
    uint node_count = s->params->node_count;
    uint current = 0u;
    while (current < node_count) {
        __global const BvhNode* node = s->nodes + current;
        if (ray_aabb(o, inv_d, 0.0f, t_max, node_min(node), node_max(node))) {
            uint leaf = node->leaf;
            if (leaf != 0u) {
                uint first = leaf & LEAF_FIRST_MASK;
                uint count = leaf >> LEAF_COUNT_SHIFT;
                for (uint k = first; k < first + count; ++k) {
                    __global const TriangleGeom* tri = s->tri_geom + k;
                    float u, v;
                    float t = ray_triangle(o, d, tri->v0.xyz, tri->v1.xyz, tri->v2.xyz, &u, &v);
                    if (t > 0.0f && t < t_max) return true;
                }
                current = node->skip;
            } else {
                current += 1u;
            }
        } else {
            current = node->skip;
        }
    }
    return false;
}

// Widens [*lo, *hi] by every triangle hit in (0, t_max).
inline void triangle_range(const SceneRefs* s, float3 o, float3 d, float t_max, float* lo,
                           float* hi) {
    float3 inv_d = safe_inverse(d);
    uint node_count = s->params->node_count;
    uint current = 0u;
    while (current < node_count) {
        __global const BvhNode* node = s->nodes + current;
        if (ray_aabb(o, inv_d, 0.0f, t_max, node_min(node), node_max(node))) {
            uint leaf = node->leaf;
            if (leaf != 0u) {
                uint first = leaf & LEAF_FIRST_MASK;
                uint count = leaf >> LEAF_COUNT_SHIFT;
                for (uint k = first; k < first + count; ++k) {
                    __global const TriangleGeom* tri = s->tri_geom + k;
                    float u, v;
                    float t = ray_triangle(o, d, tri->v0.xyz, tri->v1.xyz, tri->v2.xyz, &u, &v);
                    if (t > 0.0f && t < t_max) {
                        *lo = fmin(*lo, t);
                        *hi = fmax(*hi, t);
                    }
                }
                current = node->skip;
            } else {
                current += 1u;
            }
        } else {
            current = node->skip;
        }
    }
}
#endif

// Nearest hit along o + t d, t in (0, t_max): the triangles (by either walk), then the
// analytic spheres, each kept only when strictly nearer.
inline Hit intersect_closest(const SceneRefs* s, float3 o, float3 d, float t_max, uint* ray_count) {
    Hit hit = no_hit(t_max);
    *ray_count += 1u;
#if HAS_TRIANGLES
    DEBUG_COUNT(s, COUNT_BVH_TRAVERSAL);
    float4 tri = nearest_triangle(s, o, d, t_max);
    if (as_uint(tri.w) != NO_TRIANGLE) {
        hit.t = tri.x;
        hit.u = tri.y;
        hit.v = tri.z;
        hit.prim = as_uint(tri.w);
        hit.kind = HIT_TRIANGLE;
    }
#endif
#if HAS_SPHERES
    DEBUG_COUNT(s, COUNT_SPHERE_TEST);
    for (uint i = 0u; i < s->params->sphere_count; ++i) {
        __global const Sphere* sp = s->spheres + i;
        float3 c = (float3)(sp->center[0], sp->center[1], sp->center[2]);
        float t = ray_sphere(o, d, c, sp->radius, 0.0f, hit.t);
        if (t > 0.0f) {
            hit.t = t;
            hit.prim = i;
            hit.kind = HIT_SPHERE;
        }
    }
#endif
    return hit;
}

// Any-hit query for shadow rays: true as soon as anything lies in (0, t_max).
inline bool occluded(const SceneRefs* s, float3 o, float3 d, float t_max, uint* ray_count) {
    *ray_count += 1u;
    // The spheres first: a few dozen operations each against a tree walk, and any hit
    // answers (the answer is the same in either order). Curved, whose large sphere shadows
    // the plane, 1.06-1.08x; the other scenes within the noise (stop 53, render-ab.sh).
#if HAS_SPHERES
    for (uint i = 0u; i < s->params->sphere_count; ++i) {
        __global const Sphere* sp = s->spheres + i;
        float3 c = (float3)(sp->center[0], sp->center[1], sp->center[2]);
        if (ray_sphere(o, d, c, sp->radius, 0.0f, t_max) > 0.0f) return true;
    }
#endif
#if HAS_TRIANGLES
    if (any_triangle(s, o, d, t_max)) return true;
#endif
    return false;
}

// Every hit in (0, t_max), for AAF's shadow rays (Wang 2013 §3.4 pass 1; its released code's
// any-hit program records t and ignores the hit, so the ray goes on): the nearest and the
// farthest hit distance, both 0 when nothing is hit. A sphere counts with both of its
// crossings that lie in the range. Returns whether anything was hit.
inline bool occluder_range(const SceneRefs* s, float3 o, float3 d, float t_max, float* t_near,
                           float* t_far, uint* ray_count) {
    *ray_count += 1u;
    float lo = INFINITY, hi = 0.0f;
#if HAS_TRIANGLES
    triangle_range(s, o, d, t_max, &lo, &hi);
#endif
#if HAS_SPHERES
    for (uint i = 0u; i < s->params->sphere_count; ++i) {
        __global const Sphere* sp = s->spheres + i;
        float3 c = (float3)(sp->center[0], sp->center[1], sp->center[2]);
        float t0 = ray_sphere(o, d, c, sp->radius, 0.0f, t_max);
        if (t0 > 0.0f) {
            lo = fmin(lo, t0);
            hi = fmax(hi, t0);
            float t1 = ray_sphere(o, d, c, sp->radius, t0, t_max);
            if (t1 > 0.0f) hi = fmax(hi, t1);
        }
    }
#endif
    bool hit = hi > 0.0f;
    *t_near = hit ? lo : 0.0f;
    *t_far = hi;
    return hit;
}

#endif
