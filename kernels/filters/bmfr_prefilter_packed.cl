// bmfr's albedo prefilter on CPU devices (`packed_nlm`, src/filters/bmfr/prefilter.rs): the
// equations of bmfr_albedo_prefilter (filters/bmfr.cl) with one work-item filtering
// BMFR_NLM_PACK (16) adjacent pixels of a row on float16 lanes, over "lines" of floats as the
// packed non-local means (filters/bmfr_nlm_packed.cl, included before this file, which has the
// layout and the padding's reasons): BMFR_PREFILTER_LINES lines per row, 0-2 the mean albedo,
// 3-5 its variance (bmfr_albedo_variance), 6 a 1 for a pixel that takes part (not kept); with
// BMFR_PREFILTER_GEOMETRY also 7-9 the normal, 10 the depth, 11-14 their variances and 15-17
// the position.
//
// Why: bmfr_albedo_prefilter loops over its window per work-item, so PoCL runs it on scalar
// floats with a scalar exp (40-56 ms of bmfr's time at 512^2 on the depth-of-field scenes).
// The taps in the same order with the same float operations (FP_CONTRACT OFF); a tap outside
// the image or on a kept pixel has weight 0 here where the scalar kernel skips it (0 x a
// finite albedo adds nothing). Measured against the Rust reference: tests/bmfr.rs.

#include "vectors.cl"

// BMFR_PREFILTER_LINES comes from the build options (src/filters/bmfr/prefilter.rs
// prefilter_packed_lines), which size the lines' buffer.
#if (BMFR_PREFILTER_GEOMETRY && BMFR_PREFILTER_LINES != 18) \
    || (!BMFR_PREFILTER_GEOMETRY && BMFR_PREFILTER_LINES != 7)
#error "noisefree: BMFR_PREFILTER_LINES does not match the lines this file writes"
#endif

// bmfr_albedo_prefilter's inputs into lines. Global size: width x height.
__kernel void bmfr_prefilter_lines(__global const FilterVector* fv,
                                   __global const WelfordSums* sums,
                                   __global const float4* positions,
                                   uint width, uint height, float spp, float factor,
                                   uint stride,
                                   __global float* lines) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    __global const FilterVector* f = fv + i;
    float3 v = bmfr_albedo_variance(sums + i, factor, spp);
    __global float* at = lines + bmfr_line_at(x, y, BMFR_PREFILTER_LINES, stride);
    for (int c = 0; c < 3; ++c) at[c * (size_t)stride] = f->albedo[c];
    at[3 * (size_t)stride] = v.x;
    at[4 * (size_t)stride] = v.y;
    at[5 * (size_t)stride] = v.z;
    at[6 * (size_t)stride] = bmfr_kept(f, positions + i, spp) ? 0.0f : 1.0f;
#if BMFR_PREFILTER_GEOMETRY
    float g[7], gv[7];
    bmfr_geometry(f, sums + i, factor, spp, g, gv);
    float4 p = positions[i];
    float rest[11] = {g[3], g[4], g[5], g[6], gv[3], gv[4], gv[5], gv[6], p.x, p.y, p.z};
    for (int c = 0; c < 11; ++c) at[(7 + c) * (size_t)stride] = rest[c];
#endif
}

