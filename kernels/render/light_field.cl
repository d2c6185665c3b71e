// Sheared filtering of soft shadows (Yan et al. 2015, "Fast 4D Sheared Filtering", §3.1 and
// §5 "Sampling"): the non-adaptive pass that keeps the 4-D light field of each pixel. Included
// by kernels/render/shadows.cl inside its OUTPUT_SHADOWS && HAS_SPHERE_LIGHTS guard, after the
// AAF sparse pass (which gives the receiver, d1, r(x) and the first slopes) and before the
// slope fill (which then also fills from the slopes found here); once per light plane.
//
// - Grid: l x l points on the square [-R, R]^2 of the light's plane, in ONE global frame per
//   light (e1, e2) perpendicular to (scene centre -> light centre), shifted by the pixel's jitter
//   j in [0,1)^2 (one jitter per pixel, §3.1): y = R (2 (a + j) / l - 1). Steps 1b and 2b need
//   one (y1, y2) frame shared by neighbours (digest §3.4): a per-receiver frame (the disk
//   perpendicular to the receiver-to-centre direction, as AAF uses) would break the shear.
// - Every grid point is traced, also those outside the sphere's disk: f is the visibility of
//   that point of the light's plane, which a neighbour needs after the shear moves it onto its
//   light (Yan et al. sample the square of their Gaussian light the same way). Whether a point
//   is part of the light is the filter's business (the Gaussian w_y of sigma_y = R/2).
// - Slopes s = d1/d2 - 1 of the occluded grid samples are merged into the shadow pixel's
//   s1 = max, s2 = min (§3.1: "s_min and s_max from the same samples").
// - The light's axes on the screen (Fig. 5a): t1 = ng x e2 is the direction on the receiver's
//   plane along which x2 = p.e2 stays and x1 = p.e1 grows; its image on the screen (a finite
//   difference over one pixel footprint) is dir1, and scale1 the world x1 per pixel along it.
// src/render/shadows/light_field.rs builds the frame; the filter is kernels/filters/sheared.cl.
#ifndef NOISEFREE_LIGHT_FIELD_CL
#define NOISEFREE_LIGHT_FIELD_CL

#if OUTPUT_LIGHT_FIELD

// The image position (pixels, from the top-left corner) of world point q; the inverse of
// pinhole_direction (kernels/render/camera.cl). Returns false behind the camera.
inline bool light_field_project(__constant const SceneParams* p, float3 q, float2* out) {
    float3 v = q - p->camera_origin.xyz;
    float z = dot(v, p->camera_forward.xyz);
    if (!(z > 0.0f)) return false;
    float w = (float)p->image_width, h = (float)p->image_height;
    float sx = dot(v, p->camera_right.xyz) / z / (p->tan_half_fov * (w / h));
    float sy = dot(v, p->camera_up.xyz) / z / p->tan_half_fov;
    *out = (float2)((sx + 1.0f) * 0.5f * w, (1.0f - sy) * 0.5f * h);
    return true;
}

// The screen direction (unit, pixels) in which a step `t` (unit, on the receiver's plane, with
// dx = t.e world units per unit step) moves the image of p, and the world units of x per pixel
// along it. 0 scale where the receiver is seen edge-on or t leaves x unchanged.
inline void light_field_axis(__constant const SceneParams* p, float3 pos, float3 t, float dx,
                             float footprint, float2* dir, float* scale) {
    float2 a, b;
    *dir = (float2)(1.0f, 0.0f);
    *scale = 0.0f;
    if (!light_field_project(p, pos, &a) || !light_field_project(p, pos + footprint * t, &b))
        return;
    float2 v = b - a;
    float len = length(v);
    if (!(len > 1.0e-4f) || !(dx > 1.0e-6f)) return;
    *dir = v / len;
    *scale = footprint * dx / len;
}

// Element `plane` of pixel `pixel` in the light field's planes (pixel-major, as the shadow
// output's: src/layout/outputs.rs Per::Light).
#define LIGHT_FIELD_AT(buffer, pixel, plane, planes) \
    ((buffer) + ((size_t)(pixel) * (planes) + (plane)) * LIGHT_FIELD_PIXEL_FLOATS)

