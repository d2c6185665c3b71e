// Sheared filtering of depth of field (Yan et al. 2015, "Fast 4D Sheared Filtering", §3.1 and
// §3.2 "DoF"; digest /work/shared/notes/seeds-aaf-sheared.md §3.4 "Thin lens"): the
// non-adaptive pass that keeps each pixel's 4-D light field over the lens. Included by
// kernels/render/pathtrace.cl after trace_path (the integrand is the radiance of a whole path
// through each lens point). src/render/cpu/lens_field.rs is the same code in Rust.
//
// - Aperture: the square [-A, A]^2 (A = lens_radius) on the camera's (right, down) axes,
//   sampled on an l x l grid shifted by the pixel's jitter j in [0,1)^2 (one per pixel, §3.1):
//   u = A (2 (a + j) / l - 1). The filter weights the points by a Gaussian of sigma = A/2 (the
//   disk's per-axis standard deviation; the seed's Gaussian aperture, digest §3.4 FAITHFUL):
//   the thesis's disk indicator is not separable in (u1, u2), which steps 1a-2b need.
// - Each sample: a random point of the pixel (the path tracer's box filter), the ray from the
//   lens point through that point's image on the focal plane, its radiance (direct +
//   indirect), and the slope s = W (F/z - 1) / S = H (1/z - 1/F) / (2 tan(fov/2)) of its first
//   hit at depth z along the view axis (pixels per metre of lens; z = inf for the sky). A point
//   at depth z seen through lens point u lands at pixel x_P - s u: f(x, u) = g(x + s u), the
//   shadow case's form with the image row/column as x.
// - s_min, s_max over the l^2 samples. Where s_min s_max < 0 (samples on both sides of the focal
//   plane) the pixel gets 36 more samples (a jittered 6 x 6 grid over the same square,
//   §3.1 "a fixed 36 more samples"), kept as their Gaussian-weighted sum and weight.
// - The lens-centre ray through the pixel centre gives the position and normal for rejection.
//
// Soft shadows as well (the seed's appendix, eqs. 16-17; OUTPUT_LENS_SHADOWS, after the shadow
// passes, `lens_shadow_field_sample`): each lens sample's path is traced as the path samples
// are, against the shadow planes' receivers (the pixel centre's, the lens-centre ray's), so
// that a sample whose first hit is a diffuse point of the receiver's object keeps the filtered
// lights' direct term apart (PathSample.shadow_direct). The lens field keeps the light less
// that term; LensShadowPixel keeps the sample's albedo k(x, u) (eq. 16) and, per light, the
// mean over those samples of the unoccluded term, eq. 17's F-bar without its visibility (the
// average over the pixel's lens samples the appendix asks for). The filter puts
// k(x, u) F-bar v(x) back, v the sheared-filtered visibility of the pixel centre's receiver
// (kernels/filters/sheared_lens_shadows.cl), and filters the result over the lens.
#ifndef NOISEFREE_LENS_FIELD_CL
#define NOISEFREE_LENS_FIELD_CL

#if OUTPUT_LIGHT_FIELD && (!OUTPUT_SHADOWS || OUTPUT_LENS_SHADOWS)

// The lens-field random numbers use sample numbers no path sample reaches (nor the shadow
// passes', from 0xFFFFFF00).
#define LENS_SAMPLE_BASE 0xFFFFFE00u
#define LENS_JITTER_SAMPLE (LENS_SAMPLE_BASE + 0xF0u)
#define LENS_EXTRA_SIDE 6u

// One lens sample: the path from lens point (u1, u2) (right, down) through a random point of
// pixel (x, y) focused on the focal plane, and its slope. `shadow_lights` and `shadow_objects`
// as trace_path_from takes them (none: 0 and NaN).
inline PathSample lens_sample(const SceneRefs* s, uint x, uint y, uint key, float u1, float u2,
                              float slope_k, float* slope, uint* rays, uint shadow_lights,
                              const float* shadow_objects) {
    __constant const SceneParams* p = s->params;
    float jx = rng_uniform(key, 0u, DIM_PIXEL_X), jy = rng_uniform(key, 0u, DIM_PIXEL_Y);
    float3 forward = p->camera_forward.xyz;
    float3 dir = pinhole_direction(p, x, y, jx, jy);
    float3 o = p->camera_origin.xyz;
    float3 focus = o + dir * (p->focal_distance / dot(dir, forward));
    o = o + u1 * p->camera_right.xyz - u2 * p->camera_up.xyz;
    dir = normalize(focus - o);
    PathSample ps = trace_path_from(s, o, dir, key, rays, shadow_lights, shadow_objects);
    float z = ps.hit ? dot(ps.world1 - p->camera_origin.xyz, forward) : INFINITY;
    // s = k (1/z - 1/F), k = H / (2 tan(fov/2)); 1/inf = 0.
    *slope = slope_k * (1.0f / z - 1.0f / p->focal_distance);
    return ps;
}

