// The a-trous filter's packed variant (`variant = "packed"`, src/filters/atrous/device.rs):
// the equations and pass structure of filters/atrous.cl (included below, whose helpers it
// uses), with one work-item of `atrous_pass_packed` filtering ATROUS_PACK (16) horizontally
// adjacent pixels of one row, every tap's arithmetic written on float16 vectors whose lane i
// is pixel x0 + i.
//
// Why: PoCL packs work-items into SIMD lanes only for kernels without loops of their own; the
// scalar `atrous_pass` loops over its 25 taps per work-item and so runs on scalar floats with
// a scalar exp (4.2 % of the device's float16 FMA peak, results/README.md "Roofline"). Here
// the packing is explicit, as in the data-driven filter's packed variant (filters/ddf_packed.cl).
//
// Layout ("lines"): instead of float4 images, `atrous_init_packed` writes every image row as
// lines of `stride` floats, one line per component, the lines of one row adjacent:
//   colour (two ping-pong buffers): 3 lines per row, rgb (0 for sky);
//   guides: 8 lines per row, normal xyz, surface (1, or 0 for sky), position xyz, footprint.
// Pixel (x, y), component k sits at (y * lines + k) * stride + ATROUS_PACK + x. Every line has
// ATROUS_PACK zeros on the left and at least ATROUS_PACK - 1 on the right (stride = PACK +
// width rounded up to PACK + PACK); they are never written, so they stay 0 (the buffers are
// zeroed once), and a lane past the image's edge reads a pixel whose surface flag is 0: a
// non-surface neighbour, weight 0 through select(), as the scalar kernel skips both. A tap
// whose 16 neighbours all lie left or right of the image (the same test for every lane) is
// skipped as a whole; any other tap reads within the padding. So the padding is 16 whatever
// the tap spacing (2^i up to 2^14 pixels, MAX_ITERATIONS).
//
// Every lane does the same float operations in the same order as atrous_pass (FP_CONTRACT OFF
// from atrous.cl); a skipped tap adds nothing there and 0 x a finite colour here (the same
// sums). Sky colour is 0 in the lines, so a masked-out neighbour never brings an inf or NaN
// into the sums (0 x inf); atrous_finish_packed gives sky pixels their input colour, as
// atrous_finish does. Measured difference to the Rust reference: tests/atrous.rs.

#include "filters/atrous.cl"
#include "vectors.cl"

#if ATROUS_PACK == 16
#define floatP float16
// Loads and stores of lines in global memory (vectors.cl: one vector instruction each).
#define vloadP(n, p) load16((p) + 16 * (size_t)(n))
#define vstoreP(v, n, p) store16((v), (p) + 16 * (size_t)(n))
#else
#error "noisefree: ATROUS_PACK must be 16 (src/filters/atrous/device.rs PACK)"
#endif

#define ATROUS_COLOUR_LINES 3
#define ATROUS_GUIDE_LINES 8

// Where component 0 of pixel (x, y) lies in a buffer of `lines` lines per row.
inline size_t atrous_line_at(int x, int y, int lines, uint stride) {
    return ((size_t)y * lines) * stride + ATROUS_PACK + x;
}

// atrous_init into lines. Global size: width x height (no loop: PoCL vectorises it itself).
__kernel void atrous_init_packed(__constant const AtrousParams* p,
                                 __global const FilterVector* fv,
                                 __global float* colour,
                                 __global float* guides,
                                 uint stride) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    float3 c;
    float4 pos, nrm;
    atrous_init_pixel(p, fv + (y * (int)p->width + x), x, y, &c, &pos, &nrm);
    if (nrm.w == 0.0f) c = (float3)(0.0f);     // sky: no colour in the sums (see above)
    __global float* at = colour + atrous_line_at(x, y, ATROUS_COLOUR_LINES, stride);
    at[0] = c.x;
    at[stride] = c.y;
    at[2 * (size_t)stride] = c.z;
    float g[ATROUS_GUIDE_LINES] = {nrm.x, nrm.y, nrm.z, nrm.w, pos.x, pos.y, pos.z, pos.w};
    __global float* gat = guides + atrous_line_at(x, y, ATROUS_GUIDE_LINES, stride);
    for (int k = 0; k < ATROUS_GUIDE_LINES; ++k) gat[k * (size_t)stride] = g[k];
}

inline floatP atrous_sum_sq_p(const floatP* a, const floatP* b) {
    floatP d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
    return d0 * d0 + d1 * d1 + d2 * d2;             // atrous_sum_sq's order
}

