// Sheared filtering of soft shadows (Yan et al. 2015, "Fast 4D Sheared Filtering", eqs. 3-15):
// the filter side, over the light-field output of kernels/render/light_field.cl and the shadow
// output of kernels/render/shadows.cl. src/filters/sheared/reference.rs is the same code in
// Rust; src/filters/sheared/mod.rs and shear.rs say why each choice is what it is.
//
// 1. sheared_prepare: per pixel sigma_x (eq. 4, capped to a 32 px diameter), eta (eq. 5 as
//    corrected) and the kind, in the float4 guide (sigma_x, eta, kind, 0).
// 2. sheared_1a (eq. 12, O(l^3)): p[bin][row] = sum_a f(a, row) w_y(y1(a) - y_bin), and its
//    weight channel.
// 3. sheared_1b (eq. 13, O(n l)): gather along the screen image of x1; each neighbour gives
//    the bin of y1 = eta (x1 - x1'), weighted by w_x(x1' - x1), its rows landing in the bin of
//    their own y2' (own jitter).
// 4. sheared_2a (eq. 14, O(bins^2) = O(l^2)): q[bin] = sum_bin' g[bin'] w_y(y_bin' - y_bin).
// 5. sheared_2b (eq. 15, O(n)): gather along x2 reading the bin of y2 = eta (x2 - x2'); value
//    over weight.
// Then AAF's aaf_compose_sheared (kernels/filters/aaf_shadows.cl) writes F - replaced +
// r * visibility.
//
// Several sphere lights (§3: "filter each light separately"): the steps run once per light,
// each reading its light's plane `plane` of `planes` of the shadow output and of the light
// field (pixel-major, src/layout/outputs.rs Per::Light) with its own parameters (frame, sigma_y,
// range); the composes chain as AAF's do.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "filters/sheared_common.cl"

#define SHEARED_NONE 0.0f
#define SHEARED_LIT 1.0f
#define SHEARED_FILTERED 2.0f
#define SHEARED_MIN_SLOPE 1.0e-30f
#define SHEARED_MAX_ETA 1.0e30f

// Pixel i's element of the light plane `plane` of `planes` in a per-light buffer.
#define SHEARED_AT(buffer, i, floats) ((buffer) + ((size_t)(i) * planes + plane) * (floats))

// One gather step (the major axis moves one pixel) and the world x per step.
inline float2 sheared_step(__global const float* lf, int dir_lane, int axis, float* world) {
    float2 d = (float2)(lf[dir_lane], lf[dir_lane + 1]);
    float m = fmax(fabs(d.x), fabs(d.y));
    if (!(m > 0.0f)) {
        *world = 0.0f;
        return (float2)(1.0f, 0.0f);
    }
    float2 s = d / m;
    *world = lf[LIGHT_FIELD_PIXEL_SCALE + axis] * length(s);
    return s;
}

inline int sheared_radius(float sigma_x, float world, int max_radius) {
    if (!(world > 0.0f) || !(sigma_x > 0.0f)) return 0;
    float r = ceil(2.0f * sigma_x / world);
    return r < (float)max_radius ? (int)r : max_radius;
}

__kernel void sheared_prepare(__constant const ShearedParams* p,
                              __global const float* shadow_pixels,
                              __global const float* light_field, uint plane, uint planes,
                              __global float4* guide) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* px = SHEARED_AT(shadow_pixels, i, SHADOW_PIXEL_FLOATS);
    __global const float* lf = SHEARED_AT(light_field, i, LIGHT_FIELD_PIXEL_FLOATS);
    if (!(px[SHADOW_PIXEL_WEIGHT] > 0.0f) || !(lf[LIGHT_FIELD_PIXEL_COUNT] > 0.0f)) {
        guide[i] = (float4)(0.0f, 0.0f, SHEARED_NONE, 0.0f);
        return;
    }
    if (px[SHADOW_PIXEL_SLOPE_SOURCE] == 0.0f) {
        guide[i] = (float4)(0.0f, 0.0f, SHEARED_LIT, 0.0f);
        return;
    }
    float w1, w2;
    sheared_step(lf, LIGHT_FIELD_PIXEL_DIR1, 0, &w1);
    sheared_step(lf, LIGHT_FIELD_PIXEL_DIR2, 1, &w2);
    float a = fmax(px[SHADOW_PIXEL_SLOPE_MIN], SHEARED_MIN_SLOPE);
    float b = fmax(px[SHADOW_PIXEL_SLOPE_MAX], a);
    // Eq. 4: sigma_x = sigma_y s_min s_max / (s_max - s_min).
    float spread = b - a;
    float sx = spread > 0.0f ? p->sigma_y * (a * b / spread) : INFINITY;
    // Limited to a 32 px diameter: 2 sigma_x within max_radius steps on either axis.
    float st = (w1 > 0.0f && w2 > 0.0f) ? fmin(w1, w2) : fmax(w1, w2);
    if (st > 0.0f) sx = fmin(sx, 0.5f * (float)p->max_radius * st);
    // Eq. 5, corrected (src/filters/sheared/shear.rs): eta = (s_min + s_max) / (2 s_min s_max).
    float eta = p->shear * fmin((a + b) / (2.0f * a * b), SHEARED_MAX_ETA);
    guide[i] = (float4)(sx, eta, SHEARED_FILTERED, 0.0f);
}

