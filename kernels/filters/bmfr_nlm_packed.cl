// bmfr's non-local means on CPU devices (`packed_nlm`, src/filters/bmfr/nlm.rs): the equations
// of bmfr_nlm (filters/bmfr_nlm.cl, included before this file) with one work-item filtering
// BMFR_NLM_STEP (16 - 2 BMFR_NLM_PATCH: 12 with 5 x 5 patches) adjacent pixels x0 ..
// x0 + STEP - 1 of BMFR_NLM_ROWS rows, every operation written on float16 vectors whose lane i
// is pixel x0 - BMFR_NLM_PATCH + i: the first and last BMFR_NLM_PATCH lanes are the left and
// right neighbours that a patch's horizontal taps need, computed and never written.
//
// Why: PoCL runs bmfr_nlm's work-groups as loops over the work-items between barriers, on
// scalar floats with a scalar exp (as it does the a-trous filter's taps, filters/
// atrous_packed.cl). Here the packing is explicit, and the tap distances are shared without
// local memory: a tap's distance depends only on the pixel a = p + t and the offset q - p, so
// for one offset the work-item evaluates each of its rows' distances once (16 lanes), sums each
// row's taps by shifting the lanes, keeps the row sums, and sums BMFR_NLM_TAPS of them for each
// output row: (ROWS + 2 PATCH) / ROWS row evaluations per output row and offset, against
// TAPS^2 without sharing. Overlapping the work-items by 2 PATCH pixels costs 16 / STEP of the
// lanes; with 3 x 3 patches it replaced evaluating the two edge pixels of 16 output lanes on float2s,
// and measured 2 % faster with the same bytes (Cornell diffuse 512², `noisefree filter
// --profile`, binaries alternating four times: 109.5-110.8 ms -> 106.8-109.4 ms) and is the
// simpler code. Offsets outside the halves' window (BMFR_NLM_ESTIMATE_RADIUS) evaluate and
// weigh the frame's image only.
//
// Layout ("lines", as the a-trous filter's): bmfr_nlm_inputs_lines writes every image row as
// BMFR_NLM_LINES lines of `stride` floats: lines 0-2 the frame's light (rgb), 3-5 the odd
// half's, 6-8 the even half's, 9-11 the variance, 12 a 1 (inside the image), 13 the class
// (bmfr_nlm_class). Pixel (x, y), line k sits at (y * LINES + k) * stride + BMFR_NLM_PAD + x.
// The BMFR_NLM_PAD floats left of every line and the ones right of the image (stride = PAD + width rounded up
// to PACK + 2 PAD) are never written, so they stay 0 (the buffer is zeroed once): a tap that
// reaches past the image's left or right edge reads an "inside" of 0 and counts as invalid, as
// bmfr_nlm's bounds test makes it. Rows above and below the image are skipped (the same for
// every lane).
//
// The same float operations in the same order as bmfr_nlm and the Rust reference (offsets in
// order; per patch row the taps left to right, then the rows top to bottom; FP_CONTRACT OFF
// from bmfr.cl). Measured against the reference: tests/bmfr.rs.

#include "vectors.cl"

#define BMFR_NLM_PACK 16
#define BMFR_NLM_STEP (BMFR_NLM_PACK - 2 * BMFR_NLM_PATCH)
#define BMFR_NLM_PAD 16
#define BMFR_NLM_LINES 14
#if BMFR_NLM_RADIUS + BMFR_NLM_PATCH > BMFR_NLM_PAD
#error "noisefree: BMFR_NLM_RADIUS + BMFR_NLM_PATCH must be at most BMFR_NLM_PAD (nlm.rs)"
#endif

// v shifted by t lanes: lane i of the result is lane i + t of v (the tap t pixels right; t < 0:
// left), the edge lanes repeated where i + t lies past them (neighbour lanes, never written).
__attribute__((always_inline)) inline float16 bmfr_nlm_shift(float16 v, const int t) {
    int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15) + t;
    return shuffle(v, as_uint16(clamp(lane, 0, 15)));
}

// Where line 0 of pixel (x, y) lies in a buffer of `lines` lines per row (this layout, also
// the packed albedo prefilter's, filters/bmfr_prefilter_packed.cl).
inline size_t bmfr_line_at(int x, int y, int lines, uint stride) {
    return (size_t)y * lines * stride + BMFR_NLM_PAD + x;
}

