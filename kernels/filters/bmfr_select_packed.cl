// bmfr_select_nlm on CPU devices (`packed_nlm`, src/filters/bmfr/nlm.rs): one work-item sums
// the windows of 16 adjacent pixels x0 .. x0 + 15 of a row, lane i for pixel x0 + i, and then
// blends each pixel with bmfr_select_nlm's functions (filters/bmfr_nlm.cl, included before
// this file).
//
// Why: PoCL ran bmfr_select_nlm's 81 window terms per pixel (its unrolled window) on scalar
// floats: 8 ms of bmfr's 60 at 512², 16 ms with the floor (results/README.md, bmfr "Stop 43").
// Here each window position is one step for 16 pixels: the residuals of the 16 pixels it
// reaches are four float16 loads, one from each of the residuals' planes (V, R, N, class:
// bmfr_residuals_nlm writes them so under BMFR_RESIDUAL_PLANES, on wherever this kernel runs).
// Read as float4 per pixel they were four loads taken apart by eight shuffles
// (results/README.md, bmfr "Stop 60"). The guided filter's terms are still float4 per pixel
// (bmfr_residual_lanes): only their w enters the window.
//
// The same bytes as bmfr_select_nlm: every lane adds its window's terms in the kernel's order
// (rows top to bottom, each left to right), and a term of another class or outside the image
// leaves the lane's sums as they are (select(), not an added 0); the floor, its test and the
// blend are bmfr_select_nlm's functions, per pixel. The floor's second pass runs when some
// lane needs it, and only those lanes take its sum.

#include "vectors.cl"

#define BMFR_SELECT_PACK 16
#define BMFR_SELECT_LANES (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)

// The four channels of a float4-per-pixel buffer (the guided filter's terms) for the pixels
// x .. x + 15 of the row starting at pixel `row`; lanes outside [0, w) hold 0 (the caller
// masks them out). Always inlined: as a call its four vectors went through the stack.
__attribute__((always_inline)) inline void bmfr_residual_lanes(__global const float4* residuals, size_t row, int x, int w,
                                float16* v, float16* r, float16* n, float16* class) {
    if (x >= 0 && x + BMFR_SELECT_PACK <= w) {
        __global const float* p = (__global const float*)(residuals + row + x);
        // Pixels 0-3, 4-7, 8-11, 12-15, each (V, R, N, class).
        float16 a = load16(p), b = load16(p + 16), c = load16(p + 32), d = load16(p + 48);
        const uint16 even = (uint16)(0, 4, 8, 12, 16, 20, 24, 28, 1, 5, 9, 13, 17, 21, 25, 29);
        const uint16 odd = (uint16)(2, 6, 10, 14, 18, 22, 26, 30, 3, 7, 11, 15, 19, 23, 27, 31);
        // V and R of pixels 0-7 (and 8-15), N and the class of the same.
        float16 vr_lo = shuffle2(a, b, even), nc_lo = shuffle2(a, b, odd);
        float16 vr_hi = shuffle2(c, d, even), nc_hi = shuffle2(c, d, odd);
        const uint16 first = (uint16)(0, 1, 2, 3, 4, 5, 6, 7, 16, 17, 18, 19, 20, 21, 22, 23);
        const uint16 second = (uint16)(8, 9, 10, 11, 12, 13, 14, 15, 24, 25, 26, 27, 28, 29, 30, 31);
        *v = shuffle2(vr_lo, vr_hi, first);
        *r = shuffle2(vr_lo, vr_hi, second);
        *n = shuffle2(nc_lo, nc_hi, first);
        *class = shuffle2(nc_lo, nc_hi, second);
        return;
    }
    // A window position past the image's left or right edge: pixel by pixel.
    float lanes[4][BMFR_SELECT_PACK];
    for (int i = 0; i < BMFR_SELECT_PACK; ++i) {
        int xx = x + i;
        float4 e = xx >= 0 && xx < w ? residuals[row + xx] : (float4)(0.0f);
        lanes[0][i] = e.x;
        lanes[1][i] = e.y;
        lanes[2][i] = e.z;
        lanes[3][i] = e.w;
    }
    *v = vload16(0, lanes[0]);
    *r = vload16(0, lanes[1]);
    *n = vload16(0, lanes[2]);
    *class = vload16(0, lanes[3]);
}

// The same from the residuals' four planes (BMFR_RESIDUAL_PLANES, bmfr_residuals_nlm: plane c
// at c * n floats): four loads, no shuffles.
__attribute__((always_inline)) inline void bmfr_residual_planes(__global const float* planes, size_t n, size_t row, int x,
                                 int w, float16* v, float16* r, float16* nn, float16* class) {
    if (x >= 0 && x + BMFR_SELECT_PACK <= w) {
        __global const float* p = planes + row + x;
        *v = load16(p);
        *r = load16(p + n);
        *nn = load16(p + 2 * n);
        *class = load16(p + 3 * n);
        return;
    }
    // A window position past the image's left or right edge: pixel by pixel.
    float lanes[4][BMFR_SELECT_PACK];
    for (int i = 0; i < BMFR_SELECT_PACK; ++i) {
        int xx = x + i;
        bool in = xx >= 0 && xx < w;
        for (int c = 0; c < 4; ++c) lanes[c][i] = in ? planes[c * n + row + xx] : 0.0f;
    }
    *v = vload16(0, lanes[0]);
    *r = vload16(0, lanes[1]);
    *nn = vload16(0, lanes[2]);
    *class = vload16(0, lanes[3]);
}

