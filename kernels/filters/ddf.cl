// The data-driven filter (thesis ch. 6, Algorithm 8): a cross-bilateral filter without a
// spatial term whose feature weights are relaxed where the pixel's own features are noisy
// (eq. 6.10), filtering direct and indirect light separately (eqs. 6.11-6.21).
//
// Build options (src/filters/ddf/device.rs):
//   DDF_VARIANT   0: naive, every neighbour's FilterVector read from global memory field by
//                    field (Fig. 6.8); 1: the same with float16 vector loads (§6.3.1);
//                 2: local-memory rows (§6.3.2, Fig. 6.10), float16 loads;
//                 3: packed, DDF_PACK (16) pixels per work-item on float16 lanes
//                    (filters/ddf_packed.cl; ours, not in the thesis).
//   DDF_SKY       1: sky pixels keep their unfiltered colour (§6.3.4); 0 when the scene has
//                    no environment light (no pixel can be sky).
//   DDF_TEXTURE2  1: the texture2 term of eq. 6.14; 0 drops it.
//   DDF_DIRECTION 0: eq. 6.14 as printed, exp(-sigma2_f,3) with the centre's sigma2_f,3,
//                    the same for every neighbour (it cancels in eq. 6.21);
//                 1: exp(-sigma2_f,3 |dir - dir_N|^2) on the mean first-bounce directions;
//                 2: exp(-sigma2_f,3(N)) with sigma2_f,3 formed by eq. 6.10 from the
//                    NEIGHBOUR's direction variance (§6.2.3 says the bounce-direction variance
//                    is used for the indirect weight): neighbours whose bounce directions
//                    scatter (rough surfaces) weigh more than mirror-like ones; it does not
//                    cancel.
//   DDF_FAST_EXP  1: a polynomial exponential in the weights of eqs. 6.15-6.16 (a fast mode,
//                    `ddf_exp` below; tests/ddf.rs measures its error), 0: the built-in exp.
// Holes (§6.3.3) and the kernel width are run-time parameters (DdfParams).
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"

#if !defined(DDF_VARIANT) || !defined(DDF_SKY) || !defined(DDF_TEXTURE2) || !defined(DDF_DIRECTION) \
    || !defined(DDF_FAST_EXP)
#error "noisefree: a data-driven filter switch is missing from the build options"
#endif

#if DDF_FAST_EXP
// The fast mode's exponential, ours: exp(x) = 2^t, t = x log2(e) = n + f, n = floor(t); 2^f,
// f in [0, 1), by a degree-5 polynomial fitted for relative error (largest 1.7e-7 in float32
// Horner form over [0, 1]; the coefficients come from an iteratively reweighted least-squares
// fit, not from a source), 2^n written into the exponent bits. For the weights' exponents,
// x <= 0: below t = -126 (2^n leaves the normal range) it returns 0, as exp underflows there
// to denormals that weigh nothing beside the centre's weight 1. On PoCL, exp and native_exp
// run the same code (measured: bit-identical images), 29 flops' time per exp on float16
// (results/README.md "Roofline"); this is 14 vector operations.
#define DDF_POW2_FRACTION(f)                                                                   \
    fma(f, fma(f, fma(f, fma(f, fma(f, 0.0018775767f, 0.0089893406f), 0.055826318f),          \
                      0.24015361f), 0.69315308f), 0.99999994f)
inline float __attribute__((overloadable)) ddf_exp(float x) {
    float t = x * M_LOG2E_F;
    float n = floor(t);
    float r = DDF_POW2_FRACTION(t - n) * as_float((convert_int(n) + 127) << 23);
    return t < -126.0f ? 0.0f : r;
}
inline float16 __attribute__((overloadable)) ddf_exp(float16 x) {
    float16 t = x * M_LOG2E_F;
    float16 n = floor(t);
    float16 r = DDF_POW2_FRACTION(t - n) * as_float16((convert_int16(n) + 127) << 23);
    return select(r, (float16)(0.0f), t < -126.0f);
}
#define DDF_EXP ddf_exp
#else
#define DDF_EXP exp
#endif

