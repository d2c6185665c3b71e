// Stylized shadows (DeCoro 2009 ch. 3, "Stylized Shadows", NPAR 2007; digest: shared/notes/
// seed-decoro.md §1): the filter side, over the shadow output of kernels/render/shadows.cl
// (one sphere light: its binary matte V from the ray to its centre, the occluder distance on
// that ray, the centre hit's position and normal, the unshadowed term r, and ShadowTerms, the
// light's direct term the path tracer put into F). src/filters/stylized/ is the same code in
// Rust, one file per step, and says why each choice is what it is.
//
// 1. st_contour: contour points (§3.3.3 "pixels on shadow boundaries", digest §1.3 step 2):
//    for each pixel and its right and lower neighbour, when V differs, both are matte pixels
//    of one surface (normals within the 45° rule, at most `gap` pixel footprints apart along
//    their mean normal: not across a silhouette), the midpoint of their world positions,
//    with the mean normal and the occluder distance of the shadowed one. Two slots per
//    pixel; the host compacts them in pixel order.
// 2. st_distance: eq. 3.2 with p = 8, D = (mean |x - y|^-8)^(-1/8) over N contour points
//    (stratified over the list; all of them when there are at most N), those failing the 45°
//    rule skipped, computed as m (mean (m/d)^8)^(-1/8), m = min d (digest §1.7 item 6), and
//    negated where V = 0; no contour point: D = +-inf. Also d(x) for the quadratic controls:
//    the occluder distances of the contour points averaged with the same weights (m/d)^8.
//    On CPU devices sixteen samples per step on vector lanes, with the bits of one at a
//    time (below).
// 3. st_blur, twice: G * D (§3.3.1 Abstraction, §3.3.3 Gaussian Blur), sigma = alpha/sqrt(2)
//    per pass, importance-sampled Gaussian offsets from Halton points (bases 2 and 3) within
//    3 sigma (a different stretch of the sequence per pass), neighbours failing the 45° rule,
//    off the pixel's surface (further than `gap` footprints from its tangent plane), not in
//    the matte or with no contour (inf) skipped, the mean of the rest.
// 4. st_compose: eq. 3.3 with (1 - b) for the printed (1 - b)^-1, S = (1 - b) smoothstep(
//    i - s/2, i + s/2, D) + b (a hard step D >= i at s = 0), then F - direct + r S.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/rng.cl"
#include "filters/lanes.cl"

// The controls buffer: four quadratics in d, c0 + c1 d + c2 d^2 (src/filters/stylized/
// transfer.rs `Controls::lanes`).
#define ST_INFLATION 0
#define ST_SOFTNESS 4
#define ST_BRIGHTNESS 8
#define ST_ABSTRACTION 12

inline float3 st_lane3(__global const float* px, int lane) {
    return (float3)(px[lane], px[lane + 1], px[lane + 2]);
}

// A pixel of the matte: the ray through its centre hit a diffuse surface (the shadow pass
// writes a unit normal there and zeros elsewhere).
inline bool st_in_matte(__global const float* px) {
    float3 n = st_lane3(px, SHADOW_PIXEL_NORMAL);
    return dot(n, n) > 0.5f;
}

inline float st_quadratic(__constant const float* c, int at, float d) {
    return c[at] + (c[at + 1] + c[at + 2] * d) * d;
}

// Pixel i's element of the light plane `plane` of `planes` in the shadow output (pixel-major,
// src/layout/outputs.rs Per::Light): each stylized light reads its own plane.
#define ST_PX(i) (pixels + ((size_t)(i) * planes + plane) * SHADOW_PIXEL_FLOATS)

