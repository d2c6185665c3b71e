// The regression filter's fit for CPU devices (`packed_fit`, src/filters/bmfr/device.rs;
// included by filters/bmfr.cl, whose helpers it uses): `bmfr_fit`'s Householder QR with one
// work-item per block, its row loops written on float16 vectors.
//
// Why: PoCL runs a work-group's work-items as loops between its barriers and packs them into
// SIMD lanes only where a region has no loop of its own; every region of `bmfr_fit` loops over
// its work-item's rows or columns, so the QR ran on scalar floats, 4 barriers per column
// (about 60 ms per grid at 512², the filter's cost: results/README.md).
//
// Same bytes as `bmfr_fit`: row r = t + q * BMFR_WG belongs to work-item t there; here the
// BMFR_WG rows q * BMFR_WG .. (q + 1) * BMFR_WG - 1 are BMFR_WG / 16 float16 chunks whose lane
// i is work-item t = 16 m + i. A dot product's per-work-item partial sums over q are the
// lanes of the chunk accumulators (the same adds, q ascending), and they are summed over the
// work-items in the same order (t = 0, 1, ...); rows r < j are masked out of the dots and the
// updates as they are skipped there (adding ±0 to a partial sum leaves its bits; no partial
// sum is -0). The block's minimum, maximum and count are order-free (min, max; a count of
// 1s), but for the sign of a zero: a minimum over +0 and -0 may come out as either, which
// could only flip the sign of a zero feature or weight. Every other operation is `bmfr_fit`'s,
// element by element. tests/bmfr.rs checks both fits against the Rust reference.
//
// Beyond the vector lanes, two changes of order that keep the bytes: the grid-independent part
// of bmfr_fit's first loop (which pixels are rows, their raw features and demodulated targets)
// is written once per frame by `bmfr_rows` into planes that every grid's fit reads 16 rows at a
// time; and the dot products of column j with every later column are taken in one sweep over
// the rows. Measured on cornell_diffuse 512², 8 spp, 4 grids (`noisefree filter AOV.exr --filter
// bmfr --repeat 5`, binaries alternating): the work-group fit 230-245 ms, the packed fit with the
// first loop per grid 78-81 ms, with `bmfr_rows` 61-63 ms, with the one-sweep dots 55-60 ms.

#include "vectors.cl"
#include "filters/lanes.cl"

#if BMFR_WG % 16 != 0 || BMFR_BLOCK % 16 != 0
#error "noisefree: the packed bmfr fit needs BMFR_WG and BMFR_BLOCK to be multiples of 16"
#endif
#define BMFR_CHUNKS (BMFR_WG / 16)
// The columns of the optional features (bmfr_features' order).
#define BMFR_COL_TEXTURE (BMFR_COL_DEPTH + BMFR_DEPTH)
#define BMFR_COL_TEXTURE2 (BMFR_COL_TEXTURE + 3 * BMFR_TEXTURE)

#define BMFR_LANE_IDS (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)

// Plane c of `rows` holds column c of every pixel's row of the fit (0 for the pixels that are
// no surface row: sky, lights, partly covered), at c * BMFR_PLANE + BMFR_PAD + pixel; the
// BMFR_PAD floats either side of a plane let a chunk of 16 rows that starts left of the image or
// ends right of it be read with one vload16. Columns: 0 the constant 1, 1-3 the normal, 4-7 the
// raw position and depth (rescaled per block in the fit), the texture columns, the targets.
#define BMFR_PAD 16
#define BMFR_PLANE(pixels) ((pixels) + 2 * BMFR_PAD)

