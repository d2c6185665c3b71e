// Blockwise feature regression: single-frame BMFR (Koskela et al., ACM TOG 38(5) 2019); see
// src/filters/bmfr/mod.rs for the method and src/filters/bmfr/reference.rs for the same
// operations in Rust, in the same order (the reductions included).
//
// bmfr_fit: one work-group of BMFR_WG work-items per block of one grid. Work-item t holds the
// rows r = t + q * BMFR_WG (q < ROWS) of the block's matrix, row r being pixel
// (x0 + r % B, y0 + r / B). The matrix, column-major in local memory, has K feature columns and
// 6 target columns (direct rgb / albedo, indirect rgb / albedo). Householder QR column by
// column (paper Algorithm 1): the dot products of column j with every column c >= j over rows
// >= j are summed per work-item, then over the work-items in order; from them the reflection
//     alpha = -sign(x_j) |x|,  v = x - alpha e_j,  |v|^2 = |x|^2 - x_j^2 + v_j^2,
//     a_c -= (2 (x . a_c - alpha a_c[j]) / |v|^2) v      (x . a_c - alpha a_c[j] = v . a_c)
// is applied to the later columns, and column j becomes alpha e_j. Back-substitution of
// R w = Q^T b then gives the K weights of each target; weights and the block's rescaling go
// to global memory; block (bx, by) of grid g is slot g * stride + by * across + bx.
//
// bmfr_apply: per pixel, the fitted light of each grid's block (negative values clamped to 0)
// times the albedo, blended over the grids with tent weights (1 at a block's centre, 1/B at its
// edge) times min(1, m / (4K)), m the block's surface pixels.
//
// bmfr_residuals, bmfr_select (with `select`): each pixel blended between the fit and its
// unfiltered light by the error the half buffers estimate (after bmfr_apply).
//
// bmfr_albedo_prefilter (with `albedo_prefilter`): runs first, on a copy of F that every other
// kernel then reads (at the end of this file).
//
// bmfr_fit_packed (filters/bmfr_fit_packed.cl, included at the end; `packed_fit`, on CPU
// devices by default): bmfr_fit with one work-item per block on float16 lanes, same bytes.
//
// Build options (src/filters/bmfr/device.rs):
//   BMFR_BLOCK, BMFR_WG, BMFR_GRIDS    block side, work-items per block, shifted grids
//   BMFR_DEPTH, BMFR_TEXTURE, BMFR_TEXTURE2   0/1: the optional features
//   BMFR_NOISE, BMFR_ALBEDO_EPSILON, BMFR_PIVOT_MIN   float literals
//   BMFR_SELECT_RADIUS                 half width of the selection's window, pixels
//   BMFR_SELECT_SCALE                  kappa, the trust in the fit (float literal)
//   BMFR_SELECT_FLOOR                  c, the floor of the fit's evidence (literal; 0: none)
//   BMFR_PREFILTER_K, BMFR_PREFILTER_EPSILON   the albedo prefilter's k and epsilon (literals)
//   BMFR_PREFILTER_GEOMETRY, BMFR_GEOMETRY_K   0/1: the prefilter averages the geometry too; its k
//   BMFR_PREFILTER_LINES               lines per row of the packed prefilter's input
//   BMFR_GLOBAL_MATRIX                 0/1: bmfr_fit's matrix in `matrices` (global memory), one
//                                      slice per block, where local memory is too small for it
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"
#include "render/rng.cl"

#if !defined(BMFR_BLOCK) || !defined(BMFR_WG) || !defined(BMFR_GRIDS) || !defined(BMFR_DEPTH) \
    || !defined(BMFR_TEXTURE) || !defined(BMFR_TEXTURE2) || !defined(BMFR_NOISE)            \
    || !defined(BMFR_ALBEDO_EPSILON) || !defined(BMFR_PIVOT_MIN) || !defined(BMFR_SELECT_RADIUS)    \
    || !defined(BMFR_SELECT_SCALE) || !defined(BMFR_SELECT_FLOOR) || !defined(BMFR_PREFILTER_K) || !defined(BMFR_PREFILTER_EPSILON) \
    || !defined(BMFR_PREFILTER_GEOMETRY) || !defined(BMFR_GEOMETRY_K) || !defined(BMFR_PREFILTER_LINES) \
    || !defined(BMFR_GLOBAL_MATRIX) || !defined(BMFR_COLUMN_PAD)
