// The data-driven filter's packed variant (DDF_VARIANT 3; included by filters/ddf.cl, whose
// helpers it uses): one work-item filters DDF_PACK (16) horizontally adjacent pixels of one
// row, every tap's arithmetic written on float16 vectors whose lane i is pixel x0 + i.
//
// Why: PoCL packs work-items into SIMD lanes only for kernels without loops of their own; the
// per-work-item tap loops of variants 0-2 run on scalar floats with a scalar exp (7 % of the
// device's float16 FMA peak, results/README.md "Roofline"). Here the packing is explicit.
//
// Layout: `ddf_pack` first copies the FilterVectors (and the direction term's input) into
// "lines": each image row becomes DDF_LINES lines of `stride` floats, line k holding lane k
// of F of every pixel of the row, padded by `half` zeros on the left and at least `half` on
// the right, so that the neighbours x0 + i + dx of all lanes are one vloadN at any dx, at the
// image borders too. The lines of one row are adjacent (a row of 512 pixels at kw 21: 35 kB):
// with one plane per lane of F instead, each tap read 16 places 1 MB apart, and the kernel
// took 1.7x as long (512 x 512, kw 21, measured side by side, loaded machine). Lanes whose
// neighbour lies outside the image get weight 0 through select() (the other variants skip
// them: adding 0 to the sums leaves the same bits); rows outside the image are skipped as a
// whole (the same for every lane). Every lane does the same float operations in the same
// order as ddf_neighbour (with FP_CONTRACT OFF from ddf.cl). The result is not bit-identical
// all the same: measured within 2.8e-7 (relative) of variant 2 and 2.6e-7 of the Rust
// reference (tests/ddf.rs every_variant_matches_the_rust_reference); PoCL's float16 exp or
// division need not round like the scalar ones (not investigated further).

#include "vectors.cl"

#if DDF_PACK == 16
#define floatP float16
#define intP int16
// Loads and stores of lines in global memory (vectors.cl: one vector instruction each).
#define vloadP(n, p) load16((p) + 16 * (size_t)(n))
#define vstoreP(v, n, p) store16((v), (p) + 16 * (size_t)(n))
#define LANE_IDS (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)
#else
#error "noisefree: DDF_PACK must be 16 (src/filters/ddf/device.rs PACK)"
#endif

// Lines after the 16 of F: the direction term's input (neighbour_direction).
#if DDF_DIRECTION == 1
#define DDF_DIRECTION_LINES 3
#elif DDF_DIRECTION == 2
#define DDF_DIRECTION_LINES 1
#else
#define DDF_DIRECTION_LINES 0
#endif
#define DDF_LINES (16 + DDF_DIRECTION_LINES)

// The lines of rows row0.. (global size: width x rows): lane k of pixel (x, y) at
// (y * DDF_LINES + k) * stride + half + x.
__kernel void ddf_pack(__constant const DdfParams* p,
                       __global const float* f,
                       __global const float* gb,
                       __global const float* state,
                       __global float* lines,
                       uint stride,
                       uint row0) {
    int x = get_global_id(0), y = (int)row0 + get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    uint pixel = (uint)y * p->width + (uint)x;
    __global float* at = lines + (size_t)y * DDF_LINES * stride + p->half_width + x;
    float fv[16];
    vstore16(load16(f + 16 * (size_t)pixel), 0, fv);
    for (int k = 0; k < 16; ++k) at[(size_t)k * stride] = fv[k];
#if DDF_DIRECTION_LINES > 0
    float3 d = neighbour_direction(p, gb, state, pixel);
    at[16 * (size_t)stride] = d.x;
#if DDF_DIRECTION_LINES == 3
    at[17 * (size_t)stride] = d.y;
    at[18 * (size_t)stride] = d.z;
#endif
#endif
}

// The packed centre (Table 6.3): lane i holds pixel x0 + i.
typedef struct {
    floatP f[16];        // F (eq. 6.1), lane by lane
    floatP sigma2_f[5];  // eq. 6.10
    floatP direction[3]; // neighbour_direction of the centre (as many as used)
    floatP c_fd[3], c_fi[3], tw_d, tw_i;  // eqs. 6.17-6.20, accumulating
} DdfPacked;

