// AAF's frequency analysis, soft shadows (Wang 2013 §3.2; Mehta et al. 2012; the indirect
// light's eqs. 4.4-4.6 at the end): the filter width
// beta of eq. 3.4 and the sample count n of eq. 3.5, shared by the adaptive sampling pass
// (kernels/render/shadows.cl) and the filter (kernels/filters/aaf_shadows.cl).
// src/render/shadows/bandlimit.rs is the same code in Rust and says why each term is what it is.
#ifndef NOISEFREE_BANDLIMIT_CL
#define NOISEFREE_BANDLIMIT_CL

#include "render/sampling.cl"

// Slopes below this are treated as this (an occluder touching the light), so s1 / s2 stays
// finite or +inf, never NaN.
#define AAF_MIN_SLOPE 1.0e-30f

// Eq. 3.4 with its second term in metres (as printed, d1 / (d2max d) is in 1/m; d d1 / d2max =
// d (1 + s2) is what the authors' code uses): beta = (1/3) max(sigma s2, d (1 + s2)).
inline float aaf_beta(float sigma, float pixel_size, float s2) {
    return fmax(sigma * s2, pixel_size * (1.0f + s2)) * (1.0f / 3.0f);
}

// Eq. 3.5: n = 4 (1 + s1/s2)^2 ((2/s2) sqrt(A_p/A_l) + (1 + s2)^-1)^2 with A_p = d^2 and
// A_l = pi R^2 (the sphere's silhouette disk).
inline float aaf_sample_count(float s1, float s2, float pixel_size, float light_radius) {
    float s = fmax(s2, AAF_MIN_SLOPE);
    float ratio = pixel_size / (light_radius * sqrt(PI_F));
    float a = 1.0f + s1 / s;
    float b = 2.0f / s * ratio + 1.0f / (1.0f + s);
    return 4.0f * a * a * b * b;
}

// AAF indirect light, diffuse and glossy (Wang 2013 §4.2; src/render/indirect/bandlimit.rs).

// Eq. 4.4: beta = max(2 z_min / Omega_h^max, footprints * d) (the seed's d / 0.15 is
// footprints = 1 / 0.15).
inline float aaf_indirect_beta(float z_min, float pixel_size, float bandlimit,
                               float footprints) {
    return fmax(2.0f * z_min / bandlimit, footprints * pixel_size);
}

// Eq. 4.5: Omega_h^max of a Phong lobe of exponent m (the glossy lobe of a metal receiver;
// the diffuse 2.8 is the host's IndirectSampling::bandlimit).
inline float aaf_glossy_bandlimit(float m) { return 3.6f + 0.084f * m; }

// z below this counts as this (a reflector touching the receiver): n stays finite or +inf.
#define AAF_MIN_Z 1.0e-30f

// Eq. 4.6: n = 0.4 (0.9 Omega sqrt(A_p) / z_min + 0.3)^2 Omega^2 (1 + 0.9 z_max / z_min)^2,
// A_p = d^2.
inline float aaf_indirect_count(float z_min, float z_max, float pixel_size, float bandlimit) {
    float z = fmax(z_min, AAF_MIN_Z);
    float a = 0.9f * bandlimit * pixel_size / z + 0.3f;
    float b = 1.0f + 0.9f * z_max / z;
    return 0.4f * a * a * bandlimit * bandlimit * b * b;
}

#endif
