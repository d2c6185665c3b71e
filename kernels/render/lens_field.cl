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
#ifndef NOISEFREE_LENS_FIELD_CL
#define NOISEFREE_LENS_FIELD_CL

#if OUTPUT_LIGHT_FIELD && !OUTPUT_SHADOWS

// The lens-field random numbers use sample numbers no path sample reaches (nor the shadow
// passes', from 0xFFFFFF00).
#define LENS_SAMPLE_BASE 0xFFFFFE00u
#define LENS_JITTER_SAMPLE (LENS_SAMPLE_BASE + 0xF0u)
#define LENS_EXTRA_SIDE 6u

// One lens sample: the ray from lens point (u1, u2) (right, down) through a random point of
// pixel (x, y) focused on the focal plane; its radiance and slope.
inline float3 lens_sample(const SceneRefs* s, uint x, uint y, uint key, float u1, float u2,
                          float slope_k, float* slope, uint* rays) {
    __constant const SceneParams* p = s->params;
    float jx = rng_uniform(key, 0u, DIM_PIXEL_X), jy = rng_uniform(key, 0u, DIM_PIXEL_Y);
    float3 forward = p->camera_forward.xyz;
    float3 dir = pinhole_direction(p, x, y, jx, jy);
    float3 o = p->camera_origin.xyz;
    float3 focus = o + dir * (p->focal_distance / dot(dir, forward));
    o = o + u1 * p->camera_right.xyz - u2 * p->camera_up.xyz;
    dir = normalize(focus - o);
    float none[SHADOW_PLANES];
    for (uint l = 0u; l < SHADOW_PLANES; ++l) none[l] = NAN;
    PathSample ps = trace_path_from(s, o, dir, key, rays, 0u, none);
    float z = ps.hit ? dot(ps.world1 - p->camera_origin.xyz, forward) : INFINITY;
    // s = k (1/z - 1/F), k = H / (2 tan(fov/2)); 1/inf = 0.
    *slope = slope_k * (1.0f / z - 1.0f / p->focal_distance);
    return ps.direct + ps.indirect;
}

// Gaussian aperture weight of lens point u (sigma = A/2): exp(-|u|^2 / (2 sigma^2)).
// A pinhole (A = 0) weighs every point 1.
inline float lens_weight(float u1, float u2, float radius) {
    if (!(radius > 0.0f)) return 1.0f;
    float sigma = 0.5f * radius;
    return exp(-(u1 * u1 + u2 * u2) / (2.0f * sigma * sigma));
}

__kernel void lens_field_sample(__constant const SceneParams* params,
                                __global const BvhNode* nodes,
                                __global const TriangleGeom* tri_geom,
                                __global const TriangleShading* tri_shading,
                                __global const Sphere* spheres,
                                __global const Material* materials,
                                __global const TextureInfo* textures,
                                __global const float4* texels, __global const Light* lights,
                                __global const float* light_cdf, __global uint* debug_counters,
                                __global float* light_field, __global uint* lens_rays,
                                uint side) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    __global float* lf = light_field + (size_t)pixel * LIGHT_FIELD_PIXEL_FLOATS;
    for (uint i = 0u; i < LIGHT_FIELD_PIXEL_FLOATS; ++i) lf[i] = 0.0f;
    lens_rays[pixel] = 0u;
    SceneRefs s = {params, nodes, tri_geom, tri_shading, spheres, materials,
                   textures, texels, lights, light_cdf, debug_counters};
    uint rays = 0u;
    float radius = params->lens_radius;
    float slope_k = (float)params->image_height / (2.0f * params->tan_half_fov);
    // The lens-centre hit through the pixel centre: position and normal (rejection).
    float3 co = params->camera_origin.xyz;
    float3 cd = pinhole_direction(params, x, y, 0.5f, 0.5f);
    Hit hit = intersect_closest(&s, co, cd, INFINITY, &rays);
    if (hit.kind != HIT_NONE) {
        Surface sf = surface_at(&s, &hit, co, cd);
        lf[LIGHT_FIELD_PIXEL_POSITION] = sf.p.x;
        lf[LIGHT_FIELD_PIXEL_POSITION + 1] = sf.p.y;
        lf[LIGHT_FIELD_PIXEL_POSITION + 2] = sf.p.z;
        lf[LIGHT_FIELD_PIXEL_NORMAL] = sf.ns.x;
        lf[LIGHT_FIELD_PIXEL_NORMAL + 1] = sf.ns.y;
        lf[LIGHT_FIELD_PIXEL_NORMAL + 2] = sf.ns.z;
    }
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
            float3 l = lens_sample(&s, x, y, key, u1, u2, slope_k, &sl, &rays);
            s_min = fmin(s_min, sl);
            s_max = fmax(s_max, sl);
            lf[LIGHT_FIELD_PIXEL_SAMPLES + k] = l.x;
            lf[LIGHT_FIELD_PIXEL_GREEN + k] = l.y;
            lf[LIGHT_FIELD_PIXEL_BLUE + k] = l.z;
        }
    }
    lf[LIGHT_FIELD_PIXEL_SLOPES] = s_min;
    lf[LIGHT_FIELD_PIXEL_SLOPES + 1] = s_max;
    if (s_min * s_max < 0.0f) {
        // Both sides of the focal plane: 36 more samples for the axis-aligned fallback.
        float3 sum = (float3)(0.0f);
        float wsum = 0.0f;
        float inv6 = 1.0f / (float)LENS_EXTRA_SIDE;
        for (uint k = 0u; k < LENS_EXTRA_SIDE * LENS_EXTRA_SIDE; ++k) {
            uint key = rng_sample_key(params->seed, pixel, LENS_SAMPLE_BASE + 16u + k);
            float a = (float)(k % LENS_EXTRA_SIDE), b = (float)(k / LENS_EXTRA_SIDE);
            float u1 = radius * (2.0f * (a + rng_uniform(key, 0u, DIM_LENS_U)) * inv6 - 1.0f);
            float u2 = radius * (2.0f * (b + rng_uniform(key, 0u, DIM_LENS_V)) * inv6 - 1.0f);
            float sl;
            float3 l = lens_sample(&s, x, y, key, u1, u2, slope_k, &sl, &rays);
            float w = lens_weight(u1, u2, radius);
            sum += w * l;
            wsum += w;
        }
        lf[LIGHT_FIELD_PIXEL_EXTRA_SAMPLES] = (float)(LENS_EXTRA_SIDE * LENS_EXTRA_SIDE);
        lf[LIGHT_FIELD_PIXEL_EXTRA] = sum.x;
        lf[LIGHT_FIELD_PIXEL_EXTRA + 1] = sum.y;
        lf[LIGHT_FIELD_PIXEL_EXTRA + 2] = sum.z;
        lf[LIGHT_FIELD_PIXEL_EXTRA + 3] = wsum;
    }
    lf[LIGHT_FIELD_PIXEL_JITTER] = j1;
    lf[LIGHT_FIELD_PIXEL_JITTER + 1] = j2;
    // x is the image row and column, in pixels.
    lf[LIGHT_FIELD_PIXEL_DIR1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_DIR2 + 1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_SCALE] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_SCALE + 1] = 1.0f;
    lf[LIGHT_FIELD_PIXEL_COUNT] = (float)(side * side);
    lens_rays[pixel] = rays;
}

#endif

#endif
