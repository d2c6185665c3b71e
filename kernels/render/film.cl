// The per-pixel output stage: what one path sample leaves behind, and how it is folded into the
// pixel's statistics (thesis §6.2.1-6.2.2): the running means of the FilterVector F (eq. 6.1)
// and, when a filter needs them, Welford's running S_n of the scene features (the variance
// GBuffer GB, eq. 6.2). Later stages (sample vectors) hook in at film_accumulate.
#ifndef NOISEFREE_FILM_CL
#define NOISEFREE_FILM_CL

#include "layout.cl"
#include "render/features.cl"
#include "render/rng.cl"

// Lanes of F (src/layout.rs FilterVector).
#define F_DIRECT 0
#define F_INDIRECT 3
#define F_DEPTH 6
#define F_NORMAL 7
#define F_ALBEDO 10
#define F_ALBEDO2 13
// Lanes of GB (src/layout.rs GBuffer).
#define GB_DEPTH 0
#define GB_NORMAL 1
#define GB_ALBEDO 4
#define GB_DIRECTION 7
#define GB_ALBEDO2 10
// Lanes of the statistics state (src/layout.rs StatsState).
#define ST_DIRECTION 0
#define ST_DEPTH_SHIFT 3
#define ST_DEPTH_MEAN 4
#define ST_COMPENSATION 8
#define ST_FLOATS 24

// One path's contribution and first-hit features.
typedef struct {
    float3 direct;     // emission seen directly + light reaching the first surface from a light
    float3 indirect;   // everything else
    float depth;       // distance to the first hit, SKY_DEPTH if the camera ray escapes
    float3 normal;     // first-hit shading normal (facing the camera), 0 for sky
    float3 albedo;     // first-hit albedo, 0 for sky
    float3 albedo2;    // albedo of the first diffuse surface after the first bounce, 0 if none
    float3 direction;  // direction leaving the first hit, 0 if none
#if OUTPUT_SAMPLES
    float3 world1;     // first hit (camera origin + SKY_DEPTH x direction for sky)
    float3 world2;     // second hit, 0 if none
    float3 normal2;    // shading normal at the second hit, 0 if none
#endif
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
#if OUTPUT_SAMPLES
    ps.world1 = (float3)(0.0f);
    ps.world2 = (float3)(0.0f);
    ps.normal2 = (float3)(0.0f);
#endif
    return ps;
}

// A pixel's statistics while a launch works on it (private memory; loaded once, stored once).
typedef struct {
    float mean[16];   // F
#if OUTPUT_VARIANCE
    float s[16];      // GB: S_n per feature component
    float state[ST_FLOATS];   // StatsState (its last 16 floats: the compensation of s)
#endif
} PixelStats;

inline void pixel_stats_load(PixelStats* p, __global const float* f, __global const float* gb,
                             __global const float* st, uint pixel) {
    vstore16(vload16(pixel, f), 0, p->mean);
#if OUTPUT_VARIANCE
    vstore16(vload16(pixel, gb), 0, p->s);
    __global const float* sp = st + (size_t)pixel * ST_FLOATS;
    vstore8(vload8(0, sp), 0, p->state);
    vstore16(vload16(0, sp + 8), 0, p->state + 8);
#endif
}

inline void pixel_stats_store(const PixelStats* p, __global float* f, __global float* gb,
                              __global float* st, uint pixel) {
    vstore16(vload16(0, p->mean), pixel, f);
#if OUTPUT_VARIANCE
    vstore16(vload16(0, p->s), pixel, gb);
    __global float* sp = st + (size_t)pixel * ST_FLOATS;
    vstore8(vload8(0, p->state), 0, sp);
    vstore16(vload16(0, p->state + 8), 0, sp + 8);
#endif
}

// Eq. 6.5: mu_n = mu_{n-1} + (x_n - mu_{n-1}) / n. n is the 1-based sample count.
inline void running_mean(float* mean, float x, float n) {
    *mean += (x - *mean) / n;
}

// Eqs. 6.5 and 6.6 (Knuth, after Welford): the running mean and
// S_n = S_{n-1} + (x_n - mu_{n-1}) (x_n - mu_n), with S_1 = 0 (mu_1 = x_1 makes the product 0).
// This is the one update every statistic uses. Each term is a product of two deviations from
// the mean, so S_n never goes negative and a constant stream gives exactly 0.
//
// Where float32 loses accuracy, and what is done about it:
// - Large offsets (depth in millimetres, or 1e4 with a spread of 0.1): the deviations x - mu
//   are small next to mu, mu has an absolute rounding error of half an ulp of mu (5e-4 at 1e4),
//   and once (x - mu) / n drops below that, mu stops moving ("stagnation", after a few hundred
//   samples): S_n then grows around a wrong mean and overestimates the variance by
//   (mu - mean)^2 per sample. So depth runs on shifted data x - K, K the pixel's first sample
//   (in StatsState); F.depth = K + mean(x - K). Normals, albedos and directions are bounded by
//   1 and need no shift.
// - Long runs with outliers (fireflies): after one sample 10^4 times the mean, S_n is ~5e10
//   and its ulp 4096, so the ordinary terms (~25) that follow vanish when added. S_n is
//   therefore summed with Kahan's compensation (the compensation lives in StatsState).
// tests/statistics.rs and tests/hard_cases_statistics.rs check both against float64.
inline void welford(float* mean, float* s, float* compensation, float x, float n) {
    float delta = x - *mean;
    running_mean(mean, x, n);
    float term = delta * (x - *mean) - *compensation;
    float sum = *s + term;
    *compensation = (sum - *s) - term;
    *s = sum;
}