// The grid-independent part of bmfr_fit's first loop, once per pixel for every grid's fit.
// Global size: width x height.
__kernel void bmfr_rows(__global const FilterVector* fv,
                        __global const float4* positions,
                        uint width, uint height, float spp,
                        __global float* rows) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    size_t plane = BMFR_PLANE((size_t)width * height);
    __global float* o = rows + BMFR_PAD + i;
    __global const FilterVector* f = fv + i;
    if (bmfr_kept(f, positions + i, spp)) {
        for (int c = 0; c < BMFR_C; ++c) o[c * plane] = 0.0f;
        return;
    }
    float4 raw = bmfr_raw(f, positions + i);
    float col[BMFR_C];
    for (int c = 0; c < BMFR_C; ++c) col[c] = 0.0f;
    col[0] = 1.0f;
    col[1] = f->normal[0];
    col[2] = f->normal[1];
    col[3] = f->normal[2];
    col[4] = raw.x;
    col[5] = raw.y;
    col[6] = raw.z;
    col[7] = raw.w;
#if BMFR_TEXTURE
    for (int k = 0; k < 3; ++k) col[BMFR_COL_TEXTURE + k] = f->albedo[k];
#endif
#if BMFR_TEXTURE2
    for (int k = 0; k < 3; ++k) col[BMFR_COL_TEXTURE2 + k] = f->albedo2[k];
#endif
    float3 alb = bmfr_albedo(f);
    float3 d = (float3)(f->direct[0], f->direct[1], f->direct[2]) / alb;
    float3 n = (float3)(f->indirect[0], f->indirect[1], f->indirect[2]) / alb;
    col[BMFR_K + 0] = d.x;
    col[BMFR_K + 1] = d.y;
    col[BMFR_K + 2] = d.z;
    col[BMFR_K + 3] = n.x;
    col[BMFR_K + 4] = n.y;
    col[BMFR_K + 5] = n.z;
    for (int c = 0; c < BMFR_C; ++c) o[c * plane] = col[c];
}

