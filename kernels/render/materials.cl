// Surfaces and material evaluation (thesis §4.3.3).
#ifndef NOISEFREE_MATERIALS_CL
#define NOISEFREE_MATERIALS_CL

#include "arrays/trace.cl"
#include "render/sampling.cl"
#include "render/textures.cl"
#include "render/rng.cl"

// What the path tracer needs to know about a hit point.
typedef struct {
    float3 p;          // position
    float3 ng;         // geometric normal, facing the incoming ray
    float3 ns;         // shading normal, on the same side as ng
    float2 uv;
    uint material;
    int light;         // light index if the surface emits, else -1
    bool entering;     // the ray arrived from the side the stored normal points to (outside)
} Surface;

inline Surface surface_at(const SceneRefs* s, const Hit* hit, float3 o, float3 d) {
    Surface sf;
    sf.p = o + hit->t * d;
    float3 ng_raw, ns_raw;
    if (hit->kind == HIT_TRIANGLE) {
        __global const TriangleGeom* g = s->tri_geom + hit->prim;
        __global const TriangleShading* sh = s->tri_shading + hit->prim;
        float w = 1.0f - hit->u - hit->v;   // eq. 4.4
        ng_raw = normalize(cross(g->v1.xyz - g->v0.xyz, g->v2.xyz - g->v0.xyz));
        ns_raw = normalize(w * sh->n0.xyz + hit->u * sh->n1.xyz + hit->v * sh->n2.xyz);
        float2 uv0 = (float2)(sh->uv0.x, sh->uv0.y), uv1 = (float2)(sh->uv1.x, sh->uv1.y);
        float2 uv2 = (float2)(sh->uv2.x, sh->uv2.y);
        sf.uv = w * uv0 + hit->u * uv1 + hit->v * uv2;
        sf.material = sh->material;
        sf.light = sh->light;
    } else {
        __global const Sphere* sp = s->spheres + hit->prim;
        float3 c = (float3)(sp->center[0], sp->center[1], sp->center[2]);
        ng_raw = normalize(sf.p - c);
        ns_raw = ng_raw;
        // Spherical uv: u around the y axis, v from the south pole.
        sf.uv = (float2)(0.5f + atan2(ng_raw.x, -ng_raw.z) * (0.5f * INV_PI_F),
                         0.5f + asin(clamp(ng_raw.y, -1.0f, 1.0f)) * INV_PI_F);
        sf.material = sp->material;
        sf.light = sp->light;
    }
    sf.entering = dot(d, ng_raw) < 0.0f;
    sf.ng = sf.entering ? ng_raw : -ng_raw;
    sf.ns = (dot(ns_raw, sf.ng) < 0.0f) ? -ns_raw : ns_raw;
    return sf;
}

// The reflectance a filter sees as "texture" (Table 6.1): the diffuse albedo with its texture,
// the colour of mirrors and metals, the refraction colour of glass, the chromaticity of lights.
inline float3 surface_albedo(const SceneRefs* s, const Surface* sf) {
    __global const Material* m = s->materials + sf->material;
    float3 c = m->color.xyz;
    if (m->kind == MATERIAL_GLASS) return m->color2.xyz;
    if (m->kind == MATERIAL_EMITTER) {
        float3 e = m->emission.xyz;
        float mx = fmax(e.x, fmax(e.y, e.z));
        return mx > 0.0f ? e / mx : (float3)(0.0f);
    }
#if HAS_TEXTURES
    if (m->kind == MATERIAL_DIFFUSE && m->texture >= 0) {
        DEBUG_COUNT(s, COUNT_TEXTURE);
        c *= texture_bilinear(s, (uint)m->texture, sf->uv).xyz;
    }
#endif
    return c;
}

// The outcome of sampling a material.
typedef struct {
    float3 direction;
    float3 weight;       // multiplies the path throughput (f cos / pdf)
    float3 offset_normal;// the side of the surface the new ray leaves from
    bool specular;       // no light connection was made here: an emitter hit next counts
    bool absorbed;       // the path ends (sample below the surface)
} Scatter;

