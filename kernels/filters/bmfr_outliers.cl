// bmfr's outlier replacement (`outliers`; src/filters/bmfr/outliers.rs has the reasons and the
// measurements): a surface pixel whose light stands far above its neighbours' in one half
// buffer only (a single sample's "firefly") takes the light of its other half before the fit,
// the non-local means and the selection see it. Included at the end of filters/bmfr.cl; the
// Rust reference does the same float operations in the same order.

// Rec. 709 luminance of a colour.
inline float bmfr_luminance(float3 c) {
    return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}

// bmfr_outlier_levels: per pixel, the luminance of its light if it is a surface pixel
// (bmfr_surface), else -1 (it takes no part).
__kernel void bmfr_outlier_levels(__global const FilterVector* fv,
                                  __global const float4* positions,
                                  __global const float4* odd_halves,
                                  uint width, uint height, float spp,
                                  __global float* levels) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    uint i = y * width + x;
    __global const FilterVector* f = fv + i;
    levels[i] = bmfr_surface(f, positions + i, odd_halves[i], spp)
        ? bmfr_luminance(bmfr_beauty(f)) : -1.0f;
}

// bmfr_outliers: copies F and the odd half, replacing the light of each outlier: a surface
// pixel whose luminance l exceeds L = BMFR_OUTLIER_RATIO x the larger of its 3 x 3 neighbours'
// largest and its 7 x 7 neighbours' mean (surface pixels only, the pixel itself left out; at
// least BMFR_OUTLIER_NEIGHBOURS of them), and one of whose halves lies at or below L. It takes
// that half's light, channel by channel scaling its direct and indirect parts, and its odd half
// becomes its mean (no variance left to estimate).
__kernel void bmfr_outliers(__global const FilterVector* fv,
                            __global const float4* odd_halves,
                            uint width, uint height, float spp,
                            __global const float* levels,
                            __global FilterVector* fv_out,
                            __global float4* odd_out) {
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    uint i = (uint)y * width + (uint)x;
    FilterVector f = fv[i];
    float4 odd = odd_halves[i];
    float l = levels[i];
    if (l > 0.0f) {
        // The 3 x 3 neighbours' largest first: most pixels are no outlier of it.
        float largest = 0.0f;
        for (int dy = -1; dy <= 1; ++dy) {
            int yy = y + dy;
            if (yy < 0 || yy >= (int)height) continue;
            for (int dx = -1; dx <= 1; ++dx) {
                int xx = x + dx;
                if (xx < 0 || xx >= (int)width || (dx == 0 && dy == 0)) continue;
                largest = fmax(largest, levels[(uint)yy * width + (uint)xx]);
            }
        }
        if (l > BMFR_OUTLIER_RATIO * largest) {
            float sum = 0.0f, count = 0.0f;
            for (int dy = -BMFR_OUTLIER_RADIUS; dy <= BMFR_OUTLIER_RADIUS; ++dy) {
                int yy = y + dy;
                if (yy < 0 || yy >= (int)height) continue;
                for (int dx = -BMFR_OUTLIER_RADIUS; dx <= BMFR_OUTLIER_RADIUS; ++dx) {
                    int xx = x + dx;
                    if (xx < 0 || xx >= (int)width || (dx == 0 && dy == 0)) continue;
                    float n = levels[(uint)yy * width + (uint)xx];
                    if (n < 0.0f) continue;
                    sum += n;
                    count += 1.0f;
                }
            }
            float bound = BMFR_OUTLIER_RATIO * fmax(largest, sum / count);
            float3 b = bmfr_beauty(fv + i);
            float3 even = bmfr_even(b, odd, spp);
            float lo = bmfr_luminance(odd.xyz), le = bmfr_luminance(even);
            if (count >= BMFR_OUTLIER_NEIGHBOURS && l > bound && fmin(lo, le) <= bound) {
                float3 clean = lo <= le ? odd.xyz : even;
                float bc[3] = {b.x, b.y, b.z}, cc[3] = {clean.x, clean.y, clean.z};
                for (int c = 0; c < 3; ++c) {
                    float scale = bc[c] > 0.0f ? cc[c] / bc[c] : 0.0f;
                    f.direct[c] *= scale;
                    f.indirect[c] *= scale;
                }
                odd = (float4)(f.direct[0] + f.indirect[0], f.direct[1] + f.indirect[1],
                               f.direct[2] + f.indirect[2], odd.w);
            }
        }
    }
    fv_out[i] = f;
    odd_out[i] = odd;
}