// Light `light` on plane `plane` of `planes` (every sphere light the sheared filter filters has
// its plane, Yan et al. §3: "filter each light separately"), in that light's frame (e1, e2):
// its light field, and its slopes merged into the same plane of the shadow output. The
// samples' random numbers depend on the pixel alone, so a plane holds the bytes of a render
// of its light alone.
__kernel void light_field_sample(SCENE_PARAMS, __global float* shadow_pixels,
                                 uint plane, uint planes, __global float* light_field,
                                 __global uint* shadow_rays, uint light, uint side,
                                 float4 frame_u, float4 frame_v) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= params->image_width || y >= params->image_height) return;
    uint pixel = y * params->image_width + x;
    __global float* lf = LIGHT_FIELD_AT(light_field, pixel, plane, planes);
    for (uint i = 0u; i < LIGHT_FIELD_PIXEL_FLOATS; ++i) lf[i] = 0.0f;
    __global float* px = SHADOW_AT(shadow_pixels, pixel, plane, planes);
    shadow_rays[pixel] = 0u;
    if (!(px[SHADOW_PIXEL_WEIGHT] > 0.0f) || light >= params->light_count) return;
    SceneRefs s = SCENE_REFS;
    uint rays = 0u;
    ShadowReceiver r;
    // The sparse pass's receiver, again (its geometric normal is not kept).
    if (!shadow_receiver(&s, x, y, 0.5f, 0.5f, &r, &rays)) return;
    __global const Light* l = lights + light;
    float3 c = l->p0.xyz;
    float radius = l->p0.w;
    float3 e1 = frame_u.xyz, e2 = frame_v.xyz;
    float3 o = offset_ray_origin(r.p, r.ng, params->scene_size);
    float dc = length(c - o);
    uint key = rng_sample_key(params->seed, pixel, SHADOW_SAMPLE_BASE + 2u);
    float j1 = rng_uniform(key, 0u, DIM_LIGHT_U), j2 = rng_uniform(key, 0u, DIM_LIGHT_V);
    float inv = 1.0f / (float)side;
    float occluded = 0.0f, s1 = 0.0f, s2 = INFINITY;
    for (uint b = 0u; b < side; ++b) {
        for (uint a = 0u; a < side; ++a) {
            float y1 = radius * (2.0f * ((float)a + j1) * inv - 1.0f);
            float y2 = radius * (2.0f * ((float)b + j2) * inv - 1.0f);
            float3 to = c + y1 * e1 + y2 * e2 - o;
            float dist = length(to);
            float f = 0.0f;
            if (dist > 0.0f && dc > radius) {
                float3 dir = to / dist;
                // Into the sphere: the ray ends on its surface (the light's own crossing is
                // no occluder).
                float t = ray_sphere(o, dir, c, radius, 0.0f, INFINITY);
                if (t > 0.0f) dist = fmin(dist, t);
                float t_near, t_far;
                if (dot(r.ng, dir) <= 0.0f) {
                    f = 0.0f;                        // below the receiver's own horizon
                } else if (occluder_range(&s, o, dir, dist * SHADOW_RAY_SHORTEN, &t_near,
                                          &t_far, &rays)) {
                    // d2 = d1 - t as in shadow_sample (AAF): s = d1/d2 - 1.
                    occluded += 1.0f;
                    s2 = fmin(s2, dc / (dc - t_near) - 1.0f);
                    s1 = fmax(s1, dc / (dc - t_far) - 1.0f);
                } else {
                    f = 1.0f;
                }
            }
            lf[LIGHT_FIELD_PIXEL_SAMPLES + b * side + a] = f;
        }
    }
    if (occluded > 0.0f) {
        bool own = px[SHADOW_PIXEL_SLOPE_SOURCE] == 1.0f;
        px[SHADOW_PIXEL_SLOPE_MAX] = own ? fmax(px[SHADOW_PIXEL_SLOPE_MAX], s1) : s1;
        px[SHADOW_PIXEL_SLOPE_MIN] = own ? fmin(px[SHADOW_PIXEL_SLOPE_MIN], s2) : s2;
        px[SHADOW_PIXEL_SLOPE_SOURCE] = 1.0f;
        px[SHADOW_PIXEL_OCCLUDED] += occluded;
    }
    lf[LIGHT_FIELD_PIXEL_JITTER] = j1;
    lf[LIGHT_FIELD_PIXEL_JITTER + 1] = j2;
    // Axis 1: along the receiver with x2 fixed (t1 perpendicular to ng and to e2); axis 2 the
    // same with x1 fixed. Signs so that x grows along t.
    float footprint = px[SHADOW_PIXEL_PIXEL_SIZE];
    float3 t1 = cross(r.ng, e2), t2 = cross(r.ng, e1);
    float n1 = length(t1), n2 = length(t2);
    float2 d1 = (float2)(1.0f, 0.0f), d2 = (float2)(0.0f, 1.0f);
    float k1 = 0.0f, k2 = 0.0f;
    if (n1 > 1.0e-6f) {
        t1 = t1 / n1;
        if (dot(t1, e1) < 0.0f) t1 = -t1;
        light_field_axis(params, r.p, t1, dot(t1, e1), footprint, &d1, &k1);
    }
    if (n2 > 1.0e-6f) {
        t2 = t2 / n2;
        if (dot(t2, e2) < 0.0f) t2 = -t2;
        light_field_axis(params, r.p, t2, dot(t2, e2), footprint, &d2, &k2);
    }
    lf[LIGHT_FIELD_PIXEL_DIR1] = d1.x;
    lf[LIGHT_FIELD_PIXEL_DIR1 + 1] = d1.y;
    lf[LIGHT_FIELD_PIXEL_DIR2] = d2.x;
    lf[LIGHT_FIELD_PIXEL_DIR2 + 1] = d2.y;
    lf[LIGHT_FIELD_PIXEL_SCALE] = k1;
    lf[LIGHT_FIELD_PIXEL_SCALE + 1] = k2;
    lf[LIGHT_FIELD_PIXEL_COUNT] = (float)(side * side);
    shadow_rays[pixel] = rays;
}

#endif

#endif