// The light a lens sample puts in the lens field: all of it, or with the shadows filtered as
// well, all but the filtered lights' direct term on the receiver.
inline float3 lens_radiance(const PathSample* ps) {
    float3 l = ps->direct + ps->indirect;
#if OUTPUT_LENS_SHADOWS
    for (uint q = 0u; q < SHADOW_PLANES; ++q) l -= ps->shadow_direct[q];
#endif
    return l;
}

// Gaussian aperture weight of lens point u (sigma = A/2): exp(-|u|^2 / (2 sigma^2)).
// A pinhole (A = 0) weighs every point 1.
inline float lens_weight(float u1, float u2, float radius) {
    if (!(radius > 0.0f)) return 1.0f;
    float sigma = 0.5f * radius;
    return exp(-(u1 * u1 + u2 * u2) / (2.0f * sigma * sigma));
}

// The lens field of pixel (x, y) into lf (and, with the shadows filtered as well, ls: the
// LensShadowPixel; `shadow_lights` the filtered lights, a plane each, `shadow_objects` their
// receivers' objects, NaN for none). Returns the rays traced.
inline uint lens_field_pixel(const SceneRefs* s, uint x, uint y, uint side,
                             __global float* lf, __global float* ls, uint shadow_lights,
                             const float* shadow_objects) {
    __constant const SceneParams* params = s->params;
    uint pixel = y * params->image_width + x;
    for (uint i = 0u; i < LIGHT_FIELD_PIXEL_FLOATS; ++i) lf[i] = 0.0f;
    uint rays = 0u;
    float radius = params->lens_radius;
    float slope_k = (float)params->image_height / (2.0f * params->tan_half_fov);
    // The lens-centre hit through the pixel centre: position and normal (rejection).
    float3 co = params->camera_origin.xyz;
    float3 cd = pinhole_direction(params, x, y, 0.5f, 0.5f);
    Hit hit = intersect_closest(s, co, cd, INFINITY, &rays);
    if (hit.kind != HIT_NONE) {
        Surface sf = surface_at(s, &hit, co, cd);
        lf[LIGHT_FIELD_PIXEL_POSITION] = sf.p.x;
        lf[LIGHT_FIELD_PIXEL_POSITION + 1] = sf.p.y;
        lf[LIGHT_FIELD_PIXEL_POSITION + 2] = sf.p.z;
        lf[LIGHT_FIELD_PIXEL_NORMAL] = sf.ns.x;
        lf[LIGHT_FIELD_PIXEL_NORMAL + 1] = sf.ns.y;
        lf[LIGHT_FIELD_PIXEL_NORMAL + 2] = sf.ns.z;
    }
#if OUTPUT_LENS_SHADOWS
    for (uint i = 0u; i < LENS_SHADOW_PIXEL_FLOATS; ++i) ls[i] = 0.0f;
    // Per plane: the sum of the unoccluded term over the samples on the receiver, and their count.
    float3 unshadowed[SHADOW_PLANES];
    float on[SHADOW_PLANES];
    for (uint q = 0u; q < SHADOW_PLANES; ++q) {
        unshadowed[q] = (float3)(0.0f);
        on[q] = 0.0f;
    }
#endif
    uint jkey = rng_sample_key(params->seed, pixel, LENS_JITTER_SAMPLE);
    float j1 = rng_uniform(jkey, 0u, DIM_LENS_U), j2 = rng_uniform(jkey, 0u, DIM_LENS_V);
    float inv = 1.0f / (float)side;
    float s_min = INFINITY, s_max = -INFINITY;
    for (uint b = 0u; b < side; ++b) {
        for (uint a = 0u; a < side; ++a) {
            uint k = b * side + a;
            float u1 = radius * (2.0f * ((float)a + j1) * inv - 1.0f);
            float u2 = radius * (2.0f * ((float)b + j2) * inv - 1.0f);
            uint key = rng_sample_key(params->seed, pixel, LENS_SAMPLE_BASE + k);
            float sl;
            PathSample ps = lens_sample(s, x, y, key, u1, u2, slope_k, &sl, &rays,
                                        shadow_lights, shadow_objects);
            float3 l = lens_radiance(&ps);
            s_min = fmin(s_min, sl);
            s_max = fmax(s_max, sl);
            lf[LIGHT_FIELD_PIXEL_SAMPLES + k] = l.x;
            lf[LIGHT_FIELD_PIXEL_GREEN + k] = l.y;
            lf[LIGHT_FIELD_PIXEL_BLUE + k] = l.z;
#if OUTPUT_LENS_SHADOWS
            ls[LENS_SHADOW_PIXEL_ALBEDO + k] = ps.receiver_albedo.x;
            ls[LENS_SHADOW_PIXEL_ALBEDO_GREEN + k] = ps.receiver_albedo.y;
            ls[LENS_SHADOW_PIXEL_ALBEDO_BLUE + k] = ps.receiver_albedo.z;
            for (uint q = 0u; q < SHADOW_PLANES; ++q) {
                if (((ps.receiver >> q) & 1u) == 0u) continue;
                unshadowed[q] += ps.receiver_unshadowed[q];
                on[q] += 1.0f;
            }
#endif
        }
    }
    lf[LIGHT_FIELD_PIXEL_SLOPES] = s_min;
    lf[LIGHT_FIELD_PIXEL_SLOPES + 1] = s_max;
    if (s_min * s_max < 0.0f) {
        // Both sides of the focal plane: 36 more samples for the axis-aligned fallback.
        float3 sum = (float3)(0.0f);
        float wsum = 0.0f;
#if OUTPUT_LENS_SHADOWS
        float3 albedo_sum = (float3)(0.0f);
#endif
        float inv6 = 1.0f / (float)LENS_EXTRA_SIDE;
        for (uint k = 0u; k < LENS_EXTRA_SIDE * LENS_EXTRA_SIDE; ++k) {
            uint key = rng_sample_key(params->seed, pixel, LENS_SAMPLE_BASE + 16u + k);
            float a = (float)(k % LENS_EXTRA_SIDE), b = (float)(k / LENS_EXTRA_SIDE);
            float u1 = radius * (2.0f * (a + rng_uniform(key, 0u, DIM_LENS_U)) * inv6 - 1.0f);
            float u2 = radius * (2.0f * (b + rng_uniform(key, 0u, DIM_LENS_V)) * inv6 - 1.0f);
            float sl;
            PathSample ps = lens_sample(s, x, y, key, u1, u2, slope_k, &sl, &rays,
                                        shadow_lights, shadow_objects);
            float3 l = lens_radiance(&ps);
            float w = lens_weight(u1, u2, radius);
            sum += w * l;
            wsum += w;
#if OUTPUT_LENS_SHADOWS
            albedo_sum += w * ps.receiver_albedo;
#endif
        }
        lf[LIGHT_FIELD_PIXEL_EXTRA_SAMPLES] = (float)(LENS_EXTRA_SIDE * LENS_EXTRA_SIDE);
        lf[LIGHT_FIELD_PIXEL_EXTRA] = sum.x;
        lf[LIGHT_FIELD_PIXEL_EXTRA + 1] = sum.y;
        lf[LIGHT_FIELD_PIXEL_EXTRA + 2] = sum.z;
        lf[LIGHT_FIELD_PIXEL_EXTRA + 3] = wsum;
#if OUTPUT_LENS_SHADOWS
        ls[LENS_SHADOW_PIXEL_ALBEDO_EXTRA] = albedo_sum.x;
        ls[LENS_SHADOW_PIXEL_ALBEDO_EXTRA + 1] = albedo_sum.y;
        ls[LENS_SHADOW_PIXEL_ALBEDO_EXTRA + 2] = albedo_sum.z;
#endif
    }
#if OUTPUT_LENS_SHADOWS
    for (uint q = 0u; q < SHADOW_PLANES; ++q) {
        float3 mean = on[q] > 0.0f ? unshadowed[q] / on[q] : (float3)(0.0f);
        __global float* u = ls + LENS_SHADOW_PIXEL_UNSHADOWED + 4u * q;
        u[0] = mean.x;
        u[1] = mean.y;
        u[2] = mean.z;
        u[3] = on[q];
    }
#endif
    lf[LIGHT_FIELD_PIXEL_JITTER] = j1;
    lf[LIGHT_FIELD_PIXEL_JITTER + 1] = j2;
    // x is the image row and column, in pixels.
    lf[LIGHT_FIELD_PIXEL_DIR1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_DIR2 + 1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_SCALE] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_SCALE + 1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_COUNT] = (float)(side * side);
    return rays;
}

