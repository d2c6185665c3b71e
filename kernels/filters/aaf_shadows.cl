// Axis-aligned filtering of soft shadows (Wang 2013 ch. 3, eqs. 3.2-3.7; Mehta et al. 2012):
// the filter side, over the shadow output of kernels/render/shadows.cl. src/filters/
// aaf_shadows/reference.rs is the same code in Rust; src/filters/aaf_shadows/mod.rs says
// why each choice is what it is.
//
// 1. aaf_prepare: per pixel the noisy visibility h_n = sum(f l) / sum(l) (eq. 3.2), the filter
//    width beta of eq. 3.4 (corrected, kernels/render/bandlimit.cl) and the pixel's kind.
// 2. aaf_pass (kernels/filters/aaf_pass.cl), twice (eq. 3.7): along rows, then along
//    columns of the first pass's result, each a normalised Gaussian mean sum(w v) / sum(w)
//    with beta of the pixel being written, on distances measured in the plane perpendicular
//    to the direction to the light (the "plane parallel to the light": the sphere's
//    silhouette disk), rejecting neighbours whose normal, offset along the light direction
//    or beta differ too much.
// 3. aaf_compose: F - (the light the filtered term replaces) + r * filtered visibility, r the
//    mean of the unshadowed term over the pixel's light samples.
//
// Several sphere lights (Wang 2013 §3.4: "one light at a time"): the three steps run once per
// light, each on its light's plane `plane` of `planes` in the shadow output (pixel-major,
// src/layout/outputs.rs Per::Light); the first light's compose starts from F, every later
// one from the image the previous one wrote (`chained`), so the output is
// F - sum_l direct_l + sum_l r_l * filtered v_l, a light at a time.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/bandlimit.cl"

// The pixel kinds (AAF_NONE: no receiver, sky, not diffuse, light below its horizon: F as is;
// AAF_LIT: a receiver without slopes, no occluder near, its visibility stands; AAF_FILTERED:
// a receiver with slopes) and the 1-D pass, shared with the indirect filter.
#include "filters/aaf_pass.cl"

inline float3 aaf_lane3(__global const float* px, int lane) {
    return (float3)(px[lane], px[lane + 1], px[lane + 2]);
}

// Pixel i's element of the light plane `plane` of `planes` in a per-light buffer.
#define AAF_PLANE(buffer, i, floats) ((buffer) + ((size_t)(i) * planes + plane) * (floats))

// The pass's guide: (position, kind), (normal, beta), (direction to the light, 0); and the
// value (h_n, 0, 0, 0).
__kernel void aaf_prepare(__constant const AafShadowParams* p, __global const float* pixels,
                          uint plane, uint planes, __global float4* guide,
                          __global float4* visibility) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* px = AAF_PLANE(pixels, i, SHADOW_PIXEL_FLOATS);
    float weight = px[SHADOW_PIXEL_WEIGHT];
    float v = 0.0f, beta = 0.0f, kind = AAF_NONE;
    if (weight > 0.0f) {
        v = px[SHADOW_PIXEL_VISIBLE] / weight;
        if (px[SHADOW_PIXEL_SLOPE_SOURCE] > 0.0f) {
            beta = aaf_beta(p->sigma, px[SHADOW_PIXEL_PIXEL_SIZE], px[SHADOW_PIXEL_SLOPE_MIN]);
            kind = AAF_FILTERED;
        } else {
            kind = AAF_LIT;
        }
    }
    float3 pos = aaf_lane3(px, SHADOW_PIXEL_POSITION);
    guide[3 * i] = (float4)(pos, kind);
    guide[3 * i + 1] = (float4)(aaf_lane3(px, SHADOW_PIXEL_NORMAL), beta);
    guide[3 * i + 2] = (kind == AAF_FILTERED) ? (float4)(normalize(p->light.xyz - pos), 0.0f)
                                              : (float4)(0.0f);
    visibility[i] = (float4)(v, 0.0f, 0.0f, 0.0f);
}

// base - the replaced light + r * v at pixel i (base as is when `none`: no receiver); `t` is
// the pixel's shadow terms.
inline void aaf_compose_at(float3 base, __global const float* t, float3 r, uint i, bool none,
                           float v, __global float4* image) {
    if (none) {
        image[i] = (float4)(base, 0.0f);
        return;
    }
    float3 rest = base - aaf_lane3(t, SHADOW_TERMS_DIRECT);
    image[i] = (float4)(rest + r * v, 0.0f);
}

// AAF's r(x): the sparse and adaptive passes' unoccluded term over their receiver points.
inline float3 aaf_unshadowed(__global const float* px) {
    return aaf_lane3(px, SHADOW_PIXEL_UNSHADOWED) / px[SHADOW_PIXEL_SAMPLES];
}

// F, the beauty, at pixel i.
inline float3 aaf_beauty(__global const float* fv, uint i) {
    __global const float* f = fv + (size_t)i * FILTER_VECTOR_FLOATS;
    return aaf_lane3(f, FILTER_VECTOR_DIRECT) + aaf_lane3(f, FILTER_VECTOR_INDIRECT);
}

// This filter's compose, for the light of plane `plane`: the shared pass's guide (the kind in
// guide[3 i].w) and its values; from F, or (`chained`) from the image of the lights before.
__kernel void aaf_compose(__constant const AafShadowParams* p, __global const float* fv,
                          __global const float* terms, __global const float* pixels,
                          uint plane, uint planes, uint chained,
                          __global const float4* guide,
                          __global const float4* visibility, __global float4* image) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    float3 base = chained ? image[i].xyz : aaf_beauty(fv, i);
    aaf_compose_at(base, AAF_PLANE(terms, i, SHADOW_TERMS_FLOATS),
                   aaf_unshadowed(AAF_PLANE(pixels, i, SHADOW_PIXEL_FLOATS)), i,
                   guide[3 * i].w == AAF_NONE, visibility[i].x, image);
}

// The sheared filter's (kernels/filters/sheared.cl): one float4 of guide per pixel with the
// kind in z, one float of visibility; the light of plane `plane`, from F or (`chained`) from
// the image of the lights before, as aaf_compose (`pixels` is bound as for aaf_compose but
// not read). r is the path samples' (ShadowTerms
// .unshadowed: over the same samples as the replaced `direct`), not the sparse pass's: that
// pass traces one receiver point per pixel (sparse_spp 1), whose albedo would stand for the
// whole pixel (textures alias, edges take the receiver's r over the pixel's other objects).
__kernel void aaf_compose_sheared(__constant const AafShadowParams* p, __global const float* fv,
                                  __global const float* terms, __global const float* pixels,
                                  uint plane, uint planes, uint chained,
                                  __global const float4* guide,
                                  __global const float* visibility, __global float4* image) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    float3 base = chained ? image[i].xyz : aaf_beauty(fv, i);
    __global const float* t = AAF_PLANE(terms, i, SHADOW_TERMS_FLOATS);
    aaf_compose_at(base, t, aaf_lane3(t, SHADOW_TERMS_UNSHADOWED), i, guide[i].z == AAF_NONE,
                   visibility[i], image);
}
