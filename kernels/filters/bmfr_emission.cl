// Lights seen directly, treated apart from the reflected light (bmfr's `emission`; the method,
// its reasons and its measurements: src/filters/bmfr/emission.rs, which holds the same float
// operations in the same order in Rust). Included by filters/bmfr.cl.
//
// Build options: BMFR_EMISSION_RADIUS, BMFR_EMISSION_PATCH (half widths of the window and the
// patches), BMFR_EMISSION_K, BMFR_EMISSION_EPSILON, BMFR_EMISSION_SELF (the pixel's own extra
// weight, emission.rs "A light's edge through a pinhole"), BMFR_EMISSION_MEAN (the weight of the
// patches' mean-difference test, emission.rs "A few samples per pixel"; float literals),
// BMFR_EMISSION_MEAN_ON (1 where BMFR_EMISSION_MEAN is above 0, else 0: the work-group kernel
// then declares no local memory for the test), BMFR_EMISSION_TILE (the
// work-group kernel's tile side), BMFR_EMISSION_LINES and BMFR_EMISSION_ROWS (the packed
// kernel's lines per image row and rows per work-item).
//
// The emission's inputs ("lines", the layout of filters/bmfr_nlm_packed.cl, included before
// this file: pixel (x, y), line k at bmfr_line_at(x, y, BMFR_EMISSION_LINES, stride) + k
// stride): lines 0-2 E's rgb, 3 its luminance, 4 its variance, 5 a 1 (inside the image). The
// padding either side of every line is never written and stays 0 (zeroed once).
#if BMFR_EMISSION_RADIUS + BMFR_EMISSION_PATCH > BMFR_NLM_PAD
#error "noisefree: BMFR_EMISSION_RADIUS + BMFR_EMISSION_PATCH must be at most BMFR_NLM_PAD"
#endif

// F and the odd half with the light of emitters seen directly taken out; a pixel's mean albedo
// less its emitter samples' share of it (f E / max(E): a light's albedo is its emission's
// chromaticity), unless all its samples hit a light (then bmfr_light keeps it out of the fit).
__kernel void bmfr_reflected(__global const FilterVector* fv, __global const float4* odd_halves,
                             __global const float4* emission, __global const float4* odd_emission,
                             uint width, uint height, __global FilterVector* fv_out,
                             __global float4* odd_out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    uint i = y * width + x;
    FilterVector f = fv[i];
    float4 odd = odd_halves[i];
    float4 e = emission[i];
    float share = e.w;
    if (share > 0.0f) {
        float4 eo = odd_emission[i];
        float peak = fmax(e.x, fmax(e.y, e.z));
        float ec[3] = {e.x, e.y, e.z}, eoc[3] = {eo.x, eo.y, eo.z};
        float oc[3] = {odd.x, odd.y, odd.z};
        for (int c = 0; c < 3; ++c) {
            f.direct[c] = fmax(f.direct[c] - ec[c], 0.0f);
            oc[c] = fmax(oc[c] - eoc[c], 0.0f);
            if (share < 1.0f && peak > 0.0f) f.albedo[c] = fmax(f.albedo[c] - share * ec[c] / peak, 0.0f);
        }
        odd = (float4)(oc[0], oc[1], oc[2], odd.w);
    }
    fv_out[i] = f;
    odd_out[i] = odd;
}

// The variance of a pixel's mean E from its half buffers, averaged over the channels.
// 0 at once where no sample saw a light (most pixels; the same 0 the sums give).
inline float bmfr_emission_variance_raw(float4 e, __global const float4* odd_emission, float spp) {
    if (e.w == 0.0f) return 0.0f;
    float4 eo = *odd_emission;
    float n_odd = eo.w, n_even = spp - n_odd;
    if (n_odd <= 0.0f || n_even <= 0.0f) return 0.0f;
    float ec[3] = {e.x, e.y, e.z}, oc[3] = {eo.x, eo.y, eo.z};
    float v = 0.0f;
    for (int c = 0; c < 3; ++c) {
        float even = (ec[c] * spp - oc[c] * n_odd) / n_even;
        v += (even - oc[c]) * (even - oc[c]) * 0.25f;
    }
    return v * (1.0f / 3.0f);
}

