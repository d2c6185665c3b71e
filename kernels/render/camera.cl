// Camera rays (thesis §4.3.1, Figs. 2.7 and 4.8): a random point inside the pixel, and with a
// thin lens a random point on the lens aimed at the same point of the focal plane.
#ifndef NOISEFREE_CAMERA_CL
#define NOISEFREE_CAMERA_CL

#include "arrays/trace.cl"
#include "render/sampling.cl"
#include "render/rng.cl"

// The unit direction from the lens centre through the point (x + jx, y + jy) of the image;
// pixel (x, y) counts from the top-left corner.
inline float3 pinhole_direction(__constant const SceneParams* p, uint x, uint y, float jx,
                                float jy) {
    float w = (float)p->image_width, h = (float)p->image_height;
    float sx = (2.0f * ((float)x + jx) / w - 1.0f) * p->tan_half_fov * (w / h);
    float sy = (1.0f - 2.0f * ((float)y + jy) / h) * p->tan_half_fov;
    float3 forward = p->camera_forward.xyz;
    return normalize(forward + sx * p->camera_right.xyz + sy * p->camera_up.xyz);
}

// (jx, jy) in [0,1)^2 is the point in the pixel.
inline void camera_ray(const SceneRefs* s, uint x, uint y, uint key,
                       float3* origin, float3* direction) {
    __constant const SceneParams* p = s->params;
    float jx = rng_uniform(key, 0u, DIM_PIXEL_X);
    float jy = rng_uniform(key, 0u, DIM_PIXEL_Y);
    float3 forward = p->camera_forward.xyz;
    float3 dir = pinhole_direction(p, x, y, jx, jy);
    float3 o = p->camera_origin.xyz;
#if HAS_DOF
    if (p->lens_radius > 0.0f) {
        DEBUG_COUNT(s, COUNT_LENS_SAMPLE);
        // Everything at focal_distance (measured along the view axis) stays sharp.
        float3 focus = o + dir * (p->focal_distance / dot(dir, forward));
        float2 lens = p->lens_radius * sample_disk(rng_uniform(key, 0u, DIM_LENS_U),
                                                   rng_uniform(key, 0u, DIM_LENS_V));
        o = o + lens.x * p->camera_right.xyz + lens.y * p->camera_up.xyz;
        dir = normalize(focus - o);
    }
#endif
    *origin = o;
    *direction = dir;
}

#endif
