// Sheared filtering of diffuse indirect light (Yan et al. 2015, "Fast 4D Sheared Filtering",
// §3.1 "Diffuse Indirect Illumination", eq. 2, §5 "Sampling/Filtering for Indirect
// Illumination"; digest /work/shared/notes/seeds-aaf-sheared.md §3): the non-adaptive pass that
// keeps each pixel's 4-D indirect light field over the v-plane, in the light-field output's
// lanes (src/layout LightFieldPixel; src/render/lens_field.rs says which lane holds what).
// Included by kernels/render/pathtrace.cl after lens_field.cl; it reuses indirect_radiance of
// kernels/render/indirect.cl (one indirect sample: what the path tracer counts as indirect).
// src/render/gi_field.rs is the v-plane sampler in Rust and says why.
//
// - The receiver: the pixel centre's first hit (a diffuse surface, as the AAF indirect pass).
//   Each sample starts at its own random point of the pixel when that point lies on the same
//   object (else at the centre's), and the albedo lane is the mean of those points' albedos
//   (texture detail is multiplied back, as AAF's `indirect` output does).
// - v-plane (eq. 2): direction of v = (v1, v2) is normalize(v1 t + v2 b + n), t, b the tangent
//   frame of n (kernels/render/sampling.cl, the same frame for equal normals: "locally aligned").
//   cos(theta) d(omega) = gamma(v) dv, gamma = 1 / (1 + |v|^2)^2.
// - Importance sampling on the truncated square [-V, V]^2 (V = 5, §5): per axis the pdf
//   p(v) = (1 + v^2)^(-3/2) / (2c), c = V / sqrt(1 + V^2) (the marginal of gamma), inverted
//   exactly: v = t / sqrt(1 - t^2), t = c (2u - 1), with u = (a + j) / l on the jittered grid.
//   Weight gamma / (pi K p(v1) p(v2)) = c / atan(c) * ((1+v1^2)(1+v2^2))^(3/2) / (1+|v|^2)^2:
//   K = 4 c atan(c) / pi = 0.9683 is the part of the cosine-weighted hemisphere the square
//   keeps; dividing by it renormalises the truncation (exact for radiance uniform beyond it).
// - Each lane: weight x the demodulated indirect radiance L_i (E[lane] = irradiance / pi, the
//   AAF indirect output's L), 0 below the geometric surface. s = z, the first bounce's hit
//   distance: s_min, s_max over the samples that hit something.
#ifndef NOISEFREE_GI_FIELD_CL
#define NOISEFREE_GI_FIELD_CL

#if OUTPUT_LIGHT_FIELD && !OUTPUT_SHADOWS

// Sample numbers no path sample, shadow pass (0xFFFFFF00) or lens pass (0xFFFFFE00) reaches.
#define GI_SAMPLE_BASE 0xFFFFFD00u
#define GI_JITTER_SAMPLE (GI_SAMPLE_BASE + 0xF0u)

// Half side V of the truncated v-square (Yan et al. §5: [-5, 5]^2).
#define GI_V_MAX 5.0f

// c = V / sqrt(1 + V^2): the per-axis CDF's half range.
inline float gi_c(void) { return GI_V_MAX / sqrt(1.0f + GI_V_MAX * GI_V_MAX); }

// Grid coordinate u in [0, 1) -> v on [-V, V] (inverse CDF of (1 + v^2)^(-3/2)).
inline float gi_v(float u) {
    float t = gi_c() * (2.0f * u - 1.0f);
    return t / sqrt(1.0f - t * t);
}

// gamma(v) / (pi K p(v1) p(v2)) (renormalised by the kept fraction K).
inline float gi_weight(float v1, float v2) {
    float a = 1.0f + v1 * v1, b = 1.0f + v2 * v2, r = 1.0f + v1 * v1 + v2 * v2;
    float ab = a * b;
    return gi_c() / atan(gi_c()) * (ab * sqrt(ab)) / (r * r);
}