#error "noisefree: a bmfr filter switch is missing from the build options"
#endif

#define BMFR_N (BMFR_BLOCK * BMFR_BLOCK)
// Floats from one column of a block's matrix to the next: its BMFR_N rows and BMFR_COLUMN_PAD
// unused floats (src/filters/bmfr/device.rs `COLUMN_PAD`: 16 for the packed fit, else 0). With
// B = 32 a column is 4 KiB, so the same rows of every column fell into one set of a CPU's
// first-level cache (4 KiB apart), more columns than its ways: the packed fit's sweeps over
// the columns missed the cache on every access (results/README.md, bmfr "Stop 60").
#define BMFR_LD (BMFR_N + BMFR_COLUMN_PAD)
#define BMFR_ROWS (BMFR_N / BMFR_WG)
#define BMFR_K (10 + BMFR_DEPTH + 3 * BMFR_TEXTURE + 3 * BMFR_TEXTURE2)
#define BMFR_C (BMFR_K + 6)
#define BMFR_INFO 9
// Where bmfr_fit keeps its block's matrix. B = 32 with 10 features and 6 targets is 64 KiB,
// more than the 48 KiB of local memory NVIDIA's OpenCL gives a work-group; there the matrix
// lives in global memory, a slice of BMFR_C * BMFR_LD floats per block of the launch (as in
// the paper's own code, whose work-groups read the block from a global buffer), and the
// barriers that order its accesses fence global memory too. The same operations in the same
// order: the same bytes.
#if BMFR_GLOBAL_MATRIX
#define BMFR_MATRIX __global
#define BMFR_FENCE (CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE)
#else
#define BMFR_MATRIX __local
#define BMFR_FENCE CLK_LOCAL_MEM_FENCE
#endif
// Column of the depth feature (after 1, normal, position, position^2).
#define BMFR_COL_DEPTH 10

// The shift of grid g (src/filters/bmfr/mod.rs grid_offset).
inline int2 bmfr_grid_offset(uint g) {
    int hb = BMFR_BLOCK / 2;
#if BMFR_GRIDS == 2
    return (int2)((int)g * hb, (int)g * hb);
#elif BMFR_GRIDS == 4
    return (int2)((int)(g & 1u) * hb, (int)(g >> 1) * hb);
#else
    return (int2)(0, 0);
#endif
}

inline int bmfr_blocks_across(uint width, int2 off) {
    return ((int)width + off.x + BMFR_BLOCK - 1) / BMFR_BLOCK;
}

// Sky, or a light seen directly: kept as it is by the fit, and no row of any fit (with `nlm` the
// selection then filters the sky and the partly covered pixels: bmfr_nlm.cl's open class). A
// light's albedo is its emission's chromaticity (kernels/render/materials.cl surface_albedo), whose
// largest channel is exactly 1 (e / max(e)), and the running mean of 1s stays 1; a light's emission
// would otherwise be fitted by the block's smooth polynomial and spread as a halo around it. Paths
// end at an emitter (kernels/render/pathtrace.cl), so a light's indirect light is exactly 0; a
// surface whose albedo is 1 in a channel (a white texel, clear glass) has some, and is fitted like
// any other (until stop 31 it was kept: on Outside, 512², 8 spp, its glass sphere and white tiles
// then carried 4.8 of bmfr's MSE-LUV of 6.74; fitted, the image's is 3.58). In a direct-light-only
// render (max_depth 1) such a surface has none and is kept. So is a pixel whose samples did not all
// hit a surface (position.w, the hits, below the frame's spp): silhouettes against the sky and
// out-of-focus edges mix sky light with a surface's mean albedo, and demodulated by that small mean
// they are outliers that would ruin their block's least-squares fit.
//
// A light also has light: its emission is in its direct light, unless the emission was taken
// out of F (BMFR_SPLIT_EMISSION; filters/bmfr_emission.cl bmfr_reflected), which leaves a
// light's direct light 0. Without that test, a pixel whose samples all ended black (clear glass
// none of whose paths reached a light) has the same albedo 1 and no indirect light, and was kept
// black among its lit neighbours (Outside 512², 8 spp: 29 such pixels;
// src/filters/bmfr/reference.rs `light`). With the split such pixels are still kept.
inline bool bmfr_light(__global const FilterVector* f) {
    bool signature = fmax(f->albedo[0], fmax(f->albedo[1], f->albedo[2])) >= 1.0f
        && f->indirect[0] == 0.0f && f->indirect[1] == 0.0f && f->indirect[2] == 0.0f;
#if BMFR_SPLIT_EMISSION
    return signature;
#else
    return signature && (f->direct[0] != 0.0f || f->direct[1] != 0.0f || f->direct[2] != 0.0f);
#endif
}

