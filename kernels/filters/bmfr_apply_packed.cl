// bmfr_apply on CPU devices (`packed_fit`, src/filters/bmfr/mod.rs): one work-item applies
// every grid's fits to the 16 adjacent pixels x0 .. x0 + 15 of a row, lane i for pixel x0 + i.
// Included by filters/bmfr.cl after bmfr_apply, whose helpers it uses.
//
// Why: PoCL ran bmfr_apply on scalar floats and float3s (`perf annotate`: vmovss, vinsertps,
// vmulps on xmm registers; 5.6 % of the device's float16 FMA peak in `bench --study
// roofline`), each pixel reading its block's 6 K weights. Here the 16 pixels of a work-item
// lie in at most two blocks of a grid (blocks are at least 16 wide and start at multiples of
// half a block), so each weight is read once and multiplies all lanes of a block at once.
//
// The same bytes as bmfr_apply: every lane does bmfr_apply's float operations in its order
// (the features, the six fits summed over k, the tent weights, the sums over the grids, the
// division; FP_CONTRACT OFF from bmfr.cl). A work-item whose lanes span two blocks computes
// both blocks' fits and each lane keeps its own block's (select()). Kept pixels and lanes past
// the image's right edge are computed with the others and not written from them.

#if BMFR_BLOCK < 16
#error "noisefree: bmfr_apply_packed needs blocks at least 16 wide (two blocks per 16 lanes)"
#endif

// F's float `lane` (FILTER_VECTOR_*) of the pixels i .. i + 15 as lanes 0 .. 15 (lanes past the row's last pixel
// `last` repeat it).
inline float16 bmfr_fv_lanes(__global const FilterVector* fv, uint i, uint last, int lane) {
    float v[16];
    for (uint k = 0; k < 16; ++k)
        v[k] = ((__global const float*)(fv + min(i + k, last)))[lane];
    return vload16(0, v);
}

// The fits of block `slot` for the lanes' features (bmfr_features on float16 lanes) and the
// light they give: (fit of the direct + fit of the indirect) x albedo, per channel.
inline void bmfr_block_light16(__global const float* weights, __global const float* info,
                               uint slot, const float16 raw[4], const float16 normal[3],
                               const float16 albedo[3], const float16 texture[3],
                               const float16 texture2[3], float16 light[3]) {
    __global const float* b = info + slot * BMFR_INFO;
    float16 s[4];
    for (int c = 0; c < 4; ++c) s[c] = (raw[c] - b[c]) * b[4 + c];
    float16 feat[BMFR_K];
    feat[0] = (float16)(1.0f);
    for (int c = 0; c < 3; ++c) feat[1 + c] = normal[c];
    for (int c = 0; c < 3; ++c) feat[4 + c] = s[c];
    for (int c = 0; c < 3; ++c) feat[7 + c] = s[c] * s[c];
    int k = 10;
#if BMFR_DEPTH
    feat[k++] = s[3];
#endif
#if BMFR_TEXTURE
    for (int c = 0; c < 3; ++c) feat[k++] = texture[c];
#endif
#if BMFR_TEXTURE2
    for (int c = 0; c < 3; ++c) feat[k++] = texture2[c];
#endif
    __global const float* wt = weights + slot * 6u * BMFR_K;
    float16 fit[6];
    #pragma unroll
    for (int c = 0; c < 6; ++c) {
        float16 sum = (float16)(0.0f);
        #pragma unroll
        for (int j = 0; j < BMFR_K; ++j) sum += wt[c * BMFR_K + j] * feat[j];
        fit[c] = fmax(sum, 0.0f);
    }
    for (int c = 0; c < 3; ++c) light[c] = (fit[c] + fit[3 + c]) * albedo[c];
}

// bmfr_tent on float16 lanes.
inline float16 bmfr_tent16(int16 l) {
    float16 d = fabs(convert_float16(l) + 0.5f - 0.5f * (float)BMFR_BLOCK);
    return 1.0f - d / (0.5f * (float)BMFR_BLOCK);
}