__kernel void st_contour(__global const float* pixels, uint plane, uint planes,
                         __global float4* slots, uint width, uint height, float normal_cos,
                         float gap) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    uint i = y * width + x;
    __global const float* a = ST_PX(i);
    for (uint dir = 0u; dir < 2u; ++dir) {
        size_t slot = ((size_t)i * 2u + dir) * 2u;
        slots[slot] = (float4)(0.0f);
        slots[slot + 1u] = (float4)(0.0f);
        uint nx = x + (dir == 0u ? 1u : 0u), ny = y + (dir == 1u ? 1u : 0u);
        if (nx >= width || ny >= height) continue;
        __global const float* b = ST_PX((size_t)ny * width + nx);
        if (!st_in_matte(a) || !st_in_matte(b)) continue;
        float va = a[SHADOW_PIXEL_CENTRE_VISIBLE], vb = b[SHADOW_PIXEL_CENTRE_VISIBLE];
        if (va == vb) continue;
        float3 na = st_lane3(a, SHADOW_PIXEL_NORMAL), nb = st_lane3(b, SHADOW_PIXEL_NORMAL);
        if (dot(na, nb) < normal_cos) continue;
        float3 pa = st_lane3(a, SHADOW_PIXEL_POSITION), pb = st_lane3(b, SHADOW_PIXEL_POSITION);
        float3 delta = pb - pa;
        float3 n = na + nb;
        n = n / sqrt(dot(n, n));
        float foot = fmax(a[SHADOW_PIXEL_PIXEL_SIZE], b[SHADOW_PIXEL_PIXEL_SIZE]);
        if (fabs(dot(n, delta)) > gap * foot) continue;
        float occluder = (va == 0.0f) ? a[SHADOW_PIXEL_OCCLUDER_DISTANCE]
                                      : b[SHADOW_PIXEL_OCCLUDER_DISTANCE];
        float3 mid = (pa + pb) * 0.5f;
        slots[slot] = (float4)(mid, occluder);
        slots[slot + 1u] = (float4)(n, 1.0f);
    }
}

// Sixteen of a pixel's contour samples at once (ST_DISTANCE_LANES = 1: `variant` "lanes", the
// default on CPU devices; issue 14: every image filter faster than OIDN). PoCL runs each
// work-item as scalar code when its kernel loops, and this one loops over up to
// `contour_samples` points per pixel: 99 % of the filter's time at 512², two lights. So the
// work-item takes its samples k in lanes of 16 (uint16 / float16): the draw of entry j, the
// 45° rule and the distance, each lane exactly the float operations of the scalar loop (dot
// written out as PoCL's builtin rounds it). Only the sums of pass 2 depend on the order of
// the samples; they are added lane by lane in k order, so D and d(x) are the bits of the
// loop one sample at a time (src/filters/stylized/distance.rs, tests/stylized.rs:
// bit-identical on PoCL). A GPU's lanes are its work-items already: there the scalar loop
// (ST_DISTANCE_LANES = 0) stays, unmeasured (no GPU was lent).
//
// Pass 1 keeps its distances for pass 2 (ST_CACHE): a pass that draws and gathers again cost
// as much as the first (st_distance 1.05 s -> 0.62 s at 512², two lights, the same bits).
// Samples past the first ST_CACHE (contour_samples above 1024) are drawn again in pass 2.
#define ST_LANES 16u
#define ST_CACHE 1024u
// ST_PIXELS: pixels a work-item of the lanes takes (the host's, device.rs PIXELS_PER_ITEM;
// pass 2 below adds two at once).
#if ST_DISTANCE_LANES && ST_PIXELS != 2
#error "st_distance's lanes take two pixels a work-item (st_add_pair)"
#endif