// bmfr_albedo_prefilter on BMFR_NLM_PACK pixels of a row. Global size: ceil(width / PACK) x
// height, work-groups of 1.
__kernel void bmfr_albedo_prefilter_packed(__global const FilterVector* fv,
                                           __global const float4* positions,
                                           uint width, uint height,
                                           __global const float* lines,
                                           uint stride, uint radius,
                                           __global FilterVector* out,
                                           __global float4* pos_out) {
    int x0 = get_global_id(0) * BMFR_NLM_PACK, y = get_global_id(1);
    int w = (int)width, h = (int)height, r = (int)radius;
    if (x0 >= w || y >= h) return;
    float k2 = BMFR_PREFILTER_K * BMFR_PREFILTER_K;
    __global const float* p = lines + bmfr_line_at(x0, y, BMFR_PREFILTER_LINES, stride);
    float16 ai[3], vi[3];
    for (int c = 0; c < 3; ++c) {
        ai[c] = load16(p + c * (size_t)stride);
        vi[c] = load16(p + (3 + c) * (size_t)stride);
    }
    float16 sum[3] = {(float16)(0.0f), (float16)(0.0f), (float16)(0.0f)};
    float16 wsum = (float16)(0.0f);
#if BMFR_PREFILTER_GEOMETRY
    // The geometry's channels 3-6 (normal, depth) and their variances; 0-2 are the albedo's.
    float kg2 = BMFR_GEOMETRY_K * BMFR_GEOMETRY_K;
    float16 gi[4], gvi[4];
    #pragma unroll
    for (int c = 0; c < 4; ++c) {
        gi[c] = load16(p + (7 + c) * (size_t)stride);
        gvi[c] = load16(p + (11 + c) * (size_t)stride);
    }
    // Differences from each lane's own values are averaged (bmfr_albedo_prefilter).
    float16 own[7];
    #pragma unroll
    for (int c = 0; c < 4; ++c) own[c] = gi[c];
    #pragma unroll
    for (int c = 4; c < 7; ++c) own[c] = load16(p + (11 + c) * (size_t)stride);
    float16 gsum[7];
    #pragma unroll
    for (int c = 0; c < 7; ++c) gsum[c] = (float16)(0.0f);
    float16 gwsum = (float16)(0.0f);
#endif
    for (int yy = max(y - r, 0); yy <= min(y + r, h - 1); ++yy) {
        for (int dx = -r; dx <= r; ++dx) {
            if (x0 + dx + BMFR_NLM_PACK - 1 < 0 || x0 + dx >= w) continue;  // no lane inside
            __global const float* q = lines + bmfr_line_at(x0 + dx, yy, BMFR_PREFILTER_LINES,
                                                           stride);
            float16 aj[3], vj[3];
            float16 d2 = (float16)(0.0f);
            // Unrolled, as the sums below: PoCL keeps private float16 arrays on the stack
            // unless their loops are unrolled.
            #pragma unroll
            for (int c = 0; c < 3; ++c) {
                aj[c] = load16(q + c * (size_t)stride);
                vj[c] = load16(q + (3 + c) * (size_t)stride);
                float16 diff = ai[c] - aj[c];
                d2 += (diff * diff - (vi[c] + fmin(vi[c], vj[c])))
                    / (BMFR_PREFILTER_EPSILON + k2 * (vi[c] + vj[c]));
            }
            int16 part = load16(q + 6 * (size_t)stride) != 0.0f;
            float16 wt = part ? exp(-fmax(d2 / 3.0f, 0.0f)) : (float16)(0.0f);
            #pragma unroll
            for (int c = 0; c < 3; ++c) sum[c] += wt * aj[c];
            wsum += wt;
#if BMFR_PREFILTER_GEOMETRY
            // bmfr_albedo_prefilter's geometry distance: the albedo's three terms at kg, then
            // the normal's and the depth's.
            float16 dg = (float16)(0.0f);
            #pragma unroll
            for (int c = 0; c < 3; ++c) {
                float16 diff = ai[c] - aj[c];
                dg += (diff * diff - (vi[c] + fmin(vi[c], vj[c])))
                    / (BMFR_PREFILTER_EPSILON + kg2 * (vi[c] + vj[c]));
            }
            float16 gj[7];
            #pragma unroll
            for (int c = 0; c < 4; ++c) {
                gj[c] = load16(q + (7 + c) * (size_t)stride);
                float16 gvj = load16(q + (11 + c) * (size_t)stride);
                float16 diff = gi[c] - gj[c];
                dg += (diff * diff - (gvi[c] + fmin(gvi[c], gvj)))
                    / (BMFR_PREFILTER_EPSILON + kg2 * (gvi[c] + gvj));
            }
            #pragma unroll
            for (int c = 4; c < 7; ++c) gj[c] = load16(q + (11 + c) * (size_t)stride);
            float16 wg = part ? exp(-fmax(dg / 7.0f, 0.0f)) : (float16)(0.0f);
            #pragma unroll
            for (int c = 0; c < 7; ++c) gsum[c] += wg * (gj[c] - own[c]);
            gwsum += wg;
#endif
        }
    }
    float mean[3][BMFR_NLM_PACK];
    for (int c = 0; c < 3; ++c) vstore16(sum[c] / wsum, 0, mean[c]);
#if BMFR_PREFILTER_GEOMETRY
    float gmean[7][BMFR_NLM_PACK];
    for (int c = 0; c < 7; ++c) vstore16(own[c] + gsum[c] / gwsum, 0, gmean[c]);
#endif
    for (int lane = 0; lane < BMFR_NLM_PACK && x0 + lane < w; ++lane) {
        uint i = (uint)y * width + (uint)(x0 + lane);
        out[i] = fv[i];
        pos_out[i] = positions[i];
        // A kept pixel keeps its albedo (its own weight is 0: no mean).
        if (p[6 * (size_t)stride + lane] == 0.0f) continue;
        for (int c = 0; c < 3; ++c) out[i].albedo[c] = mean[c][lane];
#if BMFR_PREFILTER_GEOMETRY
        for (int c = 0; c < 3; ++c) out[i].normal[c] = gmean[c][lane];
        out[i].depth = gmean[3][lane];
        pos_out[i] = (float4)(gmean[4][lane], gmean[5][lane], gmean[6][lane], positions[i].w);
#endif
    }
}