// Lane k of F of the 16 neighbours whose lane 0 is at `q` (a line of the padded copy).
#define DDF_NEIGHBOUR(q, stride, k) vloadP(0, (q) + (size_t)(k) * (stride))

// sum_sq3's order, the centre's lanes a[0..2] against the neighbours' lines k .. k + 2.
inline floatP sum_sq3_p(const floatP* a, __global const float* q, uint stride, int k) {
    floatP d0 = a[0] - DDF_NEIGHBOUR(q, stride, k), d1 = a[1] - DDF_NEIGHBOUR(q, stride, k + 1),
           d2 = a[2] - DDF_NEIGHBOUR(q, stride, k + 2);
    return d0 * d0 + d1 * d1 + d2 * d2;
}

// ddf_neighbour on the DDF_PACK neighbours whose lines start at `q`; `inside` (-1 per lane)
// says which count. Written for PoCL's code generator, with the same float operations:
// - always inlined: PoCL's LLVM judged it too big (two float16 exponentials) and called it
//   per tap, so the accumulators in `c` went through memory on every tap; inlined, they
//   stay in registers, and a constant `inside` folds the selects away (ddf_filter's
//   interior work-items);
// - each neighbour lane read from the lines where it is used, not first copied into an
//   array: PoCL keeps a private array of float16s on the stack unless its loop is unrolled,
//   and unrolled, 16 live float16s spill;
// - the three-colour loop unrolled, for the same reason.
// Same bytes; results/README.md ("PoCL's code for the packed kernels") has the times.
__attribute__((always_inline)) inline void ddf_neighbour_p(__constant const DdfParams* p,
                                                           DdfPacked* c,
                                                           __global const float* q,
                                                           uint stride, intP inside) {
    floatP e_dc = p->sigma2_dc * sum_sq3_p(c->f, q, stride, 0);              // eq. 6.11
    floatP e_ic = p->sigma2_ic * sum_sq3_p(c->f + 3, q, stride, 3);          // eq. 6.12
    floatP dd = (c->f[6] - DDF_NEIGHBOUR(q, stride, 6)) * p->depth_scale;
    floatP e_fd = c->sigma2_f[0] * dd * dd                                   // eq. 6.13
                + c->sigma2_f[1] * sum_sq3_p(c->f + 7, q, stride, 7)
                + c->sigma2_f[2] * sum_sq3_p(c->f + 10, q, stride, 10);
    floatP e_fi = e_fd;                                                      // eq. 6.14
#if DDF_TEXTURE2
    e_fi += c->sigma2_f[4] * sum_sq3_p(c->f + 13, q, stride, 13);
#endif
#if DDF_DIRECTION == 1
    e_fi += c->sigma2_f[3] * sum_sq3_p(c->direction, q, stride, 16);
#elif DDF_DIRECTION == 2
    e_fi += DDF_NEIGHBOUR(q, stride, 16);     // the neighbour's own sigma2_f,3
#else
    e_fi += c->sigma2_f[3];                    // as printed; cancels in eq. 6.21
#endif
    floatP zero = (floatP)(0.0f);
    floatP w_d = select(zero, DDF_EXP(-(e_dc + e_fd)), inside);              // eq. 6.15
    floatP w_i = select(zero, DDF_EXP(-(e_ic + e_fi)), inside);              // eq. 6.16
    #pragma unroll
    for (int k = 0; k < 3; ++k) {
        c->c_fd[k] += w_d * DDF_NEIGHBOUR(q, stride, k);                     // eq. 6.17
        c->c_fi[k] += w_i * DDF_NEIGHBOUR(q, stride, 3 + k);                 // eq. 6.18
    }
    c->tw_d += w_d;                                                          // eq. 6.19
    c->tw_i += w_i;                                                          // eq. 6.20
}

