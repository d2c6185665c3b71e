// Sheared filtering of diffuse indirect light (Yan et al. 2015, "Fast 4D Sheared Filtering",
// eqs. 2-15 with the GI slopes s = z of §3.1 and the box of §5): the filter side over the GI
// field of kernels/render/gi_field.cl. The steps of kernels/filters/sheared_dof.cl with x the
// receiver's world position on its tangent plane (walking image rows in 1b, columns in 2b), y
// the v-plane coordinate on [-V, V] (V = p->range), a box of half width V in place of the
// Gaussian in steps 1a/2a, and rgb + a weight channel carried through.
// src/filters/sheared/gi.rs is the same code in Rust and says why.
//
// 1. gi_prepare: (sigma_x world, eta, kind, d): eq. 4 with sigma_v = 2/2.8 (p->sigma_y) and
//    corrected eq. 5 over s = z; no reflector among the samples: the pixel's own samples.
// 2. gi_1a: p[bin][row][rgbw] = sum_a f(a, row) box(v1(a) - v_bin).
// 3. gi_1b: gather along the row; neighbour x' reads bin eta (x - x').t, weighted by the
//    Gaussian of the tangent-plane offset, rows landing in the bin of their own v2'.
// 4. gi_2a: q[bin] = sum of g[bin'] with |v_bin' - v_bin| <= V.
// 5. gi_2b: gather along the column (shear on n x t); F.direct + albedo * value / weight.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "filters/sheared_common.cl"
#include "render/sampling.cl"

#define GI_NONE 0.0f
#define GI_OWN 1.0f
#define GI_FILTERED 2.0f
#define GI_MIN_SLOPE 1.0e-30f
#define GI_MAX_ETA 1.0e30f

// kernels/render/gi_field.cl gi_v (V = 5, c = V / sqrt(1 + V^2)).
inline float gi_grid_v(uint a, float jitter, uint side) {
    float c = 5.0f / sqrt(1.0f + 5.0f * 5.0f);
    float t = c * (2.0f * (((float)a + jitter) * (1.0f / (float)side)) - 1.0f);
    return t / sqrt(1.0f - t * t);
}

inline float gi_box(float t, float range) { return fabs(t) <= range ? 1.0f : 0.0f; }

__kernel void gi_prepare(__constant const ShearedParams* p, __global const float* light_field,
                         __global float4* guide) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* lf = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    if (!(lf[LIGHT_FIELD_PIXEL_COUNT] > 0.0f)) {
        guide[i] = (float4)(0.0f, 0.0f, GI_NONE, 0.0f);
        return;
    }
    float d = lf[LIGHT_FIELD_PIXEL_SCALE];
    // No sample met a reflector (z_max = 0, kernels/render/gi_field.cl): z is undefined.
    if (!(lf[LIGHT_FIELD_PIXEL_SLOPES + 1] > 0.0f)) {
        guide[i] = (float4)(0.0f, 0.0f, GI_OWN, d);
        return;
    }
    // src/filters/sheared/shear.rs sigma_x and eta over s = z (> 0).
    float a = fmax(lf[LIGHT_FIELD_PIXEL_SLOPES], GI_MIN_SLOPE);
    float b = fmax(lf[LIGHT_FIELD_PIXEL_SLOPES + 1], a);
    float spread = b - a;
    float sx = spread > 0.0f ? p->sigma_y * (a * b / spread) : INFINITY;
    sx = fmin(sx, 0.5f * (float)p->max_radius * d);
    float eta = fmin((a + b) / (2.0f * a * b), GI_MAX_ETA);
    guide[i] = (float4)(sx, p->shear * eta, GI_FILTERED, d);
}

__kernel void gi_1a(__constant const ShearedParams* p, __global const float* light_field,
                    __global const float4* guide, __global float* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    if (guide[i].z == GI_NONE) return;
    __global const float* lf = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    uint bins = p->bins, l = p->side;
    __global float* o = out + (size_t)i * (bins * 16u);
    float j1 = lf[LIGHT_FIELD_PIXEL_JITTER];
    for (uint c = 0u; c < bins; ++c) {
        float vc = -p->range + (float)c * (2.0f * p->range / (float)(bins - 1u));
        float wy[4];
        for (uint a = 0u; a < l; ++a) wy[a] = gi_box(gi_grid_v(a, j1, l) - vc, p->range);
        sheared_bin_rows(lf, l, wy, c, o);
    }
}

// Whether neighbour j lends to pixel i: it has a field, normals within the angle, the offset
// along i's normal within depth_tolerance sigma_x.
inline bool gi_accepts(__constant const ShearedParams* p, __global const float* li,
                       __global const float* lj, float4 g, float kind_j) {
    if (kind_j == GI_NONE) return false;
    float3 ni = vload3(0, li + LIGHT_FIELD_PIXEL_NORMAL);
    float3 nj = vload3(0, lj + LIGHT_FIELD_PIXEL_NORMAL);
    if (dot(ni, nj) < p->normal_cos) return false;
    float3 d = vload3(0, lj + LIGHT_FIELD_PIXEL_POSITION) - vload3(0, li + LIGHT_FIELD_PIXEL_POSITION);
    return fabs(dot(d, ni)) <= p->depth_tolerance * g.x;
}

// Steps on either side: ceil(2 sigma_x / d) within max_radius; 0 unless filtered.
inline int gi_steps(__constant const ShearedParams* p, float4 g) {
    if (g.z != GI_FILTERED || !(g.w > 0.0f) || !(g.x > 0.0f)) return 0;
    float r = ceil(2.0f * g.x / g.w);
    return r < (float)p->max_radius ? (int)r : p->max_radius;
}

