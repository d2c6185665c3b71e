// Axis-aligned filtering of soft shadows (Wang 2013 ch. 3, eqs. 3.2-3.7; Mehta et al. 2012):
// the filter side, over the shadow output of kernels/render/shadows.cl. src/filters/
// aaf_shadows/reference.rs is the same code in Rust; src/filters/aaf_shadows/mod.rs says
// why each choice is what it is.
//
// 1. aaf_prepare: per pixel the noisy visibility h_n = sum(f l) / sum(l) (eq. 3.2), the filter
//    width beta of eq. 3.4 (corrected, kernels/render/bandlimit.cl) and the pixel's kind.
// 2. aaf_pass, twice (eq. 3.7): along rows, then along columns of the first pass's result,
//    each a normalised Gaussian mean sum(w v) / sum(w) with beta of the pixel being written,
//    on distances measured in the plane perpendicular to the direction to the light (the
//    "plane parallel to the light": the sphere's silhouette disk), rejecting neighbours whose
//    normal, offset along the light direction or beta differ too much.
// 3. aaf_compose: F - (the light the filtered term replaces) + r * filtered visibility, r the
//    mean of the unshadowed term over the pixel's light samples.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/bandlimit.cl"

// What a pixel is to the filter (guide.z).
#define AAF_NONE 0.0f      // no receiver (sky, not diffuse, light below its horizon): F as is
#define AAF_LIT 1.0f       // a receiver without slopes: no occluder near; its visibility stands
#define AAF_FILTERED 2.0f  // a receiver with slopes: filtered

inline float3 aaf_lane3(__global const float* px, int lane) {
    return (float3)(px[lane], px[lane + 1], px[lane + 2]);
}

__kernel void aaf_prepare(__constant const AafShadowParams* p, __global const float* pixels,
                          __global float4* guide, __global float* visibility) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* px = pixels + (size_t)i * SHADOW_PIXEL_FLOATS;
    float weight = px[SHADOW_PIXEL_WEIGHT];
    float4 g = (float4)(0.0f, 0.0f, AAF_NONE, 0.0f);
    if (weight > 0.0f) {
        g.x = px[SHADOW_PIXEL_VISIBLE] / weight;
        if (px[SHADOW_PIXEL_SLOPE_SOURCE] > 0.0f) {
            g.y = aaf_beta(p->sigma, px[SHADOW_PIXEL_PIXEL_SIZE], px[SHADOW_PIXEL_SLOPE_MIN]);
            g.z = AAF_FILTERED;
        } else {
            g.z = AAF_LIT;
        }
    }
    guide[i] = g;
    visibility[i] = g.x;
}

__kernel void aaf_pass(__constant const AafShadowParams* p, __global const float* pixels,
                       __global const float4* guide, __global const float* in,
                       __global float* out) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    int i = y * (int)p->width + x;
    float4 g = guide[i];
    if (g.z != AAF_FILTERED) {
        out[i] = in[i];
        return;
    }
    __global const float* px = pixels + (size_t)i * SHADOW_PIXEL_FLOATS;
    float3 pos = aaf_lane3(px, SHADOW_PIXEL_POSITION);
    float3 normal = aaf_lane3(px, SHADOW_PIXEL_NORMAL);
    float3 to_light = normalize(p->light.xyz - pos);
    float beta = g.y;
    // Finite for any beta > 0, so that 0 * it is 0, never NaN.
    float inv_two_beta2 = fmin(1.0f / (2.0f * beta * beta), FLT_MAX);
    int c = (p->axis == 0u) ? x : y;
    int n = (p->axis == 0u) ? (int)p->width : (int)p->height;
    int stride = (p->axis == 0u) ? 1 : (int)p->width;
    float sum = in[i], sum_w = 1.0f;   // the pixel itself weighs exp(0) = 1
    for (int k = max(0, c - p->radius); k <= min(n - 1, c + p->radius); ++k) {
        if (k == c) continue;
        int j = i + (k - c) * stride;
        float4 gj = guide[j];
        if (gj.z == AAF_NONE) continue;
        __global const float* q = pixels + (size_t)j * SHADOW_PIXEL_FLOATS;
        if (dot(normal, aaf_lane3(q, SHADOW_PIXEL_NORMAL)) < p->normal_cos) continue;
        float3 delta = aaf_lane3(q, SHADOW_PIXEL_POSITION) - pos;
        float along = dot(delta, to_light);
        if (fabs(along) > p->depth_tolerance * beta) continue;
        if (gj.z == AAF_FILTERED
            && fabs(beta - gj.y) > p->beta_tolerance * fmax(beta, gj.y)) continue;
        float r2 = fmax(dot(delta, delta) - along * along, 0.0f);
        float w = exp(-r2 * inv_two_beta2);
        sum += w * in[j];
        sum_w += w;
    }
    out[i] = sum / sum_w;
}

__kernel void aaf_compose(__constant const AafShadowParams* p, __global const float* fv,
                          __global const float* terms, __global const float* pixels,
                          __global const float4* guide,
                          __global const float* visibility, __global float4* image) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* f = fv + (size_t)i * FILTER_VECTOR_FLOATS;
    float3 beauty = aaf_lane3(f, FILTER_VECTOR_DIRECT) + aaf_lane3(f, FILTER_VECTOR_INDIRECT);
    if (guide[i].z == AAF_NONE) {
        image[i] = (float4)(beauty, 0.0f);
        return;
    }
    __global const float* t = terms + (size_t)i * SHADOW_TERMS_FLOATS;
    __global const float* px = pixels + (size_t)i * SHADOW_PIXEL_FLOATS;
    float3 rest = beauty - aaf_lane3(t, SHADOW_TERMS_DIRECT);
    float3 r = aaf_lane3(px, SHADOW_PIXEL_UNSHADOWED) / px[SHADOW_PIXEL_SAMPLES];
    image[i] = (float4)(rest + r * visibility[i], 0.0f);
}
