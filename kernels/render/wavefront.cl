// The wavefront path tracer (Laine, Karras & Aila 2013, "Megakernels considered harmful:
// wavefront path tracing on GPUs"): the megakernel's loop (kernels/render/pathtrace.cl) cut at
// its ray queries into one kernel per step, over queues of paths, so that each kernel runs one
// kind of work on every path that needs it: camera rays, extension rays (the BVH walk),
// shading (path_vertex: emission, the light sample, the BSDF sample), shadow rays, and the
// film. The steps are those of kernels/render/path.cl, in the same order for every path, so
// each sample's floats, and hence the image, are the same bytes as the megakernel's.
//
// The rows of a launch are traced in waves of whole rows (src/render/wavefront.rs sizes them:
// on a CPU so that a wave's records stay in the caches); one sample of every pixel of a wave
// is in flight at a time, one path per pixel:
//
//   wavefront_generate     camera ray and Russian roulette at vertex 0; queues the survivors
//   repeat while the queue is not empty (the host reads the queues' lengths after each shade):
//       wavefront_extend   closest hit of every queued path
//       wavefront_shade    adds the last vertex's light connection, runs the vertex, queues the
//                          light sample's shadow ray and the path if it goes on
//       wavefront_shadow   any hit of every queued shadow ray: an occluded connection carries 0
//   wavefront_accumulate   the last connection, the clamp, film_accumulate
//
// The pixels of a wave are consecutive rows of the tile: slot `path_base + path` of the
// renderer's buffers is path `path` of the wave's records, which hold one wave only. A queue
// holds each path's index, and beside it, at the same place, its extension ray and then its
// hit, so that the BVH walk reads and writes consecutive records instead of the scattered
// path states (measured on PoCL: loading each ray from its 208-byte path state was 84 % of
// the extension kernel's own time). Queues are written with atomics, so their order differs
// from run to run; nothing but the order of work depends on it: every path reads and writes
// its own records only.
#ifndef NOISEFREE_WAVEFRONT_CL
#define NOISEFREE_WAVEFRONT_CL

#include "render/camera.cl"
#include "render/path.cl"

// The queues' lengths as the kernels append to them (`counts`, set to 0 by the host first):
// the paths to extend next, and the shadow rays. A kernel that reads a queue is launched over
// its length, `count`, which the host read back.
#define WAVEFRONT_NEXT 0
#define WAVEFRONT_SHADOW 1

// An extension ray as the queue holds it.
typedef struct {
    float3 o, d;
} QueuedRay;

// Appends path `path` with its next ray to a queue.
inline void wavefront_enqueue(__global uint* queue, __global QueuedRay* rays,
                              __global uint* counts, uint path, const PathState* st) {
    uint j = atomic_inc(counts + WAVEFRONT_NEXT);
    queue[j] = path;
    rays[j].o = st->o;
    rays[j].d = st->d;
}

// The sizes of the per-path records, for the host to allocate them (it never reads them).
__kernel void wavefront_sizes(__global uint* out) {
    out[0] = (uint)sizeof(PathState);
    out[1] = (uint)sizeof(Hit);
    out[2] = (uint)sizeof(LightConnection);
    out[3] = (uint)sizeof(QueuedRay);
}

// The wave's pixels start sample `sample` (one work-item per pixel, like the megakernel's
// launch): the camera ray, then the path is queued unless it ends before its first vertex.
__kernel void wavefront_generate(SCENE_PARAMS, __global PathState* paths, __global uint* queue,
                                 __global QueuedRay* rays, __global uint* counts, uint tile_x,
                                 uint tile_y,
                                 uint tile_width, uint tile_height, uint path_base,
                                 uint sample) {
    uint tx = get_global_id(0), ty = get_global_id(1);
    if (tx >= tile_width || ty >= tile_height) return;
    uint x = tile_x + tx, y = tile_y + ty;
    uint pixel = y * params->image_width + x;           // in the image: its random numbers
    uint path = ty * tile_width + tx - path_base;       // in the wave's records
    SceneRefs s = SCENE_REFS;
    uint key = rng_sample_key(params->seed, pixel, sample);
    float3 o, d;
    camera_ray(&s, x, y, key, &o, &d);
    PathState st;
    path_begin(&st, o, d, key);
    if (path_survives(&s, &st)) wavefront_enqueue(queue, rays, counts, path, &st);
    paths[path] = st;
}