#if !OUTPUT_SHADOWS
__kernel void lens_field_sample(SCENE_PARAMS, __global float* light_field,
                                __global uint* lens_rays, uint side) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    SceneRefs s = SCENE_REFS;
    float none[SHADOW_PLANES];
    for (uint l = 0u; l < SHADOW_PLANES; ++l) none[l] = NAN;
    lens_rays[pixel] = lens_field_pixel(&s, x, y, side,
                                        light_field + (size_t)pixel * LIGHT_FIELD_PIXEL_FLOATS,
                                        0, 0u, none);
}
#endif

#if OUTPUT_LENS_SHADOWS
// After the shadow passes: the receivers of the shadow planes (`shadow_lights`, a plane per
// set bit in increasing light order) as the render kernel reads them.
__kernel void lens_shadow_field_sample(SCENE_PARAMS, __global const float* shadow_pixels,
                                       uint shadow_lights, __global float* lens_field,
                                       __global float* lens_shadow, __global uint* lens_rays,
                                       uint side) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    SceneRefs s = SCENE_REFS;
    float objects[SHADOW_PLANES];
    shadow_receiver_objects(shadow_pixels, pixel, objects);
    lens_rays[pixel] = lens_field_pixel(&s, x, y, side,
                                        lens_field + (size_t)pixel * LIGHT_FIELD_PIXEL_FLOATS,
                                        lens_shadow + (size_t)pixel * LENS_SHADOW_PIXEL_FLOATS,
                                        shadow_lights, objects);
}
#endif

#endif

#endif