inline float3 reflect_dir(float3 d, float3 n) {
    return d - 2.0f * dot(d, n) * n;   // eq. 4.7 (printed as "N - (2 theta_i N)")
}

inline Scatter scatter(const SceneRefs* s, const Surface* sf, float3 d, float3 albedo,
                       uint key, uint bounce) {
    __global const Material* m = s->materials + sf->material;
    Scatter sc;
    sc.offset_normal = sf->ng;
    sc.specular = true;
    sc.absorbed = false;
    sc.weight = albedo;
    sc.direction = d;
    float r1 = rng_uniform(key, bounce, DIM_BSDF_U);
    float r2 = rng_uniform(key, bounce, DIM_BSDF_V);
    uint kind = m->kind;
#if HAS_DIFFUSE
    if (kind == MATERIAL_DIFFUSE) {
        DEBUG_COUNT(s, COUNT_DIFFUSE);
        // Lambertian: cosine sampling cancels cos/pdf, the weight is the albedo (Alg. 5).
        sc.direction = sample_diffuse(r1, r2, sf->ns);
        sc.specular = false;
        sc.absorbed = dot(sc.direction, sf->ng) <= 0.0f;
        return sc;
    }
#endif
#if HAS_SPECULAR
    if (kind == MATERIAL_SPECULAR) {
        DEBUG_COUNT(s, COUNT_SPECULAR);
        sc.direction = reflect_dir(d, sf->ns);
        sc.absorbed = dot(sc.direction, sf->ng) <= 0.0f;
        return sc;
    }
#endif
#if HAS_METAL
    if (kind == MATERIAL_METAL) {
        DEBUG_COUNT(s, COUNT_METAL);
        // Phong lobe around the mirror direction, sampled exactly, so f cos / pdf = colour.
        sc.direction = sample_phong_lobe(r1, r2, reflect_dir(d, sf->ns), m->exponent);
        sc.absorbed = dot(sc.direction, sf->ng) <= 0.0f;
        return sc;
    }
#endif
#if HAS_GLASS
    if (kind == MATERIAL_GLASS) {
        DEBUG_COUNT(s, COUNT_GLASS);
        // eqs. 4.8-4.10: Snell refraction, total internal reflection past the critical angle,
        // and Schlick's Fresnel approximation choosing reflection or refraction.
        float eta_i = sf->entering ? m->ior_outside : m->ior_inside;
        float eta_t = sf->entering ? m->ior_inside : m->ior_outside;
        if (eta_i == eta_t) {
            // Equal indices: there is no interface, so no reflection and no bending (Schlick's
            // formula would still reflect at grazing angles, and sin^2 theta_t rounds to 1
            // there and would fake total internal reflection).
            sc.weight = m->color2.xyz;
            sc.offset_normal = -sf->ng;
            return sc;
        }
        float cos_i = fmin(1.0f, -dot(d, sf->ns));
        float eta = eta_i / eta_t;
        float sin2_t = eta * eta * fmax(0.0f, 1.0f - cos_i * cos_i);   // eq. 4.9 squared
        float3 reflected = reflect_dir(d, sf->ns);
        if (sin2_t >= 1.0f) {                                          // eq. 4.10
            sc.direction = reflected;
            sc.weight = m->color.xyz;
            return sc;
        }
        float cos_t = sqrt(1.0f - sin2_t);
        float r0 = (eta_i - eta_t) / (eta_i + eta_t);
        r0 *= r0;
        float c = (eta_i <= eta_t) ? cos_i : cos_t;   // Schlick uses the angle in the rarer medium
        float k = 1.0f - c;
        float reflectance = r0 + (1.0f - r0) * k * k * k * k * k;
        if (rng_uniform(key, bounce, DIM_BSDF_LOBE) < reflectance) {
            sc.direction = reflected;
            sc.weight = m->color.xyz;
        } else {
            sc.direction = normalize(eta * d + (eta * cos_i - cos_t) * sf->ns);
            sc.weight = m->color2.xyz;
            sc.offset_normal = -sf->ng;
        }
        return sc;
    }
#endif
    // MATERIAL_EMITTER (and any kind compiled out, which the scene does not use).
    sc.absorbed = true;
    return sc;
}

#endif