// The window of lane i's pixel: rows y - RADIUS .. y + RADIUS inside the image, and in each the
// positions dx whose pixel x0 + i + dx lies inside it. `take` is the lane mask of the terms
// that count (the class test, and inside the image); BODY runs once per position.
#define BMFR_SELECT_PACKED_WINDOW(BODY)                                                         \
    for (int dy = -BMFR_SELECT_RADIUS; dy <= BMFR_SELECT_RADIUS; ++dy) {                         \
        int yy = y + dy;                                                                         \
        if (yy < 0 || yy >= h) continue;                                                         \
        for (int dx = -BMFR_SELECT_RADIUS; dx <= BMFR_SELECT_RADIUS; ++dx) {                     \
            int16 xx = xs + dx;                                                                  \
            float16 v, r, n, c;                                                                  \
            bmfr_residual_planes(planes, pixels, (size_t)yy * w, x0 + dx, w, &v, &r, &n, &c);    \
            int16 take = xx >= 0 && xx < w && c == class;                                        \
            BODY                                                                                 \
        }                                                                                        \
    }

// With the guided filter: the window position's G terms (the guided output's w) into sum_g.
#if BMFR_GUIDED
#define BMFR_SELECT_GUIDED_TERM                                                                 \
    {                                                                                            \
        float16 gx, gy, gz, gw;                                                                  \
        bmfr_residual_lanes(guided, (size_t)yy * w, x0 + dx, w, &gx, &gy, &gz, &gw);             \
        sum_g = select(sum_g, sum_g + gw, take);                                                 \
    }
#else
#define BMFR_SELECT_GUIDED_TERM
#endif

// Global size: ceil(width / 16) x height, work-groups of 1.
__kernel void bmfr_select_nlm_packed(__global const FilterVector* fv,
                                     uint width, uint height,
                                     __global const float4* residuals,
                                     __global const float4* nlm_out,
                                     __global float4* fitted
#if BMFR_GUIDED
                                     , __global const float4* guided
#endif
                                     ) {
    int x0 = get_global_id(0) * BMFR_SELECT_PACK, y = get_global_id(1);
    int w = (int)width, h = (int)height;
    if (x0 >= w || y >= h) return;
    int16 xs = (int16)(x0) + BMFR_SELECT_LANES;
    // The residuals as planes (BMFR_RESIDUAL_PLANES is on wherever this kernel runs).
    __global const float* planes = (__global const float*)residuals;
    size_t pixels = (size_t)w * (size_t)h;
    float16 own_v, own_r, own_n, class;
    bmfr_residual_planes(planes, pixels, (size_t)y * w, x0, w, &own_v, &own_r, &own_n, &class);
    float16 sum_v = 0.0f, sum_r = 0.0f, sum_n = 0.0f, count = 0.0f;
    float16 excess_sum = 0.0f, excess_min = INFINITY;
    // With the guided filter, its error terms' window sum too (bmfr_guided_blend's, whose V
    // sum is sum_v: the same terms in the same order for a surface pixel).
    float16 sum_g = 0.0f;
    BMFR_SELECT_PACKED_WINDOW(
        BMFR_SELECT_GUIDED_TERM
        sum_v = select(sum_v, sum_v + v, take);
        sum_r = select(sum_r, sum_r + r, take);
        sum_n = select(sum_n, sum_n + n, take);
        count = select(count, count + 1.0f, take);
        if (BMFR_SELECT_FLOOR > 0.0f) {
            excess_sum = select(excess_sum, excess_sum + (r - v), take);
            excess_min = select(excess_min, fmin(excess_min, r - v), take);
        }
    )
    float lane_v[16], lane_r[16], lane_n[16], lane_count[16], lane_class[16];
    float lane_excess[16], lane_min[16], lane_floor[16], lane_g[16];
    vstore16(sum_g, 0, lane_g);
    vstore16(sum_v, 0, lane_v);
    vstore16(sum_r, 0, lane_r);
    vstore16(sum_n, 0, lane_n);
    vstore16(count, 0, lane_count);
    vstore16(class, 0, lane_class);
    vstore16(excess_sum, 0, lane_excess);
    vstore16(excess_min, 0, lane_min);
    int lanes = min(BMFR_SELECT_PACK, w - x0);
    int16 needs = (int16)(0);
    if (BMFR_SELECT_FLOOR > 0.0f) {
        int need[16];
        for (int i = 0; i < BMFR_SELECT_PACK; ++i) {
            float3 sum = (float3)(lane_v[i], lane_r[i], lane_n[i]);
            need[i] = i < lanes && bmfr_select_needs_floor(lane_class[i], sum, lane_count[i],
                                                           lane_excess[i], lane_min[i])
                          ? -1 : 0;
            lane_floor[i] = bmfr_select_floor_of(lane_v[i], lane_count[i]);
        }
        needs = vload16(0, need);
    }
    if (any(needs)) {
        // The floor's pass, for the lanes that need it (bmfr_select_nlm's second window).
        float16 floor_ = vload16(0, lane_floor), floored = 0.0f;
        BMFR_SELECT_PACKED_WINDOW(
            floored = select(floored, floored + fmax(r - v, floor_), take);
        )
        vstore16(select(excess_sum, floored, needs), 0, lane_excess);
    }
    for (int i = 0; i < lanes; ++i) {
        uint p = (uint)y * width + (uint)(x0 + i);
        float3 sum = (float3)(lane_v[i], lane_r[i], lane_n[i]);
        float excess = BMFR_SELECT_FLOOR > 0.0f ? lane_excess[i] : sum.y - sum.x;
        bmfr_select_nlm_blend(fv + p, lane_class[i], sum, excess, nlm_out + 3 * p, fitted + p);
#if BMFR_GUIDED
        bmfr_guided_join(lane_class[i], lane_v[i], lane_g[i], guided[p], fitted + p);
#endif
    }
}
