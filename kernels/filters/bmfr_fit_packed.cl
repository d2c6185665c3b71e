// The regression filter's fit for CPU devices (`fit = "packed"`, src/filters/bmfr/device.rs;
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
// updates as they are skipped there (adding +0 to a partial sum leaves its bits; no partial
// sum is -0). The block's minimum, maximum and count are order-free (min, max; a count of
// 1s). Every other operation is `bmfr_fit`'s, element by element. tests/bmfr.rs checks both
// fits against the Rust reference.

#if BMFR_WG % 16 != 0
#error "noisefree: the packed bmfr fit needs BMFR_WG to be a multiple of 16"
#endif
#define BMFR_CHUNKS (BMFR_WG / 16)
#define BMFR_LANE_IDS (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bmfr_fit_packed(__global const FilterVector* fv,
                     __global const float4* positions,
                     uint width, uint height, uint grid, uint stride, float spp,
                     __global float* weights,
                     __global float* info) {
    __local float a[BMFR_C * BMFR_N];
    float factor[BMFR_C];
    uint block = (uint)get_group_id(0);
    int2 off = bmfr_grid_offset(grid);
    int across = bmfr_blocks_across(width, off);
    int x0 = (int)(block % (uint)across) * BMFR_BLOCK - off.x;
    int y0 = (int)(block / (uint)across) * BMFR_BLOCK - off.y;
    uint slot = grid * stride + block;

    // Rows: raw features, targets, the minimum and maximum of the rescaled ones (bmfr_fit).
    float4 lo = (float4)(INFINITY), hi = (float4)(-INFINITY);
    float count = 0.0f;
    for (int r = 0; r < BMFR_N; ++r) {
        int x = x0 + r % BMFR_BLOCK, y = y0 + r / BMFR_BLOCK;
        bool valid = x >= 0 && y >= 0 && x < (int)width && y < (int)height;
        uint i = valid ? (uint)y * width + (uint)x : 0u;
        valid = valid && !bmfr_kept(fv + i, positions + i, spp);
        if (!valid) {
            for (int c = 0; c < BMFR_C; ++c) a[c * BMFR_N + r] = 0.0f;
            continue;
        }
        __global const FilterVector* f = fv + i;
        float4 raw = bmfr_raw(f, positions + i);
        lo = fmin(lo, raw);
        hi = fmax(hi, raw);
        count += 1.0f;
        a[4 * BMFR_N + r] = raw.x;
        a[5 * BMFR_N + r] = raw.y;
        a[6 * BMFR_N + r] = raw.z;
        a[7 * BMFR_N + r] = raw.w;
        float3 alb = bmfr_albedo(f);
        float3 d = (float3)(f->direct[0], f->direct[1], f->direct[2]) / alb;
        float3 n = (float3)(f->indirect[0], f->indirect[1], f->indirect[2]) / alb;
        a[(BMFR_K + 0) * BMFR_N + r] = d.x;
        a[(BMFR_K + 1) * BMFR_N + r] = d.y;
        a[(BMFR_K + 2) * BMFR_N + r] = d.z;
        a[(BMFR_K + 3) * BMFR_N + r] = n.x;
        a[(BMFR_K + 4) * BMFR_N + r] = n.y;
        a[(BMFR_K + 5) * BMFR_N + r] = n.z;
    }
    int4 spread = isless(lo, hi);
    float4 blo = select((float4)(0.0f), lo, spread);
    float4 bscale = select((float4)(0.0f), (float4)(1.0f) / (hi - lo), spread);
    __global float* o = info + slot * BMFR_INFO;
    o[0] = blo.x; o[1] = blo.y; o[2] = blo.z; o[3] = blo.w;
    o[4] = bscale.x; o[5] = bscale.y; o[6] = bscale.z; o[7] = bscale.w;
    o[8] = count;
    for (int r = 0; r < BMFR_N; ++r) {
        int x = x0 + r % BMFR_BLOCK, y = y0 + r / BMFR_BLOCK;
        bool valid = x >= 0 && y >= 0 && x < (int)width && y < (int)height;
        uint i = valid ? (uint)y * width + (uint)x : 0u;
        if (!valid || bmfr_kept(fv + i, positions + i, spp)) continue;
        float4 raw = (float4)(a[4 * BMFR_N + r], a[5 * BMFR_N + r], a[6 * BMFR_N + r],
                              a[7 * BMFR_N + r]);
        float feat[BMFR_K];
        bmfr_features(fv + i, raw, blo, bscale, feat);
        a[r] = feat[0];
        for (int c = 1; c < BMFR_K; ++c) a[c * BMFR_N + r] = feat[c] + bmfr_noise(i, (uint)c);
    }

    // Householder QR, column by column (bmfr_fit's), the rows in float16 chunks.
    float alpha = 0.0f;
    for (int j = 0; j < BMFR_K; ++j) {
        __local float* aj = a + j * BMFR_N;
        float dots[BMFR_C];
        for (int c = j; c < BMFR_C; ++c) {
            __local float* ac = a + c * BMFR_N;
            float16 acc[BMFR_CHUNKS];
            for (int m = 0; m < BMFR_CHUNKS; ++m) acc[m] = (float16)(0.0f);
            for (int q = 0; q < BMFR_ROWS; ++q) {
                for (int m = 0; m < BMFR_CHUNKS; ++m) {
                    int r0 = q * BMFR_WG + 16 * m;
                    float16 p = vload16(0, aj + r0) * vload16(0, ac + r0);
                    if (q == 0) p = select((float16)(0.0f), p, BMFR_LANE_IDS + r0 >= j);
                    acc[m] += p;
                }
            }
            // The work-items' partial sums, summed in bmfr_fit's order.
            float partial[BMFR_WG];
            for (int m = 0; m < BMFR_CHUNKS; ++m) vstore16(acc[m], 0, partial + 16 * m);
            float s = 0.0f;
            for (int u = 0; u < BMFR_WG; ++u) s += partial[u];
            dots[c] = s;
        }
        for (int t = j; t < BMFR_C; ++t) {
            float norm2 = dots[j];
            float xj = aj[j];
            float norm = sqrt(norm2);
            float al = xj > 0.0f ? -norm : norm;
            float vj = xj - al;
            float vnorm2 = norm2 - xj * xj + vj * vj;
            if (t == j) {
                factor[j] = vj;
                alpha = al;
            } else {
                factor[t] = vnorm2 > 0.0f ? 2.0f * (dots[t] - al * a[t * BMFR_N + j]) / vnorm2
                                          : 0.0f;
            }
        }
        float vj = factor[j];
        for (int q = 0; q < BMFR_ROWS; ++q) {
            for (int m = 0; m < BMFR_CHUNKS; ++m) {
                int r0 = q * BMFR_WG + 16 * m;
                int16 row = BMFR_LANE_IDS + r0;
                float16 v = vload16(0, aj + r0);
                if (q == 0) v = select(v, (float16)(vj), row == j);
                for (int c = j + 1; c < BMFR_C; ++c) {
                    __local float* ac = a + c * BMFR_N + r0;
                    float16 old = vload16(0, ac);
                    float16 updated = old - factor[c] * v;
                    if (q == 0) updated = select(old, updated, row >= j);
                    vstore16(updated, 0, ac);
                }
            }
        }
        aj[j] = alpha;
    }

    // Back-substitution, each target in turn (bmfr_fit's).
    for (int t = 0; t < 6; ++t) {
        float w[BMFR_K];
        __global float* ow = weights + (slot * 6u + (uint)t) * BMFR_K;
        for (int j = BMFR_K - 1; j >= 0; --j) {
            float s = a[(BMFR_K + t) * BMFR_N + j];
            for (int i = j + 1; i < BMFR_K; ++i) s -= a[i * BMFR_N + j] * w[i];
            float rjj = a[j * BMFR_N + j];
            w[j] = fabs(rjj) > BMFR_PIVOT_MIN ? s / rjj : 0.0f;
            ow[j] = w[j];
        }
    }
}