// F is read as one float16 and taken apart with swizzles (s012 direct, s345 indirect, s6
// depth, s789 normal, sABC albedo, sDEF albedo2); the generated lanes must agree.
#if FILTER_VECTOR_DIRECT != 0 || FILTER_VECTOR_INDIRECT != 3 || FILTER_VECTOR_DEPTH != 6 \
    || FILTER_VECTOR_NORMAL != 7 || FILTER_VECTOR_ALBEDO != 10 || FILTER_VECTOR_ALBEDO2 != 13
#error "noisefree: ddf.cl's swizzles do not match the FilterVector layout"
#endif

// The centre pixel's values, fixed for the whole neighbourhood loop (Table 6.3).
typedef struct {
    float16 f;          // F of the centre (eq. 6.1)
    float sigma2_f[5];  // eq. 6.10
    float3 direction;   // the direction term's input of the centre (neighbour_direction)
    float3 c_fd;        // filtered direct colour, accumulating (eq. 6.17)
    float3 c_fi;        // filtered indirect colour (eq. 6.18)
    float tw_d;         // total direct weight (eq. 6.19)
    float tw_i;         // total indirect weight (eq. 6.20)
} DdfCentre;

// The sum of three consecutive lanes, in lane order.
inline float sum_lanes3(const float* g, int lane) {
    return g[lane] + g[lane + 1] + g[lane + 2];
}

inline float sum_sq3(float3 a, float3 b) {
    float3 d = a - b;
    return d.x * d.x + d.y * d.y + d.z * d.z;
}

// The direction term's input for pixel `index` (see DDF_DIRECTION): its mean first-bounce
// direction (1), or (sigma2_f,3 of eq. 6.10 from its own direction variance, 0, 0) (2).
inline float3 neighbour_direction(__constant const DdfParams* p, __global const float* gb,
                                  __global const float* state, uint index) {
#if DDF_DIRECTION == 1
    return vload3(0, state + (size_t)index * WELFORD_STATE_FLOATS + WELFORD_STATE_DIRECTION_MEAN);
#elif DDF_DIRECTION == 2
    __global const float* g = gb + (size_t)index * WELFORD_SUMS_FLOATS + WELFORD_SUMS_DIRECTION;
    float f = p->variance_factor;
    float v = g[0] * f + g[1] * f + g[2] * f;        // the lane order of ddf_centre
    return (float3)(p->sigma2_f[3] * (1.0f - clamp(v * p->variance_scale[3], 0.0f, 1.0f)),
                    0.0f, 0.0f);
#else
    return (float3)(0.0f);
#endif
}

// Initialisation (Alg. 8 lines 3-6): eq. 6.10 from the centre's variance GBuffer.
inline DdfCentre ddf_centre(__constant const DdfParams* p, float16 f, __global const float* gb,
                            __global const float* state, uint pixel) {
    DdfCentre c;
    c.f = f;
    float g[WELFORD_SUMS_FLOATS];                         // S_n / (n - 1): the variances
    vstore16(vload16(pixel, gb) * p->variance_factor, 0, g);
    // Depths are compared in hundredths of the scene's size (depth_scale; src/stats/mod.rs),
    // so their variance scales with depth_scale^2.
    float sums[5] = {g[WELFORD_SUMS_DEPTH] * p->depth_scale * p->depth_scale,
                     sum_lanes3(g, WELFORD_SUMS_NORMAL), sum_lanes3(g, WELFORD_SUMS_ALBEDO),
                     sum_lanes3(g, WELFORD_SUMS_DIRECTION), sum_lanes3(g, WELFORD_SUMS_ALBEDO2)};
    for (int i = 0; i < 5; ++i)
        c.sigma2_f[i] = p->sigma2_f[i] * (1.0f - clamp(sums[i] * p->variance_scale[i], 0.0f, 1.0f));
    c.direction = neighbour_direction(p, gb, state, pixel);
    c.c_fd = (float3)(0.0f);
    c.c_fi = (float3)(0.0f);
    c.tw_d = 0.0f;
    c.tw_i = 0.0f;
    return c;
}

