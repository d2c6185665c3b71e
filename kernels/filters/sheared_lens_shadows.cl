// Sheared soft shadows and depth of field together (Yan et al. 2015, appendix, eqs. 16-17;
// digest /work/shared/notes/seeds-aaf-sheared.md §3.4 "Both effects together"): between the
// two sheared filters. The shadow filter (kernels/filters/sheared.cl, steps 1a-2b over each
// light's (x, y) field) has left the filtered visibility v(x) of the pixel centre's receiver;
// this kernel puts each light's direct term back into the lens field, sample by sample,
//
//     L(x, u) = rest(x, u) + k(x, u) * sum over lights of F-bar(x) * v(x)        (eqs. 16-17)
//
// rest: the lens sample's light less the filtered lights' direct term (the lens pass took it
// out where the sample's first hit is a diffuse point of the receiver's object); k: that hit's
// albedo (0 where nothing was taken out); F-bar: the light's unoccluded term averaged over the
// pixel's lens samples on the receiver (kernels/render/lens_field.cl). The depth-of-field
// filter (kernels/filters/sheared_dof.cl) then filters the (x, u) field this writes, the
// fallback's 36 extra samples included. src/filters/sheared/lens_shadows.rs is the same code
// in Rust.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"

#define SHEARED_NONE 0.0f

// Light plane `plane` of `planes`: adds k F-bar v into the combined field `out`, which the
// first light (`chained` 0) first fills with the lens field as rendered. v: the shadow
// filter's visibility, or where it has no receiver (guide kind 0) the sparse pass's own mean.
__kernel void sheared_lens_combine(__constant const ShearedParams* p,
                                   __global const float* lens_field,
                                   __global const float* lens_shadow,
                                   __global const float* shadow_pixels, uint plane,
                                   uint planes, uint chained, __global const float4* guide,
                                   __global const float* visibility, __global float* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global float* o = out + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
    if (!chained) {
        __global const float* lf = lens_field + (size_t)i * LIGHT_FIELD_PIXEL_FLOATS;
        for (uint k = 0u; k < LIGHT_FIELD_PIXEL_FLOATS; ++k) o[k] = lf[k];
    }
    __global const float* ls = lens_shadow + (size_t)i * LENS_SHADOW_PIXEL_FLOATS;
    __global const float* u = ls + LENS_SHADOW_PIXEL_UNSHADOWED + 4u * plane;
    if (!(u[3] > 0.0f)) return;  // no lens sample on the receiver: nothing was taken out
    float v = visibility[i];
    if (guide[i].z == SHEARED_NONE) {
        __global const float* px = shadow_pixels + ((size_t)i * planes + plane) * SHADOW_PIXEL_FLOATS;
        float weight = px[SHADOW_PIXEL_WEIGHT];
        v = weight > 0.0f ? px[SHADOW_PIXEL_VISIBLE] / weight : 0.0f;
    }
    float3 d = (float3)(u[0], u[1], u[2]) * v;
    uint n = p->side * p->side;
    for (uint k = 0u; k < n; ++k) {
        o[LIGHT_FIELD_PIXEL_SAMPLES + k] += ls[LENS_SHADOW_PIXEL_ALBEDO + k] * d.x;
        o[LIGHT_FIELD_PIXEL_GREEN + k] += ls[LENS_SHADOW_PIXEL_ALBEDO_GREEN + k] * d.y;
        o[LIGHT_FIELD_PIXEL_BLUE + k] += ls[LENS_SHADOW_PIXEL_ALBEDO_BLUE + k] * d.z;
    }
    o[LIGHT_FIELD_PIXEL_EXTRA] += ls[LENS_SHADOW_PIXEL_ALBEDO_EXTRA] * d.x;
    o[LIGHT_FIELD_PIXEL_EXTRA + 1] += ls[LENS_SHADOW_PIXEL_ALBEDO_EXTRA + 1] * d.y;
    o[LIGHT_FIELD_PIXEL_EXTRA + 2] += ls[LENS_SHADOW_PIXEL_ALBEDO_EXTRA + 2] * d.z;
}