// Lanes k0 .. k0 + 15 of the pixel's draw: entry j of each sample k (rng.cl rng_uniform(key,
// k, 0), stratified as in distance.rs `Sampling::entry`) and whether k is a sample at all (a
// lane past the last sample takes lane 0's entry, inside the window below). `draws` holds
// hash_u32(k << 8), the part of rng_uniform that is the same at every pixel (distance.rs
// `draw_hashes`; 0.43 s -> 0.41 s).
__attribute__((always_inline)) inline uint16 st_entries(__global const uint* draws,
                                                        uint k0, uint samples, bool all,
                                                        uint key, uint count, float scale,
                                                        int16* valid) {
    uint16 k = (uint16)(k0) + (uint16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    *valid = k < (uint16)(samples);
    if (all) return select((uint16)(0u), k, *valid);
    uint16 h = hash_u32_16((uint16)(key) ^ vload16(0, draws + k0));
    float16 u = convert_float16(h >> 8) * 0x1.0p-24f;
    uint16 j = min(convert_uint16((convert_float16(k) + u) * scale), (uint16)(count - 1u));
    return select((uint16)(j.s0), j, *valid);
}

// One plane's sixteen drawn values from a window of the list (ST_WINDOW_CHUNKS). The draw's
// entries are non-decreasing in k (k + u <= k + 1 <= k + 1 + u' in float, and the scaling and
// the floor keep the order), so lanes k0 .. k0 + 15 read entries base = j.s0 .. top, top at
// most (k0 + 16) * scale. Where that is at most 64 points, each 32 of them come in with two
// vector loads and one two-source permute (AVX-512 vpermi2ps; `off` = j - base) instead of
// sixteen gathered points taken apart: st_distance at 512², two lights, 0.58 s -> 0.42 s.
// PoCL's shuffle2 with a mask known only at run time goes through memory a lane at a time
// (2.1 s), so without AVX-512 the window is not used. Its last read, top + 31, stays inside the
// planes: the host pads them by 32 points (contour.rs `planes`).
#define ST_WINDOW_CHUNKS 2u
#define ST_PERMUTE2(a, b, idx) \
    as_float16(__builtin_ia32_vpermi2varps512(a, as_int16(idx), b))
#define ST_WINDOW(dst, plane_at)                                                   \
    {                                                                              \
        __global const float* w = (plane_at) + base;                               \
        dst = ST_PERMUTE2(vload16(0, w), vload16(0, w + 16), off);                 \
        if (chunks > 1u) {                                                         \
            float16 v = ST_PERMUTE2(vload16(0, w + 32), vload16(0, w + 48), off);  \
            dst = select(dst, v, off > (uint16)(31u));                             \
        }                                                                          \
    }

// Lane s of sixteen drawn points: two float4 loads taken apart, where the draw spreads over
// more than the window's 64 points (more than about four points per sample: grids at 512²
// has 7.5, and there the window measured slower, 0.30 s against 0.24 s) or without AVX-512.
// (Gathered with scalar loads from the planes instead, st_distance measured slower on PoCL:
// 1.49 s against 1.07 s at 512², two lights.)
#define ST_GATHER_LANE(s)                                                          \
    {                                                                              \
        float4 q = contour[2u * j.s], qn = contour[2u * j.s + 1u];                 \
        qx.s = q.x; qy.s = q.y; qz.s = q.z; qw.s = q.w;                            \
        nx.s = qn.x; ny.s = qn.y; nz.s = qn.z;                                     \
    }

// Samples k0 .. k0 + 15 of the pixel's draw: their distances d to p, their occluder distances,
// and which of them are samples that pass the 45° rule (`keep`, as lanes of -1). With every
// point used (`all`), samples k0 .. k0 + 15 are points k0 .. k0 + 15: one vector load from
// each of the host's seven planes of `stride` floats (src/filters/stylized/contour.rs
// `planes`); a drawn subset comes from a window of the planes or is gathered (above).
// Inlined by force: as a call, PoCL passed the vectors through the stack (st_distance 1.21 s
// against 1.07 s at 512², two lights).
__attribute__((always_inline)) inline float16 st_lane_distances(
        __global const float4* contour, __global const float* points, uint stride,
        __global const uint* draws, uint count, uint samples, bool all, float scale, uint key,
        uint k0, float3 p, float3 nrm, float normal_cos, float16* occ, int16* keep) {
    int16 valid;
    uint16 j = st_entries(draws, k0, samples, all, key, count, scale, &valid);
    float16 qx, qy, qz, qw, nx, ny, nz;
    if (all) {
        __global const float* at = points + k0;
        qx = vload16(0, at);
        qy = vload16(0, at + stride);
        qz = vload16(0, at + 2u * stride);
        qw = vload16(0, at + 3u * stride);
        nx = vload16(0, at + 4u * stride);
        ny = vload16(0, at + 5u * stride);
        nz = vload16(0, at + 6u * stride);
    }
#if defined(__AVX512F__)
    // The last entry these lanes can draw: (k0 + 16) * scale bounds (k + u) * scale in float.
    else if ((min((uint)((float)(k0 + ST_LANES) * scale), count - 1u) - j.s0) / 32u
             < ST_WINDOW_CHUNKS) {
        uint base = j.s0;
        uint16 off = j - (uint16)(base);
        uint chunks = (min((uint)((float)(k0 + ST_LANES) * scale), count - 1u) - base) / 32u
                      + 1u;
        ST_WINDOW(qx, points)
        ST_WINDOW(qy, points + stride)
        ST_WINDOW(qz, points + 2u * stride)
        ST_WINDOW(qw, points + 3u * stride)
        ST_WINDOW(nx, points + 4u * stride)
        ST_WINDOW(ny, points + 5u * stride)
        ST_WINDOW(nz, points + 6u * stride)
    }
#endif
    else {
        ST_GATHER_LANE(s0) ST_GATHER_LANE(s1) ST_GATHER_LANE(s2) ST_GATHER_LANE(s3)
        ST_GATHER_LANE(s4) ST_GATHER_LANE(s5) ST_GATHER_LANE(s6) ST_GATHER_LANE(s7)
        ST_GATHER_LANE(s8) ST_GATHER_LANE(s9) ST_GATHER_LANE(sa) ST_GATHER_LANE(sb)
        ST_GATHER_LANE(sc) ST_GATHER_LANE(sd) ST_GATHER_LANE(se) ST_GATHER_LANE(sf)
    }
    float16 facing = nrm.x * nx + nrm.y * ny + nrm.z * nz;   // dot(nrm, qn.xyz)
    *keep = valid & !(facing < normal_cos);
    float16 dx = qx - p.x, dy = qy - p.y, dz = qz - p.z;    // delta = q.xyz - p
    *occ = qw;
    return sqrt(dx * dx + dy * dy + dz * dz);                // sqrt(dot(delta, delta))
}

// A pixel's part of st_distance before its loops: a pixel outside the matte gets D = inf and
// d(x) = 0 and needs no distance; otherwise its position, normal and draw key.
typedef struct {
    uint i, key;
    float3 p, nrm;
    bool lit, active;   // active: D and d(x) are still to be written
    float own_occluder, m;
} StPixel;

__attribute__((always_inline)) inline bool st_begin(__global const float* pixels, uint plane,
                                                    uint planes, uint i, uint seed,
                                                    __global float* dist,
                                                    __global float* occluder, StPixel* a) {
    __global const float* px = ST_PX(i);
    if (!st_in_matte(px)) {
        dist[i] = INFINITY;
        occluder[i] = 0.0f;
        return false;
    }
    a->i = i;
    a->key = rng_sample_key(seed, i, 0u);
    a->p = st_lane3(px, SHADOW_PIXEL_POSITION);
    a->nrm = st_lane3(px, SHADOW_PIXEL_NORMAL);
    a->lit = px[SHADOW_PIXEL_CENTRE_VISIBLE] != 0.0f;
    a->own_occluder = px[SHADOW_PIXEL_OCCLUDER_DISTANCE];
    return true;
}

// The pixel's D and d(x) from pass 1's m and pass 2's sums. No contour point on this side of
// the 45° rule (m = inf): the pixel is as far from any boundary as can be (D = +-inf gives
// S = 1 or b in st_compose, never NaN). Otherwise pass 2's mean of (m/d)^8 is at least
// 1/kept (the nearest point adds 1), so its -1/8 power is finite.
__attribute__((always_inline)) inline void st_end(const StPixel* a, float sum, float sum_occ,
                                                  uint kept, __global float* dist,
                                                  __global float* occluder) {
    if (a->m == INFINITY) {
        dist[a->i] = a->lit ? INFINITY : -INFINITY;
        occluder[a->i] = a->own_occluder;
        return;
    }
    float mean = sum / (float)kept;
    float D = a->m / sqrt(sqrt(sqrt(mean)));
    dist[a->i] = a->lit ? D : -D;
    occluder[a->i] = sum_occ / sum;
}

#if ST_DISTANCE_LANES
// Pass 1 on lanes: m = min d over the kept samples (a minimum: the same in any order). The
// first ST_CACHE samples' d go to `cached_d`, -1 for a sample that is not kept (a distance
// is +0 or more, or NaN: pass 2 reads keep back from the sign), their occluder distances to
// `cached_occ`.
__attribute__((always_inline)) inline float st_pass1(
        __global const float4* contour, __global const float* points, uint stride,
        __global const uint* draws, uint count, uint samples, bool all, float scale,
        float normal_cos, const StPixel* a, float16* cached_d, float16* cached_occ) {
    float16 m16 = (float16)(INFINITY);
    for (uint k0 = 0u; k0 < samples; k0 += ST_LANES) {
        int16 keep;
        float16 occ;
        float16 d = st_lane_distances(contour, points, stride, draws, count, samples, all,
                                      scale, a->key, k0, a->p, a->nrm, normal_cos, &occ, &keep);
        m16 = select(m16, d, keep & (d < m16));   // fmin(m16, d), NaN included
        if (k0 < ST_CACHE) {
            cached_d[k0 / ST_LANES] = select((float16)(-1.0f), d, keep);
            cached_occ[k0 / ST_LANES] = occ;
        }
    }
    float8 m8 = fmin(m16.lo, m16.hi);
    float4 m4 = fmin(m8.lo, m8.hi);
    float2 m2 = fmin(m4.lo, m4.hi);
    return fmin(m2.x, m2.y);
}

// Pass 2's terms for samples k0 .. k0 + 15 of pixel a: (m/d)^8 (1 for d <= m) and its
// product with the occluder distance, +0 for a sample that is not kept; and how many are.
__attribute__((always_inline)) inline uint st_terms(
        __global const float4* contour, __global const float* points, uint stride,
        __global const uint* draws, uint count, uint samples, bool all, float scale,
        float normal_cos, const StPixel* a, const float16* cached_d, const float16* cached_occ,
        uint k0, float16* w, float16* wo) {
    int16 keep;
    float16 occ, d;
    if (k0 < ST_CACHE) {
        d = cached_d[k0 / ST_LANES];
        occ = cached_occ[k0 / ST_LANES];
        keep = !(d < (float16)(0.0f));
    } else {
        d = st_lane_distances(contour, points, stride, draws, count, samples, all, scale,
                              a->key, k0, a->p, a->nrm, normal_cos, &occ, &keep);
    }
    float16 r = a->m / d;
    float16 r2 = r * r;
    float16 r4 = r2 * r2;
    *w = select((float16)(0.0f), select((float16)(1.0f), r4 * r4, d > a->m), keep);
    *wo = select((float16)(0.0f), *w * occ, keep);
    int8 k8 = (keep & 1).lo + (keep & 1).hi;
    int4 k4 = k8.lo + k8.hi;
    int2 k2 = k4.lo + k4.hi;
    return (uint)(k2.x + k2.y);
}

// A work-item's pixel that needs no pass 2 (outside the matte or the image, or m = inf)
// still goes through it beside the others, as terms of +0 that nobody reads: no kept sample
// in the cache, and for samples past it a pixel whose normal fails the 45° rule.
__attribute__((always_inline)) inline void st_idle(StPixel* a, uint samples, float16* cached_d,
                                                   float16* cached_occ) {
    a->active = false;
    a->key = 0u;
    a->p = a->nrm = (float3)(0.0f);
    a->m = 1.0f;
    for (uint k0 = 0u; k0 < min(samples, ST_CACHE); k0 += ST_LANES) {
        cached_d[k0 / ST_LANES] = (float16)(-1.0f);
        cached_occ[k0 / ST_LANES] = (float16)(0.0f);
    }
}

// Two pixels' terms (w, w·occ) as quads (w, wo, w_b, wo_b) of one sample: a 4 x 16 transpose
// in eight two-source shuffles. q0 holds the quads of samples 0, 4, 8, 12; q1 of 1, 5, 9, 13;
// q2 of 2, 6, 10, 14; q3 of 3, 7, 11, 15.
__attribute__((always_inline)) inline void st_quads(float16 w, float16 wo, float16 w_b,
                                                    float16 wo_b, float16* q) {
    float16 a_lo = (float16)(w.s0, wo.s0, w.s1, wo.s1, w.s4, wo.s4, w.s5, wo.s5,
                             w.s8, wo.s8, w.s9, wo.s9, w.sc, wo.sc, w.sd, wo.sd);
    float16 a_hi = (float16)(w.s2, wo.s2, w.s3, wo.s3, w.s6, wo.s6, w.s7, wo.s7,
                             w.sa, wo.sa, w.sb, wo.sb, w.se, wo.se, w.sf, wo.sf);
    float16 b_lo = (float16)(w_b.s0, wo_b.s0, w_b.s1, wo_b.s1, w_b.s4, wo_b.s4, w_b.s5,
                             wo_b.s5, w_b.s8, wo_b.s8, w_b.s9, wo_b.s9, w_b.sc, wo_b.sc,
                             w_b.sd, wo_b.sd);
    float16 b_hi = (float16)(w_b.s2, wo_b.s2, w_b.s3, wo_b.s3, w_b.s6, wo_b.s6, w_b.s7,
                             wo_b.s7, w_b.sa, wo_b.sa, w_b.sb, wo_b.sb, w_b.se, wo_b.se,
                             w_b.sf, wo_b.sf);
    q[0] = (float16)(a_lo.s01, b_lo.s01, a_lo.s45, b_lo.s45, a_lo.s89, b_lo.s89, a_lo.scd,
                     b_lo.scd);
    q[1] = (float16)(a_lo.s23, b_lo.s23, a_lo.s67, b_lo.s67, a_lo.sab, b_lo.sab, a_lo.sef,
                     b_lo.sef);
    q[2] = (float16)(a_hi.s01, b_hi.s01, a_hi.s45, b_hi.s45, a_hi.s89, b_hi.s89, a_hi.scd,
                     b_hi.scd);
    q[3] = (float16)(a_hi.s23, b_hi.s23, a_hi.s67, b_hi.s67, a_hi.sab, b_hi.sab, a_hi.sef,
                     b_hi.sef);
}

// Adds samples k0 .. k0 + 15 of two pixels' terms to their four sums (sum, sum_occ of each),
// in k order: each lane adds one sample after another, the order that fixes the bits (a
// sample the rule skipped adds +0: the sums start at +0 and only grow, so it changes no
// bit), and the four chains are one vector addition a sample.
__attribute__((always_inline)) inline float4 st_add_pair(float4 acc, const float16* w,
                                                         const float16* wo) {
    float16 q[4];
    st_quads(w[0], wo[0], w[1], wo[1], q);
    acc += q[0].s0123; acc += q[1].s0123; acc += q[2].s0123; acc += q[3].s0123;   // 0-3
    acc += q[0].s4567; acc += q[1].s4567; acc += q[2].s4567; acc += q[3].s4567;   // 4-7
    acc += q[0].s89ab; acc += q[1].s89ab; acc += q[2].s89ab; acc += q[3].s89ab;   // 8-11
    acc += q[0].scdef; acc += q[1].scdef; acc += q[2].scdef; acc += q[3].scdef;   // 12-15
    return acc;
}
#endif

// `contour` holds `count` points as (position, occluder distance), (normal, 1) pairs, and
// `points` the same as planes of `stride` floats for the lanes (unused by the scalar loop);
// `draws` the lanes' table of hash_u32(k << 8); `n` is the number of samples, `scale` =
// count / n as a float (the host's, so that the reference picks the same entries).
//
// The lanes take two pixels a work-item, (2x, y) and (2x + 1, y). Pass 2 adds each pixel's
// terms one sample after another, the order that fixes the bits: with one pixel a
// work-item, that chain of dependent additions, fed one lane at a time, was 36 % of the
// kernel's time at 512², two lights (perf annotate). Two pixels' four sums as one float4
// take one vector addition a sample (st_add_pair): st_distance 0.43 s -> 0.34 s, the same
// bits. Four pixels a work-item (a float8 of sums, 32 KiB of cache) measured no faster.
__kernel void st_distance(__global const float* pixels, uint plane, uint planes,
                          __global const float4* contour, __global const float* points,
                          uint stride, __global const uint* draws, uint count, uint n,
                          float scale, uint seed, float normal_cos, uint width, uint height,
                          __global float* dist, __global float* occluder) {
    bool all = count <= n;
    uint samples = all ? count : n;
#if ST_DISTANCE_LANES
    uint x = ST_PIXELS * get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    // 16 KiB a work-item: the host launches this variant in small work-groups (device.rs).
    float16 cached_d[ST_PIXELS][ST_CACHE / ST_LANES], cached_occ[ST_PIXELS][ST_CACHE / ST_LANES];
    StPixel px[ST_PIXELS];
    bool any = false;
    for (uint h = 0u; h < ST_PIXELS; ++h) {
        px[h].active = x + h < width && st_begin(pixels, plane, planes, y * width + x + h,
                                                 seed, dist, occluder, &px[h]);
        if (px[h].active) {
            px[h].m = st_pass1(contour, points, stride, draws, count, samples, all, scale,
                               normal_cos, &px[h], cached_d[h], cached_occ[h]);
            if (px[h].m == INFINITY) st_end(&px[h], 0.0f, 0.0f, 0u, dist, occluder);
        }
        if (!px[h].active || px[h].m == INFINITY)
            st_idle(&px[h], samples, cached_d[h], cached_occ[h]);
        any = any || px[h].active;
    }
    if (!any) return;
    // Pass 2: sum of (m/d)^8 in [0, 1] per sample (no overflow), both pixels at once.
    float4 sums = (float4)(0.0f);   // sum, sum_occ of pixel 0, then of pixel 1
    uint kept[ST_PIXELS] = {0u, 0u};
    for (uint k0 = 0u; k0 < samples; k0 += ST_LANES) {
        float16 w[ST_PIXELS], wo[ST_PIXELS];
#pragma unroll
        for (uint h = 0u; h < ST_PIXELS; ++h)
            kept[h] += st_terms(contour, points, stride, draws, count, samples, all, scale,
                                normal_cos, &px[h], cached_d[h], cached_occ[h], k0, &w[h],
                                &wo[h]);
        sums = st_add_pair(sums, w, wo);
    }
    float s[4];
    vstore4(sums, 0, s);
    for (uint h = 0u; h < ST_PIXELS; ++h)
        if (px[h].active) st_end(&px[h], s[2u * h], s[2u * h + 1u], kept[h], dist, occluder);
#else
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    StPixel a;
    if (!st_begin(pixels, plane, planes, y * width + x, seed, dist, occluder, &a)) return;
    // Pass 1: m = min d over the kept points (a minimum: the same in any order).
    float m = INFINITY;
    for (uint k = 0u; k < samples; ++k) {
        uint j = all ? k : min((uint)(((float)k + rng_uniform(a.key, k, 0u)) * scale), count - 1u);
        float4 q = contour[2u * j], qn = contour[2u * j + 1u];
        if (dot(a.nrm, qn.xyz) < normal_cos) continue;
        float3 delta = q.xyz - a.p;
        m = fmin(m, sqrt(dot(delta, delta)));
    }
    a.m = m;
    // Pass 2: sum of (m/d)^8 in [0, 1] per point (no overflow).
    float sum = 0.0f, sum_occ = 0.0f;
    uint kept = 0u;
    for (uint k = 0u; k < samples && m != INFINITY; ++k) {
        uint j = all ? k : min((uint)(((float)k + rng_uniform(a.key, k, 0u)) * scale), count - 1u);
        float4 q = contour[2u * j], qn = contour[2u * j + 1u];
        if (dot(a.nrm, qn.xyz) < normal_cos) continue;
        float3 delta = q.xyz - a.p;
        float d = sqrt(dot(delta, delta));
        float w = 1.0f;
        if (d > m) {
            float r = m / d;
            float r2 = r * r;
            float r4 = r2 * r2;
            w = r4 * r4;
        }
        sum += w;
        sum_occ += w * q.w;
        kept += 1u;
    }
    st_end(&a, sum, sum_occ, kept, dist, occluder);
#endif
}

// One blur pass over `in`. `stencil` holds this pass's n offsets of a unit Gaussian truncated
// at 3 (Halton points, made by the host: src/filters/stylized/blur.rs `stencil`); the pixel
// reads the neighbours at rint(sigma * offset), sigma = alpha(d) / sqrt(2).
__kernel void st_blur(__global const float* pixels, uint plane, uint planes,
                      __constant const float* controls,
                      __global const float* occluder, __global const float2* stencil,
                      __global const float* in, __global float* out, uint width, uint height,
                      uint n, float normal_cos, float gap) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    int i = y * (int)width + x;
    float own = in[i];
    __global const float* px = ST_PX(i);
    float alpha = st_quadratic(controls, ST_ABSTRACTION, occluder[i]);
    if (!(alpha > 0.0f) || !isfinite(own) || !st_in_matte(px)) {
        out[i] = own;
        return;
    }
    float sigma = alpha * M_SQRT1_2_F;          // two passes of alpha / sqrt(2)
    float3 nrm = st_lane3(px, SHADOW_PIXEL_NORMAL);
    float3 pos = st_lane3(px, SHADOW_PIXEL_POSITION);
    float slab = gap * px[SHADOW_PIXEL_PIXEL_SIZE];
    float sum = 0.0f;
    uint kept = 0u;
    for (uint k = 0u; k < n; ++k) {
        float2 o = stencil[k];
        int qx = x + (int)rint(sigma * o.x), qy = y + (int)rint(sigma * o.y);
        if (qx < 0 || qy < 0 || qx >= (int)width || qy >= (int)height) continue;
        int j = qy * (int)width + qx;
        __global const float* q = ST_PX(j);
        float dj = in[j];
        if (!st_in_matte(q) || !isfinite(dj)) continue;
        if (dot(nrm, st_lane3(q, SHADOW_PIXEL_NORMAL)) < normal_cos) continue;
        if (fabs(dot(nrm, st_lane3(q, SHADOW_PIXEL_POSITION) - pos)) > slab) continue;
        sum += dj;
        kept += 1u;
    }
    out[i] = kept > 0u ? sum / (float)kept : own;
}