// Per pixel, E's lines: its rgb, its luminance, its variance averaged over the 3 x 3 pixels
// around, and a 1.
__kernel void bmfr_emission_prep(__global const float4* emission,
                                 __global const float4* odd_emission, uint width, uint height,
                                 float spp, uint stride, __global float* lines) {
    int x = get_global_id(0), y = get_global_id(1), w = width, h = height;
    if (x >= w || y >= h) return;
    float sum = 0.0f, n = 0.0f;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            int u = x + dx, v = y + dy;
            if (u >= 0 && v >= 0 && u < w && v < h) {
                int j = v * w + u;
                sum += bmfr_emission_variance_raw(emission[j], odd_emission + j, spp);
                n += 1.0f;
            }
        }
    float4 e = emission[y * w + x];
    __global float* at = lines + bmfr_line_at(x, y, BMFR_EMISSION_LINES, stride);
    at[0] = e.x;
    at[stride] = e.y;
    at[2 * (size_t)stride] = e.z;
    at[3 * (size_t)stride] = (e.x + e.y + e.z) * (1.0f / 3.0f);
    at[4 * (size_t)stride] = sum / n;
    at[5 * (size_t)stride] = 1.0f;
}

// E filtered by non-local means, added to the filtered reflected light in `out`. A pixel whose
// window holds no light gives 0 and is skipped, and so is a work-group none of whose pixels'
// windows does (most of the image).
//
// The box-filter form of non-local means (Darbon et al. 2008, "Fast nonlocal filtering"): a
// patch term depends only on the pixel a = p + t and the offset d = q - p, so for each offset
// the work-group writes the terms of its tile and a BMFR_EMISSION_PATCH border to local memory
// once, sums each patch row's 5 terms once per column, and each pixel sums its patch's 5 row
// sums: about 1.6 term evaluations and 11 additions per pixel and offset instead of 25 and 25.
// The same float operations in the same order as the Rust reference (emission.rs
// `emission_nlm`): per patch row the taps left to right, then the rows top to bottom; an
// invalid tap (a + d or a outside the image) adds 0 and does not count.
// With BMFR_EMISSION_MEAN_ON the taps' differences and summed variances are box-summed the
// same way, for the mean-difference test (emission.rs `mean_test`), in two more pairs of local
// arrays; without it they are not declared, so that the group's local memory, and a GPU's
// occupancy, are those of the kernel without the test (device.rs `emission_local_bytes`).
// Work-groups of BMFR_EMISSION_TILE^2 pixels; the global size rounded up to the tile.
#define BMFR_EMISSION_SIDE (BMFR_EMISSION_TILE + 2 * BMFR_EMISSION_PATCH)
#define BMFR_EMISSION_APRON (BMFR_EMISSION_RADIUS + BMFR_EMISSION_PATCH)
#define BMFR_EMISSION_INPUT (BMFR_EMISSION_TILE + 2 * BMFR_EMISSION_APRON)
#define BMFR_EMISSION_ITEMS (BMFR_EMISSION_TILE * BMFR_EMISSION_TILE)

// How many of a patch's taps along one axis lie inside [0, n) both at c + t and at c + dc.
inline int bmfr_emission_taps(int c, int dc, int n) {
    int lo = max(-BMFR_EMISSION_PATCH, max(-c, -c - dc));
    int hi = min(BMFR_EMISSION_PATCH, min(n - 1 - c, n - 1 - c - dc));
    return max(hi - lo + 1, 0);
}

// emission.rs `mean_test`: the patches' summed differences squared, less their summed
// variances, over k^2 times those, scaled by BMFR_EMISSION_MEAN.
#define BMFR_EMISSION_MEAN_TEST(diff_sum, var_sum, k2)                                         \
    (BMFR_EMISSION_MEAN * ((diff_sum) * (diff_sum) - (var_sum))                                \
     / (BMFR_EMISSION_EPSILON + (k2) * (var_sum)))