inline void accumulate3(PixelStats* p, int f_lane, int gb_lane, float3 x, float n) {
#if OUTPUT_VARIANCE
    float* c = p->state + ST_COMPENSATION;
    welford(&p->mean[f_lane], &p->s[gb_lane], &c[gb_lane], x.x, n);
    welford(&p->mean[f_lane + 1], &p->s[gb_lane + 1], &c[gb_lane + 1], x.y, n);
    welford(&p->mean[f_lane + 2], &p->s[gb_lane + 2], &c[gb_lane + 2], x.z, n);
#else
    running_mean(&p->mean[f_lane], x.x, n);
    running_mean(&p->mean[f_lane + 1], x.y, n);
    running_mean(&p->mean[f_lane + 2], x.z, n);
#endif
}

// Folds sample number n (1-based) of this pixel into its statistics.
inline void film_accumulate(PixelStats* p, const PathSample* ps, uint count) {
    float n = (float)count;
    // Colour: means only (GB holds no colour variance, eq. 6.2).
    running_mean(&p->mean[F_DIRECT], ps->direct.x, n);
    running_mean(&p->mean[F_DIRECT + 1], ps->direct.y, n);
    running_mean(&p->mean[F_DIRECT + 2], ps->direct.z, n);
    running_mean(&p->mean[F_INDIRECT], ps->indirect.x, n);
    running_mean(&p->mean[F_INDIRECT + 1], ps->indirect.y, n);
    running_mean(&p->mean[F_INDIRECT + 2], ps->indirect.z, n);
#if OUTPUT_FEATURES
#if OUTPUT_VARIANCE
    if (count == 1u) {
        p->state[ST_DEPTH_SHIFT] = ps->depth;
        p->state[ST_DEPTH_MEAN] = 0.0f;
    }
    float* c = p->state + ST_COMPENSATION;
    welford(&p->state[ST_DEPTH_MEAN], &p->s[GB_DEPTH], &c[GB_DEPTH], ps->depth - p->state[ST_DEPTH_SHIFT], n);
    p->mean[F_DEPTH] = p->state[ST_DEPTH_SHIFT] + p->state[ST_DEPTH_MEAN];
    welford(&p->state[ST_DIRECTION], &p->s[GB_DIRECTION], &c[GB_DIRECTION], ps->direction.x, n);
    welford(&p->state[ST_DIRECTION + 1], &p->s[GB_DIRECTION + 1], &c[GB_DIRECTION + 1], ps->direction.y, n);
    welford(&p->state[ST_DIRECTION + 2], &p->s[GB_DIRECTION + 2], &c[GB_DIRECTION + 2], ps->direction.z, n);
#else
    running_mean(&p->mean[F_DEPTH], ps->depth, n);
#endif
    accumulate3(p, F_NORMAL, GB_NORMAL, ps->normal, n);
    accumulate3(p, F_ALBEDO, GB_ALBEDO, ps->albedo, n);
    accumulate3(p, F_ALBEDO2, GB_ALBEDO2, ps->albedo2, n);
#endif
}

#if OUTPUT_SAMPLES
// Random Parameter Filtering's sample vector (thesis §5.1.1, Table 5.1; src/layout.rs
// SampleVector): screen position, random parameters (lens u, v, time 0, first-bounce
// direction), world position and normal of the first and second hits, first-hit texture, and
// the sample's colour. The pixel jitter and lens numbers are drawn again from the counter-based
// generator: the same numbers the camera used.
inline void write_sample_vector(__global float* out, uint index, uint x, uint y, uint key,
                                const PathSample* ps, bool lens) {
    __global float* v = out + (size_t)index * 26u;
    v[0] = (float)x + rng_uniform(key, 0u, DIM_PIXEL_X);
    v[1] = (float)y + rng_uniform(key, 0u, DIM_PIXEL_Y);
    v[2] = lens ? rng_uniform(key, 0u, DIM_LENS_U) : 0.0f;
    v[3] = lens ? rng_uniform(key, 0u, DIM_LENS_V) : 0.0f;
    v[4] = 0.0f;                                   // t: no motion blur
    vstore3(ps->direction, 0, v + 5);
    vstore3(ps->world1, 0, v + 8);
    vstore3(ps->normal, 0, v + 11);
    vstore3(ps->world2, 0, v + 14);
    vstore3(ps->normal2, 0, v + 17);
    vstore3(ps->albedo, 0, v + 20);
    vstore3(ps->direct + ps->indirect, 0, v + 23);
}
#endif

#endif
