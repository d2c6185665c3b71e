// The megakernel path tracer (thesis §4.3, Algorithm 1, Fig. 4.7): one work-item per pixel,
// the whole path of each sample in one kernel, samples folded into the pixel's FilterVector.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/features.cl"
#include "render/rng.cl"
#include "arrays/trace.cl"
#include "render/camera.cl"
#include "render/materials.cl"
#include "render/lights.cl"
#include "render/film.cl"
#include "render/shadows.cl"
#include "render/indirect.cl"

inline float max3(float3 v) { return fmax(v.x, fmax(v.y, v.z)); }

// Adds light carried by the path. A path that reaches a light from vertex `bounce` (0 = the
// camera) is "direct" when it left at most from the first visible surface (bounce <= 1):
// emission seen directly, or light reaching the first surface straight from a light.
inline void add_light(PathSample* ps, uint bounce, float3 value) {
    if (bounce <= 1u) ps->direct += value; else ps->indirect += value;
}

// The light plane of light `light` in the shadow output's set `lights` (a bit mask; planes in
// increasing light order, src/render/shadows `LightPlanes`), or -1 when it has none.
inline int shadow_plane(uint lights, uint light) {
    if (light >= 32u || ((lights >> light) & 1u) == 0u) return -1;
    return (int)popcount(lights & ((1u << light) - 1u));
}

