// AAF indirect light, the sampling side (Wang 2013 ch. 4, the passes of §3.4 with z_min /
// z_max in place of the slopes, after Mehta et al. 2013). Compiled into the megakernel's
// program with OUTPUT_INDIRECT; src/render/indirect says why each choice is what it is,
// src/render/indirect/bandlimit.rs is eqs. 4.4-4.6 in Rust, src/render/cpu/indirect.rs is this
// file in Rust.
//
// Two lobes share the passes and the per-pixel output (the seed's separate diffuse and
// specular buffers, §4.3: a pixel's centre receiver is one or the other): a diffuse receiver
// samples the cosine-weighted hemisphere, a metal receiver (with `glossy`) its Phong lobe
// around the mirror direction of the camera ray through the sample's point, as the megakernel
// samples it (kernels/render/materials.cl scatter). Either way f cos / pdf is the receiver's
// albedo (the metal's colour), so sum L_i / n is the demodulated indirect light.
//
// - indirect_sparse (pass 1): the pixel centre's first hit through the lens centre (the
//   receiver; its position, normal, object and pixel size d are what the filter's weights
//   use; its lobe's Omega_h^max of eq. 4.5) and sqrt_spp^2 indirect samples, one per stratum
//   of the lobe, each from its own random point of the pixel that lies on the receiver's
//   object: the demodulated indirect radiance sum L_i, the albedo sum, and the nearest and
//   farthest first-bounce hit (z_min, z_max).
// - indirect_adaptive (pass 2): n(x) of eq. 4.6 with the pixel's Omega, clamped to
//   [sparse, max], the samples beyond the sparse ones as one more square of strata (the shadow
//   passes' plan).
#ifndef NOISEFREE_INDIRECT_CL
#define NOISEFREE_INDIRECT_CL

#include "layout.cl"
#include "arrays/trace.cl"
#include "render/camera.cl"
#include "render/materials.cl"
#include "render/lights.cl"
#include "render/shadows.cl"
#include "render/bandlimit.cl"


// indirect_radiance also serves the sheared filter's GI field (kernels/render/gi_field.cl).
#if OUTPUT_INDIRECT || OUTPUT_LIGHT_FIELD

// The random numbers of the indirect passes use sample numbers no path sample reaches (and
// below the shadow passes' 0xFFFFFF00): one key per indirect sample.
#define INDIRECT_SAMPLE_BASE 0xF0000000u

// The light a path sample would count as indirect at the receiver: the radiance arriving at x
// from direction d (cosine-sampled there), without what reaches x straight from a light or
// the sky (that is direct light: kernels/render/pathtrace.cl add_light), following the path
// tracer's rules from the first bounce on (next-event estimation at diffuse vertices,
// emission after a specular scatter, Russian roulette from rr_depth). `z` is the first
// bounce's hit distance (INFINITY: none).
inline float3 indirect_radiance(const SceneRefs* s, float3 o, float3 d, uint key, float* z,
                                uint* rays) {
    __constant const SceneParams* params = s->params;
    float3 throughput = (float3)(1.0f);
    float3 l = (float3)(0.0f);
    bool count_emission = false;
    *z = INFINITY;
    for (uint bounce = 1u; bounce < params->max_vertices; ++bounce) {
#if HAS_RUSSIAN_ROULETTE
        if (bounce >= params->rr_depth) {
            float survive = fmin(0.95f, fmax(throughput.x, fmax(throughput.y, throughput.z)));
            if (!(rng_uniform(key, bounce, DIM_RUSSIAN_ROULETTE) < survive)) break;
            throughput /= survive;
        }
#else
        if (bounce >= params->rr_depth) break;
#endif
        Hit hit = intersect_closest(s, o, d, INFINITY, rays);
        if (hit.kind == HIT_NONE) {
#if HAS_ENV
            if (bounce >= 2u) l += throughput * environment_radiance(s, d);
#endif
            break;
        }
        if (bounce == 1u) *z = hit.t;
        Surface sf = surface_at(s, &hit, o, d);
        __global const Material* m = s->materials + sf.material;
        if (m->kind == MATERIAL_EMITTER) {
            if (bounce >= 2u && count_emission && sf.entering)
                l += throughput * m->emission.xyz;
            break;
        }
        float3 albedo = surface_albedo(s, &sf);
#if HAS_LIGHTS && NEXT_EVENT_ESTIMATION
        if (m->kind == MATERIAL_DIFFUSE && params->light_count > 0u) {
            uint chosen;
            float3 li = sample_direct_light(s, sf.p, sf.ng, sf.ns, key, bounce, rays, &chosen);
            l += throughput * albedo * INV_PI_F * li;
        }
#endif
        Scatter sc = scatter(s, &sf, d, albedo, key, bounce);
        if (sc.absorbed) break;
        throughput *= sc.weight;
#if NEXT_EVENT_ESTIMATION
        count_emission = sc.specular;
#else
        count_emission = true;
#endif
        o = offset_ray_origin(sf.p, sc.offset_normal, params->scene_size);
        d = sc.direction;
    }
    return l;
}

