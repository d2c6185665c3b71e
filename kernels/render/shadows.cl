// AAF soft shadows, the sampling side (Wang 2013 ch. 3 §3.4, passes 1 and 2, after Mehta et
// al. 2012), for one sphere light. Compiled into the megakernel's program with OUTPUT_SHADOWS.
//
// - The megakernel (kernels/render/pathtrace.cl) folds into ShadowTerms the part of F the
//   filtered term replaces: the light's direct term on the path samples whose first hit lies
//   on the pixel centre's receiver (same object). At a silhouette the other samples keep their
//   own light, so the centre's visibility is applied only to the part of the pixel that
//   belongs to it.
// - shadow_sparse (pass 1): the pixel centre's first hit, through the lens centre (a thin lens
//   leaves a pixel no single world point; the filter's world-space weights need one), and
//   sqrt_spp^2 light samples (stratified over the light, from random points of the pixel on
//   the centre's surface): visibility sums, the nearest and farthest occluder of every shadow
//   ray (an any-hit that goes on), hence the slopes s1 and s2 (eq. 3.5).
// - shadow_fill: the released code's slope fill, two 1-D passes of +-radius pixels taking the
//   max of s1 and the min of s2 of the neighbours that saw an occluder, within one object:
//   pixels whose sparse samples all reached the light get slopes from their neighbours.
// - shadow_adaptive (pass 2): n(x) of eq. 3.5 clamped to [sparse, max], and the samples it
//   asks for beyond the sparse ones, in one more square of strata.
//
// The light is the sphere's cone of directions, sampled uniformly by solid angle (as the path
// tracer samples it); each sample is weighted by l = cos(theta) at the receiver, so that
// r · sum(f l) / sum(l) is the light's shadowed direct term (src/render/shadows/mod.rs).
// src/render/cpu/shadows.rs is the same code in Rust.
#ifndef NOISEFREE_SHADOWS_CL
#define NOISEFREE_SHADOWS_CL

#include "layout.cl"
#include "arrays/trace.cl"
#include "render/camera.cl"
#include "render/materials.cl"
#include "render/lights.cl"
#include "render/bandlimit.cl"

// r(x) of eq. 3.1 / albedo: L sin^2(alpha) max(cos theta_c, 0), alpha the half-angle of the
// sphere's cone
// and theta_c the angle of its centre: albedo / pi times the unoccluded integral of L cos over
// the cone (pi L sin^2 alpha cos theta_c, exact while the cone lies above the horizon). 0 from
// inside the light.
inline float3 shadow_unshadowed(__global const Light* light, float3 p, float3 ns) {
    float3 to_c = light->p0.xyz - p;
    float d2 = dot(to_c, to_c);
    float r2 = light->p0.w * light->p0.w;
    if (d2 <= r2) return (float3)(0.0f);
    float cos_c = dot(ns, to_c) / sqrt(d2);
    return light->emission.xyz * (r2 / d2 * fmax(cos_c, 0.0f));
}

// The passes exist when a filter asks for the output, and the host asks only when the scene
// has a sphere light.
// The object a hit belongs to, as a float (exact up to 2^24): the mesh part of a triangle,
// -1 - index for a sphere.
inline float hit_object(const SceneRefs* s, const Hit* hit) {
    return (hit->kind == HIT_TRIANGLE) ? (float)s->tri_shading[hit->prim].object
                                       : -1.0f - (float)hit->prim;
}

// What the AAF passes of both filters share (the shadow passes here, the indirect passes of
// kernels/render/indirect.cl): the receiver, the kernels' scene parameters, square roots.
#if (OUTPUT_SHADOWS && HAS_SPHERE_LIGHTS) || OUTPUT_INDIRECT || OUTPUT_LIGHT_FIELD

// The first hit of the ray through the point (x + jx, y + jy) of the image from the lens
// centre, when it is a receiver: a diffuse surface (the path tracer connects to lights there
// only), or with `glossy` a metal too (the indirect passes' glossy lobe, kernels/render/
// indirect.cl). `d` is the camera ray's direction, `material` the surface's material.
typedef struct {
    float3 p, ng, ns, albedo, d;
    float t;
    float object;
    uint material;
} ShadowReceiver;