// Its matrix is in local memory: left out of a build that puts bmfr_fit's in global memory
// (BMFR_GLOBAL_MATRIX, a device with too little local memory), where it is not used.
#if !BMFR_GLOBAL_MATRIX
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bmfr_fit_packed(__global const float* rows,
                     uint width, uint height, uint grid, uint stride,
                     __global float* weights,
                     __global float* info) {
    __local float a[BMFR_C * BMFR_LD];
    float factor[BMFR_C];
    uint block = (uint)get_group_id(0);
    int2 off = bmfr_grid_offset(grid);
    int across = bmfr_blocks_across(width, off);
    int x0 = (int)(block % (uint)across) * BMFR_BLOCK - off.x;
    int y0 = (int)(block / (uint)across) * BMFR_BLOCK - off.y;
    uint slot = grid * stride + block;
    size_t plane = BMFR_PLANE((size_t)width * height);

    // The block's rows from the planes, 16 at a time (one image row each), and the minimum,
    // maximum and count of its surface rows (bmfr_fit's first loop).
    float16 lo16[4], hi16[4];
    for (int k = 0; k < 4; ++k) {
        lo16[k] = (float16)(INFINITY);
        hi16[k] = (float16)(-INFINITY);
    }
    int16 count16 = (int16)(0);
    for (int r0 = 0; r0 < BMFR_N; r0 += 16) {
        int y = y0 + r0 / BMFR_BLOCK, xs = x0 + r0 % BMFR_BLOCK;
        if (y < 0 || y >= (int)height || xs + 15 < 0 || xs >= (int)width) {
            for (int c = 0; c < BMFR_C; ++c) store16_local((float16)(0.0f), a + c * BMFR_LD + r0);
            continue;
        }
        int16 x = (int16)(xs) + BMFR_LANE_IDS;
        __global const float* at = rows + BMFR_PAD + (size_t)((long)y * width + xs);
        int16 inside = x >= 0 && x < (int)width;
        int16 surface = inside && load16(at) != 0.0f;
        for (int c = 0; c < BMFR_C; ++c)
            store16_local(select((float16)(0.0f), load16(at + c * plane), surface),
                          a + c * BMFR_LD + r0);
        for (int k = 0; k < 4; ++k) {
            float16 raw = load16_local(a + (4 + k) * BMFR_LD + r0);
            lo16[k] = select(lo16[k], fmin(lo16[k], raw), surface);
            hi16[k] = select(hi16[k], fmax(hi16[k], raw), surface);
        }
        count16 -= surface;                       // -1 per surface lane
    }
    float lo_[4], hi_[4];
    for (int k = 0; k < 4; ++k) {
        float l[16], h[16];
        vstore16(lo16[k], 0, l);
        vstore16(hi16[k], 0, h);
        lo_[k] = INFINITY;
        hi_[k] = -INFINITY;
        for (int u = 0; u < 16; ++u) {
            lo_[k] = fmin(lo_[k], l[u]);
            hi_[k] = fmax(hi_[k], h[u]);
        }
    }
    int counts[16];
    vstore16(count16, 0, counts);
    int total = 0;
    for (int u = 0; u < 16; ++u) total += counts[u];
    float4 lo = (float4)(lo_[0], lo_[1], lo_[2], lo_[3]);
    float4 hi = (float4)(hi_[0], hi_[1], hi_[2], hi_[3]);
    float count = (float)total;
    int4 spread = isless(lo, hi);
    float4 blo = select((float4)(0.0f), lo, spread);
    float4 bscale = select((float4)(0.0f), (float4)(1.0f) / (hi - lo), spread);
    __global float* o = info + slot * BMFR_INFO;
    o[0] = blo.x; o[1] = blo.y; o[2] = blo.z; o[3] = blo.w;
    o[4] = bscale.x; o[5] = bscale.y; o[6] = bscale.z; o[7] = bscale.w;
    o[8] = count;
    // The feature columns (bmfr_features) with the regularisation noise (bmfr_noise), 16 rows
    // of one image row at a time: the same operations lane by lane; rows that are no surface
    // row (constant column 0) stay 0.
    for (int r0 = 0; r0 < BMFR_N; r0 += 16) {
        float16 one = load16_local(a + r0);
        int16 surface = one != 0.0f;
        int16 x = (int16)(x0 + r0 % BMFR_BLOCK) + BMFR_LANE_IDS;
        uint16 i = convert_uint16((int16)((y0 + r0 / BMFR_BLOCK) * (int)width) + x);
        uint16 h = hash_u32_16(i ^ 0x62d3f1a7u);
#define BMFR_NOISE16(c)                                                                        \
    ((convert_float16(hash_u32_16(h ^ (uint)(c)) >> 8) * 0x1.0p-24f - 0.5f) * BMFR_NOISE)
#define BMFR_PUT(c, v) store16_local(select((float16)(0.0f), (v) + BMFR_NOISE16(c), surface), \
                                     a + (c) * BMFR_LD + r0)
        float16 sx = (load16_local(a + 4 * BMFR_LD + r0) - blo.x) * bscale.x;
        float16 sy = (load16_local(a + 5 * BMFR_LD + r0) - blo.y) * bscale.y;
        float16 sz = (load16_local(a + 6 * BMFR_LD + r0) - blo.z) * bscale.z;
        float16 sw = (load16_local(a + 7 * BMFR_LD + r0) - blo.w) * bscale.w;
        for (int c = 1; c <= 3; ++c) BMFR_PUT(c, load16_local(a + c * BMFR_LD + r0));
        BMFR_PUT(4, sx);
        BMFR_PUT(5, sy);
        BMFR_PUT(6, sz);
        BMFR_PUT(7, sx * sx);
        BMFR_PUT(8, sy * sy);
        BMFR_PUT(9, sz * sz);
#if BMFR_DEPTH
        BMFR_PUT(BMFR_COL_DEPTH, sw);
#endif
#if BMFR_TEXTURE
        for (int c = BMFR_COL_TEXTURE; c < BMFR_COL_TEXTURE + 3; ++c)
            BMFR_PUT(c, load16_local(a + c * BMFR_LD + r0));
#endif
#if BMFR_TEXTURE2
        for (int c = BMFR_COL_TEXTURE2; c < BMFR_COL_TEXTURE2 + 3; ++c)
            BMFR_PUT(c, load16_local(a + c * BMFR_LD + r0));
#endif
#undef BMFR_PUT
#undef BMFR_NOISE16
    }

    // Householder QR, column by column (bmfr_fit's), the rows in float16 chunks. The dot
    // products of column j with the columns c >= j: chunk m's lanes are the partial sums of
    // work-items 16 m .. 16 m + 15, over q ascending, then the work-items' sums are added in
    // bmfr_fit's order. Column 0's are summed in a sweep of their own; column j + 1's in the
    // sweep that applies reflection j, from the columns just updated (one sweep over the
    // block's columns per step instead of two: the same sums in the same order).
    float alpha = 0.0f;
    float partial[BMFR_C][BMFR_WG];
    for (int m = 0; m < BMFR_CHUNKS; ++m) {
        float16 acc[BMFR_C];
        for (int c = 0; c < BMFR_C; ++c) acc[c] = (float16)(0.0f);
        for (int q = 0; q < BMFR_ROWS; ++q) {
            int r0 = q * BMFR_WG + 16 * m;
            // Column 0 from row 0: every row takes part.
            float16 x = load16_local(a + r0);
            for (int c = 0; c < BMFR_C; ++c) acc[c] += x * load16_local(a + c * BMFR_LD + r0);
        }
        for (int c = 0; c < BMFR_C; ++c) vstore16(acc[c], 0, partial[c] + 16 * m);
    }
    for (int j = 0; j < BMFR_K; ++j) {
        __local float* aj = a + j * BMFR_LD;
        // Each column's sum over the work-items in order, the columns side by side: one
        // chain of dependent adds per column, interleaved (the sums of bmfr_fit's order).
        float dots[BMFR_C];
        for (int c = j; c < BMFR_C; ++c) dots[c] = 0.0f;
        for (int u = 0; u < BMFR_WG; ++u)
            for (int c = j; c < BMFR_C; ++c) dots[c] += partial[c][u];
        float vnorm2;
        bmfr_reflection(dots[j], aj[j], &alpha, &factor[j], &vnorm2);
        for (int t = j + 1; t < BMFR_C; ++t)
            factor[t] = bmfr_factor(dots[t], alpha, a[t * BMFR_LD + j], vnorm2);
        float vj = factor[j];
        // Reflection j applied to the columns c > j, and column `next`'s dot products with
        // the updated columns (none after the last feature column).
        int next = j + 1;
        for (int m = 0; m < BMFR_CHUNKS; ++m) {
            float16 acc[BMFR_C];
            for (int c = next; c < BMFR_C; ++c) acc[c] = (float16)(0.0f);
            for (int q = 0; q < BMFR_ROWS; ++q) {
                int r0 = q * BMFR_WG + 16 * m;
                int16 row = BMFR_LANE_IDS + r0;
                float16 v = load16_local(aj + r0);
                if (q == 0) v = select(v, (float16)(vj), row == j);
                float16 x = (float16)(0.0f);
                for (int c = j + 1; c < BMFR_C; ++c) {
                    __local float* ac = a + c * BMFR_LD + r0;
                    float16 old = load16_local(ac);
                    float16 updated = old - factor[c] * v;
                    if (q == 0) updated = select(old, updated, row >= j);
                    store16_local(updated, ac);
                    if (next < BMFR_K) {
                        // Rows above `next` take no part: x = 0 there adds 0 (a finite
                        // column; a non-finite entry makes the fit non-finite in bmfr_fit
                        // too, at j = 0).
                        if (c == next)
                            x = q == 0 ? select((float16)(0.0f), updated, row >= next) : updated;
                        acc[c] += x * updated;
                    }
                }
            }
            if (next < BMFR_K)
                for (int c = next; c < BMFR_C; ++c) vstore16(acc[c], 0, partial[c] + 16 * m);
        }
        aj[j] = alpha;
    }

    // Back-substitution, each target in turn (bmfr_fit's).
    for (int t = 0; t < 6; ++t)
        bmfr_back_substitute(a, t, weights + (slot * 6u + (uint)t) * BMFR_K);
}
#endif  // !BMFR_GLOBAL_MATRIX