inline bool bmfr_kept(__global const FilterVector* f, __global const float4* pos, float spp) {
    return f->depth >= SKY_DEPTH || bmfr_light(f) || (*pos).w < spp;
}

// The pixel's unfiltered light, direct + indirect.
inline float3 bmfr_beauty(__global const FilterVector* f) {
    return (float3)(f->direct[0] + f->indirect[0], f->direct[1] + f->indirect[1],
                    f->direct[2] + f->indirect[2]);
}

inline float3 bmfr_albedo(__global const FilterVector* f) {
    return fmax((float3)(f->albedo[0], f->albedo[1], f->albedo[2]), (float3)(BMFR_ALBEDO_EPSILON));
}

// The raw values of the four rescaled features (position xyz, depth) of a pixel.
inline float4 bmfr_raw(__global const FilterVector* f, __global const float4* pos) {
    float4 p = *pos;
    return (float4)(p.x, p.y, p.z, f->depth);
}

// The K features of a pixel, rescaled with the block's minimum and 1 / range.
inline void bmfr_features(__global const FilterVector* f, float4 raw, float4 lo, float4 scale,
                          float* out) {
    float4 s = (raw - lo) * scale;
    out[0] = 1.0f;
    out[1] = f->normal[0];
    out[2] = f->normal[1];
    out[3] = f->normal[2];
    out[4] = s.x;
    out[5] = s.y;
    out[6] = s.z;
    out[7] = s.x * s.x;
    out[8] = s.y * s.y;
    out[9] = s.z * s.z;
    int k = 10;
#if BMFR_DEPTH
    out[k++] = s.w;
#endif
#if BMFR_TEXTURE
    out[k++] = f->albedo[0];
    out[k++] = f->albedo[1];
    out[k++] = f->albedo[2];
#endif
#if BMFR_TEXTURE2
    out[k++] = f->albedo2[0];
    out[k++] = f->albedo2[1];
    out[k++] = f->albedo2[2];
#endif
}

// Regularisation noise of feature column c at pixel i: uniform in [-noise/2, noise/2).
inline float bmfr_noise(uint pixel, uint c) {
    uint h = hash_u32(hash_u32(pixel ^ 0x62d3f1a7u) ^ c);
    return ((float)(h >> 8) * 0x1.0p-24f - 0.5f) * BMFR_NOISE;
}

// Column j's Householder reflection from its squared norm over rows >= j and its diagonal
// entry x_j: alpha = -sign(x_j) |x|, v_j = x_j - alpha, |v|^2 (bmfr_fit and bmfr_fit_packed).
inline void bmfr_reflection(float norm2, float xj, float* alpha, float* vj, float* vnorm2) {
    float norm = sqrt(norm2);
    *alpha = xj > 0.0f ? -norm : norm;
    *vj = xj - *alpha;
    *vnorm2 = norm2 - xj * xj + *vj * *vj;
}

// The factor 2 (v . a_c) / |v|^2 that the reflection subtracts times v from column c, from
// x . a_c (`dot`) and a_c's entry in row j: v . a_c = x . a_c - alpha a_c[j].
inline float bmfr_factor(float dot, float alpha, float a_cj, float vnorm2) {
    return vnorm2 > 0.0f ? 2.0f * (dot - alpha * a_cj) / vnorm2 : 0.0f;
}

// Back-substitution of R w = Q^T b for target t, into o[0..K) (both fits).
inline void bmfr_back_substitute(BMFR_MATRIX const float* a, int t, __global float* o) {
    float w[BMFR_K];
    for (int j = BMFR_K - 1; j >= 0; --j) {
        float s = a[(BMFR_K + t) * BMFR_LD + j];
        for (int i = j + 1; i < BMFR_K; ++i) s -= a[i * BMFR_LD + j] * w[i];
        float rjj = a[j * BMFR_LD + j];
        w[j] = fabs(rjj) > BMFR_PIVOT_MIN ? s / rjj : 0.0f;
        o[j] = w[j];
    }
}