// One neighbour N (eqs. 6.11-6.20). The products of exponentials in eqs. 6.13-6.16 are formed
// as one exponential of the summed exponents: the same value, one exp instead of six.
inline void ddf_neighbour(__constant const DdfParams* p, DdfCentre* c, float16 n,
                          float3 n_direction) {
    float e_dc = p->sigma2_dc * sum_sq3(c->f.s012, n.s012);                 // eq. 6.11
    float e_ic = p->sigma2_ic * sum_sq3(c->f.s345, n.s345);                 // eq. 6.12
    float dd = (c->f.s6 - n.s6) * p->depth_scale;
    float e_fd = c->sigma2_f[0] * dd * dd                                    // eq. 6.13
               + c->sigma2_f[1] * sum_sq3(c->f.s789, n.s789)
               + c->sigma2_f[2] * sum_sq3(c->f.sABC, n.sABC);
    float e_fi = e_fd;                                                       // eq. 6.14
#if DDF_TEXTURE2
    e_fi += c->sigma2_f[4] * sum_sq3(c->f.sDEF, n.sDEF);
#endif
#if DDF_DIRECTION == 1
    e_fi += c->sigma2_f[3] * sum_sq3(c->direction, n_direction);
#elif DDF_DIRECTION == 2
    e_fi += n_direction.x;                     // the neighbour's own sigma2_f,3
#else
    // As printed: one factor for every neighbour, which cancels in eq. 6.21.
    e_fi += c->sigma2_f[3];
#endif
    float w_d = DDF_EXP(-(e_dc + e_fd));                                     // eq. 6.15
    float w_i = DDF_EXP(-(e_ic + e_fi));                                     // eq. 6.16
    c->c_fd += w_d * n.s012;                                                 // eq. 6.17
    c->c_fi += w_i * n.s345;                                                 // eq. 6.18
    c->tw_d += w_d;                                                          // eq. 6.19
    c->tw_i += w_i;                                                          // eq. 6.20
}

// Normalisation and output (eq. 6.21). When every weight underflowed (extreme sigmas), the
// pixel keeps its own light instead of dividing 0 by 0.
inline float4 ddf_output(const DdfCentre* c) {
    float3 d = c->tw_d > 0.0f ? c->c_fd / c->tw_d : c->f.s012;
    float3 i = c->tw_i > 0.0f ? c->c_fi / c->tw_i : c->f.s345;
    return (float4)(d + i, 0.0f);
}

// The window: Alg. 8 loops from -half to half - 1, which is asymmetric; we use the symmetric
// inclusive kw x kw window. With holes (step 2) and an odd half the grid -half, -half+2, ...
// skips offset 0, so the centre is visited once more at the end: its own weight keeps
// tw >= 1 whenever the weights do not underflow.
inline bool ddf_centre_off_grid(__constant const DdfParams* p) {
    return (p->half_width % p->step) != 0;
}


inline float16 load_f_scalar(__global const FilterVector* fv, uint index) {
    __global const FilterVector* n = fv + index;
    return (float16)(n->direct[0], n->direct[1], n->direct[2],
                     n->indirect[0], n->indirect[1], n->indirect[2], n->depth,
                     n->normal[0], n->normal[1], n->normal[2],
                     n->albedo[0], n->albedo[1], n->albedo[2],
                     n->albedo2[0], n->albedo2[1], n->albedo2[2]);
}

inline float16 load_f(__global const float* f, uint index) {
#if DDF_VARIANT == 0
    return load_f_scalar((__global const FilterVector*)f, index);
#else
    return vload16(index, f);
#endif
}

inline bool is_sky(float16 f) {
    return f.s6 >= SKY_DEPTH;
}

#if DDF_VARIANT == 0 || DDF_VARIANT == 1