__kernel __attribute__((reqd_work_group_size(BMFR_EMISSION_TILE, BMFR_EMISSION_TILE, 1)))
void bmfr_emission_nlm(__global const float* lines, uint stride, uint width, uint height,
                       __global float4* out) {
    // prep over the tile and a RADIUS + PATCH apron (0 outside the image), the offset's terms
    // over the tile and a PATCH border, and their patch-row sums over the tile's columns.
    __local float2 input[BMFR_EMISSION_INPUT * BMFR_EMISSION_INPUT];
    // The terms, and for the mean-difference test the taps' differences and variances.
    __local float dist[BMFR_EMISSION_SIDE * BMFR_EMISSION_SIDE];
    __local float rows[BMFR_EMISSION_SIDE * BMFR_EMISSION_TILE];
#if BMFR_EMISSION_MEAN_ON
    __local float dist_diff[BMFR_EMISSION_SIDE * BMFR_EMISSION_SIDE];
    __local float dist_var[BMFR_EMISSION_SIDE * BMFR_EMISSION_SIDE];
    __local float rows_diff[BMFR_EMISSION_SIDE * BMFR_EMISSION_TILE];
    __local float rows_var[BMFR_EMISSION_SIDE * BMFR_EMISSION_TILE];
#endif
    __local int any_lit;
    const int r = BMFR_EMISSION_RADIUS, pr = BMFR_EMISSION_PATCH;
    int lx = get_local_id(0), ly = get_local_id(1);
    int x = get_global_id(0), y = get_global_id(1), w = width, h = height;
    int first = ly * BMFR_EMISSION_TILE + lx;
    int tx = (int)get_group_id(0) * BMFR_EMISSION_TILE, ty = (int)get_group_id(1) * BMFR_EMISSION_TILE;
    if (first == 0) any_lit = 0;
    barrier(CLK_LOCAL_MEM_FENCE);
    bool group_lit = false;
    for (int e = first; e < BMFR_EMISSION_INPUT * BMFR_EMISSION_INPUT; e += BMFR_EMISSION_ITEMS) {
        int ix = e % BMFR_EMISSION_INPUT, iy = e / BMFR_EMISSION_INPUT;
        int ax = tx - BMFR_EMISSION_APRON + ix, ay = ty - BMFR_EMISSION_APRON + iy;
        bool in = ax >= 0 && ay >= 0 && ax < w && ay < h;
        float2 p = (float2)(0.0f);
        if (in) {
            __global const float* at = lines + bmfr_line_at(ax, ay, BMFR_EMISSION_LINES, stride);
            p = (float2)(at[3 * (size_t)stride], at[4 * (size_t)stride]);
        }
        input[e] = p;
        // Inside some pixel's window of the tile (the apron less the patch border)?
        bool window = ix >= pr && iy >= pr && ix < BMFR_EMISSION_INPUT - pr
                      && iy < BMFR_EMISSION_INPUT - pr;
        group_lit |= window && p.x > 0.0f;
    }
    if (group_lit) atomic_or(&any_lit, 1);
    barrier(CLK_LOCAL_MEM_FENCE);
    if (any_lit == 0) return;  // the same for every work-item of the group
    bool lit = false;
    if (x < w && y < h)
        for (int v = max(y - r, 0); v <= min(y + r, h - 1) && !lit; ++v)
            for (int u = max(x - r, 0); u <= min(x + r, w - 1); ++u)
                if (input[(v - ty + BMFR_EMISSION_APRON) * BMFR_EMISSION_INPUT
                          + u - tx + BMFR_EMISSION_APRON].x > 0.0f) {
                    lit = true;
                    break;
                }
    const float k2 = BMFR_EMISSION_K * BMFR_EMISSION_K;
    float3 acc = (float3)(0.0f);
    float wsum = 0.0f;
    for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
            barrier(CLK_LOCAL_MEM_FENCE);
            // The terms of the pixels a of the tile and its border against a + (dx, dy).
            for (int e = first; e < BMFR_EMISSION_SIDE * BMFR_EMISSION_SIDE; e += BMFR_EMISSION_ITEMS) {
                int sx = e % BMFR_EMISSION_SIDE, sy = e / BMFR_EMISSION_SIDE;
                int ax = tx - pr + sx, ay = ty - pr + sy, bx = ax + dx, by = ay + dy;
                float t = 0.0f, diff = 0.0f, var = 0.0f;
                if (ax >= 0 && ay >= 0 && ax < w && ay < h && bx >= 0 && by >= 0 && bx < w && by < h) {
                    float2 p = input[(sy + r) * BMFR_EMISSION_INPUT + sx + r];
                    float2 q = input[(sy + r + dy) * BMFR_EMISSION_INPUT + sx + r + dx];
                    diff = p.x - q.x;
                    var = p.y + q.y;
                    t = (diff * diff - (p.y + fmin(p.y, q.y))) / (BMFR_EMISSION_EPSILON + k2 * var);
                }
                dist[e] = t;
#if BMFR_EMISSION_MEAN_ON
                dist_diff[e] = diff;
                dist_var[e] = var;
#endif
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            for (int e = first; e < BMFR_EMISSION_SIDE * BMFR_EMISSION_TILE; e += BMFR_EMISSION_ITEMS) {
                int cx = e % BMFR_EMISSION_TILE, sy = e / BMFR_EMISSION_TILE;
                int at = sy * BMFR_EMISSION_SIDE + cx;
                float s = 0.0f;
                for (int px = 0; px <= 2 * pr; ++px) s += dist[at + px];
                rows[e] = s;
#if BMFR_EMISSION_MEAN_ON
                float s_diff = 0.0f, s_var = 0.0f;
                for (int px = 0; px <= 2 * pr; ++px) {
                    s_diff += dist_diff[at + px];
                    s_var += dist_var[at + px];
                }
                rows_diff[e] = s_diff;
                rows_var[e] = s_var;
#endif
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            int u = x + dx, v = y + dy;
            if (!lit || u < 0 || v < 0 || u >= w || v >= h) continue;
            float d = 0.0f;
            for (int py = 0; py <= 2 * pr; ++py) d += rows[(ly + py) * BMFR_EMISSION_TILE + lx];
            float n = (float)(bmfr_emission_taps(x, dx, w) * bmfr_emission_taps(y, dy, h));
            float distance = d / n;
#if BMFR_EMISSION_MEAN_ON
            float d_diff = 0.0f, d_var = 0.0f;
            for (int py = 0; py <= 2 * pr; ++py) {
                d_diff += rows_diff[(ly + py) * BMFR_EMISSION_TILE + lx];
                d_var += rows_var[(ly + py) * BMFR_EMISSION_TILE + lx];
            }
            distance = fmax(distance, BMFR_EMISSION_MEAN_TEST(d_diff, d_var, k2));
#endif
            float wt = exp(-fmax(distance, 0.0f));
            __global const float* e = lines + bmfr_line_at(u, v, BMFR_EMISSION_LINES, stride);
            acc.x += wt * e[0];
            acc.y += wt * e[stride];
            acc.z += wt * e[2 * (size_t)stride];
            wsum += wt;
        }
    if (!lit) return;
    if (BMFR_EMISSION_SELF > 0.0f) {  // the pixel's own E, last (emission.rs `self_weight`)
        __global const float* e = lines + bmfr_line_at(x, y, BMFR_EMISSION_LINES, stride);
        acc.x += BMFR_EMISSION_SELF * e[0];
        acc.y += BMFR_EMISSION_SELF * e[stride];
        acc.z += BMFR_EMISSION_SELF * e[2 * (size_t)stride];
        wsum += BMFR_EMISSION_SELF;
    }
    float4 o = out[y * w + x];
    out[y * w + x] = (float4)(o.x + acc.x / wsum, o.y + acc.y / wsum, o.z + acc.z / wsum, o.w);
}

// bmfr_emission_nlm on CPU devices (`packed_nlm`, as bmfr_nlm_packed): one work-item filters
// BMFR_EMISSION_STEP (12) adjacent pixels x0 .. x0 + 11 of BMFR_EMISSION_ROWS rows, every
// operation on float16 vectors whose lane i is pixel x0 - 2 + i (lanes 0, 1, 14 and 15 are the
// neighbours a patch row's taps need, computed and never written). Why: PoCL runs the
// work-group kernel's loops between barriers on scalar floats with a scalar exp. For one
// offset, each of the work-item's rows is evaluated once (16 lanes), each patch row's five taps
// summed by shifting the lanes, and each output row's five such row sums added. A pixel
// is lit when some q of its window inside the image has a luminance above 0 (the reference's
// test, gathered over the offsets), and a work-item none of whose pixels' windows holds light
// returns at once. The same float operations in the same order as the work-group kernel and
// the Rust reference.
#include "vectors.cl"

#define BMFR_EMISSION_STEP (BMFR_NLM_PACK - 2 * BMFR_EMISSION_PATCH)
#if BMFR_EMISSION_PATCH != 2
#error "noisefree: bmfr_emission_nlm_packed sums patch rows of 5 taps (EMISSION_PATCH 2)"
#endif

// Per lane (((t(x - 2) + t(x - 1)) + t(x)) + t(x + 1)) + t(x + 2): a patch row's sum, right in
// lanes 2 .. 13.
__attribute__((always_inline)) inline float16 bmfr_emission_row_sum(float16 t) {
    float16 l2 = shuffle(t, (uint16)(0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13));
    float16 l1 = shuffle(t, (uint16)(0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14));
    float16 r1 = shuffle(t, (uint16)(1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 15));
    float16 r2 = shuffle(t, (uint16)(2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 15, 15));
    return (((l2 + l1) + t) + r1) + r2;
}

// A patch row's sums for the lanes xv .. xv + 15 of row ay against row by shifted by dx: of the
// terms (returned) and, for the mean-difference test, of the taps' differences and variances.
__attribute__((always_inline)) inline float16 bmfr_emission_row(__global const float* lines,
                                                                uint stride, int xv, int ay,
                                                                int by, int dx, float k2,
                                                                float16* diffs, float16* vars) {
    __global const float* a = lines + bmfr_line_at(xv, ay, BMFR_EMISSION_LINES, stride);
    __global const float* b = lines + bmfr_line_at(xv + dx, by, BMFR_EMISSION_LINES, stride);
    float16 va = load16(a + 4 * (size_t)stride), vb = load16(b + 4 * (size_t)stride);
    float16 diff = load16(a + 3 * (size_t)stride) - load16(b + 3 * (size_t)stride);
    float16 var = va + vb;
    float16 t = (diff * diff - (va + fmin(va, vb))) / (BMFR_EMISSION_EPSILON + k2 * var);
    float16 inside = load16(a + 5 * (size_t)stride) * load16(b + 5 * (size_t)stride);
    t = inside != 0.0f ? t : (float16)(0.0f);
#if BMFR_EMISSION_MEAN_ON
    *diffs = bmfr_emission_row_sum(inside != 0.0f ? diff : (float16)(0.0f));
    *vars = bmfr_emission_row_sum(inside != 0.0f ? var : (float16)(0.0f));
#endif
    return bmfr_emission_row_sum(t);
}

// The five row sums of output row `row`'s patch, top to bottom: (((hs[row][k] + hs[row + 1][k])
// + ...) + hs[row + 4][k]).
#define BMFR_EMISSION_COLUMN(hs, row, k)                                                     \
    ((((hs[row][k] + hs[row + 1][k]) + hs[row + 2][k]) + hs[row + 3][k]) + hs[row + 4][k])

// Global size: ceil(width / STEP) x ceil(height / ROWS), work-groups of 1.
__kernel void bmfr_emission_nlm_packed(__global const float* lines, uint stride, uint width,
                                       uint height, __global float4* out) {
    const int r = BMFR_EMISSION_RADIUS, pr = BMFR_EMISSION_PATCH;
    int x0 = get_global_id(0) * BMFR_EMISSION_STEP, y0 = get_global_id(1) * BMFR_EMISSION_ROWS;
    int w = width, h = height;
    if (x0 >= w || y0 >= h) return;
    bool any = false;
    for (int v = max(y0 - r, 0); v <= min(y0 + BMFR_EMISSION_ROWS - 1 + r, h - 1) && !any; ++v) {
        __global const float* lum = lines + bmfr_line_at(0, v, BMFR_EMISSION_LINES, stride)
                                    + 3 * (size_t)stride;
        for (int u = max(x0 - r, 0); u <= min(x0 + BMFR_EMISSION_STEP - 1 + r, w - 1); ++u)
            if (lum[u] > 0.0f) {
                any = true;
                break;
            }
    }
    if (!any) return;
    int xv = x0 - pr;  // the pixel of lane 0
    int16 xs = (int16)(xv) + (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const float k2 = BMFR_EMISSION_K * BMFR_EMISSION_K;
    float16 acc[BMFR_EMISSION_ROWS][3], wsum[BMFR_EMISSION_ROWS];
    int16 lit[BMFR_EMISSION_ROWS];
    float16 hs[BMFR_EMISSION_ROWS + 2 * BMFR_EMISSION_PATCH][1 + 2 * BMFR_EMISSION_MEAN_ON];
    for (int row = 0; row < BMFR_EMISSION_ROWS; ++row) {
        for (int c = 0; c < 3; ++c) acc[row][c] = (float16)(0.0f);
        wsum[row] = (float16)(0.0f);
        lit[row] = (int16)(0);
    }
    for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
            if (x0 + dx + BMFR_EMISSION_STEP - 1 < 0 || x0 + dx >= w) continue;  // no q inside
            // bmfr_emission_taps per lane: the patch's valid taps along x.
            int16 lo = max((int16)(-pr), max(-xs, -xs - dx));
            int16 hi = min((int16)(pr), min(w - 1 - xs, w - 1 - xs - dx));
            float16 taps_x = convert_float16(max(hi - lo + 1, (int16)(0)));
            // Two passes, as bmfr_nlm_packed's offsets (why there): every row's patch row sums
            // into hs (hs[i]: row y0 - 2 + i; hs[i][1] and [2] the taps' differences and
            // variances for the mean test), then each output row's five summed top to bottom.
            for (int rr = -pr; rr < BMFR_EMISSION_ROWS + pr; ++rr) {
                int ay = y0 + rr, by = ay + dy;
                float16 hd = 0.0f, hv = 0.0f, h0 = 0.0f;
                if (ay >= 0 && ay < h && by >= 0 && by < h)
                    h0 = bmfr_emission_row(lines, stride, xv, ay, by, dx, k2, &hd, &hv);
                hs[rr + pr][0] = h0;
#if BMFR_EMISSION_MEAN_ON
                hs[rr + pr][1] = hd;
                hs[rr + pr][2] = hv;
#endif
            }
            for (int row = 0; row < BMFR_EMISSION_ROWS; ++row) {
                int py = y0 + row, qy = py + dy;
                if (py >= h || qy < 0 || qy >= h) continue;
                __global const float* p = lines + bmfr_line_at(xv, py, BMFR_EMISSION_LINES, stride);
                __global const float* q =
                    lines + bmfr_line_at(xv + dx, qy, BMFR_EMISSION_LINES, stride);
                int16 valid = load16(p + 5 * (size_t)stride) != 0.0f
                              && load16(q + 5 * (size_t)stride) != 0.0f;
                lit[row] |= valid && load16(q + 3 * (size_t)stride) > 0.0f;
                float16 d = BMFR_EMISSION_COLUMN(hs, row, 0);
                float16 n = taps_x * (float)bmfr_emission_taps(py, dy, h);
                float16 distance = d / n;
#if BMFR_EMISSION_MEAN_ON
                float16 d_diff = BMFR_EMISSION_COLUMN(hs, row, 1);
                float16 d_var = BMFR_EMISSION_COLUMN(hs, row, 2);
                distance = fmax(distance, BMFR_EMISSION_MEAN_TEST(d_diff, d_var, k2));
#endif
                float16 wt = valid ? exp(-fmax(distance, 0.0f)) : (float16)(0.0f);
                for (int c = 0; c < 3; ++c) acc[row][c] += wt * load16(q + c * (size_t)stride);
                wsum[row] += wt;
            }
        }
    for (int row = 0; row < BMFR_EMISSION_ROWS && y0 + row < h; ++row) {
        float mean[3][BMFR_NLM_PACK], on[BMFR_NLM_PACK];
        if (BMFR_EMISSION_SELF > 0.0f) {  // the pixels' own E, last (emission.rs `self_weight`)
            __global const float* p =
                lines + bmfr_line_at(xv, y0 + row, BMFR_EMISSION_LINES, stride);
            for (int c = 0; c < 3; ++c)
                acc[row][c] += BMFR_EMISSION_SELF * load16(p + c * (size_t)stride);
            wsum[row] += BMFR_EMISSION_SELF;
        }
        for (int c = 0; c < 3; ++c) vstore16(acc[row][c] / wsum[row], 0, mean[c]);
        vstore16(convert_float16(lit[row]), 0, on);
        for (int i = pr; i < pr + BMFR_EMISSION_STEP && xv + i < w; ++i) {
            if (on[i] == 0.0f) continue;
            __global float4* o = out + (size_t)(y0 + row) * width + (xv + i);
            *o = (float4)((*o).x + mean[0][i], (*o).y + mean[1][i], (*o).z + mean[2][i], (*o).w);
        }
    }
}