__kernel __attribute__((reqd_work_group_size(BMFR_WG, 1, 1)))
void bmfr_fit(__global const FilterVector* fv,
              __global const float4* positions,
              uint width, uint height, uint grid, uint stride, float spp,
              __global float* weights,
              __global float* info,
              __global float* matrices) {
#if BMFR_GLOBAL_MATRIX
    __global float* a = matrices + (size_t)get_group_id(0) * (BMFR_C * BMFR_LD);
#else
    __local float a[BMFR_C * BMFR_LD];
#endif
    __local float partial[BMFR_WG * BMFR_C];
    __local float dots[BMFR_C];
    __local float factor[BMFR_C];
    __local float range[9];
    int t = (int)get_local_id(0);
    uint block = (uint)get_group_id(0);
    int2 off = bmfr_grid_offset(grid);
    int across = bmfr_blocks_across(width, off);
    int x0 = (int)(block % (uint)across) * BMFR_BLOCK - off.x;
    int y0 = (int)(block / (uint)across) * BMFR_BLOCK - off.y;
    uint slot = grid * stride + block;

    // Rows: raw features, targets, and the work-item's minimum and maximum of the rescaled ones.
    float4 lo = (float4)(INFINITY), hi = (float4)(-INFINITY);
    float count = 0.0f;
    for (int q = 0; q < BMFR_ROWS; ++q) {
        int r = t + q * BMFR_WG;
        int x = x0 + r % BMFR_BLOCK, y = y0 + r / BMFR_BLOCK;
        bool valid = x >= 0 && y >= 0 && x < (int)width && y < (int)height;
        uint i = valid ? (uint)y * width + (uint)x : 0u;
        valid = valid && !bmfr_kept(fv + i, positions + i, spp);
        if (!valid) {
            for (int c = 0; c < BMFR_C; ++c) a[c * BMFR_LD + r] = 0.0f;
            continue;
        }
        __global const FilterVector* f = fv + i;
        float4 raw = bmfr_raw(f, positions + i);
        lo = fmin(lo, raw);
        hi = fmax(hi, raw);
        count += 1.0f;
        a[4 * BMFR_LD + r] = raw.x;
        a[5 * BMFR_LD + r] = raw.y;
        a[6 * BMFR_LD + r] = raw.z;
        a[7 * BMFR_LD + r] = raw.w;         // parked; its column is rewritten below
        float3 alb = bmfr_albedo(f);
        float3 d = (float3)(f->direct[0], f->direct[1], f->direct[2]) / alb;
        float3 n = (float3)(f->indirect[0], f->indirect[1], f->indirect[2]) / alb;
        a[(BMFR_K + 0) * BMFR_LD + r] = d.x;
        a[(BMFR_K + 1) * BMFR_LD + r] = d.y;
        a[(BMFR_K + 2) * BMFR_LD + r] = d.z;
        a[(BMFR_K + 3) * BMFR_LD + r] = n.x;
        a[(BMFR_K + 4) * BMFR_LD + r] = n.y;
        a[(BMFR_K + 5) * BMFR_LD + r] = n.z;
    }
    partial[t * BMFR_C + 0] = lo.x;
    partial[t * BMFR_C + 1] = lo.y;
    partial[t * BMFR_C + 2] = lo.z;
    partial[t * BMFR_C + 3] = lo.w;
    partial[t * BMFR_C + 4] = hi.x;
    partial[t * BMFR_C + 5] = hi.y;
    partial[t * BMFR_C + 6] = hi.z;
    partial[t * BMFR_C + 7] = hi.w;
    partial[t * BMFR_C + 8] = count;
    barrier(BMFR_FENCE);
    if (t < 9) {
        float v = partial[t];
        for (int u = 1; u < BMFR_WG; ++u) {
            float p = partial[u * BMFR_C + t];
            v = t < 4 ? fmin(v, p) : t < 8 ? fmax(v, p) : v + p;
        }
        range[t] = v;
    }
    barrier(BMFR_FENCE);
    // The block's rescaling: minimum and 1 / (max - min); a constant feature (or no surface
    // pixel) rescales to 0.
    float4 bmin = (float4)(range[0], range[1], range[2], range[3]);
    float4 bmax = (float4)(range[4], range[5], range[6], range[7]);
    int4 spread = isless(bmin, bmax);
    float4 blo = select((float4)(0.0f), bmin, spread);
    float4 bscale = select((float4)(0.0f), (float4)(1.0f) / (bmax - bmin), spread);
    if (t == 0) {
        __global float* o = info + slot * BMFR_INFO;
        o[0] = blo.x; o[1] = blo.y; o[2] = blo.z; o[3] = blo.w;
        o[4] = bscale.x; o[5] = bscale.y; o[6] = bscale.z; o[7] = bscale.w;
        o[8] = range[8];
    }
    // Feature columns, with the regularisation noise on every column but the constant.
    for (int q = 0; q < BMFR_ROWS; ++q) {
        int r = t + q * BMFR_WG;
        int x = x0 + r % BMFR_BLOCK, y = y0 + r / BMFR_BLOCK;
        bool valid = x >= 0 && y >= 0 && x < (int)width && y < (int)height;
        uint i = valid ? (uint)y * width + (uint)x : 0u;
        if (!valid || bmfr_kept(fv + i, positions + i, spp)) continue;
        float4 raw = (float4)(a[4 * BMFR_LD + r], a[5 * BMFR_LD + r], a[6 * BMFR_LD + r],
                              a[7 * BMFR_LD + r]);
        float feat[BMFR_K];
        bmfr_features(fv + i, raw, blo, bscale, feat);
        a[r] = feat[0];
        for (int c = 1; c < BMFR_K; ++c) a[c * BMFR_LD + r] = feat[c] + bmfr_noise(i, (uint)c);
    }
    barrier(BMFR_FENCE);

    // Householder QR, column by column.
    for (int j = 0; j < BMFR_K; ++j) {
        for (int c = j; c < BMFR_C; ++c) {
            float s = 0.0f;
            for (int q = 0; q < BMFR_ROWS; ++q) {
                int r = t + q * BMFR_WG;
                if (r >= j) s += a[j * BMFR_LD + r] * a[c * BMFR_LD + r];
            }
            partial[t * BMFR_C + c] = s;
        }
        barrier(BMFR_FENCE);
        if (t >= j && t < BMFR_C) {
            float s = 0.0f;
            for (int u = 0; u < BMFR_WG; ++u) s += partial[u * BMFR_C + t];
            dots[t] = s;
        }
        barrier(BMFR_FENCE);
        if (t >= j && t < BMFR_C) {
            float alpha, vj, vnorm2;
            bmfr_reflection(dots[j], a[j * BMFR_LD + j], &alpha, &vj, &vnorm2);
            if (t == j) {
                factor[j] = vj;
                range[0] = alpha;  // the min/max are no longer needed
            } else {
                factor[t] = bmfr_factor(dots[t], alpha, a[t * BMFR_LD + j], vnorm2);
            }
        }
        barrier(BMFR_FENCE);
        float vj = factor[j];
        for (int q = 0; q < BMFR_ROWS; ++q) {
            int r = t + q * BMFR_WG;
            if (r < j) continue;
            float v = r == j ? vj : a[j * BMFR_LD + r];
            for (int c = j + 1; c < BMFR_C; ++c) a[c * BMFR_LD + r] -= factor[c] * v;
            if (r == j) a[j * BMFR_LD + j] = range[0];
        }
        barrier(BMFR_FENCE);
    }

    // Back-substitution, one target per work-item.
    if (t < 6) bmfr_back_substitute(a, t, weights + (slot * 6u + (uint)t) * BMFR_K);
}

