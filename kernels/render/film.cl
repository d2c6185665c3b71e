// The per-pixel output stage: what one path sample leaves behind, and how it is folded into the
// pixel's outputs (thesis §6.2.1-6.2.2): the running means of the FilterVector F (eq. 6.1) and,
// when a filter needs them, Welford's running S_n of the scene features (the variance GBuffer
// GB, eq. 6.2), the mean first-hit position and the per-sample RPF vectors. Which outputs exist
// is decided by the OUTPUT_* switches of src/layout/outputs.rs; the buffers and the float lane
// of every field come from the generated layout.cl and render/outputs.cl, none by hand.
//
// One rule holds for every output: its bytes do not depend on which other outputs are on. So a
// filter sees the same F whether the render also gathered variances, AOVs or sample vectors
// (tests/online_offline.rs).
#ifndef NOISEFREE_FILM_CL
#define NOISEFREE_FILM_CL

#include "layout.cl"
#include "render/features.cl"
#include "render/outputs.cl"
#include "render/rng.cl"

// The light planes of the shadow output (a build define from the host: the shadow output's
// lights, src/render/shadows `LightPlanes`; 1 in builds that do not set it).
#ifndef SHADOW_PLANES
#define SHADOW_PLANES 1
#endif

#if FILTER_VECTOR_FLOATS != 16 || WELFORD_SUMS_FLOATS != 16 || WELFORD_STATE_FLOATS != 20 \
    || DEPTH_SHIFT_FLOATS != 2 || SHADOW_TERMS_FLOATS != 8
#error "noisefree: film.cl moves F and GB as float16, WelfordState as float4 + float16, ShadowTerms as float8"
#endif

// One path's contribution and first-hit features.
typedef struct {
    float3 direct;     // emission seen directly + light reaching the first surface from a light
    float3 indirect;   // everything else
    float depth;       // distance to the first hit, SKY_DEPTH if the camera ray escapes
    float3 normal;     // first-hit shading normal (facing the camera), 0 for sky
    float3 albedo;     // first-hit albedo, 0 for sky
    float3 albedo2;    // albedo of the first diffuse surface after the first bounce, 0 if none
    float3 direction;  // direction leaving the first hit, 0 if none
#if OUTPUT_POSITION || OUTPUT_SAMPLES || OUTPUT_LIGHT_FIELD
    float3 world1;     // first hit (camera origin + SKY_DEPTH x direction for sky)
    bool hit;          // the camera ray hit a surface
#endif
#if OUTPUT_SAMPLES
    float3 world2;     // second hit, 0 if none
    float3 normal2;    // shading normal at the second hit, 0 if none
#endif
#if OUTPUT_SHADOWS
    float3 shadow_direct[SHADOW_PLANES]; // per light plane: light straight from the plane's
                                         // light to the first surface, when that is the pixel
                                         // centre's receiver (ShadowTerms)
    float3 shadow_unshadowed[SHADOW_PLANES]; // and albedo x the light's unoccluded term there
#endif
#if OUTPUT_EMISSION
    float4 emitted;         // light of an emitter the camera ray hit (rgb, part of direct) and
                            // whether it hit one (w: 1 or 0)
#endif
#if OUTPUT_LENS_SHADOWS
    uint receiver;          // the shadow planes whose receiver's object the first hit is on
                            // (the planes whose shadow_direct it records), a bit each
    float3 receiver_albedo; // that hit's albedo (0 when receiver is 0)
    float3 receiver_unshadowed[SHADOW_PLANES]; // and each plane's light's unoccluded term
                                               // there (shadow_unshadowed), 0 off its receiver
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
#if OUTPUT_POSITION || OUTPUT_SAMPLES || OUTPUT_LIGHT_FIELD
    ps.world1 = (float3)(0.0f);
    ps.hit = false;
#endif
#if OUTPUT_SAMPLES
    ps.world2 = (float3)(0.0f);
    ps.normal2 = (float3)(0.0f);
#endif
#if OUTPUT_SHADOWS
    for (uint l = 0u; l < SHADOW_PLANES; ++l) {
        ps.shadow_direct[l] = (float3)(0.0f);
        ps.shadow_unshadowed[l] = (float3)(0.0f);
    }
#endif
#if OUTPUT_EMISSION
    ps.emitted = (float4)(0.0f);
#endif
#if OUTPUT_LENS_SHADOWS
    ps.receiver = 0u;
    ps.receiver_albedo = (float3)(0.0f);
    for (uint l = 0u; l < SHADOW_PLANES; ++l) ps.receiver_unshadowed[l] = (float3)(0.0f);
#endif
    return ps;
}

