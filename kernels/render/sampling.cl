// Direction and point sampling. Sine and cosine of one angle come from one sincos call
// (issue 14: one argument reduction instead of two); on the test device its bits are those of
// sin and cos for every angle rng_uniform can give (tests/determinism.rs, exhaustively).
#ifndef NOISEFREE_SAMPLING_CL
#define NOISEFREE_SAMPLING_CL

#define PI_F 3.14159265358979323846f
#define TWO_PI_F 6.28318530717958647692f
#define INV_PI_F 0.31830988618379067154f

// The tangent frame of Algorithm 5 lines 4-15: u from (0,1,0) x w, or (1,0,0) x w when w is
// close to the y axis.
inline void tangent_frame(float3 w, float3* u, float3* v) {
    float3 temp = (fabs(w.x) > 0.1f) ? (float3)(0.0f, 1.0f, 0.0f) : (float3)(1.0f, 0.0f, 0.0f);
    *u = normalize(cross(temp, w));
    *v = cross(w, *u);
}

// Algorithm 5: a cosine-weighted direction around `normal` (pdf cos(theta) / pi).
inline float3 sample_diffuse(float r1, float r2, float3 normal) {
    float azimuthal = TWO_PI_F * r1;
    float deflection = r2;
    float3 u, v;
    tangent_frame(normal, &u, &v);
    float s = sqrt(deflection);
    float c_az, s_az = sincos(azimuthal, &c_az);
    return normalize(u * (c_az * s) + v * (s_az * s)
                     + normal * sqrt(1.0f - deflection));
}

// A direction around `axis` with cos(theta) distributed as cos^n (normalised Phong lobe,
// pdf (n+1)/(2 pi) cos^n).
inline float3 sample_phong_lobe(float r1, float r2, float3 axis, float exponent) {
    float cos_t = pow(r2, 1.0f / (exponent + 1.0f));
    float sin_t = sqrt(fmax(0.0f, 1.0f - cos_t * cos_t));
    float phi = TWO_PI_F * r1;
    float3 u, v;
    tangent_frame(axis, &u, &v);
    float c_phi, s_phi = sincos(phi, &c_phi);
    return normalize(u * (c_phi * sin_t) + v * (s_phi * sin_t) + axis * cos_t);
}

// A point on the unit disk, polar mapping (Fig. 2.7b): r = sqrt(u1), phi = 2 pi u2.
inline float2 sample_disk(float r1, float r2) {
    float r = sqrt(r1);
    float c_phi, s_phi = sincos(TWO_PI_F * r2, &c_phi);
    return (float2)(r * c_phi, r * s_phi);
}

// A direction uniformly inside the cone around `axis` whose half-angle has
// 1 - cos = one_minus_cos_max. Written with 1 - cos(theta) instead of cos(theta) so that
// cones around tiny or distant lights (1 - cos ~ 1e-10) keep their precision.
inline float3 sample_cone(float r1, float r2, float3 axis, float one_minus_cos_max) {
    float one_minus_cos = r1 * one_minus_cos_max;
    float cos_t = 1.0f - one_minus_cos;
    float sin_t = sqrt(fmax(0.0f, one_minus_cos * (2.0f - one_minus_cos)));
    float phi = TWO_PI_F * r2;
    float3 u, v;
    tangent_frame(axis, &u, &v);
    float c_phi, s_phi = sincos(phi, &c_phi);
    return normalize(u * (c_phi * sin_t) + v * (s_phi * sin_t) + axis * cos_t);
}

// Barycentric coordinates of a uniformly distributed point on a triangle.
inline float2 sample_triangle(float r1, float r2) {
    float s = sqrt(r1);
    return (float2)(1.0f - s, r2 * s);
}

#endif