// The lens pass's arguments (src/render/lens_field.rs binds them by name).
__kernel void gi_field_sample(SCENE_PARAMS, __global float* light_field,
                              __global uint* lens_rays, uint side) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    __global float* lf = light_field + (size_t)pixel * LIGHT_FIELD_PIXEL_FLOATS;
    for (uint i = 0u; i < LIGHT_FIELD_PIXEL_FLOATS; ++i) lf[i] = 0.0f;
    lens_rays[pixel] = 0u;
    SceneRefs s = SCENE_REFS;
    uint rays = 0u;
    uint jkey = rng_sample_key(params->seed, pixel, GI_JITTER_SAMPLE);
    float j1 = rng_uniform(jkey, 0u, DIM_LENS_U), j2 = rng_uniform(jkey, 0u, DIM_LENS_V);
    lf[LIGHT_FIELD_PIXEL_JITTER] = j1;
    lf[LIGHT_FIELD_PIXEL_JITTER + 1] = j2;
    ShadowReceiver r;
    if (!shadow_receiver(&s, x, y, 0.5f, 0.5f, &r, &rays)) {
        lens_rays[pixel] = rays;
        return;
    }
    float3 albedo = (float3)(0.0f);
    float inv = 1.0f / (float)side;
    float z_min = INFINITY, z_max = 0.0f, reflectors = 0.0f;
    for (uint b = 0u; b < side; ++b) {
        for (uint a = 0u; a < side; ++a) {
            uint k = b * side + a;
            uint key = rng_sample_key(params->seed, pixel, GI_SAMPLE_BASE + k);
            ShadowReceiver q;
            float jx = rng_uniform(key, 0u, DIM_PIXEL_X), jy = rng_uniform(key, 0u, DIM_PIXEL_Y);
            if (!shadow_receiver(&s, x, y, jx, jy, &q, &rays) || q.object != r.object) q = r;
            albedo += q.albedo;
            float v1 = gi_v(((float)a + j1) * inv), v2 = gi_v(((float)b + j2) * inv);
            float3 t, bt;
            tangent_frame(q.ns, &t, &bt);
            float3 d = normalize(v1 * t + v2 * bt + q.ns);
            if (dot(d, q.ng) <= 0.0f) continue;   // below the geometric surface: absorbed
            float3 o = offset_ray_origin(q.p, q.ng, params->scene_size);
            float z;
            float3 l = gi_weight(v1, v2) * indirect_radiance(&s, o, d, key, &z, &rays);
            lf[LIGHT_FIELD_PIXEL_SAMPLES + k] = l.x;
            lf[LIGHT_FIELD_PIXEL_GREEN + k] = l.y;
            lf[LIGHT_FIELD_PIXEL_BLUE + k] = l.z;
            if (z < INFINITY) {
                z_min = fmin(z_min, z);
                z_max = fmax(z_max, z);
                reflectors += 1.0f;
            }
        }
    }
    bool hit = reflectors > 0.0f;
    lf[LIGHT_FIELD_PIXEL_SLOPES] = hit ? z_min : 0.0f;
    lf[LIGHT_FIELD_PIXEL_SLOPES + 1] = hit ? z_max : 0.0f;
    // The lane is depth of field's fallback count (lens_field.cl); GI takes no extra samples,
    // and "a sample met a reflector" is z_max > 0 (hit distances are positive).
    lf[LIGHT_FIELD_PIXEL_EXTRA_SAMPLES] = 0.0f;
    vstore3(albedo * inv * inv, 0, lf + LIGHT_FIELD_PIXEL_EXTRA);
    vstore3(r.p, 0, lf + LIGHT_FIELD_PIXEL_POSITION);
    vstore3(r.ns, 0, lf + LIGHT_FIELD_PIXEL_NORMAL);
    // 1b walks the image row, 2b the column; scale: the world size of a pixel at the receiver.
    float d_px = r.t * 2.0f * params->tan_half_fov / (float)params->image_height;
    lf[LIGHT_FIELD_PIXEL_DIR1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_DIR2 + 1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_SCALE] = d_px;
    lf[LIGHT_FIELD_PIXEL_SCALE + 1] = d_px;
    lf[LIGHT_FIELD_PIXEL_COUNT] = (float)(side * side);
    lens_rays[pixel] = rays;
}

#endif

#endif
