// Subtractive shadows (DeCoro 2009 ch. 4, eq. 4.1; digest shared/notes/seed-decoro.md §2.3):
// the image kernels of the real-time preview, steps 2(c-d), 3, 4 and 5. The plain Rust
// reference of each is src/render/subtractive/reference.rs, in the same order of operations.
// Options: SUB_VISIBLE = 1 makes sub_shadow sum the *visible* lights at every pixel (the
// additive form, the comparison of §2.5), 0 the *blocked* ones (the shadow buffer S).
#ifndef SUB_VISIBLE
#define SUB_VISIBLE 0
#endif

#define SUB_INV_PI 0.318309886183790671538f

// f (n.w) E for f = albedo / pi over the lights whose visibility bit == want (bits == 0:
// every light), facing lights only.
inline float3 sub_sum(float3 albedo, float3 n, __global const float4* dirs,
                      __global const float4* irr, uint count,
                      __global const uint* bits, uint want) {
    float3 sum = (float3)(0.0f);
    for (uint l = 0; l < count; ++l) {
        float c = dot(n, dirs[l].xyz);
        if (c > 0.0f) {
            if (bits != 0 && ((bits[l >> 5] >> (l & 31u)) & 1u) != want) continue;
            sum += irr[l].xyz * c;
        }
    }
    return albedo * SUB_INV_PI * sum;
}

// Step 3: C, unshadowed, at every pixel; the sky (stored in albedo) where the ray escaped.
__kernel void sub_unshadowed(__global const float4* pos, __global const float4* nrm,
                             __global const float4* alb, __global const float4* dirs,
                             __global const float4* irr, uint count, uint n_pixels,
                             __global float4* out) {
    uint k = get_global_id(0);
    if (k >= n_pixels) return;
    if (pos[k].w == 0.0f) { out[k] = alb[k]; return; }
    float3 c = sub_sum(alb[k].xyz, nrm[k].xyz, dirs, irr, count, 0, 0u);
    out[k] = (float4)(c, 0.0f);
}

// Step 3 with the prefiltered irradiance map (64x32 lat-long over normals, MAP_W x MAP_H from
// the host's -D options): C = albedo / pi * E(n), bilinear, u wrapping, v clamped.
__kernel void sub_prefiltered(__global const float4* pos, __global const float4* nrm,
                              __global const float4* alb, __global const float4* map,
                              uint n_pixels, __global float4* out) {
    uint k = get_global_id(0);
    if (k >= n_pixels) return;
    if (pos[k].w == 0.0f) { out[k] = alb[k]; return; }
    float3 n = nrm[k].xyz;
    float u = 0.5f + atan2(n.x, -n.z) * (0.5f * SUB_INV_PI);
    float v = 0.5f + asin(clamp(n.y, -1.0f, 1.0f)) * SUB_INV_PI;
    float fx = u * (float)MAP_W - 0.5f;
    float fy = clamp(v * (float)MAP_H - 0.5f, 0.0f, (float)(MAP_H - 1));
    float x0 = floor(fx), y0 = floor(fy);
    float ax = fx - x0, ay = fy - y0;
    int i0 = (int)x0, j0 = (int)y0;
    int ia = ((i0 % MAP_W) + MAP_W) % MAP_W, ib = (((i0 + 1) % MAP_W) + MAP_W) % MAP_W;
    int ja = clamp(j0, 0, MAP_H - 1), jb = clamp(j0 + 1, 0, MAP_H - 1);
    float3 e = (map[ja * MAP_W + ia].xyz * (1.0f - ax) + map[ja * MAP_W + ib].xyz * ax) * (1.0f - ay)
             + (map[jb * MAP_W + ia].xyz * (1.0f - ax) + map[jb * MAP_W + ib].xyz * ax) * ay;
    out[k] = (float4)(alb[k].xyz * SUB_INV_PI * e, 0.0f);
}

// Step 2(c-d): per sample k (at pixel pixels[k]), the light of the blocked lights (S) or,
// with SUB_VISIBLE, of the visible ones (the additive image).
__kernel void sub_shadow(__global const float4* pos, __global const float4* nrm,
                         __global const float4* alb, __global const uint* pixels,
                         __global const float4* dirs, __global const float4* irr, uint count,
                         __global const uint* bits, uint n_samples, __global float4* out) {
    uint k = get_global_id(0);
    if (k >= n_samples) return;
    uint px = pixels[k];
    if (pos[px].w == 0.0f) {
        out[k] = SUB_VISIBLE ? alb[px] : (float4)(0.0f);
        return;
    }
    uint words = (count + 31u) >> 5;
    float3 c = sub_sum(alb[px].xyz, nrm[px].xyz, dirs, irr, count, bits + (size_t)k * words,
                       (uint)SUB_VISIBLE);
    out[k] = (float4)(c, 0.0f);
}

// Steps 4-5: S' by joint-bilateral upsampling, w = bilinear x G(|S'_p - S_p|) x max(n'.n, 0)
// (the thesis's weight, §2.2, with the bilinear footprint of the 2x2 nearest samples as the
// spatial term); the nearest sample when every weight is 0 (§2.4); then max(C - S', 0).
__kernel void sub_compose(__global const float4* pos, __global const float4* nrm,
                          __global const float4* col, __global const float4* s_low,
                          __global const uint* pixels, uint width, uint height, uint lw,
                          uint lh, uint block, float sigma, __global float4* out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    uint k = y * width + x;
    float4 p4 = pos[k];
    if (p4.w == 0.0f) { out[k] = col[k]; return; }
    float3 p = p4.xyz;
    float3 n = nrm[k].xyz;
    float sig = sigma * (float)block * nrm[k].w;
    float inv2s2 = 1.0f / (2.0f * sig * sig);
    float half_block = (float)(block / 2u);
    float fx = ((float)x - half_block) / (float)block;
    float fy = ((float)y - half_block) / (float)block;
    float x0 = floor(fx), y0 = floor(fy);
    float ax = fx - x0, ay = fy - y0;
    float3 sum = (float3)(0.0f);
    float wsum = 0.0f;
    for (int dj = 0; dj < 2; ++dj) {
        for (int di = 0; di < 2; ++di) {
            float wb = (di == 0 ? 1.0f - ax : ax) * (dj == 0 ? 1.0f - ay : ay);
            int i = clamp((int)x0 + di, 0, (int)lw - 1);
            int j = clamp((int)y0 + dj, 0, (int)lh - 1);
            uint q = pixels[j * lw + i];
            if (pos[q].w == 0.0f) continue;
            float3 d = pos[q].xyz - p;
            float wg = exp(-dot(d, d) * inv2s2);
            float wn = fmax(dot(n, nrm[q].xyz), 0.0f);
            float wt = wb * wg * wn;
            sum += wt * s_low[j * lw + i].xyz;
            wsum += wt;
        }
    }
    float3 s;
    if (wsum > 0.0f) {
        s = sum / wsum;
    } else {
        uint i = min(x / block, lw - 1u), j = min(y / block, lh - 1u);
        s = s_low[j * lw + i].xyz;
    }
    out[k] = (float4)(fmax(col[k].xyz - s, (float3)(0.0f)), 0.0f);
}