// The tent weight of local coordinate l in [0, B): 1 - 1/B next to the centre, 1/B at the edges.
inline float bmfr_tent(int l) {
    float d = fabs((float)l + 0.5f - 0.5f * (float)BMFR_BLOCK);
    return 1.0f - d / (0.5f * (float)BMFR_BLOCK);
}

__kernel void bmfr_apply(__global const FilterVector* fv,
                         __global const float4* positions,
                         uint width, uint height, uint stride, float spp,
                         __global const float* weights,
                         __global const float* info,
                         __global float4* out) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    __global const FilterVector* f = fv + i;
    float3 beauty = bmfr_beauty(f);
    if (bmfr_kept(f, positions + i, spp)) {
        out[i] = (float4)(beauty, 0.0f);
        return;
    }
    float4 raw = bmfr_raw(f, positions + i);
    float3 alb = bmfr_albedo(f);
    float3 sum = (float3)(0.0f);
    float wsum = 0.0f;
    // Unrolled (every trip count is a -D constant), the kernel has no loops left, and PoCL
    // packs its work-items into SIMD lanes: 20 -> 8.5 ms at 512^2, 4 grids, the same bytes
    // (profiling events before and after the pragmas, stop 33; the loop version is gone).
    #pragma unroll
    for (uint g = 0; g < BMFR_GRIDS; ++g) {
        int2 off = bmfr_grid_offset(g);
        int across = bmfr_blocks_across(width, off);
        int bx = (x + off.x) / BMFR_BLOCK, by = (y + off.y) / BMFR_BLOCK;
        uint slot = g * stride + (uint)(by * across + bx);
        __global const float* b = info + slot * BMFR_INFO;
        float4 lo = (float4)(b[0], b[1], b[2], b[3]);
        float4 scale = (float4)(b[4], b[5], b[6], b[7]);
        float feat[BMFR_K];
        bmfr_features(f, raw, lo, scale, feat);
        __global const float* wt = weights + slot * 6u * BMFR_K;
        float fit[6];
        #pragma unroll
        for (int c = 0; c < 6; ++c) {
            float s = 0.0f;
            #pragma unroll
            for (int k = 0; k < BMFR_K; ++k) s += wt[c * BMFR_K + k] * feat[k];
            fit[c] = fmax(s, 0.0f);
        }
        float3 light = ((float3)(fit[0], fit[1], fit[2]) + (float3)(fit[3], fit[4], fit[5])) * alb;
        float wg = bmfr_tent(x + off.x - bx * BMFR_BLOCK) * bmfr_tent(y + off.y - by * BMFR_BLOCK)
                 * fmin(1.0f, b[8] / (4.0f * (float)BMFR_K));
        sum += wg * light;
        wsum += wg;
    }
    out[i] = (float4)(sum / wsum, 0.0f);
}

