// Sheared filtering of depth of field (Yan et al. 2015, "Fast 4D Sheared Filtering", eqs. 3-15
// with the DoF slopes of §3.2): the filter side over the lens field of
// kernels/render/lens_field.cl. The steps of kernels/filters/sheared.cl (shadows) with x in
// pixels along the image rows (1b) and columns (2b), y the lens coordinate (metres on the lens
// square, sigma_y = A/2 in p->sigma_y, the lens radius A in p->light.w), and rgb + a weight
// channel carried through. src/filters/sheared/dof.rs is the same code in Rust and says why.
//
// 1. dof_prepare: (sigma_x in pixels, eta, kind, 0): eq. 4 and corrected eq. 5 with signed
//    slopes (both sides of the focal plane: the fallback; exactly in focus: eta -> 1e30, the
//    pixel's own samples).
// 2. dof_1a: p[bin][row][rgbw] = sum_a f(a, row) w_y(u1(a) - u_bin).
// 3. dof_1b: gather along the row; neighbour x' reads bin eta (x - x'), weighted w_x(x' - x),
//    rows landing in the bin of their own u2'.
// 4. dof_2a: q[bin] = sum_bin' g[bin'] w_y(u_bin' - u_bin).
// 5. dof_2b: gather along the column; value over weight. Fallback pixels: the Gaussian-weighted
//    mean of their own l^2 + 36 samples; no field: F as rendered.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "filters/sheared_common.cl"

#define DOF_NONE 0.0f
#define DOF_FILTERED 2.0f
#define DOF_FALLBACK 3.0f
#define DOF_MIN_SLOPE 1.0e-30f
#define DOF_MAX_ETA 1.0e30f

// |s| at least DOF_MIN_SLOPE, sign kept (0 counts as +).
inline float dof_signed(float s) { return s >= 0.0f ? fmax(s, DOF_MIN_SLOPE) : fmin(s, -DOF_MIN_SLOPE); }

__kernel void dof_prepare(__constant const ShearedParams* p, __global const float* light_field,
                          __global float4* guide) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* lf = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    if (!(lf[LIGHT_FIELD_PIXEL_COUNT] > 0.0f)) {
        guide[i] = (float4)(0.0f, 0.0f, DOF_NONE, 0.0f);
        return;
    }
    if (lf[LIGHT_FIELD_PIXEL_EXTRA_SAMPLES] > 0.0f) {
        guide[i] = (float4)(0.0f, 0.0f, DOF_FALLBACK, 0.0f);
        return;
    }
    float a = dof_signed(lf[LIGHT_FIELD_PIXEL_SLOPES]);
    float b = dof_signed(fmax(lf[LIGHT_FIELD_PIXEL_SLOPES + 1], lf[LIGHT_FIELD_PIXEL_SLOPES]));
    // Eq. 4 (one sign): sigma_x = sigma_y |s_min s_max| / (s_max - s_min), in pixels.
    float spread = b - a;
    float sx = spread > 0.0f ? p->sigma_y * (fabs(a * b) / spread) : INFINITY;
    // A 32 px diameter: 2 sigma_x within max_radius one-pixel steps.
    sx = fmin(sx, 0.5f * (float)p->max_radius);
    // Eq. 5 corrected: eta = mean of 1/s = (s_min + s_max) / (2 s_min s_max), lens metres per
    // pixel.
    float eta = (a + b) / (2.0f * a * b);
    eta = fmax(fmin(eta, DOF_MAX_ETA), -DOF_MAX_ETA);
    guide[i] = (float4)(sx, p->shear * eta, DOF_FILTERED, 0.0f);
}

__kernel void dof_1a(__constant const ShearedParams* p, __global const float* light_field,
                     __global const float4* guide, __global float* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    // Fallback pixels too: their grid samples lend to neighbours in 1b.
    if (guide[i].z == DOF_NONE) return;
    __global const float* lf = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    uint bins = p->bins, l = p->side;
    __global float* o = out + (size_t)i * (bins * 16u);
    float inv = fmin(1.0f / (2.0f * p->sigma_y * p->sigma_y), FLT_MAX);
    float j1 = lf[LIGHT_FIELD_PIXEL_JITTER];
    for (uint c = 0u; c < bins; ++c) {
        float yc = -p->range + (float)c * (2.0f * p->range / (float)(bins - 1u));
        float wy[4];
        for (uint a = 0u; a < l; ++a) wy[a] = sheared_gauss(sheared_grid(a, j1, l, p->light.w) - yc, inv);
        sheared_bin_rows(lf, l, wy, c, o);
    }
}

// Whether neighbour j lends to pixel i: it has a field, and both lens-centre hits' normals
// within the angle (two sky pixels agree; a sky pixel and a surface do not).
inline bool dof_accepts(__constant const ShearedParams* p, __global const float* li,
                        __global const float* lj, float kind_j) {
    if (kind_j == DOF_NONE) return false;
    float3 ni = vload3(0, li + LIGHT_FIELD_PIXEL_NORMAL);
    float3 nj = vload3(0, lj + LIGHT_FIELD_PIXEL_NORMAL);
    bool si = dot(ni, ni) == 0.0f, sj = dot(nj, nj) == 0.0f;
    if (si || sj) return si && sj;
    return dot(ni, nj) >= p->normal_cos;
}

inline int dof_radius(float sigma_x, int max_radius) {
    if (!(sigma_x > 0.0f)) return 0;
    float r = ceil(2.0f * sigma_x);
    return r < (float)max_radius ? (int)r : max_radius;
}

