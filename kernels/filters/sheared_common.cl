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

#endif