inline bool aaf_receiver(const SceneRefs* s, uint x, uint y, float jx, float jy, bool glossy,
                         ShadowReceiver* r, uint* rays) {
    float3 o = s->params->camera_origin.xyz;
    float3 d = pinhole_direction(s->params, x, y, jx, jy);
    Hit hit = intersect_closest(s, o, d, INFINITY, rays);
    if (hit.kind == HIT_NONE) return false;
    Surface sf = surface_at(s, &hit, o, d);
    uint kind = s->materials[sf.material].kind;
    if (kind != MATERIAL_DIFFUSE && !(glossy && kind == MATERIAL_METAL)) return false;
    r->p = sf.p;
    r->ng = sf.ng;
    r->ns = sf.ns;
    r->albedo = surface_albedo(s, &sf);
    r->d = d;
    r->t = hit.t;
    r->object = hit_object(s, &hit);
    r->material = sf.material;
    return true;
}

inline bool shadow_receiver(const SceneRefs* s, uint x, uint y, float jx, float jy,
                            ShadowReceiver* r, uint* rays) {
    return aaf_receiver(s, x, y, jx, jy, false, r, rays);
}

// The largest k with k^2 <= n, and the smallest with k^2 >= n (n is small: at most max_spp).
inline uint shadow_isqrt_floor(uint n) {
    uint k = 0u;
    while ((k + 1u) * (k + 1u) <= n) ++k;
    return k;
}

inline uint shadow_isqrt_ceil(uint n) {
    uint k = shadow_isqrt_floor(n);
    return k * k < n ? k + 1u : k;
}

#endif

#if OUTPUT_SHADOWS && HAS_SPHERE_LIGHTS

// The random numbers of the shadow passes use sample numbers no path sample reaches.
#define SHADOW_SAMPLE_BASE 0xFFFFFF00u

// The distance from a receiver's shadow-ray origin to the light's centre (d1; 0 inside the
// light).
inline float shadow_light_distance(const SceneRefs* s, __global const Light* light,
                                   const ShadowReceiver* r) {
    float3 p = offset_ray_origin(r->p, r->ng, s->params->scene_size);
    float3 to_c = light->p0.xyz - p;
    float d2 = dot(to_c, to_c);
    return d2 <= light->p0.w * light->p0.w ? 0.0f : sqrt(d2);
}

// The stylized-shadows filter's binary matte (DeCoro 2009 §3.3 step 1; digest §1.4 "a shadow
// ray to the sphere centre"): V of one ray from the receiver to the light's centre, and d(x),
// the distance to the nearest occluder on it (§3.3.2: raytraced distances are allowed). A
// centre below the geometric surface counts as occluded at d = 0, as a shadow-volume or
// shadow-map matte has it (the attached shadow), so the terminator is a contour too.
inline float shadow_centre_visible(const SceneRefs* s, __global const Light* light,
                                   const ShadowReceiver* r, float* occluder, uint* rays) {
    *occluder = 0.0f;
    float3 p = offset_ray_origin(r->p, r->ng, s->params->scene_size);
    float3 to_c = light->p0.xyz - p;
    float d2 = dot(to_c, to_c);
    float radius = light->p0.w;
    if (d2 <= radius * radius) return 1.0f;                      // inside the light
    float dc = sqrt(d2);
    float3 dir = to_c / dc;
    if (dot(r->ng, dir) <= 0.0f) return 0.0f;
    float t_near, t_far;
    if (occluder_range(s, p, dir, (dc - radius) * SHADOW_RAY_SHORTEN, &t_near, &t_far, rays)) {
        *occluder = t_near;
        return 0.0f;
    }
    return 1.0f;
}

// Running sums of one pixel's light samples.
typedef struct {
    float visible, weight, occluded, s1, s2;
    float3 unshadowed;
} ShadowSums;

