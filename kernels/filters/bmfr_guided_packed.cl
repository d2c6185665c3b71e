// The guided filter's passes on CPU devices (`packed_nlm`, src/filters/bmfr/guided.rs): the
// equations of filters/bmfr_guided.cl (included before this file) with one work-item taking
// 16 adjacent pixels x0 .. x0 + 15 of a row, lane i for pixel x0 + i, every operation written
// on float16 vectors (lane ids: BMFR_LANE_IDS, filters/bmfr_fit_packed.cl).
//
// Why: PoCL ran bmfr_guided's four kernels one pixel per work-item on scalar floats, with the
// 91 moments, the 6 x 6 Cholesky factor and the nine right-hand sides in private arrays that
// it kept on the stack: 540 ms of bmfr's 613 at 512² (results/README.md, bmfr "Stop 57").
// Here the arrays' indices are constants after unrolling and each operation serves 16 pixels.
//
// Layout: the packed non-local means' lines (filters/bmfr_nlm_packed.cl `bmfr_line_at`, the
// same stride and padding). Inputs: the non-local means' input lines (the demodulated light of
// the frame, the odd and the even half in lines 0-8, the class in line 13) and the six guides'
// lines (`bmfr_guided_guide_lines`). The moments, the models and the models' row sums are
// planes of lines too (BMFR_GUIDED_MOMENTS or BMFR_GUIDED_MODEL lines per image row). The
// padding left of each line is never written and stays 0 (the buffers are zeroed once); a
// lane right of the image writes zeros, so a row sum that reaches past either edge adds what
// the one-pixel kernels skip as 0 (select(), so not even a zero's sign differs).
//
// `fv` is the frame's argument that every selection kernel takes (src/filters/bmfr/device.rs);
// only the evaluation reads it.
//
// The same float operations in the same order as bmfr_guided.cl and the Rust reference (row
// sums left to right, column sums top to bottom; FP_CONTRACT OFF from bmfr.cl). Measured
// against the reference: tests/bmfr.rs.

#define BMFR_GUIDED_PACK 16
#if BMFR_GUIDED_RADIUS > BMFR_NLM_PAD
#error "noisefree: BMFR_GUIDED_RADIUS must be at most BMFR_NLM_PAD (guided.rs)"
#endif

// bmfr_guided_guides into lines: guide d of pixel (x, y) at bmfr_line_at(x, y, BMFR_GUIDES,
// stride) + d * stride. Global size: width x height.
__kernel void bmfr_guided_guide_lines(__global const FilterVector* fv,
                                      __global const float4* positions, uint width,
                                      uint height, uint stride, __global float* guides) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    size_t i = (size_t)y * width + x;
    float g[BMFR_GUIDES];
    bmfr_guided_guides(fv + i, positions + i, g);
    __global float* at = guides + bmfr_line_at(x, y, BMFR_GUIDES, stride);
    for (int d = 0; d < BMFR_GUIDES; ++d) at[d * (size_t)stride] = g[d];
}

// bmfr_guided_rows for 16 pixels: the surface pixels' moments (bmfr_guided_add_moments, per
// lane) summed over x - r .. x + r. Global size: ceil(width / 16) x height, work-groups of 1.
__kernel void bmfr_guided_rows_packed(__global const FilterVector* fv,
                                      uint width, uint height, uint stride,
                                      __global const float* nlm_lines,
                                      __global const float* guides, __global float* planes) {
    int x0 = get_global_id(0) * BMFR_GUIDED_PACK, y = get_global_id(1);
    if (x0 >= (int)width || y >= (int)height) return;
    float16 acc[BMFR_GUIDED_MOMENTS];
    #pragma unroll
    for (int c = 0; c < BMFR_GUIDED_MOMENTS; ++c) acc[c] = 0.0f;
    for (int dx = -BMFR_GUIDED_RADIUS; dx <= BMFR_GUIDED_RADIUS; ++dx) {
        __global const float* u = nlm_lines + bmfr_line_at(x0 + dx, y, BMFR_NLM_LINES, stride);
        __global const float* g = guides + bmfr_line_at(x0 + dx, y, BMFR_GUIDES, stride);
        // Outside the image the class line holds 0 (padding, or right of the image never
        // written), so `take` is the one-pixel kernel's test.
        int16 take = load16(u + 13 * (size_t)stride) == BMFR_NLM_SURFACE;
        float16 x[BMFR_GUIDES], t[BMFR_GUIDED_TARGETS];
        #pragma unroll
        for (int d = 0; d < BMFR_GUIDES; ++d) x[d] = load16(g + d * (size_t)stride);
        #pragma unroll
        for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) t[k] = load16(u + k * (size_t)stride);
        acc[0] = select(acc[0], acc[0] + 1.0f, take);
        #pragma unroll
        for (int d = 0; d < BMFR_GUIDES; ++d)
            acc[1 + d] = select(acc[1 + d], acc[1 + d] + x[d], take);
        int n = 1 + BMFR_GUIDES;
        #pragma unroll
        for (int a = 0; a < BMFR_GUIDES; ++a) {
            #pragma unroll
            for (int c = a; c < BMFR_GUIDES; ++c, ++n)
                acc[n] = select(acc[n], acc[n] + x[a] * x[c], take);
        }
        #pragma unroll
        for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k, ++n)
            acc[n] = select(acc[n], acc[n] + t[k], take);
        #pragma unroll
        for (int d = 0; d < BMFR_GUIDES; ++d) {
            #pragma unroll
            for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k, ++n)
                acc[n] = select(acc[n], acc[n] + x[d] * t[k], take);
        }
    }
    int16 inside = (int16)(x0) + BMFR_LANE_IDS < (int)width;
    __global float* out = planes + bmfr_line_at(x0, y, BMFR_GUIDED_MOMENTS, stride);
    #pragma unroll
    for (int c = 0; c < BMFR_GUIDED_MOMENTS; ++c)
        store16(select((float16)(0.0f), acc[c], inside), out + c * (size_t)stride);
}