#endif

#if OUTPUT_INDIRECT

// Running sums of one pixel's indirect samples.
typedef struct {
    float3 irradiance, albedo;
    float weight, z_min, z_max, reflectors;
} IndirectSums;

// The lobe of a receiver: 1 glossy (a metal), 0 diffuse.
inline float indirect_lobe(const SceneRefs* s, const ShadowReceiver* r) {
    return s->materials[r->material].kind == MATERIAL_METAL ? 1.0f : 0.0f;
}

// k x k indirect samples of pixel (x, y), numbered from `first`, one per stratum of the
// receiver's lobe (the cosine-weighted hemisphere, or the Phong lobe around the mirror
// direction of the camera ray through the sample's point), each from its own random point of
// the pixel, kept when that point lies on the centre's receiver `object` with the centre's
// `lobe`.
inline void indirect_samples(const SceneRefs* s, uint x, uint y, uint pixel, float object,
                             float lobe, uint first, uint k, IndirectSums* acc, uint* rays) {
    float inv_k = 1.0f / (float)k;
    bool glossy = lobe > 0.0f;
    for (uint i = 0u; i < k; ++i) {
        for (uint j = 0u; j < k; ++j) {
            uint key = rng_sample_key(s->params->seed, pixel,
                                      INDIRECT_SAMPLE_BASE + first + i * k + j);
            ShadowReceiver q;
            float jx = rng_uniform(key, 0u, DIM_PIXEL_X), jy = rng_uniform(key, 0u, DIM_PIXEL_Y);
            if (!aaf_receiver(s, x, y, jx, jy, glossy, &q, rays) || q.object != object
                || indirect_lobe(s, &q) != lobe)
                continue;
            float u = ((float)i + rng_uniform(key, 0u, DIM_BSDF_U)) * inv_k;
            float v = ((float)j + rng_uniform(key, 0u, DIM_BSDF_V)) * inv_k;
            float3 d = glossy ? sample_phong_lobe(u, v, reflect_dir(q.d, q.ns),
                                                  s->materials[q.material].exponent)
                              : sample_diffuse(u, v, q.ns);
            acc->weight += 1.0f;
            acc->albedo += q.albedo;
            if (dot(d, q.ng) <= 0.0f) continue;   // below the geometric surface: absorbed
            float3 o = offset_ray_origin(q.p, q.ng, s->params->scene_size);
            float z;
            acc->irradiance += indirect_radiance(s, o, d, key, &z, rays);
            if (z < INFINITY) {
                acc->z_min = fmin(acc->z_min, z);
                acc->z_max = fmax(acc->z_max, z);
                acc->reflectors += 1.0f;
            }
        }
    }
}

