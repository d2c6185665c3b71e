// Small kernels that expose single device functions to the tests, so each can be compared
// with its Rust reference (src/render/cpu/). Not used for rendering.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/features.cl"
#include "render/rng.cl"
#include "arrays/trace.cl"
#include "render/camera.cl"
#include "render/film.cl"

// rng_uniform for each (pixel, sample, bounce, dim) quadruple.
__kernel void probe_rng(__global const uint4* counters, uint seed, __global float* out, uint n) {
    uint i = get_global_id(0);
    if (i >= n) return;
    uint4 c = counters[i];
    out[i] = rng_uniform(rng_sample_key(seed, c.x, c.y), c.z, c.w);
}

// Nearest hit (t, prim, kind) or any-hit for each ray (origin.xyz, t_max in origin.w).
__kernel void probe_intersect(__constant const SceneParams* params,
                              __global const SceneNode* nodes,
                              __global const TriangleGeom* tri_geom,
                              __global const TrianglePack* tri_packs,
                              __global const Sphere* spheres,
                              __global const float4* origins,
                              __global const float4* directions,
                              __global float* out_t,
                              __global int* out_prim,
                              __global int* out_occluded,
                              uint n) {
    uint i = get_global_id(0);
    if (i >= n) return;
    SceneRefs s = {params, nodes, tri_geom, tri_packs, 0, spheres, 0, 0, 0, 0, 0, 0};
    float3 o = origins[i].xyz, d = directions[i].xyz;
    float t_max = origins[i].w;
    uint rays = 0u;
    Hit hit = intersect_closest(&s, o, d, t_max, &rays);
    out_t[i] = hit.kind == HIT_NONE ? -1.0f : hit.t;
    out_prim[i] = hit.kind == HIT_NONE ? -1 : (hit.kind == HIT_SPHERE ? -2 - (int)hit.prim : (int)hit.prim);
    out_occluded[i] = occluded(&s, o, d, t_max, &rays) ? 1 : 0;
}

// Camera rays for every pixel of one sample.
__kernel void probe_camera(__constant const SceneParams* params, uint sample,
                           __global float4* out_origin, __global float4* out_dir) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    float3 o, d;
    SceneRefs s = {params, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    camera_ray(&s, x, y, rng_sample_key(params->seed, pixel, sample), &o, &d);
    out_origin[pixel] = (float4)(o, 0.0f);
    out_dir[pixel] = (float4)(d, 0.0f);
}

// Feeds one stream of values per pixel through the renderer's output stage (film_accumulate),
// for samples [first, first + count): several calls emulate progressive launches. Every
// feature lane of a sample gets the stream value; the buffers are the render kernel's.
__kernel void probe_film(__global const float* stream, uint stream_len, uint first, uint count,
                         RENDER_OUTPUT_PARAMS, uint pixels) {
    uint pixel = get_global_id(0);
    if (pixel >= pixels) return;
    PixelStats stats;
    pixel_stats_load(&stats, RENDER_OUTPUT_ARGS, pixel);
    for (uint k = first; k < first + count; ++k) {
        float v = stream[pixel * stream_len + k];
        PathSample ps = path_sample_empty();
        ps.direct = (float3)(v);
        ps.depth = v;
        ps.normal = (float3)(v);
        ps.albedo = (float3)(v);
        ps.albedo2 = (float3)(v);
        ps.direction = (float3)(v);
        film_accumulate(&stats, &ps, k + 1u, k);
    }
    pixel_stats_store(&stats, RENDER_OUTPUT_ARGS, pixel);
}

// sizeof and field offsets of every shared struct, measured on the device (tests/layout.rs).
// The test prepends `#define LAYOUT_PROBE_KERNEL ...`, the whole kernel, generated from
// src/layout.
#ifdef LAYOUT_PROBE_KERNEL
LAYOUT_PROBE_KERNEL
#endif

// The samplers (kernels/render/sampling.cl) take sine and cosine of angles 2 pi r with
// r = k 2^-24 (rng_uniform's values) from one sincos call. Each work-item checks one k against
// separate sin and cos and counts the angles where any bit differs.
__kernel void probe_sincos(__global uint* mismatches) {
    uint k = get_global_id(0);
    float a = TWO_PI_F * ((float)k * 0x1.0p-24f);
    float c, sn = sincos(a, &c);
    if (as_uint(sn) != as_uint(sin(a)) || as_uint(c) != as_uint(cos(a))) atomic_inc(mismatches);
}

// a / b and sqrt(a) for each pair (a, b): with -cl-fp32-correctly-rounded-divide-sqrt (given
// wherever the device offers it, src/gpu/mod.rs) they must be IEEE 754's results.
__kernel void probe_divide_sqrt(__global const float* ab, __global float* out, uint n) {
    uint i = get_global_id(0);
    if (i >= n) return;
    float a = ab[2 * i], b = ab[2 * i + 1];
    out[2 * i] = a / b;
    out[2 * i + 1] = sqrt(a);
}