// A pixel's outputs while a launch works on it (private memory; loaded once, stored once).
typedef struct {
    float mean[FILTER_VECTOR_FLOATS];      // F
#if OUTPUT_FEATURES
    float depth[DEPTH_SHIFT_FLOATS];       // DepthShift: K and the mean of x - K
#endif
#if OUTPUT_VARIANCE
    float s[WELFORD_SUMS_FLOATS];          // GB: S_n per feature component
    float state[WELFORD_STATE_FLOATS];     // the rest of Welford's state (WelfordState)
#endif
#if OUTPUT_POSITION
    float position[4];                     // mean first-hit position (xyz), hits (w)
#endif
#if OUTPUT_SHADOWS
    float shadow[SHADOW_PLANES * SHADOW_TERMS_FLOATS]; // ShadowTerms per light plane: the means
                                                       // of the replaced light and of r
#endif
#if OUTPUT_HALVES
    float odd[4];                          // mean light of the odd-numbered samples, count
#endif
#if OUTPUT_EMISSION
    float emission[4];                     // mean light of emitters seen directly, their share
    float odd_emission[4];                 // the same over the odd-numbered samples, count
#endif
} PixelStats;

inline void pixel_stats_load(PixelStats* p, RENDER_OUTPUT_PARAMS, uint pixel) {
    vstore16(vload16(pixel, filter_vectors), 0, p->mean);
#if OUTPUT_FEATURES
    vstore2(vload2(pixel, depth_shifts), 0, p->depth);
#endif
#if OUTPUT_VARIANCE
    vstore16(vload16(pixel, welford_sums), 0, p->s);
    __global const float* sp = welford_state + (size_t)pixel * WELFORD_STATE_FLOATS;
    vstore4(vload4(0, sp), 0, p->state);                  // 20 floats: float4 + float16
    vstore16(vload16(0, sp + 4), 0, p->state + 4);
#endif
#if OUTPUT_POSITION
    vstore4(vload4(pixel, positions), 0, p->position);
#endif
#if OUTPUT_SHADOWS
    for (uint l = 0u; l < SHADOW_PLANES; ++l)
        vstore8(vload8(pixel * SHADOW_PLANES + l, shadow_terms), l, p->shadow);
#endif
#if OUTPUT_HALVES
    vstore4(vload4(pixel, odd_halves), 0, p->odd);
#endif
#if OUTPUT_EMISSION
    vstore4(vload4(pixel, first_emission), 0, p->emission);
    vstore4(vload4(pixel, odd_emission), 0, p->odd_emission);
#endif
}

inline void pixel_stats_store(const PixelStats* p, RENDER_OUTPUT_PARAMS, uint pixel) {
    vstore16(vload16(0, p->mean), pixel, filter_vectors);
#if OUTPUT_FEATURES
    vstore2(vload2(0, p->depth), pixel, depth_shifts);
#endif
#if OUTPUT_VARIANCE
    vstore16(vload16(0, p->s), pixel, welford_sums);
    __global float* sp = welford_state + (size_t)pixel * WELFORD_STATE_FLOATS;
    vstore4(vload4(0, p->state), 0, sp);
    vstore16(vload16(0, p->state + 4), 0, sp + 4);
#endif
#if OUTPUT_POSITION
    vstore4(vload4(0, p->position), pixel, positions);
#endif
#if OUTPUT_SHADOWS
    for (uint l = 0u; l < SHADOW_PLANES; ++l)
        vstore8(vload8(l, p->shadow), pixel * SHADOW_PLANES + l, shadow_terms);
#endif
#if OUTPUT_HALVES
    vstore4(vload4(0, p->odd), pixel, odd_halves);
#endif
#if OUTPUT_EMISSION
    vstore4(vload4(0, p->emission), pixel, first_emission);
    vstore4(vload4(0, p->odd_emission), pixel, odd_emission);
#endif
}

// Eq. 6.5: mu_n = mu_{n-1} + (x_n - mu_{n-1}) / n. n is the 1-based sample count.
inline void running_mean(float* mean, float x, float n) {
    *mean += (x - *mean) / n;
}