// Global size: ceil(width / DDF_PACK) x height.
__kernel void ddf_filter(__constant const DdfParams* p,
                         __global const float* f,
                         __global const float* gb,
                         __global const float* state,
                         __global float4* out,
                         __global const float* lines,
                         uint stride) {
    int x0 = get_global_id(0) * DDF_PACK, y = get_global_id(1);
    int w = (int)p->width, h = (int)p->height, r = p->half_width;
    if (x0 >= w || y >= h) return;
    DdfPacked c;
    // The centres: eq. 6.10 pixel by pixel with ddf_centre (once per pixel, not per tap).
    // Lanes past the image's right edge repeat its last pixel; they are not written.
    float s2[5][DDF_PACK];
    for (int i = 0; i < DDF_PACK; ++i) {
        uint pixel = (uint)(y * w + min(x0 + i, w - 1));
        DdfCentre one = ddf_centre(p, load16(f + 16 * (size_t)pixel), gb, state, pixel);
        for (int j = 0; j < 5; ++j) s2[j][i] = one.sigma2_f[j];
    }
    for (int j = 0; j < 5; ++j) c.sigma2_f[j] = vload16(0, s2[j]);
    __global const float* centre = lines + (size_t)y * DDF_LINES * stride + r + x0;
    for (int k = 0; k < 16; ++k) c.f[k] = vloadP(0, centre + (size_t)k * stride);
    for (int k = 0; k < DDF_DIRECTION_LINES; ++k)
        c.direction[k] = vloadP(0, centre + (size_t)(16 + k) * stride);
    for (int k = 0; k < 3; ++k) c.c_fd[k] = c.c_fi[k] = (floatP)(0.0f);
    c.tw_d = c.tw_i = (floatP)(0.0f);
    int lanes = min(DDF_PACK, w - x0);
#if DDF_SKY
    // A group of sky pixels only (lanes past the image's edge count as sky) keeps its colours
    // without visiting a tap (§6.3.4): the other variants skip sky pixels one by one.
    if (all(c.f[6] >= SKY_DEPTH || LANE_IDS >= lanes)) {
        for (int i = 0; i < lanes; ++i) {
            uint pixel = (uint)(y * w + x0 + i);
            float16 fc = load16(f + 16 * (size_t)pixel);
            out[pixel] = (float4)(fc.s012 + fc.s345, 0.0f);
        }
        return;
    }
#endif

    // A work-item whose every tap of every lane lies inside the image (all but the first
    // and last of a row) needs no per-lane test: select(0, w, -1) is w, the same bits.
    bool interior = x0 - r >= 0 && x0 + DDF_PACK - 1 + r < w;
    for (int dy = -r; dy <= r; dy += p->step) {
        int ny = y + dy;
        if (ny < 0 || ny >= h) continue;           // the same for every lane
        __global const float* row = lines + (size_t)ny * DDF_LINES * stride + r + x0;
        for (int dx = -r; dx <= r; dx += p->step) {
            if (interior) {
                ddf_neighbour_p(p, &c, row + dx, stride, (intP)(-1));
            } else {
                intP nx = (intP)(x0 + dx) + LANE_IDS;
                intP inside = nx >= 0 && nx < w;      // out-of-image neighbours weigh 0
                ddf_neighbour_p(p, &c, row + dx, stride, inside);
            }
        }
    }
    if (ddf_centre_off_grid(p)) ddf_neighbour_p(p, &c, centre, stride, (intP)(-1));

    // eq. 6.21 (ddf_output), lane by lane; sky centres keep their colour (§6.3.4).
    float rgb[3][DDF_PACK];
    for (int k = 0; k < 3; ++k) {
        floatP d = select(c.f[k], c.c_fd[k] / c.tw_d, c.tw_d > 0.0f);
        floatP i = select(c.f[3 + k], c.c_fi[k] / c.tw_i, c.tw_i > 0.0f);
        floatP v = d + i;
#if DDF_SKY
        v = select(v, c.f[k] + c.f[3 + k], c.f[6] >= SKY_DEPTH);
#endif
        vstore16(v, 0, rgb[k]);
    }
    for (int i = 0; i < lanes; ++i)
        out[y * w + x0 + i] = (float4)(rgb[0][i], rgb[1][i], rgb[2][i], 0.0f);
}
