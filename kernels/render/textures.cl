// Texture lookups: bilinear, repeating, with the texture's uv scale and shift (§4.2.2).
#ifndef NOISEFREE_TEXTURES_CL
#define NOISEFREE_TEXTURES_CL

#include "arrays/trace.cl"
#include "render/sampling.cl"

// TextureInfo.format (src/arrays/texels.rs): a linear float4 per texel, or an 8-bit texture's
// four codes per texel (r | g << 8 | b << 16 | a << 24), decoded by the 256-entry colour and
// alpha tables at the start of the texel buffer, which hold exactly the floats the loader
// makes of each code. Codes take a quarter of the memory, so the bundled textures stay in
// cache (issue 14); a lookup gives the same floats in either format.
#define TEXTURE_LINEAR 0u
#define TEXTURE_SRGB8 1u

inline float4 texel_fetch(const SceneRefs* s, __global const TextureInfo* t, int x, int y) {
    int w = (int)t->width, h = (int)t->height;
    // The bilinear taps lie in [-1, size]: a compare each instead of the integer division
    // of %, which the lookups waited on (issue 14); % only for anything else.
    if (x < 0) x += w; else if (x >= w) x -= w;
    if (y < 0) y += h; else if (y >= h) y -= h;
    if ((uint)x >= (uint)w || (uint)y >= (uint)h) {
        x %= w; if (x < 0) x += w;
        y %= h; if (y < 0) y += h;
    }
    uint i = (uint)(y * w + x);
    if (t->format == TEXTURE_SRGB8) {
        uint code = ((__global const uint*)(s->texels + t->offset))[i];
        __global const float* table = (__global const float*)s->texels;
        return (float4)(table[code & 0xffu], table[(code >> 8) & 0xffu],
                        table[(code >> 16) & 0xffu], table[256u + (code >> 24)]);
    }
    return s->texels[t->offset + i];
}

// uv (0,0) is the bottom-left of the image (OBJ convention); rows are stored top-down.
inline float4 texture_bilinear(const SceneRefs* s, uint index, float2 uv) {
    __global const TextureInfo* t = s->textures + index;
    float2 st = uv * (float2)(t->uv_scale.x, t->uv_scale.y) + (float2)(t->uv_shift.x, t->uv_shift.y);
    st -= floor(st);
    float x = st.x * (float)t->width - 0.5f;
    float y = (1.0f - st.y) * (float)t->height - 0.5f;
    float fx = floor(x), fy = floor(y);
    float ax = x - fx, ay = y - fy;
    int x0 = (int)fx, y0 = (int)fy;
    float4 a = texel_fetch(s, t, x0, y0), b = texel_fetch(s, t, x0 + 1, y0);
    float4 c = texel_fetch(s, t, x0, y0 + 1), d = texel_fetch(s, t, x0 + 1, y0 + 1);
    return (a * (1.0f - ax) + b * ax) * (1.0f - ay) + (c * (1.0f - ax) + d * ax) * ay;
}

#if HAS_ENV
// The infinite light (the thesis's sky-box): equirectangular lookup by direction, y up,
// u = 0.5 at -z. Without a texture it is a constant colour.
inline float3 environment_radiance(const SceneRefs* s, float3 d) {
    __constant const SceneParams* p = s->params;
    DEBUG_COUNT(s, COUNT_ENV_LOOKUP);
    float3 radiance = p->env_radiance.xyz;
#if HAS_ENV_TEXTURE
    if (p->env_texture >= 0) {
        DEBUG_COUNT(s, COUNT_ENV_TEXTURE);
        float u = 0.5f + atan2(d.x, -d.z) * (0.5f * INV_PI_F);
        float v = 0.5f + asin(clamp(d.y, -1.0f, 1.0f)) * INV_PI_F;
        float2 uv = (float2)(u, v) * p->env_uv.xy + p->env_uv.zw;
        radiance *= texture_bilinear(s, (uint)p->env_texture, uv).xyz;
    }
#endif
    return radiance;
}
#endif

#endif