__kernel void sheared_1a(__constant const ShearedParams* p, __global const float* light_field,
                         uint plane, uint planes, __global const float4* guide,
                         __global float* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    if (guide[i].z == SHEARED_NONE) return;
    __global const float* lf = SHEARED_AT(light_field, i, LIGHT_FIELD_PIXEL_FLOATS);
    uint bins = p->bins, l = p->side;
    __global float* o = out + (size_t)i * (2u * bins * 4u);
    float inv = fmin(1.0f / (2.0f * p->sigma_y * p->sigma_y), FLT_MAX);
    float j1 = lf[LIGHT_FIELD_PIXEL_JITTER];
    for (uint c = 0u; c < bins; ++c) {
        float yc = sheared_bin_centre(c, bins, p->range);
        // w_y of column a, the same for every row (l <= 4).
        float wy[4];
        for (uint a = 0u; a < l; ++a)
            wy[a] = sheared_gauss(sheared_grid(a, j1, l, p->light.w) - yc, inv);
        for (uint b = 0u; b < l; ++b) {
            float v = 0.0f, w = 0.0f;
            for (uint a = 0u; a < l; ++a) {
                v += lf[LIGHT_FIELD_PIXEL_SAMPLES + b * l + a] * wy[a];
                w += wy[a];
            }
            o[c * 4u + b] = v;
            o[bins * 4u + c * 4u + b] = w;
        }
    }
}

// Whether neighbour j lends to pixel i (guide g): a receiver, normals within the angle, its
// offset along the light direction within depth_tolerance * sigma_x.
inline bool sheared_accepts(__constant const ShearedParams* p, __global const float* px,
                            float4 g, __global const float* q, float4 gq) {
    if (gq.z == SHEARED_NONE) return false;
    float3 normal = sheared_lane3(px, SHADOW_PIXEL_NORMAL);
    if (dot(normal, sheared_lane3(q, SHADOW_PIXEL_NORMAL)) < p->normal_cos) return false;
    float3 pos = sheared_lane3(px, SHADOW_PIXEL_POSITION);
    float3 to_light = normalize(p->light.xyz - pos);
    float along = dot(sheared_lane3(q, SHADOW_PIXEL_POSITION) - pos, to_light);
    return fabs(along) <= p->depth_tolerance * g.x;
}

// The pixel k steps from (x, y) along s, or -1 outside the image.
inline int sheared_neighbour(__constant const ShearedParams* p, int x, int y, float2 s, int k) {
    int qx = (int)round((float)x + (float)k * s.x);
    int qy = (int)round((float)y + (float)k * s.y);
    if (qx < 0 || qy < 0 || qx >= (int)p->width || qy >= (int)p->height) return -1;
    return qy * (int)p->width + qx;
}

__kernel void sheared_1b(__constant const ShearedParams* p, __global const float* shadow_pixels,
                         __global const float* light_field, uint plane, uint planes,
                         __global const float4* guide, __global const float* in,
                         __global float* out) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    int i = y * (int)p->width + x;
    uint bins = p->bins, l = p->side;
    __global float* o = out + (size_t)i * (2u * bins);
    for (uint c = 0u; c < 2u * bins; ++c) o[c] = 0.0f;
    float4 g = guide[i];
    if (g.z == SHEARED_NONE) return;
    __global const float* px = SHEARED_AT(shadow_pixels, i, SHADOW_PIXEL_FLOATS);
    __global const float* lf = SHEARED_AT(light_field, i, LIGHT_FIELD_PIXEL_FLOATS);
    float world;
    float2 s = sheared_step(lf, LIGHT_FIELD_PIXEL_DIR1, 0, &world);
    int r = sheared_radius(g.x, world, p->max_radius);
    float inv_x = fmin(1.0f / (2.0f * g.x * g.x), FLT_MAX);
    float3 pos = sheared_lane3(px, SHADOW_PIXEL_POSITION);
    size_t stride = 2u * bins * 4u;
    for (int k = -r; k <= r; ++k) {
        int j = sheared_neighbour(p, x, y, s, k);
        if (j < 0) continue;
        __global const float* q = SHEARED_AT(shadow_pixels, j, SHADOW_PIXEL_FLOATS);
        if (k != 0 && !sheared_accepts(p, px, g, q, guide[j])) continue;
        float dx = dot(sheared_lane3(q, SHADOW_PIXEL_POSITION) - pos, p->axis1.xyz);
        float wx = sheared_gauss(dx, inv_x);
        int c1 = sheared_bin_of(g.y * -dx, bins, p->range);
        if (c1 < 0) continue;
        __global const float* src = in + (size_t)j * stride;
        float j2 =
            SHEARED_AT(light_field, j, LIGHT_FIELD_PIXEL_FLOATS)[LIGHT_FIELD_PIXEL_JITTER + 1];
        for (uint b = 0u; b < l; ++b) {
            int c2 = sheared_bin_of(sheared_grid(b, j2, l, p->light.w), bins, p->range);
            if (c2 < 0) continue;
            uint at = (uint)c1 * 4u + b;
            o[c2] += wx * src[at];
            o[bins + (uint)c2] += wx * src[bins * 4u + at];
        }
    }
}