// A pixel the selection estimates errors for: not kept, and both halves hold samples.
inline bool bmfr_surface(__global const FilterVector* f, __global const float4* pos,
                         float4 odd, float spp) {
    return !bmfr_kept(f, pos, spp) && odd.w >= 1.0f && spp - odd.w >= 1.0f;
}

// Per channel, the fit's squared residual (f - y)^2 and the variance of the frame's mean y
// estimated from the half buffers, (y - odd)^2 n_odd / n_even (bmfr_fit_error,
// bmfr_residuals_nlm).
inline void bmfr_fit_terms(float3 beauty, float3 fitted, float4 odd, float spp, float3* rr,
                           float3* v) {
    float3 r = fitted - beauty;
    float3 d = beauty - odd.xyz;
    *rr = r * r;
    *v = d * d * (odd.w / (spp - odd.w));
}

// bmfr_fit_terms summed over the channels, (R, V) (bmfr_residuals).
inline float2 bmfr_fit_error(float3 beauty, float3 fitted, float4 odd, float spp) {
    float3 rr, v;
    bmfr_fit_terms(beauty, fitted, odd, spp, &rr, &v);
    return (float2)(rr.x + rr.y + rr.z, v.x + v.y + v.z);
}

// Per-pixel selection between the fit and the unfiltered light (src/filters/bmfr/select.rs).
// bmfr_residuals: per pixel, over the three channels, the squared residual of the fit
// (f - y)^2 and the variance of y estimated from the half buffers, (y - odd)^2 n_odd / n_even;
// (0, 0) for a kept pixel or one without samples in both halves (1 spp).
__kernel void bmfr_residuals(__global const FilterVector* fv,
                             __global const float4* positions,
                             __global const float4* odd_halves,
                             uint width, uint height, float spp,
                             __global const float4* fitted,
                             __global float2* residuals) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    __global const FilterVector* f = fv + i;
    float4 odd = odd_halves[i];
    residuals[i] = bmfr_surface(f, positions + i, odd, spp)
        ? bmfr_fit_error(bmfr_beauty(f), fitted[i].xyz, odd, spp) : (float2)(0.0f);
}

