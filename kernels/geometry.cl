// Ray-primitive intersection (thesis §4.3.2) and robust secondary-ray origins.
#ifndef NOISEFREE_GEOMETRY_CL
#define NOISEFREE_GEOMETRY_CL

// Slightly enlarge the far distance of the slab test so that rounding in the products of Alg. 2
// never rejects a box the ray touches (Ize 2013, "Robust BVH ray traversal": 1 + 2*gamma(3)).
#define ROBUST_FAR_SCALE 1.0000004f

// Replace zero direction components by +-1e-30 before inverting (Alg. 2 line 2). With the exact
// 1/D = +-inf, an origin lying on a slab plane gives 0 * inf = NaN, and the comparisons of a
// NaN decide the hit arbitrarily; with +-1e30 every product is finite or +-inf, never NaN, an
// axis-parallel ray inside a slab gets the interval (-huge, +huge) and one outside an empty
// one. A ray exactly in a face's plane is classified by the sign of its zero; the host pads
// every box outward (src/bvh/mod.rs pad_bound) so that no triangle lies on a box face and that
// choice never decides a hit.
inline float3 safe_inverse(float3 d) {
    const float tiny = 1.0e-30f;
    float3 s = (float3)(fabs(d.x) < tiny ? copysign(tiny, d.x) : d.x,
                        fabs(d.y) < tiny ? copysign(tiny, d.y) : d.y,
                        fabs(d.z) < tiny ? copysign(tiny, d.z) : d.z);
    return 1.0f / s;
}

// Minimum and maximum by one comparison, for operands that are never NaN: OpenCL's fmin and
// fmax must return the other operand when one is NaN, which costs x86 a compare, a mask and a
// blend per call on top of the min/max instruction (issue 14: a quarter of the box test).
inline float3 min3_nonan(float3 a, float3 b) { return select(b, a, a < b); }
inline float3 max3_nonan(float3 a, float3 b) { return select(b, a, a > b); }
inline float8 min8_nonan(float8 a, float8 b) { return select(b, a, a < b); }
inline float8 max8_nonan(float8 a, float8 b) { return select(b, a, a > b); }
inline float min_nonan(float a, float b) { return a < b ? a : b; }
inline float max_nonan(float a, float b) { return a > b ? a : b; }

// Algorithm 2 (Williams et al. 2005), with the inverse direction precomputed per ray.
// No slab distance is NaN for a finite ray: safe_inverse keeps 1/D finite (|1/D| <= 1e30), so
// each product is finite or infinite, never 0 * inf; the plain min/max then give the values
// fmin/fmax give, up to the sign of a zero, which the final comparison ignores. A ray with a
// NaN or infinite origin or direction hits no triangle or sphere whichever boxes it enters
// (every intersection distance is NaN), so the answer of a query never depends on this choice.
inline bool ray_aabb(float3 o, float3 inv_d, float t_near_plane, float t_far_plane,
                     float3 bmin, float3 bmax) {
    float3 l1 = (bmin - o) * inv_d;
    float3 l2 = (bmax - o) * inv_d;
    float3 t_near = min3_nonan(l1, l2);
    float3 t_far = max3_nonan(l1, l2);
    float t0 = max_nonan(max_nonan(t_near.x, t_near.y), max_nonan(t_near.z, t_near_plane));
    float t1 = min_nonan(min_nonan(t_far.x, t_far.y), min_nonan(t_far.z, t_far_plane));
    // Alg. 2 returns t1 > t0; >= keeps rays that exactly touch a box edge or face.
    return t1 * ROBUST_FAR_SCALE >= t0;
}

// dot and cross written out, products left to right, rather than the builtins: a builtin is
// the driver's library code, which the FP_CONTRACT OFF of our files does not reach. NVIDIA's
// rounds differently from these products (an fma, seen as the skip-index and the wide BVH,
// whose pack_hits writes them out, giving different bits on an H200), PoCL's as here.
inline float dot_exact(float3 a, float3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline float3 cross_exact(float3 a, float3 b) {
    return (float3)(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

// Algorithm 3 (Möller-Trumbore 1997) as printed: divide by the determinant, reject det == 0
// (ray parallel to the plane, or a degenerate triangle). Returns t, or -1 for a miss. The
// same float operations as pack_hits's lanes (arrays/trace_wide.cl) on any device.
inline float ray_triangle(float3 o, float3 d, float3 p1, float3 p2, float3 p3,
                          float* out_u, float* out_v) {
    float3 e1 = p2 - p1;
    float3 e2 = p3 - p1;
    float3 c = cross_exact(d, e2);
    float det = dot_exact(e1, c);
    if (det == 0.0f) return -1.0f;
    float3 vec1 = o - p1;
    float u = dot_exact(vec1, c) / det;
    if (u < 0.0f || u > 1.0f) return -1.0f;
    float3 vec2 = cross_exact(vec1, e1);
    float v = dot_exact(d, vec2) / det;
    if (v < 0.0f || u + v > 1.0f) return -1.0f;
    float t = dot_exact(e2, vec2) / det;
    *out_u = u;
    *out_v = v;
    return t;
}

// Analytic sphere, in the numerically careful form of Haines et al. ("Precision improvements
// for ray/sphere intersection", Ray Tracing Gems ch. 7): the discriminant is computed from the
// squared distance of the centre to the ray, and the near root without cancellation.
// d must be unit length. Returns the nearest t in (t_min, t_max), or -1.
inline float ray_sphere(float3 o, float3 d, float3 center, float radius, float t_min, float t_max) {
    float3 f = o - center;
    float b = -dot(f, d);
    float3 l = f + b * d;
    float r2 = radius * radius;
    float disc = r2 - dot(l, l);
    if (disc < 0.0f) return -1.0f;
    float c = dot(f, f) - r2;
    float q = b + copysign(sqrt(disc), b);
    float t0 = (q != 0.0f) ? c / q : 0.0f;
    float t1 = q;
    float lo = fmin(t0, t1), hi = fmax(t0, t1);
    if (lo > t_min && lo < t_max) return lo;
    if (hi > t_min && hi < t_max) return hi;
    return -1.0f;
}

// Secondary rays start on the surface they leave. Moving the origin a fixed distance fails at
// some scene scale, so the origin is moved by a few units in the last place along the normal
// (Wächter & Binder, "A fast and robust method for avoiding self-intersection", Ray Tracing Gems
// ch. 6): scale-invariant, except near the world origin where ulps vanish and a small absolute
// step is taken. The paper's absolute constants (1/32 and 1/65536) assume a scene of size 1;
// here they are multiplied by the scene's size `scale`, so a Cornell box of 2 mm and one of
// 2 km take the same relative steps (tests/hard_cases_transport.rs).
// n must point to the side the new ray leaves towards.
inline float offset_component(float p, float n, float scale) {
    const float origin = scale * (1.0f / 32.0f);
    const float float_scale = scale * (1.0f / 65536.0f);
    const float int_scale = 256.0f;
    int of_i = (int)(int_scale * n);
    float p_i = as_float(as_int(p) + ((p < 0.0f) ? -of_i : of_i));
    return fabs(p) < origin ? p + float_scale * n : p_i;
}

inline float3 offset_ray_origin(float3 p, float3 n, float scale) {
    return (float3)(offset_component(p.x, n.x, scale), offset_component(p.y, n.y, scale),
                    offset_component(p.z, n.z, scale));
}

#endif
