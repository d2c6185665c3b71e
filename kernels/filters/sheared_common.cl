// What the sheared filters' kernels share (kernels/filters/sheared.cl: shadows,
// sheared_dof.cl: depth of field, sheared_gi.cl: diffuse indirect light; Yan et al. 2015
// eqs. 3-15): the Gaussian, the l x l grid, the bins, a sample's rgb lanes in the light field.
// src/filters/sheared/shear.rs is the same code in Rust.
#ifndef NOISEFREE_SHEARED_COMMON_CL
#define NOISEFREE_SHEARED_COMMON_CL

#include "layout.cl"

inline float3 sheared_lane3(__global const float* px, int lane) {
    return (float3)(px[lane], px[lane + 1], px[lane + 2]);
}

inline float sheared_gauss(float t, float inv_two_sigma2) {
    return exp(-(t * t) * inv_two_sigma2);
}

inline float sheared_grid(uint a, float jitter, uint side, float radius) {
    return radius * (2.0f * ((float)a + jitter) * (1.0f / (float)side) - 1.0f);
}

inline float sheared_bin_centre(uint c, uint bins, float range) {
    return -range + (float)c * (2.0f * range / (float)(bins - 1u));
}

// The nearest bin of y, or -1 beyond the bins (and for NaN).
inline int sheared_bin_of(float y, uint bins, float range) {
    float c = round((y + range) * ((float)(bins - 1u) / (2.0f * range)));
    return (c >= 0.0f && c < (float)bins) ? (int)c : -1;
}

// Channel ch (0 red, 1 green, 2 blue) of light-field sample k (depth of field and GI).
inline float sheared_rgb_lane(__global const float* lf, int k, int ch) {
    int base = ch == 0 ? LIGHT_FIELD_PIXEL_SAMPLES
                       : (ch == 1 ? LIGHT_FIELD_PIXEL_GREEN : LIGHT_FIELD_PIXEL_BLUE);
    return lf[base + k];
}

// The lens and v-plane filters' steps (kernels/filters/sheared_dof.cl, sheared_gi.cl; their
// Rust reference src/filters/sheared/dof.rs `bin_rows`, `gather_rows`, `neighbours`):

// Zeroes n floats of a pixel's step output (pixels without a field write zero bins).
inline void sheared_zero(__global float* o, uint n) {
    for (uint c = 0u; c < n; ++c) o[c] = 0.0f;
}

// Step 1a (eq. 12) for bin c of pixel field lf: each row b gets sum_a f(a, b) wy[a], rgb and
// the weight, wy[a] being grid point a's weight against the bin centre.
inline void sheared_bin_rows(__global const float* lf, uint l, const float* wy, uint c,
                             __global float* o) {
    for (uint b = 0u; b < l; ++b) {
        float4 v = (float4)(0.0f);
        for (uint a = 0u; a < l; ++a) {
            int k = (int)(b * l + a);
            v.x += sheared_rgb_lane(lf, k, 0) * wy[a];
            v.y += sheared_rgb_lane(lf, k, 1) * wy[a];
            v.z += sheared_rgb_lane(lf, k, 2) * wy[a];
            v.w += wy[a];
        }
        vstore4(v, c * 4u + b, o);
    }
}

// Steps 1b and 2b walk k = -r..r steps from pixel (x, y) along axis 0 (its row) or 1 (its
// column): the neighbour's index in *j, false beyond the image.
inline bool sheared_walk(__constant const ShearedParams* p, int x, int y, int k, int axis,
                         int* j) {
    int qx = axis == 0 ? x + k : x, qy = axis == 0 ? y : y + k;
    if (qx < 0 || qy < 0 || qx >= (int)p->width || qy >= (int)p->height) return false;
    *j = qy * (int)p->width + qx;
    return true;
}

// Step 1b (eq. 13): neighbour j's step-1a rows of its bin c1 (src), weighted wx, added to the
// bins c2[row] of their own second coordinate (-1: beyond the bins, skipped).
inline void sheared_splat_rows(__global const float* src, int c1, const int* c2, uint l, float wx,
                               __global float* o) {
    for (uint row = 0u; row < l; ++row) {
        if (c2[row] < 0) continue;
        float4 v = vload4((uint)c1 * 4u + row, src);
        float4 acc = vload4((uint)c2[row], o);
        vstore4(acc + wx * v, (uint)c2[row], o);
    }
}

#endif
