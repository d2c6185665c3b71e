// The edge-avoiding a-trous wavelet filter (Dammertz, Sewtz, Hanika, Lensch, HPG 2010).
//
// Each pass is one launch of `atrous_pass` (ping-pong buffers): a 5 x 5 B3-spline kernel
// h = (1/16, 1/4, 3/8, 1/4, 1/16) whose taps are `step` = 2^iteration pixels apart, each tap
// weighted by
//     w = h(dx) h(dy) * w_colour * w_normal * w_position,
//     w_f = min(1, exp(-|f_p - f_q|^2 / sigma_f^2)),
// and the weighted sum divided by the sum of the weights. Since every exponent is >= 0, the
// three factors are formed as one exp of the summed exponents (the same value, one exp
// instead of three); min(1, .) is kept as written.
//
//   sigma_colour  = sigma_color * 2^-iteration: halved every pass, because each pass leaves
//                   the colour smoother than the last.
//   sigma_normal  = sigma_normal, on the mean shading normals of F.
//   sigma_position = sigma_position * footprint(p): in units of the world size of one pixel
//                   at the centre's depth, footprint = depth * 2 tan(fov/2) / height. So the
//                   filter does not depend on the scene's scale (scaling the scene scales
//                   |p - q| and the footprint alike) nor, in pixels, on the resolution. Like
//                   the paper's world-space sigma it is the same in every pass (a sigma that
//                   grows with the tap spacing filtered worse: see src/filters/atrous.rs).
//
// Positions are reconstructed once, by `atrous_init`, from F's depth (the distance along the
// camera ray) and the ray through the pixel centre (kernels/render/camera.cl without the jitter):
//     dir = normalize(forward + sx right + sy up), p = origin + depth dir.
// Only differences of positions enter the weights and the origin cancels in them, so the
// buffer holds depth * dir (camera-relative, better float precision far from the world
// origin). With a thin lens (DOF) the real rays start anywhere on the lens; the pinhole
// reconstruction is then off by about lens radius * (1 + depth / focal distance).
//
// Sky pixels (depth >= SKY_DEPTH) have no position and no normal: they keep their unfiltered
// colour and are never a neighbour of another pixel. (A pixel partly covered by sky has a
// mean depth between its surface's and SKY_DEPTH: it is filtered as a surface very far away,
// see src/filters/atrous.rs.) Taps outside the image are skipped; the division by the summed
// weights renormalises. The centre tap always has weight h(0)^2 = 9/64 > 0, so the division
// is safe whatever the sigmas.
//
// Build options (src/filters/atrous.rs):
//   ATROUS_DEMODULATE      1: filter the light divided by the first-hit albedo (per channel,
//                          albedo clamped below at ATROUS_ALBEDO_EPSILON) and multiply the
//                          albedo back at the end, so texture detail is never blurred and the
//                          colour weight sees lighting, not texture; 0: filter the beauty.
//   ATROUS_ALBEDO_EPSILON  the clamp, a float literal.
// The packed variant (filters/atrous_packed.cl, 16 pixels per work-item on float16 lanes)
// includes this file and adds ATROUS_PACK.
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"

#if !defined(ATROUS_DEMODULATE) || !defined(ATROUS_ALBEDO_EPSILON)
#error "noisefree: an a-trous filter switch is missing from the build options"
#endif

// The B3-spline taps, offsets -2..2.
__constant float ATROUS_B3[5] = {1.0f / 16.0f, 1.0f / 4.0f, 3.0f / 8.0f, 1.0f / 4.0f, 1.0f / 16.0f};

// The unit direction of the camera ray through the centre of pixel (x, y); the same formula
// as camera_ray with jitter 0.5. Written out (no normalize/dot builtins) so the Rust reference
// performs the same float operations in the same order.
inline float3 atrous_pixel_direction(__constant const AtrousParams* p, int x, int y) {
    float w = (float)p->width, h = (float)p->height;
    float sx = (2.0f * ((float)x + 0.5f) / w - 1.0f) * p->tan_half_fov * (w / h);
    float sy = (1.0f - 2.0f * ((float)y + 0.5f) / h) * p->tan_half_fov;
    float3 d = p->camera_forward.xyz + sx * p->camera_right.xyz + sy * p->camera_up.xyz;
    float len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    return d / len;
}

inline float atrous_sum_sq(float3 a, float3 b) {
    float3 d = a - b;
    return d.x * d.x + d.y * d.y + d.z * d.z;
}

// 1 / sigma^2 kept finite and non-negative for any sigma: 0 * it is 0, never NaN.
inline float atrous_inv_sq(float sigma) {
    return 1.0f / clamp(sigma * sigma, FLT_MIN, FLT_MAX);
}

inline float3 atrous_albedo(__global const FilterVector* f) {
    return fmax((float3)(f->albedo[0], f->albedo[1], f->albedo[2]), (float3)(ATROUS_ALBEDO_EPSILON));
}