// Eq. 3.3 with (1 - b) (the printed (1 - b)^-1 exceeds 1 and divides by 0 at b = 1). The
// shader smoothstep 3t^2 - 2t^3, written out so that the Rust reference matches it.
inline float st_transfer(float D, float i, float s, float b) {
    float t;
    if (s > 0.0f) {
        t = clamp((D - (i - 0.5f * s)) / s, 0.0f, 1.0f);
        t = t * t * (3.0f - 2.0f * t);
    } else {
        t = (D >= i) ? 1.0f : 0.0f;
    }
    return (1.0f - b) * t + b;
}

// Eq. 3.1, one light per launch: the first stylized light starts from F, each next one from
// the image so far (`first` = 0), so that after every light the image is
// F - sum_l direct_l + sum_l r_l S_l (the terms are disjoint parts of F: next-event estimation
// picks one light per vertex).
__kernel void st_compose(__global const float* fv, uint first, __global const float* terms,
                         __global const float* pixels, uint plane, uint planes,
                         __constant const float* controls, __global const float* occluder,
                         __global const float* dist, uint width, uint height,
                         __global float* matte, __global float4* image) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    uint i = y * width + x;
    __global const float* f = fv + (size_t)i * FILTER_VECTOR_FLOATS;
    float3 beauty = first != 0u
        ? st_lane3(f, FILTER_VECTOR_DIRECT) + st_lane3(f, FILTER_VECTOR_INDIRECT)
        : image[i].xyz;
    __global const float* px = ST_PX(i);
    float d = occluder[i];
    float inflation = st_quadratic(controls, ST_INFLATION, d);
    float softness = fmax(st_quadratic(controls, ST_SOFTNESS, d), 0.0f);
    float brightness = clamp(st_quadratic(controls, ST_BRIGHTNESS, d), 0.0f, 1.0f);
    float S = st_transfer(dist[i], inflation, softness, brightness);
    matte[i] = S;
    if (!(px[SHADOW_PIXEL_WEIGHT] > 0.0f)) {
        image[i] = (float4)(beauty, 0.0f);
        return;
    }
    __global const float* t = terms + ((size_t)i * planes + plane) * SHADOW_TERMS_FLOATS;
    float3 rest = beauty - st_lane3(t, SHADOW_TERMS_DIRECT);
    float3 r = st_lane3(px, SHADOW_PIXEL_UNSHADOWED) / px[SHADOW_PIXEL_SAMPLES];
    image[i] = (float4)(rest + r * S, 0.0f);
}