// bmfr_nlm_inputs into lines. Global size: width x height.
__kernel void bmfr_nlm_inputs_lines(__global const FilterVector* fv,
                                    __global const float4* odd_halves,
                                    uint width, uint height, float spp,
                                    __global const float4* raw,
                                    uint stride,
                                    __global float* lines) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    float4 u[4];
    bmfr_nlm_pixel(fv, odd_halves, x, y, width, height, spp, raw, u);
    __global float* at = lines + bmfr_line_at(x, y, BMFR_NLM_LINES, stride);
    for (int m = 0; m < 4; ++m) {
        at[(3 * m) * (size_t)stride] = u[m].x;
        at[(3 * m + 1) * (size_t)stride] = u[m].y;
        at[(3 * m + 2) * (size_t)stride] = u[m].z;
    }
    at[12 * (size_t)stride] = 1.0f;
    at[13 * (size_t)stride] = u[0].w;
}

// One patch row's sum for the lanes xv .. xv + 15 of row ay, against row by shifted by dx:
// per lane ((D(x - P) + D(x - P + 1)) + ...) + D(x + P), P = BMFR_NLM_PATCH, for the three
// images (h[0..2]) and the valid taps (h[3]); right only in lanes P .. 15 - P (the others lack
// a neighbour). `images` (a constant
// after inlining: 3, or 1 outside the halves' estimate window) says how many of the three
// images are computed; the others' h[m] are left unset. `inside` (a constant too): every
// tap of the sixteen lanes lies in the image, for a and b alike (bmfr_nlm_inside), so each
// tap is valid, h[3] is not computed and no distance is zeroed. Always inlined, and
// every small loop over private float16 arrays here and in the kernel unrolled: PoCL called it
// per row and kept those arrays on the stack (same bytes; Cornell diffuse 512² 124 -> 113 ms,
// `noisefree filter --profile`, binaries alternating).
__attribute__((always_inline)) inline void bmfr_nlm_row(__global const float* lines,
                                                        uint stride, int xv, int ay, int by,
                                                        int dx, float k2, const int images,
                                                        const int inside, float16 h[4]) {
    __global const float* a = lines + bmfr_line_at(xv, ay, BMFR_NLM_LINES, stride);
    __global const float* b = lines + bmfr_line_at(xv + dx, by, BMFR_NLM_LINES, stride);
    // The distances of the tap for the frame (d[0]) and the two halves (d[1], d[2]),
    // bmfr_nlm's expressions channel by channel, 0 where the tap is invalid (either pixel
    // outside the image: d[3]). Each channel's terms are added to d[m] as soon as they are
    // made (the same order, (q0 + q1) + q2): fewer vectors live at once than making all
    // nine first, which on AVX2 (sixteen 8-float registers, two per float16) spilled.
    float16 d[4];
    #pragma unroll
    for (int c = 0; c < 3; ++c) {
        float16 va = load16(a + (9 + c) * (size_t)stride);
        float16 vb = load16(b + (9 + c) * (size_t)stride);
        float16 s = va + fmin(va, vb);
        float16 inv = 1.0f / (BMFR_NLM_EPSILON + k2 * (va + vb));
        // Constant trip counts with `m < images` inside: a loop bound that is a parameter
        // cannot be unrolled before inlining, and clang warns about each such pragma.
        #pragma unroll
        for (int m = 0; m < 3; ++m) {
            if (m < images) {
                float16 diff = load16(a + (3 * m + c) * (size_t)stride)
                             - load16(b + (3 * m + c) * (size_t)stride);
                float16 q = m == 0 ? (diff * diff - s) * inv : (0.5f * (diff * diff) - s) * inv;
                d[m] = c == 0 ? q : d[m] + q;
            }
        }
    }
    if (!inside) {
        d[3] = load16(a + 12 * (size_t)stride) * load16(b + 12 * (size_t)stride);
        #pragma unroll
        for (int m = 0; m < 3; ++m)
            if (m < images) d[m] = d[3] != 0.0f ? d[m] : (float16)(0.0f);
    }
    #pragma unroll
    for (int m = 0; m < 4; ++m) {
        if (m < images || (m == 3 && !inside)) {
        // The lanes shifted by each tap's offset, summed left to right.
        float16 sum = bmfr_nlm_shift(d[m], -BMFR_NLM_PATCH);
        #pragma unroll
        for (int t = 1 - BMFR_NLM_PATCH; t <= BMFR_NLM_PATCH; ++t)
            sum += t == 0 ? d[m] : bmfr_nlm_shift(d[m], t);
        h[m] = sum;
        }
    }
}