// bmfr_select: the window sums R (residuals) and V (variances) over the (2 r + 1)^2 pixels
// around, row by row, and the blend y + lambda (f - y) with lambda = min(1, kappa V / R) (1
// when R = 0: no estimate).
// The selection's window: the statements between BMFR_SELECT_WINDOW_BEGIN and
// BMFR_SELECT_WINDOW_END run for each pixel j of the (2 BMFR_SELECT_RADIUS + 1)^2 window around
// (x, y) inside the image, row by row, as src/filters/bmfr/select.rs `window_for_each` does.
// Unrolled (the radius is a build constant), so that the kernel has no loop of its own and
// PoCL packs its work-items into SIMD lanes, as bmfr_apply's. Two macros rather than one
// taking the statements: OpenCL C 1.2 has no variadic macros (NVIDIA's compiler refuses them).
#define BMFR_SELECT_WINDOW_BEGIN                                                    \
    _Pragma("unroll") for (int dy = -BMFR_SELECT_RADIUS; dy <= BMFR_SELECT_RADIUS; ++dy) { \
        int yy = y + dy;                                                            \
        if (yy < 0 || yy >= (int)height) continue;                                  \
        _Pragma("unroll") for (int dx = -BMFR_SELECT_RADIUS; dx <= BMFR_SELECT_RADIUS; ++dx) { \
            int xx = x + dx;                                                        \
            if (xx < 0 || xx >= (int)width) continue;                               \
            uint j = (uint)yy * width + (uint)xx;
#define BMFR_SELECT_WINDOW_END                                                      \
        }                                                                           \
    }

__kernel void bmfr_select(__global const FilterVector* fv,
                          uint width, uint height,
                          __global const float2* residuals,
                          __global float4* fitted) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    float sum_r = 0.0f, sum_v = 0.0f;
    BMFR_SELECT_WINDOW_BEGIN
        float2 e = residuals[j];
        sum_r += e.x;
        sum_v += e.y;
    BMFR_SELECT_WINDOW_END
    float lambda = sum_r > 0.0f ? fmin(1.0f, BMFR_SELECT_SCALE * sum_v / sum_r) : 1.0f;
    float3 beauty = bmfr_beauty(fv + i);
    float3 fit = fitted[i].xyz;
    fitted[i] = (float4)(beauty + lambda * (fit - beauty), 0.0f);
}

// bmfr_albedo_prefilter (with `albedo_prefilter`, src/filters/bmfr/prefilter.rs): F copied to
// `out` with each surface pixel's mean albedo replaced by its per-pixel non-local mean over
// the (2 radius + 1)^2 window (Rousselle et al. 2012 eq. 4 at patch size 1: the distance less
// the noise the two means' variances explain), the variance of a mean being the Welford sum
// times `factor` (1 / (n - 1)) over spp. Kept pixels neither change nor lend their albedo.
// With BMFR_PREFILTER_GEOMETRY the normal, the depth and the positions' xyz (into `pos_out`)
// are averaged too, weighted by the same distance over albedo, normal and depth at
// BMFR_GEOMETRY_K (NFOR's feature prefilter: out of focus the fit would reproduce their noise,
// which is the light's); without it `pos_out` is a copy of the positions.
inline float3 bmfr_albedo_variance(__global const WelfordSums* s, float factor, float spp) {
    return (float3)(s->albedo[0] * factor / spp, s->albedo[1] * factor / spp,
                    s->albedo[2] * factor / spp);
}

// One channel's term of the prefilter's distances.
inline float bmfr_prefilter_term(float a, float b, float va, float vb, float k2) {
    float diff = a - b;
    return (diff * diff - (va + fmin(va, vb))) / (BMFR_PREFILTER_EPSILON + k2 * (va + vb));
}

#if BMFR_PREFILTER_GEOMETRY
// The geometry distance's seven channels (albedo, normal, depth) and their mean's variances.
inline void bmfr_geometry(__global const FilterVector* f, __global const WelfordSums* s,
                          float factor, float spp, float* g, float* v) {
    for (int c = 0; c < 3; ++c) {
        g[c] = f->albedo[c];
        g[3 + c] = f->normal[c];
        v[c] = s->albedo[c] * factor / spp;
        v[3 + c] = s->normal[c] * factor / spp;
    }
    g[6] = f->depth;
    v[6] = s->depth * factor / spp;
}
#endif