// Neighbour lj, k steps from pixel li (position pi, normal n, shear axis e) along the walk of
// 1b or 2b: the bin of eta (x - x').e it lends from, w_x in *wx; -1 when it does not lend
// (rejected, or beyond the bins).
inline int gi_lend(__constant const ShearedParams* p, __global const float* li,
                   __global const float* lj, float kind_j, int k, float4 g, float inv_x,
                   float3 pi, float3 n, float3 e, float* wx) {
    if (k != 0 && !gi_accepts(p, li, lj, g, kind_j)) return -1;
    float3 delta = vload3(0, lj + LIGHT_FIELD_PIXEL_POSITION) - pi;
    float3 tangential = delta - n * dot(delta, n);
    *wx = sheared_gauss(length(tangential), inv_x);
    return sheared_bin_of(g.y * -dot(delta, e), p->bins, p->range);
}

__kernel void gi_1b(__constant const ShearedParams* p, __global const float* light_field,
                    __global const float4* guide, __global const float* in,
                    __global float* out) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    int i = y * (int)p->width + x;
    uint bins = p->bins, l = p->side;
    __global float* o = out + (size_t)i * (bins * 4u);
    sheared_zero(o, bins * 4u);
    float4 g = guide[i];
    if (g.z == GI_NONE) return;
    __global const float* li = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    float3 n = vload3(0, li + LIGHT_FIELD_PIXEL_NORMAL), t, b;
    tangent_frame(n, &t, &b);
    float3 pi = vload3(0, li + LIGHT_FIELD_PIXEL_POSITION);
    int r = gi_steps(p, g);
    float inv_x = fmin(1.0f / (2.0f * g.x * g.x), FLT_MAX);
    for (int k = -r; k <= r; ++k) {
        int j;
        if (!sheared_walk(p, x, y, k, 0, &j)) continue;
        __global const float* lj = light_field + (size_t)j * LIGHT_FIELD_PIXEL_FLOATS;
        float wx;
        int c1 = gi_lend(p, li, lj, guide[j].z, k, g, inv_x, pi, n, t, &wx);
        if (c1 < 0) continue;
        __global const float* src = in + (size_t)j * (bins * 16u);
        float j2 = lj[LIGHT_FIELD_PIXEL_JITTER + 1];
        int c2[4];
        for (uint row = 0u; row < l; ++row) c2[row] = sheared_bin_of(gi_grid_v(row, j2, l), bins, p->range);
        sheared_splat_rows(src, c1, c2, l, wx, o);
    }
}

__kernel void gi_2a(__constant const ShearedParams* p, __global const float4* guide,
                    __global const float* in, __global float* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    uint bins = p->bins, reach = (bins - 1u) / 2u;
    __global float* o = out + (size_t)i * (bins * 4u);
    if (guide[i].z == GI_NONE) {
        sheared_zero(o, bins * 4u);
        return;
    }
    __global const float* src = in + (size_t)i * (bins * 4u);
    for (uint c = 0u; c < bins; ++c) {
        float4 v = (float4)(0.0f);
        uint lo = c > reach ? c - reach : 0u, hi = min(c + reach + 1u, bins);
        for (uint c2 = lo; c2 < hi; ++c2) v += vload4(c2, src);
        vstore4(v, c, o);
    }
}

// The mean of the pixel's own l^2 samples.
inline float3 gi_own(__constant const ShearedParams* p, __global const float* lf) {
    int n = (int)(p->side * p->side);
    float3 v = (float3)(0.0f);
    for (int k = 0; k < n; ++k) v += (float3)(sheared_rgb_lane(lf, k, 0), sheared_rgb_lane(lf, k, 1), sheared_rgb_lane(lf, k, 2));
    return v / (float)n;
}

__kernel void gi_2b(__constant const ShearedParams* p, __global const float* light_field,
                    __global const float* fv, __global const float4* guide,
                    __global const float* in, __global float4* image) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    int i = y * (int)p->width + x;
    float4 g = guide[i];
    __global const float* li = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    __global const float* f = fv + (size_t)i * FILTER_VECTOR_FLOATS;
    float3 direct = vload3(0, f + FILTER_VECTOR_DIRECT);
    if (g.z == GI_NONE) {
        image[i] = (float4)(direct + vload3(0, f + FILTER_VECTOR_INDIRECT), 1.0f);
        return;
    }
    float4 v = (float4)(0.0f);
    if (g.z == GI_FILTERED) {
        uint bins = p->bins;
        float3 n = vload3(0, li + LIGHT_FIELD_PIXEL_NORMAL), t, b;
        tangent_frame(n, &t, &b);
        float3 pi = vload3(0, li + LIGHT_FIELD_PIXEL_POSITION);
        int r = gi_steps(p, g);
        float inv_x = fmin(1.0f / (2.0f * g.x * g.x), FLT_MAX);
        for (int k = -r; k <= r; ++k) {
            int j;
            if (!sheared_walk(p, x, y, k, 1, &j)) continue;
            __global const float* lj = light_field + (size_t)j * LIGHT_FIELD_PIXEL_FLOATS;
            float wx;
            int c = gi_lend(p, li, lj, guide[j].z, k, g, inv_x, pi, n, b, &wx);
            if (c < 0) continue;
            v += wx * vload4((uint)c, in + (size_t)j * (bins * 4u));
        }
    }
    float3 l = v.w > 0.0f ? v.xyz / v.w : gi_own(p, li);
    image[i] = (float4)(direct + vload3(0, li + LIGHT_FIELD_PIXEL_EXTRA) * l, 1.0f);
}
