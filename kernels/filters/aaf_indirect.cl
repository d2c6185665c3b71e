// Axis-aligned filtering of indirect light, diffuse and glossy (Wang 2013 ch. 4, eqs.
// 4.2-4.5; Mehta et al. 2013): the filter side, over the indirect output of kernels/render/
// indirect.cl. src/filters/aaf_indirect/reference.rs is the same code in Rust; src/filters/
// aaf_indirect/mod.rs says why each choice is what it is.
//
// 1. aaf_indirect_prepare: per pixel the demodulated indirect light sum(L_i) / n, the width
//    beta of eq. 4.4 with the Omega_h^max of the receiver's lobe (eq. 4.5: diffuse or the
//    metal's glossy lobe), the pixel's kind, and its lobe as the pass's group, as the guide of
//    the shared pass. Glossy receivers are no receivers unless p->glossy.
// 2. aaf_pass (kernels/filters/aaf_pass.cl), twice: rows, then columns, on distances in the
//    receiver's tangent plane, each lobe apart (the seed's separate buffers).
// 3. aaf_indirect_compose: direct + albedo * filtered demodulated indirect light (the albedo
//    of a glossy receiver is the metal's colour).
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/bandlimit.cl"
#include "filters/aaf_pass.cl"

inline float3 aafi_lane3(__global const float* px, int lane) {
    return (float3)(px[lane], px[lane + 1], px[lane + 2]);
}

// The guide: (position, kind), (normal, beta), (normal, lobe): distances in the tangent
// plane, offsets along the normal tested against depth_tolerance * beta, lobes apart. The
// value: (L, 0).
__kernel void aaf_indirect_prepare(__constant const AafIndirectParams* p,
                                   __global const float* pixels, __global float4* guide,
                                   __global float4* values) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* px = pixels + (size_t)i * INDIRECT_PIXEL_FLOATS;
    float weight = px[INDIRECT_PIXEL_WEIGHT];
    float lobe = px[INDIRECT_PIXEL_LOBE];
    float3 v = (float3)(0.0f);
    float beta = 0.0f, kind = AAF_NONE;
    if (weight > 0.0f && (lobe == 0.0f || p->glossy != 0u)) {
        v = aafi_lane3(px, INDIRECT_PIXEL_IRRADIANCE) / weight;
        if (px[INDIRECT_PIXEL_REFLECTORS] > 0.0f) {
            beta = aaf_indirect_beta(px[INDIRECT_PIXEL_Z_MIN], px[INDIRECT_PIXEL_PIXEL_SIZE],
                                     px[INDIRECT_PIXEL_BANDLIMIT], p->footprints);
            kind = AAF_FILTERED;
        } else {
            kind = AAF_LIT;
        }
    }
    float3 normal = aafi_lane3(px, INDIRECT_PIXEL_NORMAL);
    guide[3 * i] = (float4)(aafi_lane3(px, INDIRECT_PIXEL_POSITION), kind);
    guide[3 * i + 1] = (float4)(normal, beta);
    guide[3 * i + 2] = (float4)(normal, lobe);
    values[i] = (float4)(v, 0.0f);
}

// F.direct + (mean albedo over the samples' points: a metal's colour for a glossy receiver)
// * filtered L for a receiver; F as is for the rest.
__kernel void aaf_indirect_compose(__constant const AafIndirectParams* p,
                                   __global const float* fv, __global const float* pixels,
                                   __global const float4* guide, __global const float4* values,
                                   __global float4* image) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= p->width || y >= p->height) return;
    uint i = y * p->width + x;
    __global const float* f = fv + (size_t)i * FILTER_VECTOR_FLOATS;
    float3 direct = aafi_lane3(f, FILTER_VECTOR_DIRECT);
    if (guide[3 * i].w == AAF_NONE) {
        image[i] = (float4)(direct + aafi_lane3(f, FILTER_VECTOR_INDIRECT), 0.0f);
        return;
    }
    __global const float* px = pixels + (size_t)i * INDIRECT_PIXEL_FLOATS;
    float3 albedo = aafi_lane3(px, INDIRECT_PIXEL_ALBEDO) / px[INDIRECT_PIXEL_WEIGHT];
    image[i] = (float4)(direct + albedo * values[i].xyz, 0.0f);
}