__kernel void bmfr_albedo_prefilter(__global const FilterVector* fv,
                                    __global const WelfordSums* sums,
                                    __global const float4* positions,
                                    uint width, uint height, float spp, float factor,
                                    uint radius,
                                    __global FilterVector* out,
                                    __global float4* pos_out) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    __global const FilterVector* f = fv + i;
    out[i] = *f;
    pos_out[i] = positions[i];
    if (bmfr_kept(f, positions + i, spp)) return;
    float k2 = BMFR_PREFILTER_K * BMFR_PREFILTER_K;
    int r = (int)radius;
    float3 vi = bmfr_albedo_variance(sums + i, factor, spp);
    float ai[3] = {f->albedo[0], f->albedo[1], f->albedo[2]};
    float vis[3] = {vi.x, vi.y, vi.z};
    float sum[3] = {0.0f, 0.0f, 0.0f};
    float wsum = 0.0f;
#if BMFR_PREFILTER_GEOMETRY
    float kg2 = BMFR_GEOMETRY_K * BMFR_GEOMETRY_K;
    float gi[7], gvi[7], gj[7], gvj[7];
    bmfr_geometry(f, sums + i, factor, spp, gi, gvi);
    // Differences from the pixel's own values are averaged (prefilter.rs: a feature constant
    // over the window stays exactly so).
    float4 pi = positions[i];
    float own[7] = {gi[3], gi[4], gi[5], gi[6], pi.x, pi.y, pi.z};
    float gsum[7] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    float gwsum = 0.0f;
#endif
    for (int yy = max(y - r, 0); yy <= min(y + r, (int)height - 1); ++yy) {
        for (int xx = max(x - r, 0); xx <= min(x + r, (int)width - 1); ++xx) {
            uint j = (uint)yy * width + (uint)xx;
            __global const FilterVector* g = fv + j;
            if (bmfr_kept(g, positions + j, spp)) continue;
            float3 vj = bmfr_albedo_variance(sums + j, factor, spp);
            float vjs[3] = {vj.x, vj.y, vj.z};
            float d2 = 0.0f;
            for (int c = 0; c < 3; ++c) d2 += bmfr_prefilter_term(ai[c], g->albedo[c], vis[c], vjs[c], k2);
            float wt = exp(-fmax(d2 / 3.0f, 0.0f));
            for (int c = 0; c < 3; ++c) sum[c] += wt * g->albedo[c];
            wsum += wt;
#if BMFR_PREFILTER_GEOMETRY
            bmfr_geometry(g, sums + j, factor, spp, gj, gvj);
            float dg = 0.0f;
            for (int c = 0; c < 7; ++c) dg += bmfr_prefilter_term(gi[c], gj[c], gvi[c], gvj[c], kg2);
            float wg = exp(-fmax(dg / 7.0f, 0.0f));
            float4 q = positions[j];
            float values[7] = {gj[3], gj[4], gj[5], gj[6], q.x, q.y, q.z};
            for (int c = 0; c < 7; ++c) gsum[c] += wg * (values[c] - own[c]);
            gwsum += wg;
#endif
        }
    }
    for (int c = 0; c < 3; ++c) out[i].albedo[c] = sum[c] / wsum;
#if BMFR_PREFILTER_GEOMETRY
    float m[7];
    for (int c = 0; c < 7; ++c) m[c] = own[c] + gsum[c] / gwsum;
    for (int c = 0; c < 3; ++c) out[i].normal[c] = m[c];
    out[i].depth = m[3];
    pos_out[i] = (float4)(m[4], m[5], m[6], positions[i].w);
#endif
}

#include "filters/bmfr_fit_packed.cl"
#include "filters/bmfr_apply_packed.cl"
#include "filters/bmfr_nlm.cl"
#include "filters/bmfr_outliers.cl"
#include "filters/bmfr_nlm_packed.cl"
#if BMFR_GUIDED
#include "filters/bmfr_guided.cl"
#include "filters/bmfr_guided_packed.cl"
#endif
#include "filters/bmfr_select_packed.cl"
#include "filters/bmfr_prefilter_packed.cl"
#include "filters/bmfr_emission.cl"