// Neighbour lj, k steps from pixel li along the walk of 1b or 2b: the bin of eta (x - x') it
// lends from, w_x in *wx; -1 when it does not lend (rejected, or beyond the bins).
inline int dof_lend(__constant const ShearedParams* p, __global const float* li,
                    __global const float* lj, float kind_j, int k, float4 g, float inv_x,
                    float* wx) {
    if (k != 0 && !dof_accepts(p, li, lj, kind_j)) return -1;
    float dx = (float)k;
    *wx = sheared_gauss(dx, inv_x);
    return sheared_bin_of(g.y * -dx, p->bins, p->range);
}

__kernel void dof_1b(__constant const ShearedParams* p, __global const float* light_field,
                     __global const float4* guide, __global const float* in,
                     __global float* out) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    int i = y * (int)p->width + x;
    uint bins = p->bins, l = p->side;
    __global float* o = out + (size_t)i * (bins * 4u);
    sheared_zero(o, bins * 4u);
    float4 g = guide[i];
    if (g.z != DOF_FILTERED) return;
    __global const float* li = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    int r = dof_radius(g.x, p->max_radius);
    float inv_x = fmin(1.0f / (2.0f * g.x * g.x), FLT_MAX);
    for (int k = -r; k <= r; ++k) {
        int j;
        if (!sheared_walk(p, x, y, k, 0, &j)) continue;
        __global const float* lj = light_field + (size_t)j * LIGHT_FIELD_PIXEL_FLOATS;
        float wx;
        int c1 = dof_lend(p, li, lj, guide[j].z, k, g, inv_x, &wx);
        if (c1 < 0) continue;
        __global const float* src = in + (size_t)j * (bins * 16u);
        float j2 = lj[LIGHT_FIELD_PIXEL_JITTER + 1];
        int c2[4];
        for (uint b = 0u; b < l; ++b) c2[b] = sheared_bin_of(sheared_grid(b, j2, l, p->light.w), bins, p->range);
        sheared_splat_rows(src, c1, c2, l, wx, o);
    }
}

__kernel void dof_2a(__constant const ShearedParams* p, __global const float4* guide,
                     __global const float* in, __global float* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    uint bins = p->bins;
    __global float* o = out + (size_t)i * (bins * 4u);
    if (guide[i].z == DOF_NONE) {
        sheared_zero(o, bins * 4u);
        return;
    }
    __global const float* src = in + (size_t)i * (bins * 4u);
    float inv = fmin(1.0f / (2.0f * p->sigma_y * p->sigma_y), FLT_MAX);
    float table[65];
    float spacing = 2.0f * p->range / (float)(bins - 1u);
    for (int d = 0; d < 2 * (int)bins - 1; ++d)
        table[d] = sheared_gauss((float)(d - ((int)bins - 1)) * spacing, inv);
    for (uint c = 0u; c < bins; ++c) {
        float4 v = (float4)(0.0f);
        for (uint c2 = 0u; c2 < bins; ++c2)
            v += vload4(c2, src) * table[(int)c2 - (int)c + (int)bins - 1];
        vstore4(v, c, o);
    }
}

// The pixel's own samples, Gaussian-weighted (w_y(u1) w_y(u2)), and its 36 extra samples.
inline float3 dof_own(__constant const ShearedParams* p, __global const float* lf) {
    uint l = p->side;
    float inv = fmin(1.0f / (2.0f * p->sigma_y * p->sigma_y), FLT_MAX);
    float3 v = vload3(0, lf + LIGHT_FIELD_PIXEL_EXTRA);
    float w = lf[LIGHT_FIELD_PIXEL_EXTRA + 3];
    for (uint b = 0u; b < l; ++b) {
        float wb = sheared_gauss(sheared_grid(b, lf[LIGHT_FIELD_PIXEL_JITTER + 1], l, p->light.w), inv);
        for (uint a = 0u; a < l; ++a) {
            float wt = sheared_gauss(sheared_grid(a, lf[LIGHT_FIELD_PIXEL_JITTER], l, p->light.w), inv) * wb;
            int k = (int)(b * l + a);
            v += wt * (float3)(sheared_rgb_lane(lf, k, 0), sheared_rgb_lane(lf, k, 1), sheared_rgb_lane(lf, k, 2));
            w += wt;
        }
    }
    return w > 0.0f ? v / w : (float3)(0.0f);
}

__kernel void dof_2b(__constant const ShearedParams* p, __global const float* light_field,
                     __global const float* fv, __global const float4* guide,
                     __global const float* in, __global float4* image) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    int i = y * (int)p->width + x;
    float4 g = guide[i];
    __global const float* li = light_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    if (g.z == DOF_NONE) {
        __global const float* f = fv + (size_t)i * FILTER_VECTOR_FLOATS;
        float3 c = vload3(0, f + FILTER_VECTOR_DIRECT) + vload3(0, f + FILTER_VECTOR_INDIRECT);
        image[i] = (float4)(c, 1.0f);
        return;
    }
    if (g.z == DOF_FALLBACK) {
        image[i] = (float4)(dof_own(p, li), 1.0f);
        return;
    }
    uint bins = p->bins;
    int r = dof_radius(g.x, p->max_radius);
    float inv_x = fmin(1.0f / (2.0f * g.x * g.x), FLT_MAX);
    float4 v = (float4)(0.0f);
    for (int k = -r; k <= r; ++k) {
        int j;
        if (!sheared_walk(p, x, y, k, 1, &j)) continue;
        __global const float* lj = light_field + (size_t)j * LIGHT_FIELD_PIXEL_FLOATS;
        float wx;
        int c = dof_lend(p, li, lj, guide[j].z, k, g, inv_x, &wx);
        if (c < 0) continue;
        v += wx * vload4((uint)c, in + (size_t)j * (bins * 4u));
    }
    image[i] = v.w > 0.0f ? (float4)(v.xyz / v.w, 1.0f) : (float4)(dof_own(p, li), 1.0f);
}
