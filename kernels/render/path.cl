// One path of Algorithm 1 (thesis §4.3) as a state and the steps between its ray queries, so
// that the megakernel (kernels/render/pathtrace.cl) and the wavefront tracer
// (kernels/render/wavefront.cl, Laine, Karras & Aila 2013) run the same float operations in
// the same order and write the same bytes. The megakernel runs the steps in a loop in one
// work-item; the wavefront tracer stores the state between kernels, one kernel per step.
//
//   path_begin
//   while (path_survives)                    Alg. 1 lines 5-11 (Russian roulette)
//       hit = intersect_closest(o, d)        the extension ray
//       path_vertex(hit)                     lines 12-18: emission, light sample, BSDF sample;
//                                            the megakernel traces the light sample's shadow
//                                            ray inside it, the wavefront tracer after it
//       (path_add_connection)                the shadow ray's light, added before the next
//                                            vertex adds anything
//   path_finish                              the optional clamp
#ifndef NOISEFREE_PATH_CL
#define NOISEFREE_PATH_CL

#include "layout.cl"
#include "render/features.cl"
#include "render/rng.cl"
#include "arrays/trace.cl"
#include "render/materials.cl"
#include "render/lights.cl"
#include "render/film.cl"
#include "render/shadows.cl"

#define PATH_COUNT_EMISSION 1u     // no light connection was made at the last vertex
#define PATH_WANT_ALBEDO2 2u       // texture2 not found yet
#define PATH_CONNECTION 4u         // a light connection waits for its shadow ray

typedef struct {
    PathSample ps;             // what the path has gathered
    float3 o, d;               // the next extension ray
    float3 throughput;         // "weight" in Alg. 1
    float3 connection_weight;  // the waiting connection: throughput x albedo / pi at its vertex
    uint bounce;               // surfaces the path has left: the next hit is vertex `bounce`
    uint flags;                // PATH_*
    uint key;                  // the sample's random-number key
    uint on_receiver;          // shadow planes whose centre's receiver is the first hit
    uint connection_vertex;    // the vertex that made the waiting connection
    int connection_plane;      // the waiting connection's shadow plane, -1: none
} PathState;

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

inline void path_begin(PathState* st, float3 o, float3 d, uint key) {
    st->ps = path_sample_empty();
    st->o = o;
    st->d = d;
    st->throughput = (float3)(1.0f);
    st->connection_weight = (float3)(0.0f);
    st->bounce = 0u;
    st->flags = PATH_COUNT_EMISSION | PATH_WANT_ALBEDO2;
    st->key = key;
    st->on_receiver = 0u;
    st->connection_vertex = 0u;
    st->connection_plane = -1;
}

// Whether a path may trace vertex `vertex` at all: within the vertex cap and, without Russian
// roulette, below the fixed depth (rr_depth is then the path's last vertex + 1).
inline bool path_may_continue(__constant const SceneParams* params, uint vertex) {
    if (vertex >= params->max_vertices) return false;
#if !HAS_RUSSIAN_ROULETTE
    if (vertex >= params->rr_depth) return false;   // without Russian roulette: a fixed depth
#endif
    return true;
}

// Whether the path goes on to trace vertex st->bounce: within the vertex limit and, from
// rr_depth on, through Russian roulette (Alg. 1 lines 5-11, eq. 2.9: the path survives with
// probability 1/m and its weight is multiplied by m; 1/m = the weight's largest component,
// capped at 0.95 so every path ends, so dim paths are cut and bright ones kept).
inline bool path_survives(const SceneRefs* s, PathState* st) {
    __constant const SceneParams* params = s->params;
    if (!path_may_continue(params, st->bounce)) return false;
#if HAS_RUSSIAN_ROULETTE
    if (st->bounce >= params->rr_depth) {
        float survive = fmin(0.95f, max3(st->throughput));
        if (!(rng_uniform(st->key, st->bounce, DIM_RUSSIAN_ROULETTE) < survive)) return false;
        st->throughput /= survive;
    }
#endif
    return true;
}