// Pass 1. `glossy`: metal receivers are sampled too (their Phong lobe); `bandlimit` is the
// diffuse Omega_h^max of eq. 4.5.
__kernel void indirect_sparse(SCENE_PARAMS, __global float* indirect_pixels,
                              __global uint* indirect_rays, uint sqrt_spp, uint glossy,
                              float bandlimit) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    SceneRefs s = SCENE_REFS;
    __global float* px = indirect_pixels + (size_t)pixel * INDIRECT_PIXEL_FLOATS;
    for (uint i = 0u; i < INDIRECT_PIXEL_FLOATS; ++i) px[i] = 0.0f;
    uint rays = 0u;
    ShadowReceiver r;
    if (aaf_receiver(&s, x, y, 0.5f, 0.5f, glossy != 0u, &r, &rays)) {
        float lobe = indirect_lobe(&s, &r);
        IndirectSums acc = {(float3)(0.0f), (float3)(0.0f), 0.0f, INFINITY, 0.0f, 0.0f};
        indirect_samples(&s, x, y, pixel, r.object, lobe, 0u, sqrt_spp, &acc, &rays);
        bool z = acc.reflectors > 0.0f;
        px[INDIRECT_PIXEL_SAMPLES] = acc.weight > 0.0f ? (float)(sqrt_spp * sqrt_spp) : 0.0f;
        px[INDIRECT_PIXEL_WEIGHT] = acc.weight;
        px[INDIRECT_PIXEL_Z_MIN] = z ? acc.z_min : 0.0f;
        px[INDIRECT_PIXEL_Z_MAX] = z ? acc.z_max : 0.0f;
        px[INDIRECT_PIXEL_REFLECTORS] = acc.reflectors;
        px[INDIRECT_PIXEL_PIXEL_SIZE] = r.t * 2.0f * params->tan_half_fov
                                        / (float)params->image_height;
        px[INDIRECT_PIXEL_TARGET] = px[INDIRECT_PIXEL_SAMPLES];
        px[INDIRECT_PIXEL_OBJECT] = r.object;
        px[INDIRECT_PIXEL_BANDLIMIT] =
            lobe > 0.0f ? aaf_glossy_bandlimit(materials[r.material].exponent) : bandlimit;
        px[INDIRECT_PIXEL_LOBE] = lobe;
        vstore3(acc.irradiance, 0, px + INDIRECT_PIXEL_IRRADIANCE);
        vstore3(acc.albedo, 0, px + INDIRECT_PIXEL_ALBEDO);
        vstore3(r.p, 0, px + INDIRECT_PIXEL_POSITION);
        vstore3(r.ns, 0, px + INDIRECT_PIXEL_NORMAL);
    }
    indirect_rays[pixel] = rays;
}

// Pass 2: receivers with a reflector get n(x) of eq. 4.6 (with their lobe's Omega) clamped to
// [sparse_spp, max_spp], the samples beyond the sparse ones as one more k x k square
// (shadow_adaptive's plan).
__kernel void indirect_adaptive(SCENE_PARAMS, __global float* indirect_pixels,
                                __global uint* indirect_rays, uint sparse_spp, uint max_spp) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    indirect_rays[pixel] = 0u;
    __global float* px = indirect_pixels + (size_t)pixel * INDIRECT_PIXEL_FLOATS;
    if (!(px[INDIRECT_PIXEL_WEIGHT] > 0.0f) || !(px[INDIRECT_PIXEL_REFLECTORS] > 0.0f)) return;
    float n = aaf_indirect_count(px[INDIRECT_PIXEL_Z_MIN], px[INDIRECT_PIXEL_Z_MAX],
                                 px[INDIRECT_PIXEL_PIXEL_SIZE], px[INDIRECT_PIXEL_BANDLIMIT]);
    float target = fmin(fmax(n, (float)sparse_spp), (float)max_spp);
    px[INDIRECT_PIXEL_TARGET] = target;
    uint extra = (uint)ceil(target - (float)sparse_spp);
    uint k = min(shadow_isqrt_ceil(extra), shadow_isqrt_floor(max_spp - sparse_spp));
    if (k == 0u) return;
    SceneRefs s = SCENE_REFS;
    uint rays = 0u;
    IndirectSums acc = {vload3(0, px + INDIRECT_PIXEL_IRRADIANCE),
                        vload3(0, px + INDIRECT_PIXEL_ALBEDO), px[INDIRECT_PIXEL_WEIGHT],
                        px[INDIRECT_PIXEL_Z_MIN], px[INDIRECT_PIXEL_Z_MAX],
                        px[INDIRECT_PIXEL_REFLECTORS]};
    indirect_samples(&s, x, y, pixel, px[INDIRECT_PIXEL_OBJECT], px[INDIRECT_PIXEL_LOBE],
                     sparse_spp, k, &acc, &rays);
    vstore3(acc.irradiance, 0, px + INDIRECT_PIXEL_IRRADIANCE);
    vstore3(acc.albedo, 0, px + INDIRECT_PIXEL_ALBEDO);
    px[INDIRECT_PIXEL_WEIGHT] = acc.weight;
    px[INDIRECT_PIXEL_SAMPLES] += (float)(k * k);
    indirect_rays[pixel] = rays;
}

#endif

#endif