// Global size: ceil(width / 16) x height, work-groups of 1.
__kernel void bmfr_apply_packed(__global const FilterVector* fv,
                                __global const float4* positions,
                                uint width, uint height, uint stride, float spp,
                                __global const float* weights,
                                __global const float* info,
                                __global float4* out) {
    int x0 = get_global_id(0) * 16, y = get_global_id(1);
    int w = (int)width, h = (int)height;
    if (x0 >= w || y >= h) return;
    int lanes = min(16, w - x0);
    uint i = (uint)y * width + (uint)x0, last = i + (uint)lanes - 1u;
    int16 xs = (int16)(x0) + (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    // The lanes' inputs (FilterVector's float lanes: layout.cl).
    float16 raw[4], normal[3], albedo[3], texture[3], texture2[3];
    float p[4][16];
    for (int k = 0; k < 16; ++k) {
        float4 q = positions[min(i + (uint)k, last)];
        p[0][k] = q.x;
        p[1][k] = q.y;
        p[2][k] = q.z;
    }
    for (int c = 0; c < 3; ++c) raw[c] = vload16(0, p[c]);
    raw[3] = bmfr_fv_lanes(fv, i, last, FILTER_VECTOR_DEPTH);
    for (int c = 0; c < 3; ++c) {
        normal[c] = bmfr_fv_lanes(fv, i, last, FILTER_VECTOR_NORMAL + c);
        texture[c] = bmfr_fv_lanes(fv, i, last, FILTER_VECTOR_ALBEDO + c);
        texture2[c] = bmfr_fv_lanes(fv, i, last, FILTER_VECTOR_ALBEDO2 + c);
        albedo[c] = fmax(texture[c], BMFR_ALBEDO_EPSILON);   // bmfr_albedo
    }
    float16 sum[3] = {(float16)(0.0f), (float16)(0.0f), (float16)(0.0f)};
    float16 wsum = (float16)(0.0f);
    #pragma unroll
    for (uint g = 0; g < BMFR_GRIDS; ++g) {
        int2 off = bmfr_grid_offset(g);
        int across = bmfr_blocks_across(width, off);
        int by = (y + off.y) / BMFR_BLOCK;
        // The first lane's block and the last lane's (lanes past the edge: the last pixel's).
        int bx_first = (x0 + off.x) / BMFR_BLOCK, bx_last = (x0 + lanes - 1 + off.x) / BMFR_BLOCK;
        int16 bx = min((xs + off.x) / BMFR_BLOCK, (int16)(bx_last));
        uint slot = g * stride + (uint)(by * across + bx_first);
        float16 light[3];
        bmfr_block_light16(weights, info, slot, raw, normal, albedo, texture, texture2, light);
        float16 count = (float16)(info[slot * BMFR_INFO + 8]);
        if (bx_last != bx_first) {
            uint slot2 = g * stride + (uint)(by * across + bx_last);
            float16 light2[3];
            bmfr_block_light16(weights, info, slot2, raw, normal, albedo, texture, texture2,
                               light2);
            int16 second = bx == bx_last;
            for (int c = 0; c < 3; ++c) light[c] = select(light[c], light2[c], second);
            count = select(count, (float16)(info[slot2 * BMFR_INFO + 8]), second);
        }
        float16 wg = bmfr_tent16(xs + off.x - bx * BMFR_BLOCK)
                   * bmfr_tent(y + off.y - by * BMFR_BLOCK)
                   * fmin(1.0f, count / (4.0f * (float)BMFR_K));
        for (int c = 0; c < 3; ++c) sum[c] += wg * light[c];
        wsum += wg;
    }
    float o[3][16];
    for (int c = 0; c < 3; ++c) vstore16(sum[c] / wsum, 0, o[c]);
    for (int k = 0; k < lanes; ++k) {
        __global const FilterVector* f = fv + i + k;
        out[i + k] = bmfr_kept(f, positions + i + k, spp) ? (float4)(bmfr_beauty(f), 0.0f)
                                                         : (float4)(o[0][k], o[1][k], o[2][k], 0.0f);
    }
}