// Adds the waiting light connection, with `value` its light (0 when its shadow ray was
// occluded): the megakernel's `throughput * albedo / pi * li` at the vertex that made it.
inline void path_add_connection(PathState* st, float3 value) {
    if (!(st->flags & PATH_CONNECTION)) return;
    st->flags &= ~PATH_CONNECTION;
    float3 light = st->connection_weight * value;
    add_light(&st->ps, st->connection_vertex + 1u, light);
#if OUTPUT_SHADOWS
    int plane = st->connection_plane;
    if (st->connection_vertex == 0u && plane >= 0 && ((st->on_receiver >> plane) & 1u))
        st->ps.shadow_direct[plane] += light;
#endif
}

// Vertex st->bounce of the path at `hit` (Alg. 1 lines 12-18). Returns whether the path goes
// on; if so, st->o and st->d hold the next ray and st->bounce counts the vertex. The light
// sample's shadow ray is in *connection: with `ray_count` (the megakernel) it is traced at
// once and its light added; with 0 (the wavefront tracer) PATH_CONNECTION stays set, even
// when the path ends here, and the caller traces it and calls path_add_connection before
// anything else. (Tracing it here rather than in the megakernel's loop after the call:
// 0.89-0.92x of the old megakernel's speed on Grids, Curved and Toasters became 0.97-1.00x.)
// With OUTPUT_SHADOWS, `shadow_lights` is the set of lights whose shadows are filtered (one
// plane each) and `shadow_objects[plane]` the object the pixel centre's receiver of that
// plane belongs to (NaN: none): the samples whose first hit is on it record the plane's
// light's terms (kernels/render/shadows.cl). Next-event estimation picks one light per
// vertex, so the planes' terms are disjoint parts of F.
inline bool path_vertex(const SceneRefs* s, PathState* st, const Hit* hit,
                        uint shadow_lights, const float* shadow_objects,
                        LightConnection* connection, uint* ray_count) {
    __constant const SceneParams* params = s->params;
    PathSample* ps = &st->ps;
    uint bounce = st->bounce;
    float3 o = st->o, d = st->d;
    if (hit->kind == HIT_NONE) {              // Alg. 1 lines 12-16: SampleSky
#if OUTPUT_POSITION || OUTPUT_SAMPLES || OUTPUT_LIGHT_FIELD
        if (bounce == 0u) ps->world1 = o + SKY_DEPTH * d;
#endif
#if HAS_ENV
        add_light(ps, bounce, st->throughput * environment_radiance(s, d));
#endif
        return false;
    }
    Surface sf = surface_at(s, hit, o, d);
    __global const Material* m = s->materials + sf.material;
#if OUTPUT_POSITION || OUTPUT_SAMPLES || OUTPUT_LIGHT_FIELD
    if (bounce == 0u) {
        ps->world1 = sf.p;
        ps->hit = true;
    }
#endif
#if OUTPUT_SAMPLES
    if (bounce == 1u) {
        ps->world2 = sf.p;
        ps->normal2 = sf.ns;
    }
#endif
    if (m->kind == MATERIAL_EMITTER) {        // an implicit connection ends the path
        // Lights emit from their front (outside) only, matching connect_light.
        if ((st->flags & PATH_COUNT_EMISSION) && sf.entering) {
            add_light(ps, bounce, st->throughput * m->emission.xyz);
#if OUTPUT_EMISSION
            if (bounce == 0u) ps->emitted.xyz = st->throughput * m->emission.xyz;
#endif
#if OUTPUT_SHADOWS
            // Without light sampling, the shadow light's direct term arrives here.
            int plane = sf.light >= 0 ? shadow_plane(shadow_lights, (uint)sf.light) : -1;
            if (bounce == 1u && plane >= 0 && ((st->on_receiver >> plane) & 1u))
                ps->shadow_direct[plane] += st->throughput * m->emission.xyz;
#endif
        }
#if OUTPUT_FEATURES
        if (bounce == 0u) {
            ps->depth = hit->t;
            ps->normal = sf.ns;
            ps->albedo = surface_albedo(s, &sf);
        }
#endif
#if OUTPUT_EMISSION
        if (bounce == 0u) ps->emitted.w = 1.0f;
#endif
        return false;
    }
    float3 albedo = surface_albedo(s, &sf);
#if OUTPUT_FEATURES
    if (bounce == 0u) {
        ps->depth = hit->t;
        ps->normal = sf.ns;
        ps->albedo = albedo;
    } else if ((st->flags & PATH_WANT_ALBEDO2) && m->kind == MATERIAL_DIFFUSE) {
        ps->albedo2 = albedo;                 // texture2: first diffuse surface after bounce 0
        st->flags &= ~PATH_WANT_ALBEDO2;
    }
#endif
#if OUTPUT_SHADOWS && HAS_SPHERE_LIGHTS
    if (bounce == 0u && m->kind == MATERIAL_DIFFUSE && shadow_lights != 0u) {
        float object = hit_object(s, hit);
        for (uint l = 0u, light = 0u; l < SHADOW_PLANES; ++l, ++light) {
            while (light < 32u && ((shadow_lights >> light) & 1u) == 0u) ++light;
            if (object != shadow_objects[l] || light >= params->light_count) continue;
            st->on_receiver |= 1u << l;
            // r of this sample (ShadowTerms.unshadowed), what the filtered term puts back.
            float3 u = shadow_unshadowed(s->lights + light, sf.p, sf.ns);
            ps->shadow_unshadowed[l] = albedo * u;
#if OUTPUT_LENS_SHADOWS
            ps->receiver_unshadowed[l] = u;
#endif
        }
#if OUTPUT_LENS_SHADOWS
        // The lens pass puts k(x, u) back on the filtered term (Yan et al.'s eq. 16).
        if (st->on_receiver != 0u) {
            ps->receiver = st->on_receiver;
            ps->receiver_albedo = albedo;
        }
#endif
    }
#endif
#if HAS_LIGHTS && NEXT_EVENT_ESTIMATION
    // Alg. 1 line 18: SampleLights, at diffuse hits only. The light count is checked at run
    // time too: the generic kernel (all effects compiled in) renders light-less scenes.
    if (m->kind == MATERIAL_DIFFUSE && params->light_count > 0u) {
        uint chosen;
        connect_light(s, sf.p, sf.ng, sf.ns, st->key, bounce, &chosen, connection);
        st->flags |= PATH_CONNECTION;
        st->connection_vertex = bounce;
        st->connection_weight = st->throughput * albedo * INV_PI_F;
#if OUTPUT_SHADOWS
        st->connection_plane = shadow_plane(shadow_lights, chosen);
#endif
        if (ray_count) path_add_connection(st, trace_connection(s, connection, ray_count));
    }
#endif
    // The last vertex a path can have (path_survives would refuse the next one whatever the
    // BSDF sample: the vertex cap, or the fixed depth without Russian roulette) needs no BSDF
    // sample unless the features record its direction: nothing reads it, and the random
    // numbers are counters, so skipping it leaves every output the same bytes. On the
    // direct-light scenes (max_depth = 1) it was a sixth of the kernel's time (perf).
    if (!path_may_continue(params, bounce + 1u)
#if OUTPUT_FEATURES
        && bounce != 0u
#endif
    )
        return false;
    Scatter sc = scatter(s, &sf, d, albedo, st->key, bounce);   // Alg. 1 line 17: SampleBRDF
#if OUTPUT_FEATURES
    if (bounce == 0u && !sc.absorbed) ps->direction = sc.direction;
#endif
    if (sc.absorbed) return false;
    st->throughput *= sc.weight;
#if NEXT_EVENT_ESTIMATION
    if (sc.specular) st->flags |= PATH_COUNT_EMISSION; else st->flags &= ~PATH_COUNT_EMISSION;
#endif
    st->o = offset_ray_origin(sf.p, sc.offset_normal, params->scene_size);
    st->d = sc.direction;
    st->bounce = bounce + 1u;
    return true;
}

// Ends the path: the optional firefly clamp (off by default: it biases the image). Direct and
// indirect are scaled together so their sum keeps its hue.
inline void path_finish(const SceneRefs* s, PathState* st) {
    float limit = s->params->sample_clamp;
    if (limit > 0.0f) {
        PathSample* ps = &st->ps;
        float peak = max3(ps->direct + ps->indirect);
        if (peak > limit) {
            float k = limit / peak;
            ps->direct *= k;
            ps->indirect *= k;
#if OUTPUT_SHADOWS
            for (uint l = 0u; l < SHADOW_PLANES; ++l) ps->shadow_direct[l] *= k;
#endif
#if OUTPUT_EMISSION
            ps->emitted.xyz *= k;
#endif
        }
    }
}

#endif