// One light sample from receiver r in the point (u, v) of the unit square, mapped by
// sample_cone (which keeps areas: strata of the square are equal solid angles of the cone),
// and r's unshadowed term.
inline void shadow_sample(const SceneRefs* s, __global const Light* light,
                          const ShadowReceiver* r, float u, float v, ShadowSums* acc,
                          uint* rays) {
    float3 p = offset_ray_origin(r->p, r->ng, s->params->scene_size);
    acc->unshadowed += r->albedo * shadow_unshadowed(light, p, r->ns);
    float3 c = light->p0.xyz;
    float radius = light->p0.w;
    float3 to_c = c - p;
    float d2 = dot(to_c, to_c);
    float r2 = radius * radius;
    if (d2 <= r2) return;                                         // inside the light
    float dc = sqrt(d2);
    float sin2_max = r2 / d2;
    float cos_max = sqrt(fmax(0.0f, 1.0f - sin2_max));
    float one_minus_cos_max = sin2_max / (1.0f + cos_max);
    float3 dir = sample_cone(u, v, to_c / dc, one_minus_cos_max);
    float cos_s = dot(r->ns, dir);
    if (cos_s <= 0.0f || dot(r->ng, dir) <= 0.0f) return;       // l = 0: below the horizon
    float t = ray_sphere(p, dir, c, radius, 0.0f, INFINITY);
    float dist = (t > 0.0f) ? t : dc;
    acc->weight += cos_s;
    float t_near, t_far;
    if (occluder_range(s, p, dir, dist * SHADOW_RAY_SHORTEN, &t_near, &t_far, rays)) {
        // d2 = d1 - t: the occluder's distance to the light (eq. 3.5's s = d1/d2 - 1); the
        // nearest occluder gives d2max and s2, the farthest d2min and s1.
        acc->occluded += 1.0f;
        acc->s2 = fmin(acc->s2, dc / (dc - t_near) - 1.0f);
        acc->s1 = fmax(acc->s1, dc / (dc - t_far) - 1.0f);
    } else {
        acc->visible += cos_s;
    }
}

// k x k light samples of pixel (x, y), one per stratum of the light's cone, each from its own
// random point of the pixel (a ray from the lens centre), kept when that point lies on the
// centre's receiver `object`: h_n is then the visibility over the part of the pixel the
// centre's surface covers, as the pixel's path samples see it (a visibility from the centre
// alone would alias every shadow edge). Random numbers from `key`.
inline void shadow_samples(const SceneRefs* s, __global const Light* light, uint x, uint y,
                           float object, uint key, uint k, ShadowSums* acc, uint* rays) {
    float inv_k = 1.0f / (float)k;
    for (uint i = 0u; i < k; ++i) {
        for (uint j = 0u; j < k; ++j) {
            uint n = i * k + j;
            ShadowReceiver q;
            float jx = rng_uniform(key, n, DIM_PIXEL_X), jy = rng_uniform(key, n, DIM_PIXEL_Y);
            if (!shadow_receiver(s, x, y, jx, jy, &q, rays) || q.object != object) continue;
            float u = ((float)i + rng_uniform(key, n, DIM_LIGHT_U)) * inv_k;
            float v = ((float)j + rng_uniform(key, n, DIM_LIGHT_V)) * inv_k;
            shadow_sample(s, light, &q, u, v, acc, rays);
        }
    }
}

// Element `plane` of pixel `pixel` in the shadow output's light planes (pixel-major:
// src/layout/outputs.rs Per::Light).
#define SHADOW_AT(buffer, pixel, plane, planes) \
    ((buffer) + ((size_t)(pixel) * (planes) + (plane)) * SHADOW_PIXEL_FLOATS)