// atrous_pass on ATROUS_PACK pixels of a row. Global size: ceil(width / PACK) x height.
__kernel void atrous_pass_packed(__constant const AtrousParams* p,
                                 __global const float* in,
                                 __global const float* guides,
                                 __global float* out,
                                 uint stride) {
    int x0 = get_global_id(0) * ATROUS_PACK, y = get_global_id(1);
    int w = (int)p->width, h = (int)p->height;
    if (x0 >= w || y >= h) return;
    size_t c_at = atrous_line_at(x0, y, ATROUS_COLOUR_LINES, stride);
    size_t g_at = atrous_line_at(x0, y, ATROUS_GUIDE_LINES, stride);
    floatP cc[3], nc[3], pc[3];
    for (int k = 0; k < 3; ++k) {
        cc[k] = vloadP(0, in + c_at + k * (size_t)stride);
        nc[k] = vloadP(0, guides + g_at + k * (size_t)stride);
        pc[k] = vloadP(0, guides + g_at + (4 + k) * (size_t)stride);
    }
    floatP surface = vloadP(0, guides + g_at + 3 * (size_t)stride);
    floatP footprint = vloadP(0, guides + g_at + 7 * (size_t)stride);
    floatP sum[3] = {(floatP)(0.0f), (floatP)(0.0f), (floatP)(0.0f)};
    floatP wsum = (floatP)(0.0f);
    // A group of sky pixels only (lanes past the edge count as sky) keeps its colours (0).
    if (any(surface != 0.0f)) {
        int step = p->step;
        float inv_c = atrous_inv_sq(ldexp(p->sigma_color, -(int)p->iteration));
        float inv_n = atrous_inv_sq(p->sigma_normal);
        floatP sp = p->sigma_position * footprint;
        floatP inv_p = 1.0f / clamp(sp * sp, FLT_MIN, FLT_MAX);   // atrous_inv_sq, per lane
        floatP cq[3], nq[3], pq[3];
        for (int ky = 0; ky < 5; ++ky) {
            int ny = y + (ky - 2) * step;
            if (ny < 0 || ny >= h) continue;     // the same for every lane
            for (int kx = 0; kx < 5; ++kx) {
                int dx = (kx - 2) * step;
                if (x0 + dx + ATROUS_PACK - 1 < 0 || x0 + dx >= w) continue;  // no lane inside
                size_t cq_at = atrous_line_at(x0 + dx, ny, ATROUS_COLOUR_LINES, stride);
                size_t gq_at = atrous_line_at(x0 + dx, ny, ATROUS_GUIDE_LINES, stride);
                // Unrolled, as the accumulation below: PoCL keeps a private array of
                // float16s on the stack unless its loop is unrolled (results/README.md,
                // "PoCL's code for the packed kernels").
                #pragma unroll
                for (int k = 0; k < 3; ++k) {
                    cq[k] = vloadP(0, in + cq_at + k * (size_t)stride);
                    nq[k] = vloadP(0, guides + gq_at + k * (size_t)stride);
                    pq[k] = vloadP(0, guides + gq_at + (4 + k) * (size_t)stride);
                }
                floatP sq = vloadP(0, guides + gq_at + 3 * (size_t)stride);
                floatP e = atrous_sum_sq_p(cc, cq) * inv_c
                         + atrous_sum_sq_p(nc, nq) * inv_n
                         + atrous_sum_sq_p(pc, pq) * inv_p;
                // Sky, and pixels outside the image (flag 0 in the padding), weigh 0.
                floatP wq = select((floatP)(0.0f),
                                   ATROUS_B3[kx] * ATROUS_B3[ky] * fmin(1.0f, exp(-e)),
                                   sq != 0.0f);
                #pragma unroll
                for (int k = 0; k < 3; ++k) sum[k] += wq * cq[k];
                wsum += wq;
            }
        }
    }
    // Sky centres (and lanes past the edge: 0 stays 0) pass through unfiltered.
    for (int k = 0; k < 3; ++k)
        vstoreP(select(cc[k], sum[k] / wsum, surface != 0.0f), 0,
                out + c_at + k * (size_t)stride);
}

// atrous_finish from lines into the float4 image. Global size: width x height.
__kernel void atrous_finish_packed(__constant const AtrousParams* p,
                                   __global const FilterVector* fv,
                                   __global const float* colour,
                                   __global float4* image,
                                   uint stride) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    uint i = (uint)(y * (int)p->width + x);
    __global const FilterVector* f = fv + i;
    if (f->depth >= SKY_DEPTH) {
        image[i] = (float4)(f->direct[0] + f->indirect[0], f->direct[1] + f->indirect[1],
                            f->direct[2] + f->indirect[2], 0.0f);
        return;
    }
    __global const float* at = colour + atrous_line_at(x, y, ATROUS_COLOUR_LINES, stride);
    float3 c = (float3)(at[0], at[stride], at[2 * (size_t)stride]);
#if ATROUS_DEMODULATE
    c = c * atrous_albedo(f);
#endif
    image[i] = (float4)(c, 0.0f);
}