// The column sums of `n` planes of lines for the lanes x0 .. x0 + 15: rows y - r .. y + r
// inside the image, top to bottom (bmfr_guided_columns).
__attribute__((always_inline)) inline void bmfr_guided_columns_packed(
    __global const float* planes, const int n, int x0, int y, uint height, uint stride,
    float16* acc) {
    #pragma unroll
    for (int c = 0; c < n; ++c) acc[c] = 0.0f;
    int y0 = max(y - BMFR_GUIDED_RADIUS, 0), y1 = min(y + BMFR_GUIDED_RADIUS, (int)height - 1);
    for (int yy = y0; yy <= y1; ++yy) {
        __global const float* p = planes + bmfr_line_at(x0, yy, n, stride);
        #pragma unroll
        for (int c = 0; c < n; ++c) acc[c] += load16(p + c * (size_t)stride);
    }
}

// bmfr_guided_solve for 16 windows; a window without surface pixels, or a lane right of the
// image, writes zeros. Global size: ceil(width / 16) x height, work-groups of 1.
__kernel void bmfr_guided_solve_packed(__global const FilterVector* fv,
                                       uint width, uint height, uint stride,
                                       __global const float* moments, __global float* models) {
    int x0 = get_global_id(0) * BMFR_GUIDED_PACK, y = get_global_id(1);
    if (x0 >= (int)width || y >= (int)height) return;
    float16 s[BMFR_GUIDED_MOMENTS];
    bmfr_guided_columns_packed(moments, BMFR_GUIDED_MOMENTS, x0, y, height, stride, s);
    float16 m = s[0];
    int16 keep = m >= 1.0f && (int16)(x0) + BMFR_LANE_IDS < (int)width;
    float16 xm[BMFR_GUIDES], tm[BMFR_GUIDED_TARGETS];
    #pragma unroll
    for (int d = 0; d < BMFR_GUIDES; ++d) xm[d] = s[1 + d] / m;
    #pragma unroll
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) tm[k] = s[BMFR_GUIDED_T + k] / m;
    float16 c[BMFR_GUIDES][BMFR_GUIDES];
    int n = 1 + BMFR_GUIDES;
    #pragma unroll
    for (int a = 0; a < BMFR_GUIDES; ++a) {
        #pragma unroll
        for (int b = a; b < BMFR_GUIDES; ++b, ++n) {
            float16 v = s[n] / m - xm[a] * xm[b];
            c[a][b] = a == b ? v + BMFR_GUIDED_RIDGE : v;
            c[b][a] = c[a][b];
        }
    }
    float16 l[BMFR_GUIDES][BMFR_GUIDES];
    #pragma unroll
    for (int r = 0; r < BMFR_GUIDES; ++r) {
        #pragma unroll
        for (int j = 0; j <= r; ++j) {
            float16 v = c[r][j];
            #pragma unroll
            for (int k = 0; k < j; ++k) v -= l[r][k] * l[j][k];
            l[r][j] = r == j ? sqrt(fmax(v, BMFR_GUIDED_RIDGE)) : v / l[j][j];
        }
    }
    __global float* out = models + bmfr_line_at(x0, y, BMFR_GUIDED_MODEL, stride);
    const float16 zero = 0.0f;
    #pragma unroll
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) {
        float16 z[BMFR_GUIDES], a[BMFR_GUIDES];
        #pragma unroll
        for (int r = 0; r < BMFR_GUIDES; ++r) {
            float16 v = s[BMFR_GUIDED_XT + r * BMFR_GUIDED_TARGETS + k] / m - xm[r] * tm[k];
            #pragma unroll
            for (int j = 0; j < r; ++j) v -= l[r][j] * z[j];
            z[r] = v / l[r][r];
        }
        #pragma unroll
        for (int r = BMFR_GUIDES - 1; r >= 0; --r) {
            float16 v = z[r];
            #pragma unroll
            for (int j = r + 1; j < BMFR_GUIDES; ++j) v -= l[j][r] * a[j];
            a[r] = v / l[r][r];
        }
        float16 b = tm[k];
        #pragma unroll
        for (int d = 0; d < BMFR_GUIDES; ++d) {
            b -= a[d] * xm[d];
            store16(select(zero, m * a[d], keep),
                    out + (d * BMFR_GUIDED_TARGETS + k) * (size_t)stride);
        }
        store16(select(zero, m * b, keep), out + (BMFR_GUIDED_B + k) * (size_t)stride);
    }
    store16(select(zero, m, keep), out + (BMFR_GUIDED_MODEL - 1) * (size_t)stride);
}