// Pass 1. `light` indexes the light list (a sphere light); an index past it samples nothing.
// Each light plane runs the passes with its light (`plane` of `planes`).
__kernel void shadow_sparse(SCENE_PARAMS, __global float* shadow_pixels, uint plane,
                            uint planes, __global uint* shadow_rays, uint light,
                            uint sqrt_spp) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    SceneRefs s = SCENE_REFS;
    __global float* px = SHADOW_AT(shadow_pixels, pixel, plane, planes);
    for (uint i = 0u; i < SHADOW_PIXEL_FLOATS; ++i) px[i] = 0.0f;
    uint rays = 0u;
    ShadowReceiver r;
    if (light < params->light_count && shadow_receiver(&s, x, y, 0.5f, 0.5f, &r, &rays)) {
        ShadowSums acc = {0.0f, 0.0f, 0.0f, 0.0f, INFINITY, (float3)(0.0f)};
        uint key = rng_sample_key(params->seed, pixel, SHADOW_SAMPLE_BASE);
        shadow_samples(&s, lights + light, x, y, r.object, key, sqrt_spp, &acc, &rays);
        float d1 = shadow_light_distance(&s, lights + light, &r);
        // A receiver sees part of the light above its horizon; the rest sample nothing.
        bool sampled = acc.weight > 0.0f;
        bool slopes = acc.occluded > 0.0f;
        px[SHADOW_PIXEL_VISIBLE] = acc.visible;
        px[SHADOW_PIXEL_WEIGHT] = acc.weight;
        px[SHADOW_PIXEL_SAMPLES] = sampled ? (float)(sqrt_spp * sqrt_spp) : 0.0f;
        px[SHADOW_PIXEL_OCCLUDED] = acc.occluded;
        px[SHADOW_PIXEL_LIGHT_DISTANCE] = d1;
        px[SHADOW_PIXEL_SLOPE_MAX] = slopes ? acc.s1 : 0.0f;
        px[SHADOW_PIXEL_SLOPE_MIN] = slopes ? acc.s2 : 0.0f;
        px[SHADOW_PIXEL_SLOPE_SOURCE] = slopes ? 1.0f : 0.0f;
        px[SHADOW_PIXEL_PIXEL_SIZE] = r.t * 2.0f * params->tan_half_fov
                                      / (float)params->image_height;
        px[SHADOW_PIXEL_TARGET] = px[SHADOW_PIXEL_SAMPLES];
        px[SHADOW_PIXEL_OBJECT] = r.object;
        float occluder;
        px[SHADOW_PIXEL_CENTRE_VISIBLE] = shadow_centre_visible(&s, lights + light, &r,
                                                                &occluder, &rays);
        px[SHADOW_PIXEL_OCCLUDER_DISTANCE] = occluder;
        vstore3(r.p, 0, px + SHADOW_PIXEL_POSITION);
        vstore3(r.ns, 0, px + SHADOW_PIXEL_NORMAL);
        vstore3(acc.unshadowed, 0, px + SHADOW_PIXEL_UNSHADOWED);
    }
    shadow_rays[pixel] = rays;
}

// Whether pixel `q` can lend its slopes in the fill: a receiver that saw an occluder.
inline bool shadow_has_own_slopes(__global const float* q) {
    return q[SHADOW_PIXEL_WEIGHT] > 0.0f && q[SHADOW_PIXEL_OCCLUDED] > 0.0f;
}

// The slope fill, pass 0 along rows into `fill` (s1, s2, found), pass 1 along columns of
// `fill`, writing slopes (source 2) into the receivers that had none.
__kernel void shadow_fill(__global float* shadow_pixels, uint plane, uint planes,
                          __global float4* fill, uint width, uint height, int radius,
                          uint pass) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint pixel = (uint)y * width + (uint)x;
    __global float* px = SHADOW_AT(shadow_pixels, pixel, plane, planes);
    float object = px[SHADOW_PIXEL_OBJECT];
    if (pass == 0u) {
        float4 acc = (float4)(0.0f, INFINITY, 0.0f, 0.0f);
        for (int i = max(0, x - radius); i <= min((int)width - 1, x + radius); ++i) {
            __global const float* q = SHADOW_AT(shadow_pixels, (uint)y * width + (uint)i,
                                                plane, planes);
            if (shadow_has_own_slopes(q) && q[SHADOW_PIXEL_OBJECT] == object) {
                acc.x = fmax(acc.x, q[SHADOW_PIXEL_SLOPE_MAX]);
                acc.y = fmin(acc.y, q[SHADOW_PIXEL_SLOPE_MIN]);
                acc.z = 1.0f;
            }
        }
        fill[pixel] = acc;
        return;
    }
    if (!(px[SHADOW_PIXEL_WEIGHT] > 0.0f) || px[SHADOW_PIXEL_SLOPE_SOURCE] != 0.0f) return;
    float4 acc = (float4)(0.0f, INFINITY, 0.0f, 0.0f);
    for (int j = max(0, y - radius); j <= min((int)height - 1, y + radius); ++j) {
        uint q = (uint)j * width + (uint)x;
        float4 f = fill[q];
        if (f.z > 0.0f && SHADOW_AT(shadow_pixels, q, plane, planes)[SHADOW_PIXEL_OBJECT]
                              == object) {
            acc.x = fmax(acc.x, f.x);
            acc.y = fmin(acc.y, f.y);
            acc.z = 1.0f;
        }
    }
    if (acc.z > 0.0f) {
        px[SHADOW_PIXEL_SLOPE_MAX] = acc.x;
        px[SHADOW_PIXEL_SLOPE_MIN] = acc.y;
        px[SHADOW_PIXEL_SLOPE_SOURCE] = 2.0f;
    }
}