// Whether every tap that the work-item at (xv, y0) reads for offset (dx, dy) lies in the
// image, for a and for b = a + (dx, dy): its sixteen lanes and its rows with their patches'.
// Then every patch has all its (2 P + 1)² taps, and bmfr_nlm_row's `inside` skips counting
// them. The count it would make is 25 ones summed, exact, so the weights are the same bytes.
// At 512², radius 5, 32-row work-items: 41 of 43 columns and 14 of 16 rows of them.
inline bool bmfr_nlm_inside(int xv, int y0, int w, int h, int dx, int dy) {
    int x_lo = min(xv, xv + dx), x_hi = max(xv, xv + dx) + BMFR_NLM_PACK - 1;
    int y_lo = y0 - BMFR_NLM_PATCH + min(0, dy);
    int y_hi = y0 + BMFR_NLM_ROWS - 1 + BMFR_NLM_PATCH + max(0, dy);
    return x_lo >= 0 && x_hi < w && y_lo >= 0 && y_hi < h;
}

// One offset (dx, dy) of the search window for every row of the work-item, the weights of
// `images` of the three images (see bmfr_nlm_row) added to acc and wsum; `inside`:
// bmfr_nlm_inside holds for it. Two passes: every row's patch row sums into hs (hs[i]: row
// y0 - P + i), then each output row's 2 P + 1 of them summed top to bottom and weighed. One
// pass sliding a window of 2 P + 1 row sums in private variables (as this kernel and
// bmfr_emission_nlm_packed did before stop 59) is the same float operations in the same
// order, but its 15-20 float16s do not fit in AVX2's registers and the compiler's spills
// cost more than this buffer's stores and loads
// (`scripts/filter-ab.sh` on six scenes' 512² AOVs on an AVX2 CPU: 0.86-0.91x of the sliding
// window's time, Cornell diffuse 130.6 -> 112.7 ms, the same bytes; results/README.md, bmfr,
// "Stop 59").
__attribute__((always_inline)) inline void bmfr_nlm_offset(
    __global const float* lines, uint stride, int xv, int y0, int h, int dx, int dy, float k2,
    const int images, const int inside, float16 hs[BMFR_NLM_ROWS + 2 * BMFR_NLM_PATCH][4],
    float16 acc[BMFR_NLM_ROWS][9], float16 wsum[BMFR_NLM_ROWS][3]) {
    for (int r = -BMFR_NLM_PATCH; r < BMFR_NLM_ROWS + BMFR_NLM_PATCH; ++r) {
        int ay = y0 + r, by = ay + dy;
        float16 row[4];
        if (ay >= 0 && ay < h && by >= 0 && by < h) {
            bmfr_nlm_row(lines, stride, xv, ay, by, dx, k2, images, inside, row);
        } else {
            #pragma unroll
            for (int m = 0; m < 4; ++m) row[m] = (float16)(0.0f);
        }
        #pragma unroll
        for (int m = 0; m < 4; ++m)
            if (m < images || (m == 3 && !inside)) hs[r + BMFR_NLM_PATCH][m] = row[m];
    }
    for (int row = 0; row < BMFR_NLM_ROWS; ++row) {
        int py = y0 + row, qy = py + dy;
        if (py >= h || qy < 0 || qy >= h) continue;
        __global const float* q = lines + bmfr_line_at(xv + dx, qy, BMFR_NLM_LINES, stride);
        __global const float* p = lines + bmfr_line_at(xv, py, BMFR_NLM_LINES, stride);
        // q takes part when it is of p's class (and p of one: others pass through).
        float16 class_q = load16(q + 13 * (size_t)stride);
        int16 same = class_q == load16(p + 13 * (size_t)stride) && class_q != 0.0f;
        float16 taps;
        if (inside) {
            taps = (float16)(3.0f * (float)(BMFR_NLM_TAPS * BMFR_NLM_TAPS));
        } else {
            float16 valid = hs[row][3];
            #pragma unroll
            for (int t = 1; t < BMFR_NLM_TAPS; ++t) valid += hs[row + t][3];
            taps = 3.0f * valid;
        }
        #pragma unroll
        for (int m = 0; m < 3; ++m) {
            if (m < images) {
                float16 d2 = hs[row][m];
                #pragma unroll
                for (int t = 1; t < BMFR_NLM_TAPS; ++t) d2 += hs[row + t][m];
                float16 wt = same ? exp(-fmax(d2 / taps, 0.0f)) : (float16)(0.0f);
                #pragma unroll
                for (int c = 0; c < 3; ++c)
                    acc[row][3 * m + c] += wt * load16(q + (3 * m + c) * (size_t)stride);
                wsum[row][m] += wt;
            }
        }
    }
}