// bmfr_guided_average_rows for 16 pixels: each model float summed over x - r .. x + r (the
// padding and the lanes right of the image hold zeros, taken as the image's edge).
// Global size: ceil(width / 16) x height, work-groups of 1.
__kernel void bmfr_guided_average_rows_packed(__global const FilterVector* fv,
                                              uint width, uint height, uint stride,
                                              __global const float* models,
                                              __global float* rows) {
    int x0 = get_global_id(0) * BMFR_GUIDED_PACK, y = get_global_id(1);
    if (x0 >= (int)width || y >= (int)height) return;
    int16 xs = (int16)(x0) + BMFR_LANE_IDS;
    __global const float* p = models + bmfr_line_at(x0, y, BMFR_GUIDED_MODEL, stride);
    __global float* out = rows + bmfr_line_at(x0, y, BMFR_GUIDED_MODEL, stride);
    for (int c = 0; c < BMFR_GUIDED_MODEL; ++c) {
        float16 acc = 0.0f;
        #pragma unroll
        for (int dx = -BMFR_GUIDED_RADIUS; dx <= BMFR_GUIDED_RADIUS; ++dx) {
            int16 inside = xs + dx >= 0 && xs + dx < (int)width;
            acc = select(acc, acc + load16(p + c * (size_t)stride + dx), inside);
        }
        store16(acc, out + c * (size_t)stride);
    }
}

// bmfr_guided_eval for 16 pixels: the averaged model at the lanes' guides on vectors, then
// per pixel its modulation and error term (bmfr_guided_output). Global size: ceil(width / 16)
// x height, work-groups of 1.
__kernel void bmfr_guided_eval_packed(__global const FilterVector* fv,
                                      __global const float4* odd_halves, uint width,
                                      uint height, float spp, uint stride,
                                      __global const float4* raw, __global const float* guides,
                                      __global const float* rows,
                                      __global const float4* fitted,
                                      __global const float4* nlm_out,
                                      __global float4* guided) {
    int x0 = get_global_id(0) * BMFR_GUIDED_PACK, y = get_global_id(1);
    if (x0 >= (int)width || y >= (int)height) return;
    float16 s[BMFR_GUIDED_MODEL];
    bmfr_guided_columns_packed(rows, BMFR_GUIDED_MODEL, x0, y, height, stride, s);
    __global const float* at = guides + bmfr_line_at(x0, y, BMFR_GUIDES, stride);
    float16 xg[BMFR_GUIDES];
    #pragma unroll
    for (int d = 0; d < BMFR_GUIDES; ++d) xg[d] = load16(at + d * (size_t)stride);
    float16 count = s[BMFR_GUIDED_MODEL - 1];
    float lanes[BMFR_GUIDED_TARGETS][BMFR_GUIDED_PACK];
    #pragma unroll
    for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) {
        float16 v = s[BMFR_GUIDED_B + k] / count;
        #pragma unroll
        for (int d = 0; d < BMFR_GUIDES; ++d) v += s[d * BMFR_GUIDED_TARGETS + k] / count * xg[d];
        vstore16(fmax(v, 0.0f), 0, lanes[k]);
    }
    int n = min(BMFR_GUIDED_PACK, (int)width - x0);
    for (int i = 0; i < n; ++i) {
        size_t p = (size_t)y * width + x0 + i;
        if (raw[p].w != BMFR_NLM_SURFACE) {
            guided[p] = (float4)(0.0f);
            continue;
        }
        float g[BMFR_GUIDED_TARGETS];
        for (int k = 0; k < BMFR_GUIDED_TARGETS; ++k) g[k] = lanes[k][i];
        guided[p] = bmfr_guided_output(fv + p, odd_halves[p], spp, g, fitted[p], nlm_out[3 * p]);
    }
}