// running_mean of each channel of x into mean[0..2], in the order x, y, z.
inline void running_mean3(float* mean, float3 x, float n) {
    running_mean(&mean[0], x.x, n);
    running_mean(&mean[1], x.y, n);
    running_mean(&mean[2], x.z, n);
}

// A mean over only some samples (those that hit a surface, the odd-numbered ones): mean[3]
// counts them, and this one is folded into mean[0..2] by running_mean3.
inline void counted_mean3(float* mean, float3 x) {
    mean[3] += 1.0f;
    running_mean3(mean, x, mean[3]);
}

// Eqs. 6.5 and 6.6 (Knuth, after Welford): the running mean and
// S_n = S_{n-1} + (x_n - mu_{n-1}) (x_n - mu_n), with S_1 = 0 (mu_1 = x_1 makes the product 0).
// This is the one update every statistic uses; its mean is exactly running_mean's. Each term is
// a product of two deviations from the mean, so S_n never goes negative and a constant stream
// gives exactly 0.
//
// Where float32 loses accuracy, and what is done about it:
// - Large offsets (depth in millimetres, or 1e4 with a spread of 0.1): the deviations x - mu
//   are small next to mu, mu has an absolute rounding error of half an ulp of mu (5e-4 at 1e4),
//   and once (x - mu) / n drops below that, mu stops moving ("stagnation", after a few hundred
//   samples): S_n then grows around a wrong mean and overestimates the variance by
//   (mu - mean)^2 per sample. So depth runs on shifted data x - K, K the pixel's first sample
//   (DepthShift, part of the features output, so that F.depth has the same bytes with and
//   without variances); F.depth = K + mean(x - K). Normals, albedos and directions are bounded
//   by 1 and need no shift.
// - Long runs with outliers (fireflies): after one sample 10^4 times the mean, S_n is ~5e10
//   and its ulp 4096, so the ordinary terms (~25) that follow vanish when added. S_n is
//   therefore summed with Kahan's compensation (the compensation lives in WelfordState).
// tests/statistics.rs and tests/hard_cases_statistics.rs check both against float64.
inline void welford(float* mean, float* s, float* compensation, float x, float n) {
    float delta = x - *mean;
    running_mean(mean, x, n);
    float term = delta * (x - *mean) - *compensation;
    float sum = *s + term;
    *compensation = (sum - *s) - term;
    *s = sum;
}

inline void accumulate3(PixelStats* p, int f_lane, int s_lane, float3 x, float n) {
#if OUTPUT_VARIANCE
    float* c = p->state + WELFORD_STATE_S_COMPENSATION;
    welford(&p->mean[f_lane], &p->s[s_lane], &c[s_lane], x.x, n);
    welford(&p->mean[f_lane + 1], &p->s[s_lane + 1], &c[s_lane + 1], x.y, n);
    welford(&p->mean[f_lane + 2], &p->s[s_lane + 2], &c[s_lane + 2], x.z, n);
#else
    running_mean3(&p->mean[f_lane], x, n);
#endif
}

