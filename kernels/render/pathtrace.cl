// The megakernel path tracer (thesis §4.3, Algorithm 1, Fig. 4.7): one work-item per pixel,
// the whole path of each sample in one kernel, samples folded into the pixel's FilterVector.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/features.cl"
#include "render/rng.cl"
#include "arrays/trace.cl"
#include "render/camera.cl"
#include "render/path.cl"
#include "render/indirect.cl"

// Algorithm 1 for one sample from the camera ray (o, d), the steps of kernels/render/path.cl
// in one loop: each vertex traces its shadow ray as soon as it has made it. With
// OUTPUT_SHADOWS, `shadow_lights` and `shadow_objects` say which first hits record which
// light's shadow terms (path_vertex). The lens-field pass of sheared depth of field
// (kernels/render/lens_field.cl) calls this with its own lens point.
inline PathSample trace_path_from(const SceneRefs* s, float3 o, float3 d, uint key,
                                  uint* ray_count, uint shadow_lights,
                                  const float* shadow_objects) {
    PathState st;
    path_begin(&st, o, d, key);
    while (path_survives(s, &st)) {
        Hit hit = intersect_closest(s, st.o, st.d, INFINITY, ray_count);
        LightConnection connection;
        if (!path_vertex(s, &st, &hit, shadow_lights, shadow_objects, &connection, ray_count))
            break;
    }
    path_finish(s, &st);
    return st.ps;
}

inline PathSample trace_path(const SceneRefs* s, uint x, uint y, uint key, uint* ray_count,
                             uint shadow_lights, const float* shadow_objects) {
    float3 o, d;
    camera_ray(s, x, y, key, &o, &d);
    return trace_path_from(s, o, d, key, ray_count, shadow_lights, shadow_objects);
}

#include "render/lens_field.cl"
#include "render/gi_field.cl"

// One work-item per pixel of a tile of the image adds `sample_count` samples, numbered from
// `sample_base`, to the pixel's outputs. The samples of one render are those from
// `range_first` on: a render of the range A..B (`render --samples A..B`) counts its samples from
// A, so its outputs are those of exactly the samples A..B-1, which `noisefree merge` combines
// with the other ranges (src/stats/merge.rs). The random numbers hash the pixel's place in the
// whole image and the absolute sample number, so a sample is the same whichever render, tile
// or launch draws it. The host binds every argument by name (src/render/mod.rs): the scene's
// (SCENE_PARAMS, the debug counters last, used by DEBUG_COUNTERS builds only), then the output
// buffers in the order of the generated RENDER_OUTPUT_PARAMS; they hold the tile's pixels.
__kernel void render(SCENE_PARAMS,
                     RENDER_OUTPUT_PARAMS,
                     __global uint* ray_counts,
                     uint sample_capacity,              // samples per pixel sample_vectors holds
                     uint tile_x,                       // the tile's top-left pixel in the image
                     uint tile_y,
                     uint tile_width,
                     uint tile_height,
                     uint range_first,
                     uint sample_base,
                     uint sample_count,
                     uint shadow_lights) {               // OUTPUT_SHADOWS builds only
    uint tx = get_global_id(0), ty = get_global_id(1);
    if (tx >= tile_width || ty >= tile_height) return;
    uint x = tile_x + tx, y = tile_y + ty;
    uint pixel = y * params->image_width + x;           // in the image: its random numbers
    uint slot = ty * tile_width + tx;                   // in this render's buffers
    SceneRefs s = SCENE_REFS;
    PixelStats stats;
    pixel_stats_load(&stats, RENDER_OUTPUT_ARGS, slot);
    // The shadow passes ran before the first path samples (whole images only: the host
    // refuses tiles with the shadow output, so slot == pixel).
    float shadow_objects[SHADOW_PLANES];
    shadow_receiver_objects(shadow_pixels, slot, shadow_objects);
    uint rays = 0u;
    for (uint k = 0u; k < sample_count; ++k) {
        uint sample = sample_base + k;
        uint key = rng_sample_key(params->seed, pixel, sample);
        PathSample ps = trace_path(&s, x, y, key, &rays, shadow_lights, shadow_objects);
        uint index = sample - range_first;              // 0 for the render's first sample
        film_accumulate(&stats, &ps, index + 1u, sample);
#if OUTPUT_SAMPLES
        if (index < sample_capacity)
            write_sample_vector(sample_vectors, slot * sample_capacity + index, x, y, key, &ps,
                                HAS_DOF && params->lens_radius > 0.0f);
#endif
    }
    pixel_stats_store(&stats, RENDER_OUTPUT_ARGS, slot);
    ray_counts[slot] = rays;
}

// The wavefront tracer's kernels, built beside the megakernel when asked for (-D WAVEFRONT=1).
#if defined(WAVEFRONT) && WAVEFRONT
#include "render/wavefront.cl"
#endif