// Algorithm 1 for one sample. `bounce` counts the surfaces the path has left. With
// OUTPUT_SHADOWS, `shadow_lights` is the set of lights whose shadows are filtered (one plane
// each) and `shadow_objects[plane]` the object the pixel centre's receiver of that plane
// belongs to (NaN: none): the samples whose first hit is on it record the plane's light's
// terms (kernels/render/shadows.cl). Next-event estimation picks one light per vertex, so the
// planes' terms are disjoint parts of F.
// trace_path_from: the same from a given camera ray (o, d) (the lens-field pass of sheared
// depth of field, kernels/render/lens_field.cl, chooses the lens point).
inline PathSample trace_path_from(const SceneRefs* s, float3 o, float3 d, uint key,
                                  uint* ray_count, uint shadow_lights,
                                  const float* shadow_objects) {
    __constant const SceneParams* params = s->params;
    PathSample ps = path_sample_empty();
    float3 throughput = (float3)(1.0f);       // "weight" in Alg. 1
    bool count_emission = true;               // no light connection was made at the last vertex
#if OUTPUT_FEATURES
    bool want_albedo2 = true;
#endif
#if OUTPUT_SHADOWS
    uint on_receiver = 0u;                    // planes whose centre's receiver is the first hit
#endif
    for (uint bounce = 0u; bounce < params->max_vertices; ++bounce) {
#if HAS_RUSSIAN_ROULETTE
        // Alg. 1 lines 5-11, eq. 2.9: from rr_depth on, the path survives with probability
        // 1/m and its weight is multiplied by m. We take 1/m = max component of the weight,
        // capped at 0.95 so every path ends, so dim paths are cut and bright ones kept.
        if (bounce >= params->rr_depth) {
            float survive = fmin(0.95f, max3(throughput));
            if (!(rng_uniform(key, bounce, DIM_RUSSIAN_ROULETTE) < survive)) break;
            throughput /= survive;
        }
#else
        if (bounce >= params->rr_depth) break;  // without Russian roulette: a fixed depth
#endif
        Hit hit = intersect_closest(s, o, d, INFINITY, ray_count);
        if (hit.kind == HIT_NONE) {           // Alg. 1 lines 12-16: SampleSky
#if OUTPUT_POSITION || OUTPUT_SAMPLES || OUTPUT_LIGHT_FIELD
            if (bounce == 0u) ps.world1 = o + SKY_DEPTH * d;
#endif
#if HAS_ENV
            add_light(&ps, bounce, throughput * environment_radiance(s, d));
#endif
            break;
        }
        Surface sf = surface_at(s, &hit, o, d);
        __global const Material* m = s->materials + sf.material;
#if OUTPUT_POSITION || OUTPUT_SAMPLES || OUTPUT_LIGHT_FIELD
        if (bounce == 0u) {
            ps.world1 = sf.p;
            ps.hit = true;
        }
#endif
#if OUTPUT_SAMPLES
        if (bounce == 1u) {
            ps.world2 = sf.p;
            ps.normal2 = sf.ns;
        }
#endif
        if (m->kind == MATERIAL_EMITTER) {    // an implicit connection ends the path
            // Lights emit from their front (outside) only, matching sample_direct_light.
            if (count_emission && sf.entering) {
                add_light(&ps, bounce, throughput * m->emission.xyz);
#if OUTPUT_SHADOWS
                // Without light sampling, the shadow light's direct term arrives here.
                int plane = sf.light >= 0 ? shadow_plane(shadow_lights, (uint)sf.light) : -1;
                if (bounce == 1u && plane >= 0 && ((on_receiver >> plane) & 1u))
                    ps.shadow_direct[plane] += throughput * m->emission.xyz;
#endif
            }
#if OUTPUT_FEATURES
            if (bounce == 0u) {
                ps.depth = hit.t;
                ps.normal = sf.ns;
                ps.albedo = surface_albedo(s, &sf);
            }
#endif
            break;
        }
        float3 albedo = surface_albedo(s, &sf);
#if OUTPUT_FEATURES
        if (bounce == 0u) {
            ps.depth = hit.t;
            ps.normal = sf.ns;
            ps.albedo = albedo;
        } else if (want_albedo2 && m->kind == MATERIAL_DIFFUSE) {
            ps.albedo2 = albedo;              // texture2: first diffuse surface after bounce 0
            want_albedo2 = false;
        }
#endif
#if OUTPUT_SHADOWS && HAS_SPHERE_LIGHTS
        if (bounce == 0u && m->kind == MATERIAL_DIFFUSE && shadow_lights != 0u) {
            float object = hit_object(s, &hit);
            for (uint l = 0u, light = 0u; l < SHADOW_PLANES; ++l, ++light) {
                while (light < 32u && ((shadow_lights >> light) & 1u) == 0u) ++light;
                if (object != shadow_objects[l] || light >= params->light_count) continue;
                on_receiver |= 1u << l;
                // r of this sample (ShadowTerms.unshadowed), what the filtered term puts back.
                float3 u = shadow_unshadowed(s->lights + light, sf.p, sf.ns);
                ps.shadow_unshadowed[l] = albedo * u;
#if OUTPUT_LENS_SHADOWS
                ps.receiver_unshadowed[l] = u;
#endif
            }
#if OUTPUT_LENS_SHADOWS
            // The lens pass puts k(x, u) back on the filtered term (Yan et al.'s eq. 16).
            if (on_receiver != 0u) {
                ps.receiver = on_receiver;
                ps.receiver_albedo = albedo;
            }
#endif
        }
#endif
#if HAS_LIGHTS && NEXT_EVENT_ESTIMATION
        // Alg. 1 line 18: SampleLights, at diffuse hits only. The light count is checked at run
        // time too: the generic kernel (all effects compiled in) renders light-less scenes.
        if (m->kind == MATERIAL_DIFFUSE && params->light_count > 0u) {
            uint chosen;
            float3 li = sample_direct_light(s, sf.p, sf.ng, sf.ns, key, bounce, ray_count,
                                            &chosen);
            add_light(&ps, bounce + 1u, throughput * albedo * INV_PI_F * li);
#if OUTPUT_SHADOWS
            int plane = shadow_plane(shadow_lights, chosen);
            if (bounce == 0u && plane >= 0 && ((on_receiver >> plane) & 1u))
                ps.shadow_direct[plane] += throughput * albedo * INV_PI_F * li;
#endif
        }
#endif
        Scatter sc = scatter(s, &sf, d, albedo, key, bounce);   // Alg. 1 line 17: SampleBRDF
#if OUTPUT_FEATURES
        if (bounce == 0u && !sc.absorbed) ps.direction = sc.direction;
#endif
        if (sc.absorbed) break;
        throughput *= sc.weight;
#if NEXT_EVENT_ESTIMATION
        count_emission = sc.specular;
#endif
        o = offset_ray_origin(sf.p, sc.offset_normal, params->scene_size);
        d = sc.direction;
    }
    // Optional firefly clamp (off by default: it biases the image). Direct and indirect are
    // scaled together so their sum keeps its hue.
    float limit = params->sample_clamp;
    if (limit > 0.0f) {
        float peak = max3(ps.direct + ps.indirect);
        if (peak > limit) {
            float k = limit / peak;
            ps.direct *= k;
            ps.indirect *= k;
#if OUTPUT_SHADOWS
            for (uint l = 0u; l < SHADOW_PLANES; ++l) ps.shadow_direct[l] *= k;
#endif
        }
    }
    return ps;
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
// or launch draws it. The host binds every argument by name (src/render/mod.rs), the output
// buffers in the order of the generated RENDER_OUTPUT_PARAMS; they hold the tile's pixels.
__kernel void render(__constant const SceneParams* params,
                     __global const BvhNode* nodes,
                     __global const TriangleGeom* tri_geom,
                     __global const TriangleShading* tri_shading,
                     __global const Sphere* spheres,
                     __global const Material* materials,
                     __global const TextureInfo* textures,
                     __global const float4* texels,
                     __global const Light* lights,
                     __global const float* light_cdf,
                     RENDER_OUTPUT_PARAMS,
                     __global uint* ray_counts,
                     __global uint* debug_counters,     // DEBUG_COUNTERS builds only
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
    SceneRefs s = {params, nodes, tri_geom, tri_shading, spheres, materials,
                   textures, texels, lights, light_cdf, debug_counters};
    PixelStats stats;
    pixel_stats_load(&stats, RENDER_OUTPUT_ARGS, slot);
    float shadow_objects[SHADOW_PLANES];
    for (uint l = 0u; l < SHADOW_PLANES; ++l) shadow_objects[l] = NAN;
#if OUTPUT_SHADOWS
    // The shadow passes ran before the first path samples (whole images only: the host
    // refuses tiles with the shadow output, so slot == pixel).
    for (uint l = 0u; l < SHADOW_PLANES; ++l) {
        __global const float* centre =
            shadow_pixels + ((size_t)slot * SHADOW_PLANES + l) * SHADOW_PIXEL_FLOATS;
        if (centre[SHADOW_PIXEL_WEIGHT] > 0.0f) shadow_objects[l] = centre[SHADOW_PIXEL_OBJECT];
    }
#endif
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