// Folds sample number `count` (1-based) of this render of the pixel into its outputs;
// `sample` is its absolute number (the half buffers split by its parity, so that renders of
// sample ranges merge into the one-machine halves).
inline void film_accumulate(PixelStats* p, const PathSample* ps, uint count, uint sample) {
    float n = (float)count;
    // Colour: means only (GB holds no colour variance, eq. 6.2).
    running_mean3(&p->mean[FILTER_VECTOR_DIRECT], ps->direct, n);
    running_mean3(&p->mean[FILTER_VECTOR_INDIRECT], ps->indirect, n);
#if OUTPUT_FEATURES
    if (count == 1u) {
        p->depth[DEPTH_SHIFT_SHIFT] = ps->depth;
        p->depth[DEPTH_SHIFT_MEAN] = 0.0f;
    }
    float shifted = ps->depth - p->depth[DEPTH_SHIFT_SHIFT];
#if OUTPUT_VARIANCE
    float* st = p->state;
    float* c = st + WELFORD_STATE_S_COMPENSATION;
    welford(&p->depth[DEPTH_SHIFT_MEAN], &p->s[WELFORD_SUMS_DEPTH], &c[WELFORD_SUMS_DEPTH],
            shifted, n);
#else
    running_mean(&p->depth[DEPTH_SHIFT_MEAN], shifted, n);
#endif
    p->mean[FILTER_VECTOR_DEPTH] = p->depth[DEPTH_SHIFT_SHIFT] + p->depth[DEPTH_SHIFT_MEAN];
#if OUTPUT_VARIANCE
    int d = WELFORD_STATE_DIRECTION_MEAN, sd = WELFORD_SUMS_DIRECTION;
    welford(&st[d], &p->s[sd], &c[sd], ps->direction.x, n);
    welford(&st[d + 1], &p->s[sd + 1], &c[sd + 1], ps->direction.y, n);
    welford(&st[d + 2], &p->s[sd + 2], &c[sd + 2], ps->direction.z, n);
#endif
    accumulate3(p, FILTER_VECTOR_NORMAL, WELFORD_SUMS_NORMAL, ps->normal, n);
    accumulate3(p, FILTER_VECTOR_ALBEDO, WELFORD_SUMS_ALBEDO, ps->albedo, n);
    accumulate3(p, FILTER_VECTOR_ALBEDO2, WELFORD_SUMS_ALBEDO2, ps->albedo2, n);
#endif
#if OUTPUT_SHADOWS
    for (uint l = 0u; l < SHADOW_PLANES; ++l) {
        float* sh = p->shadow + l * SHADOW_TERMS_FLOATS;
        running_mean3(&sh[SHADOW_TERMS_DIRECT], ps->shadow_direct[l], n);
        running_mean3(&sh[SHADOW_TERMS_UNSHADOWED], ps->shadow_unshadowed[l], n);
    }
#endif
#if OUTPUT_POSITION
    // The mean over the samples whose camera ray hit a surface; w counts them. A pixel whose
    // every sample escaped keeps (0, 0, 0, 0).
    if (ps->hit) counted_mean3(p->position, ps->world1);
#endif
#if OUTPUT_HALVES
    // The odd half: a running mean over the odd-numbered samples; w counts them. The even
    // half is what F's light holds beyond it (src/filters/bmfr/select.rs).
    if (sample & 1u) counted_mean3(p->odd, ps->direct + ps->indirect);
#else
    (void)sample;
#endif
#if OUTPUT_EMISSION
    // Means over all the samples, as F's (so renders of sample ranges merge as F does).
    running_mean3(p->emission, ps->emitted.xyz, n);
    running_mean(&p->emission[3], ps->emitted.w, n);
    // The odd half, as the halves output's.
    if (sample & 1u) counted_mean3(p->odd_emission, ps->emitted.xyz);
#endif
}

#if OUTPUT_SAMPLES
// Random Parameter Filtering's sample vector (thesis §5.1.1, Table 5.1; src/layout/mod.rs
// SampleVector): screen position, random parameters (lens u, v, time 0, first-bounce
// direction), world position and normal of the first and second hits, first-hit texture, and
// the sample's colour. The pixel jitter and lens numbers are drawn again from the counter-based
// generator: the same numbers the camera used.
inline void write_sample_vector(__global float* out, uint index, uint x, uint y, uint key,
                                const PathSample* ps, bool lens) {
    __global float* v = out + (size_t)index * SAMPLE_VECTOR_FLOATS;
    v[SAMPLE_VECTOR_POSITION] = (float)x + rng_uniform(key, 0u, DIM_PIXEL_X);
    v[SAMPLE_VECTOR_POSITION + 1] = (float)y + rng_uniform(key, 0u, DIM_PIXEL_Y);
    v[SAMPLE_VECTOR_RANDOM] = lens ? rng_uniform(key, 0u, DIM_LENS_U) : 0.0f;
    v[SAMPLE_VECTOR_RANDOM + 1] = lens ? rng_uniform(key, 0u, DIM_LENS_V) : 0.0f;
    v[SAMPLE_VECTOR_RANDOM + 2] = 0.0f;            // t: no motion blur
    vstore3(ps->direction, 0, v + SAMPLE_VECTOR_RANDOM + 3);
    vstore3(ps->world1, 0, v + SAMPLE_VECTOR_WORLD1);
    vstore3(ps->normal, 0, v + SAMPLE_VECTOR_NORMAL1);
    vstore3(ps->world2, 0, v + SAMPLE_VECTOR_WORLD2);
    vstore3(ps->normal2, 0, v + SAMPLE_VECTOR_NORMAL2);
    vstore3(ps->albedo, 0, v + SAMPLE_VECTOR_TEXTURE1);
    vstore3(ps->direct + ps->indirect, 0, v + SAMPLE_VECTOR_COLOR);
}
#endif

#endif