// The extension ray of every queued path (Alg. 4), its hit at the same place in `hits`.
__kernel void wavefront_extend(SCENE_PARAMS, __global const QueuedRay* rays, __global Hit* hits,
                               __global const uint* queue, uint count,
                               __global uint* ray_counts, uint path_base) {
    uint i = get_global_id(0);
    if (i >= count) return;
    SceneRefs s = SCENE_REFS;
    uint traced = 0u;
    hits[i] = intersect_closest(&s, rays[i].o, rays[i].d, INFINITY, &traced);
    ray_counts[path_base + queue[i]] += traced;
}

// One vertex of every queued path (Alg. 1 lines 12-18), after the light its last vertex's
// connection brought. Queues the connection's shadow ray (unless it cannot carry light) and
// the path if it survives to its next vertex.
__kernel void wavefront_shade(SCENE_PARAMS, __global PathState* paths,
                              __global const Hit* hits,
                              __global LightConnection* connections,
                              __global const uint* queue, uint count,
                              __global uint* next_queue, __global QueuedRay* next_rays,
                              __global uint* shadow_queue,
                              __global uint* counts, __global const float* shadow_pixels,
                              uint shadow_lights, uint path_base) {
    uint i = get_global_id(0);
    if (i >= count) return;
    uint path = queue[i];
    SceneRefs s = SCENE_REFS;
    PathState st = paths[path];
    path_add_connection(&st, connections[path].value);
    float shadow_objects[SHADOW_PLANES];
    shadow_receiver_objects(shadow_pixels, path_base + path, shadow_objects);
    Hit hit = hits[i];
    LightConnection connection;
    bool more = path_vertex(&s, &st, &hit, shadow_lights, shadow_objects, &connection, 0);
    if (st.flags & PATH_CONNECTION) {
        connections[path] = connection;
        if (connection.valid) shadow_queue[atomic_inc(counts + WAVEFRONT_SHADOW)] = path;
    }
    if (more && path_survives(&s, &st))
        wavefront_enqueue(next_queue, next_rays, counts, path, &st);
    paths[path] = st;
}

// The shadow ray of every queued light connection: an occluded one carries no light.
__kernel void wavefront_shadow(SCENE_PARAMS, __global LightConnection* connections,
                               __global const uint* shadow_queue, uint count,
                               __global uint* ray_counts, uint path_base) {
    uint i = get_global_id(0);
    if (i >= count) return;
    uint path = shadow_queue[i];
    SceneRefs s = SCENE_REFS;
    uint rays = 0u;
    __global LightConnection* c = connections + path;
    if (occluded(&s, c->o, c->d, c->t_max, &rays)) c->value = (float3)(0.0f);
    ray_counts[path_base + path] += rays;
}

// The wave's finished paths into the film, as the megakernel's loop body after trace_path.
__kernel void wavefront_accumulate(SCENE_PARAMS, __global PathState* paths,
                                   __global const LightConnection* connections,
                                   RENDER_OUTPUT_PARAMS, uint sample_capacity, uint tile_x,
                                   uint tile_y, uint tile_width, uint tile_height,
                                   uint path_base, uint range_first, uint sample) {
    uint tx = get_global_id(0), ty = get_global_id(1);
    if (tx >= tile_width || ty >= tile_height) return;
    uint x = tile_x + tx, y = tile_y + ty;
    uint slot = ty * tile_width + tx;
    uint path = slot - path_base;
    SceneRefs s = SCENE_REFS;
    PathState st = paths[path];
    path_add_connection(&st, connections[path].value);
    path_finish(&s, &st);
    PixelStats stats;
    pixel_stats_load(&stats, RENDER_OUTPUT_ARGS, slot);
    uint index = sample - range_first;                  // 0 for the render's first sample
    film_accumulate(&stats, &st.ps, index + 1u, sample);
#if OUTPUT_SAMPLES
    if (index < sample_capacity)
        write_sample_vector(sample_vectors, slot * sample_capacity + index, x, y, st.key,
                            &st.ps, HAS_DOF && params->lens_radius > 0.0f);
#else
    (void)x;
    (void)y;
    (void)sample_capacity;
#endif
    pixel_stats_store(&stats, RENDER_OUTPUT_ARGS, slot);
}

#endif
