// Explicit light connections ("direct light sampling v1.0", §2.4.2): at a diffuse hit, one
// light is picked with probability proportional to its power, a point on it is sampled and a
// shadow ray decides visibility.
#ifndef NOISEFREE_LIGHTS_CL
#define NOISEFREE_LIGHTS_CL

#include "arrays/trace.cl"
#include "render/sampling.cl"
#include "render/rng.cl"

// A light connection before its shadow ray is traced: the ray (o, d) to t_max and the value
// the connection carries if nothing lies on it. `valid` is false when the sample cannot carry
// light whatever the shadow ray finds (no ray is traced then).
typedef struct {
    float3 o, d;
    float t_max;
    float3 value;
    bool valid;
} LightConnection;

// Makes *c a connection that carries no light. Returns false (connect_light's verdict).
inline bool no_connection(LightConnection* c) {
    c->o = (float3)(0.0f);
    c->d = (float3)(0.0f);
    c->t_max = 0.0f;
    c->value = (float3)(0.0f);
    c->valid = false;
    return false;
}

// The connection's light if its shadow ray is unoccluded, else 0.
inline float3 trace_connection(const SceneRefs* s, const LightConnection* c, uint* ray_count) {
    if (!c->valid || occluded(s, c->o, c->d, c->t_max, ray_count)) return (float3)(0.0f);
    return c->value;
}

#if HAS_LIGHTS

// Shadow rays stop this fraction short of the light so the light's own surface never
// occludes itself; relative, so it works at any scene scale.
#define SHADOW_RAY_SHORTEN 0.9999f

// Index of the light whose cdf interval holds u (cdf[i] = sum of pmf[0..=i]).
inline uint select_light(const SceneRefs* s, float u) {
    uint lo = 0u, hi = s->params->light_count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) >> 1;
        if (u < s->light_cdf[mid]) hi = mid; else lo = mid + 1u;
    }
    return lo;
}

// One sampled light seen from p: the radiance it sends, divided by the sample's probability
// density (solid angle, including the light choice) and multiplied by cos at p (the estimator
// of integral L_e cos dw; the caller multiplies by the throughput and albedo / pi), and the
// shadow ray that decides whether it arrives, into *conn (returns conn->valid). `chosen` gets
// the index of the light picked. Split from the shadow ray so that the wavefront tracer
// (kernels/render/wavefront.cl) can trace all shadow rays of a bounce in one kernel (Laine et
// al. 2013, §4). The connection is written through a pointer, not returned: PoCL returned the
// struct through the stack and its copy stalled on store forwarding (35 % of path_vertex).
inline bool connect_light(const SceneRefs* s, float3 surface_p, float3 ng, float3 ns, uint key,
                          uint bounce, uint* chosen, LightConnection* conn) {
    // The shadow ray starts at the offset origin, so the light is sampled from there too:
    // directions aimed from the unmoved point would, at grazing angles, cross the light's
    // plane before the sampled point (an offset of 6e-5 under a ceiling moved the hit on a
    // lamp 1 cm below it by 0.6% of the distance) and the light would shadow itself.
    float3 p = offset_ray_origin(surface_p, ng, s->params->scene_size);
    uint index = select_light(s, rng_uniform(key, bounce, DIM_LIGHT_SELECT));
    *chosen = index;
    __global const Light* light = s->lights + index;
    float r1 = rng_uniform(key, bounce, DIM_LIGHT_U);
    float r2 = rng_uniform(key, bounce, DIM_LIGHT_V);
    float3 dir;
    float dist;
    float inv_pdf;   // 1 / (pdf in solid angle), without the light choice
#if HAS_SPHERE_LIGHTS
    if (light->kind == LIGHT_SPHERE) {
        DEBUG_COUNT(s, COUNT_SPHERE_LIGHT);
        // Uniform directions in the cone the sphere subtends (solid-angle sampling).
        float3 c = light->p0.xyz;
        float r = light->p0.w;
        float3 to_c = c - p;
        float d2 = dot(to_c, to_c);
        float r2s = r * r;
        if (d2 <= r2s) return no_connection(conn);   // inside the light: it emits outwards only
        float dc = sqrt(d2);
        float sin2_max = r2s / d2;
        float cos_max = sqrt(fmax(0.0f, 1.0f - sin2_max));
        float one_minus_cos_max = sin2_max / (1.0f + cos_max);   // exact for tiny cones
        dir = sample_cone(r1, r2, to_c / dc, one_minus_cos_max);
        float t = ray_sphere(p, dir, c, r, 0.0f, INFINITY);
        dist = (t > 0.0f) ? t : dc;                 // a grazing sample may miss by rounding
        inv_pdf = TWO_PI_F * one_minus_cos_max;
    } else
#endif
    {
#if HAS_TRIANGLE_LIGHTS
        DEBUG_COUNT(s, COUNT_TRIANGLE_LIGHT);
        // Uniform point on the triangle, converted to solid angle: pdf = d^2 / (cos_l area).
        float2 b = sample_triangle(r1, r2);
        float3 v0 = light->p0.xyz, v1 = light->p1.xyz, v2 = light->p2.xyz;
        float3 q = v0 + b.x * (v1 - v0) + b.y * (v2 - v0);
        float3 to_q = q - p;
        float d2 = dot(to_q, to_q);
        if (!(d2 > 0.0f)) return no_connection(conn);
        dist = sqrt(d2);
        dir = to_q / dist;
        float3 nl = normalize(cross(v1 - v0, v2 - v0));
        // Emissive triangles emit from their front face (counter-clockwise winding), like
        // pbrt's one-sided area lights; the back is dark.
        float cos_l = -dot(nl, dir);
        if (cos_l <= 0.0f) return no_connection(conn);
        inv_pdf = cos_l * light->area / d2;
#else
        return no_connection(conn);
#endif
    }
    float cos_s = dot(ns, dir);
    if (cos_s <= 0.0f || dot(ng, dir) <= 0.0f) return no_connection(conn);
    conn->o = p;
    conn->d = dir;
    conn->t_max = dist * SHADOW_RAY_SHORTEN;
    conn->value = light->emission.xyz * (cos_s * inv_pdf / light->pmf);
    conn->valid = true;
    return true;
}

// connect_light with its shadow ray traced at once (the megakernel's form).
inline float3 sample_direct_light(const SceneRefs* s, float3 surface_p, float3 ng, float3 ns,
                                  uint key, uint bounce, uint* ray_count, uint* chosen) {
    LightConnection c;
    connect_light(s, surface_p, ng, ns, key, bounce, chosen, &c);
    return trace_connection(s, &c, ray_count);
}

#endif

#endif