// bmfr_nlm on BMFR_NLM_STEP x BMFR_NLM_ROWS pixels. Global size: ceil(width / STEP) x
// ceil(height / ROWS), work-groups of 1.
__kernel void bmfr_nlm_packed(__global const FilterVector* fv,
                              __global const float4* odd_halves,
                              uint width, uint height, float spp,
                              __global const float* lines,
                              uint stride,
                              __global float4* nlm_out) {
    int x0 = get_global_id(0) * BMFR_NLM_STEP, y0 = get_global_id(1) * BMFR_NLM_ROWS;
    int w = (int)width, h = (int)height;
    if (x0 >= w || y0 >= h) return;
    int xv = x0 - BMFR_NLM_PATCH;            // the pixel of lane 0
    float k2 = BMFR_NLM_K * BMFR_NLM_K;
    // Per row: the weighted sums of the three images' rgb (3 m + c) and their weights.
    float16 acc[BMFR_NLM_ROWS][9], wsum[BMFR_NLM_ROWS][3];
    float16 hs[BMFR_NLM_ROWS + 2 * BMFR_NLM_PATCH][4];  // bmfr_nlm_offset's row sums
    for (int row = 0; row < BMFR_NLM_ROWS; ++row) {
        for (int k = 0; k < 9; ++k) acc[row][k] = (float16)(0.0f);
        for (int m = 0; m < 3; ++m) wsum[row][m] = (float16)(0.0f);
    }
    for (int dy = -BMFR_NLM_RADIUS; dy <= BMFR_NLM_RADIUS; ++dy) {
        for (int dx = -BMFR_NLM_RADIUS; dx <= BMFR_NLM_RADIUS; ++dx) {
            if (x0 + dx + BMFR_NLM_STEP - 1 < 0 || x0 + dx >= w) continue;  // no q inside
            bool inside = bmfr_nlm_inside(xv, y0, w, h, dx, dy);
            if (BMFR_NLM_ESTIMATING(dx, dy)) {
                if (inside)
                    bmfr_nlm_offset(lines, stride, xv, y0, h, dx, dy, k2, 3, 1, hs, acc, wsum);
                else
                    bmfr_nlm_offset(lines, stride, xv, y0, h, dx, dy, k2, 3, 0, hs, acc, wsum);
            } else if (inside) {
                bmfr_nlm_offset(lines, stride, xv, y0, h, dx, dy, k2, 1, 1, hs, acc, wsum);
            } else {
                bmfr_nlm_offset(lines, stride, xv, y0, h, dx, dy, k2, 1, 0, hs, acc, wsum);
            }
        }
    }
    for (int row = 0; row < BMFR_NLM_ROWS && y0 + row < h; ++row) {
        int y = y0 + row;
        float mean[9][BMFR_NLM_PACK];
        for (int k = 0; k < 9; ++k) vstore16(acc[row][k] / wsum[row][k / 3], 0, mean[k]);
        __global const float* p = lines + bmfr_line_at(xv, y, BMFR_NLM_LINES, stride);
        for (int lane = BMFR_NLM_PATCH; lane < BMFR_NLM_PATCH + BMFR_NLM_STEP && xv + lane < w;
             ++lane) {
            uint i = (uint)y * width + (uint)(xv + lane);
            __global const FilterVector* f = fv + i;
            float class = p[13 * (size_t)stride + lane];
            if (class == 0.0f) {
                bmfr_nlm_pass_through(f, odd_halves[i], spp, nlm_out + 3 * i);
                continue;
            }
            float3 al = bmfr_nlm_modulation(f, class);
            for (int m = 0; m < 3; ++m)
                nlm_out[3 * i + m] = (float4)((float3)(mean[3 * m][lane], mean[3 * m + 1][lane],
                                                       mean[3 * m + 2][lane]) * al, 0.0f);
        }
    }
}