// Pass 0's values of pixel (x, y) (written by atrous_init, and into lines by the packed
// variant's atrous_init_packed, kernels/filters/atrous_packed.cl):
//   colour:   rgb to filter (beauty, or beauty / albedo)
//   position: depth * dir (camera-relative position), w = pixel footprint at that depth
//   normal:   mean shading normal, w = 1 for a surface, 0 for sky
inline void atrous_init_pixel(__constant const AtrousParams* p, __global const FilterVector* f,
                              int x, int y, float3* colour, float4* position, float4* normal) {
    float3 beauty = (float3)(f->direct[0] + f->indirect[0], f->direct[1] + f->indirect[1],
                             f->direct[2] + f->indirect[2]);
    float depth = f->depth;
    bool sky = depth >= SKY_DEPTH;
    float3 c = beauty;
#if ATROUS_DEMODULATE
    if (!sky) c = beauty / atrous_albedo(f);
#endif
    *colour = c;
    if (sky) {
        *position = (float4)(0.0f);
        *normal = (float4)(0.0f);
    } else {
        float3 dir = atrous_pixel_direction(p, x, y);
        float footprint = depth * (2.0f * p->tan_half_fov / (float)p->height);
        *position = (float4)(depth * dir, footprint);
        *normal = (float4)(f->normal[0], f->normal[1], f->normal[2], 1.0f);
    }
}

// Pass 0 input: the colour to filter (w = 0), and the per-pixel guides every pass reads.
__kernel void atrous_init(__constant const AtrousParams* p,
                          __global const FilterVector* fv,
                          __global float4* colour,
                          __global float4* position,
                          __global float4* normal) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    uint i = (uint)(y * (int)p->width + x);
    float3 c;
    float4 pos, nrm;
    atrous_init_pixel(p, fv + i, x, y, &c, &pos, &nrm);
    colour[i] = (float4)(c, 0.0f);
    position[i] = pos;
    normal[i] = nrm;
}

// One a-trous pass with tap spacing p->step = 2^p->iteration.
__kernel void atrous_pass(__constant const AtrousParams* p,
                          __global const float4* in,
                          __global const float4* position,
                          __global const float4* normal,
                          __global float4* out) {
    int x = get_global_id(0), y = get_global_id(1);
    int w = (int)p->width, h = (int)p->height;
    if (x >= w || y >= h) return;
    uint i = (uint)(y * w + x);
    float4 cc = in[i];
    float4 nc = normal[i];
    if (nc.w == 0.0f) {                      // sky: passes through, unfiltered
        out[i] = cc;
        return;
    }
    float4 pc = position[i];
    int step = p->step;
    float inv_c = atrous_inv_sq(ldexp(p->sigma_color, -(int)p->iteration));
    float inv_n = atrous_inv_sq(p->sigma_normal);
    float inv_p = atrous_inv_sq(p->sigma_position * pc.w);
    float3 sum = (float3)(0.0f);
    float wsum = 0.0f;
    for (int ky = 0; ky < 5; ++ky) {
        int ny = y + (ky - 2) * step;
        if (ny < 0 || ny >= h) continue;     // out-of-image taps are skipped
        for (int kx = 0; kx < 5; ++kx) {
            int nx = x + (kx - 2) * step;
            if (nx < 0 || nx >= w) continue;
            uint j = (uint)(ny * w + nx);
            float4 nq = normal[j];
            if (nq.w == 0.0f) continue;      // sky is never a neighbour
            float4 cq = in[j];
            float e = atrous_sum_sq(cc.xyz, cq.xyz) * inv_c
                    + atrous_sum_sq(nc.xyz, nq.xyz) * inv_n
                    + atrous_sum_sq(pc.xyz, position[j].xyz) * inv_p;
            float wq = ATROUS_B3[kx] * ATROUS_B3[ky] * fmin(1.0f, exp(-e));
            sum += wq * cq.xyz;
            wsum += wq;
        }
    }
    out[i] = (float4)(sum / wsum, 0.0f);
}

// After the last pass, in place: multiply the albedo back (ATROUS_DEMODULATE), and give sky
// pixels their input colour bit for bit.
__kernel void atrous_finish(__constant const AtrousParams* p,
                            __global const FilterVector* fv,
                            __global float4* colour) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)p->width || y >= (int)p->height) return;
    uint i = (uint)(y * (int)p->width + x);
    __global const FilterVector* f = fv + i;
    if (f->depth >= SKY_DEPTH) {
        colour[i] = (float4)(f->direct[0] + f->indirect[0], f->direct[1] + f->indirect[1],
                             f->direct[2] + f->indirect[2], 0.0f);
        return;
    }
#if ATROUS_DEMODULATE
    colour[i] = (float4)(colour[i].xyz * atrous_albedo(f), 0.0f);
#endif
}