// Pass 2: pixels with slopes get n(x) of eq. 3.5, clamped to [sparse_spp, max_spp]; the
// samples beyond the sparse ones come as one more k x k square, the smallest that covers them
// (the released code's ceil(sqrt)^2) and no larger than max_spp - sparse_spp allows.
__kernel void shadow_adaptive(SCENE_PARAMS, __global float* shadow_pixels, uint plane,
                              uint planes, __global uint* shadow_rays, uint light,
                              uint sparse_spp, uint max_spp) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    shadow_rays[pixel] = 0u;
    __global float* px = SHADOW_AT(shadow_pixels, pixel, plane, planes);
    if (!(px[SHADOW_PIXEL_WEIGHT] > 0.0f) || px[SHADOW_PIXEL_SLOPE_SOURCE] == 0.0f) return;
    __global const Light* l = lights + light;
    float n = aaf_sample_count(px[SHADOW_PIXEL_SLOPE_MAX], px[SHADOW_PIXEL_SLOPE_MIN],
                               px[SHADOW_PIXEL_PIXEL_SIZE], l->p0.w);
    float target = fmin(fmax(n, (float)sparse_spp), (float)max_spp);
    px[SHADOW_PIXEL_TARGET] = target;
    uint extra = (uint)ceil(target - (float)sparse_spp);
    uint k = min(shadow_isqrt_ceil(extra), shadow_isqrt_floor(max_spp - sparse_spp));
    if (k == 0u) return;
    SceneRefs s = SCENE_REFS;
    uint rays = 0u;
    ShadowSums acc = {px[SHADOW_PIXEL_VISIBLE], px[SHADOW_PIXEL_WEIGHT],
                      px[SHADOW_PIXEL_OCCLUDED], px[SHADOW_PIXEL_SLOPE_MAX],
                      px[SHADOW_PIXEL_SLOPE_MIN], vload3(0, px + SHADOW_PIXEL_UNSHADOWED)};
    uint key = rng_sample_key(params->seed, pixel, SHADOW_SAMPLE_BASE + 1u);
    shadow_samples(&s, l, x, y, px[SHADOW_PIXEL_OBJECT], key, k, &acc, &rays);
    px[SHADOW_PIXEL_VISIBLE] = acc.visible;
    px[SHADOW_PIXEL_WEIGHT] = acc.weight;
    px[SHADOW_PIXEL_OCCLUDED] = acc.occluded;
    px[SHADOW_PIXEL_SAMPLES] += (float)(k * k);
    px[SHADOW_PIXEL_SLOPE_MAX] = acc.s1;
    px[SHADOW_PIXEL_SLOPE_MIN] = acc.s2;
    vstore3(acc.unshadowed, 0, px + SHADOW_PIXEL_UNSHADOWED);
    if (acc.occluded > 0.0f) px[SHADOW_PIXEL_SLOPE_SOURCE] = 1.0f;
    shadow_rays[pixel] = rays;
}

// The light-field pass of sheared filtering (Yan et al. 2015), over these passes' receivers.
#include "render/light_field.cl"

#endif

// The object each shadow plane's pixel-centre receiver lies on (NaN: none, or no shadow
// output): the first hits on it record the plane's light's terms (path_vertex, path.cl).
inline void shadow_receiver_objects(__global const float* shadow_pixels, size_t pixel,
                                    float* objects) {
    for (uint l = 0u; l < SHADOW_PLANES; ++l) {
        objects[l] = NAN;
#if OUTPUT_SHADOWS
        __global const float* centre =
            shadow_pixels + (pixel * SHADOW_PLANES + l) * SHADOW_PIXEL_FLOATS;
        if (centre[SHADOW_PIXEL_WEIGHT] > 0.0f) objects[l] = centre[SHADOW_PIXEL_OBJECT];
#endif
    }
}

#endif