__kernel void sheared_2a(__constant const ShearedParams* p, __global const float4* guide,
                         __global const float* in, __global float* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    uint bins = p->bins;
    __global float* o = out + (size_t)i * (2u * bins);
    if (guide[i].z == SHEARED_NONE) {
        for (uint c = 0u; c < 2u * bins; ++c) o[c] = 0.0f;
        return;
    }
    __global const float* src = in + (size_t)i * (2u * bins);
    float inv = fmin(1.0f / (2.0f * p->sigma_y * p->sigma_y), FLT_MAX);
    // w_y between two bins depends on their offset only: 2 bins - 1 values (bins <= 33).
    float table[65];
    float spacing = 2.0f * p->range / (float)(bins - 1u);
    for (int d = 0; d < 2 * (int)bins - 1; ++d)
        table[d] = sheared_gauss((float)(d - ((int)bins - 1)) * spacing, inv);
    for (uint c = 0u; c < bins; ++c) {
        float v = 0.0f, w = 0.0f;
        for (uint c2 = 0u; c2 < bins; ++c2) {
            float wy = table[(int)c2 - (int)c + (int)bins - 1];
            v += src[c2] * wy;
            w += src[bins + c2] * wy;
        }
        o[c] = v;
        o[bins + c] = w;
    }
}

__kernel void sheared_2b(__constant const ShearedParams* p, __global const float* shadow_pixels,
                         __global const float* light_field, uint plane, uint planes,
                         __global const float4* guide, __global const float* in,
                         __global float* visibility) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    int i = y * (int)p->width + x;
    float4 g = guide[i];
    if (g.z == SHEARED_NONE) {
        visibility[i] = 0.0f;
        return;
    }
    uint bins = p->bins;
    __global const float* px = SHEARED_AT(shadow_pixels, i, SHADOW_PIXEL_FLOATS);
    __global const float* lf = SHEARED_AT(light_field, i, LIGHT_FIELD_PIXEL_FLOATS);
    float world;
    float2 s = sheared_step(lf, LIGHT_FIELD_PIXEL_DIR2, 1, &world);
    int r = sheared_radius(g.x, world, p->max_radius);
    float inv_x = fmin(1.0f / (2.0f * g.x * g.x), FLT_MAX);
    float3 pos = sheared_lane3(px, SHADOW_PIXEL_POSITION);
    float v = 0.0f, w = 0.0f;
    for (int k = -r; k <= r; ++k) {
        int j = sheared_neighbour(p, x, y, s, k);
        if (j < 0) continue;
        __global const float* q = SHEARED_AT(shadow_pixels, j, SHADOW_PIXEL_FLOATS);
        if (k != 0 && !sheared_accepts(p, px, g, q, guide[j])) continue;
        float dx = dot(sheared_lane3(q, SHADOW_PIXEL_POSITION) - pos, p->axis2.xyz);
        float wx = sheared_gauss(dx, inv_x);
        int c = sheared_bin_of(g.y * -dx, bins, p->range);
        if (c < 0) continue;
        v += wx * in[(size_t)j * 2u * bins + (uint)c];
        w += wx * in[(size_t)j * 2u * bins + bins + (uint)c];
    }
    if (w > 0.0f) {
        visibility[i] = v / w;
        return;
    }
    uint n = p->side * p->side;
    float sum = 0.0f;
    for (uint k = 0u; k < n; ++k) sum += lf[LIGHT_FIELD_PIXEL_SAMPLES + k];
    visibility[i] = sum / (float)n;
}