// Naive (Fig. 6.8): each work-item loads every neighbour from global memory.
__kernel void ddf_filter(__constant const DdfParams* p,
                         __global const float* f,
                         __global const float* gb,
                         __global const float* state,
                         __global float4* out) {
    int x = get_global_id(0), y = get_global_id(1);
    int w = (int)p->width, h = (int)p->height;
    if (x >= w || y >= h) return;
    uint pixel = (uint)(y * w + x);
    float16 fc = load_f(f, pixel);
#if DDF_SKY
    if (is_sky(fc)) {
        out[pixel] = (float4)(fc.s012 + fc.s345, 0.0f);
        return;
    }
#endif
    DdfCentre c = ddf_centre(p, fc, gb, state, pixel);
    for (int dy = -p->half_width; dy <= p->half_width; dy += p->step) {
        int ny = y + dy;
        if (ny < 0 || ny >= h) continue;          // out-of-image neighbours are skipped
        for (int dx = -p->half_width; dx <= p->half_width; dx += p->step) {
            int nx = x + dx;
            if (nx < 0 || nx >= w) continue;
            uint ni = (uint)(ny * w + nx);
            ddf_neighbour(p, &c, load_f(f, ni), neighbour_direction(p, gb, state, ni));
        }
    }
    if (ddf_centre_off_grid(p)) ddf_neighbour(p, &c, fc, c.direction);
    out[pixel] = ddf_output(&c);
}

#elif DDF_VARIANT == 2

// Local-memory rows (§6.3.2, Fig. 6.10). A work-group is a horizontal run of pixels of one
// image row. For each row of the neighbourhood, every work-item loads the pixel in its own
// column into local memory; after a barrier all of them read that row from local memory, and
// neighbours left or right of the loaded run come from global memory. Local memory is one
// float16 per work-item (64 bytes x work-group size), whatever the kernel width.
// All work-items of a group share y, so the row loop and its barriers are uniform.
__kernel void ddf_filter(__constant const DdfParams* p,
                         __global const float* f,
                         __global const float* gb,
                         __global const float* state,
                         __global float4* out,
                         __local float16* row) {
    int x = get_global_id(0), y = get_global_id(1);
    int lid = get_local_id(0), run = get_local_size(0);
    int x0 = x - lid;                              // first column of this run
    int w = (int)p->width, h = (int)p->height;
    bool active = x < w && y < h;
    uint pixel = (uint)(y * w + x);
    float16 fc = active ? vload16(pixel, f) : (float16)(0.0f);
    bool keep = !active;
#if DDF_SKY
    keep = keep || is_sky(fc);                     // still takes part in the barriers
    // A run of sky pixels only keeps its colours without loading a row (§6.3.4): the thesis's
    // time with the sky-box in full view is flat over the kernel width (§7.2, Fig. 7.11),
    // which loading kw rows per run before the per-pixel test would not be. The flag is the
    // same for the whole group, so the early return is uniform and skips no barrier.
    __local int any_filtered;
    if (lid == 0) any_filtered = 0;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (!keep) atomic_or(&any_filtered, 1);
    barrier(CLK_LOCAL_MEM_FENCE);
    if (any_filtered == 0) {
        if (active) out[pixel] = (float4)(fc.s012 + fc.s345, 0.0f);
        return;
    }
#endif
    DdfCentre c;
    if (!keep) c = ddf_centre(p, fc, gb, state, pixel);
    for (int dy = -p->half_width; dy <= p->half_width; dy += p->step) {
        int ny = y + dy;
        bool row_inside = ny >= 0 && ny < h;       // the same for the whole group
        if (row_inside) row[lid] = x < w ? vload16((uint)(ny * w + x), f) : (float16)(0.0f);
        barrier(CLK_LOCAL_MEM_FENCE);
        if (row_inside && !keep) {
            for (int dx = -p->half_width; dx <= p->half_width; dx += p->step) {
                int nx = x + dx;
                if (nx < 0 || nx >= w) continue;
                int t = lid + dx;
                uint ni = (uint)(ny * w + nx);
                float16 n = (t >= 0 && t < run) ? row[t] : vload16(ni, f);
                ddf_neighbour(p, &c, n, neighbour_direction(p, gb, state, ni));
            }
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (!active) return;
    if (keep) {
        out[pixel] = (float4)(fc.s012 + fc.s345, 0.0f);
        return;
    }
    if (ddf_centre_off_grid(p)) ddf_neighbour(p, &c, fc, c.direction);
    out[pixel] = ddf_output(&c);
}

#elif DDF_VARIANT == 3

#include "filters/ddf_packed.cl"

#else
#error "noisefree: DDF_VARIANT must be 0, 1, 2 or 3"
#endif
