// The per-pixel output stage: what one path sample leaves behind, and how it is folded into the
// pixel's running means (the FilterVector F, eq. 6.1, with the mean update of eq. 6.5).
// Statistics stages added later (variances, sample vectors) hook in at film_accumulate.
#ifndef NOISEFREE_FILM_CL
#define NOISEFREE_FILM_CL

#include "layout.cl"
#include "features.cl"

// One path's contribution and first-hit features.
typedef struct {
    float3 direct;     // emission seen directly + light reaching the first surface from a light
    float3 indirect;   // everything else
    float depth;       // distance to the first hit, SKY_DEPTH if the camera ray escapes
    float3 normal;     // first-hit shading normal (facing the camera), 0 for sky
    float3 albedo;     // first-hit albedo, 0 for sky
    float3 albedo2;    // albedo of the first diffuse surface after the first bounce, 0 if none
    float3 direction;  // direction leaving the first hit, 0 if none
} PathSample;

inline PathSample path_sample_empty(void) {
    PathSample ps;
    ps.direct = (float3)(0.0f);
    ps.indirect = (float3)(0.0f);
    ps.depth = SKY_DEPTH;
    ps.normal = (float3)(0.0f);
    ps.albedo = (float3)(0.0f);
    ps.albedo2 = (float3)(0.0f);
    ps.direction = (float3)(0.0f);
    return ps;
}

// Packs a sample in FilterVector order (src/layout.rs: direct, indirect, depth, normal,
// albedo, albedo2).
inline float16 filter_vector_of(const PathSample* ps) {
    return (float16)(ps->direct.x, ps->direct.y, ps->direct.z,
                     ps->indirect.x, ps->indirect.y, ps->indirect.z,
                     ps->depth,
                     ps->normal.x, ps->normal.y, ps->normal.z,
                     ps->albedo.x, ps->albedo.y, ps->albedo.z,
                     ps->albedo2.x, ps->albedo2.y, ps->albedo2.z);
}

// Eq. 6.5: mu_n = mu_{n-1} + (x_n - mu_{n-1}) / n, on all sixteen components at once.
// n is the sample's 1-based count in the pixel.
inline float16 running_mean(float16 mean, float16 x, float n) {
    return mean + (x - mean) / n;
}

inline void film_accumulate(float16* mean, const PathSample* ps, uint n) {
    float16 x = filter_vector_of(ps);
#if !OUTPUT_FEATURES
    // Only the light is wanted: the feature lanes stay at their (zero) initial value.
    x.s6789 = (float4)(0.0f);
    x.sABCD = (float4)(0.0f);
    x.sEF = (float2)(0.0f);
#endif
    *mean = running_mean(*mean, x, (float)n);
}

#endif
