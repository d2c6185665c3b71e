// Lights seen directly, treated apart from the reflected light (bmfr's `emission`; the method,
// its reasons and its measurements: src/filters/bmfr/emission.rs, which holds the same float
// operations in the same order in Rust). Included by filters/bmfr.cl.
//
// Build options: BMFR_EMISSION_RADIUS, BMFR_EMISSION_PATCH (half widths of the window and the
// patches), BMFR_EMISSION_K, BMFR_EMISSION_EPSILON (float literals).

// F and the odd half with the light of emitters seen directly taken out; a pixel's mean albedo
// less its emitter samples' share of it (f E / max(E): a light's albedo is its emission's
// chromaticity), unless all its samples hit a light (then bmfr_light keeps it out of the fit).
__kernel void bmfr_reflected(__global const FilterVector* fv, __global const float4* odd_halves,
                             __global const float4* emission, __global const float4* odd_emission,
                             uint width, uint height, __global FilterVector* fv_out,
                             __global float4* odd_out) {
    uint x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    uint i = y * width + x;
    FilterVector f = fv[i];
    float4 odd = odd_halves[i];
    float4 e = emission[i];
    float share = e.w;
    if (share > 0.0f) {
        float4 eo = odd_emission[i];
        float peak = fmax(e.x, fmax(e.y, e.z));
        float ec[3] = {e.x, e.y, e.z}, eoc[3] = {eo.x, eo.y, eo.z};
        float oc[3] = {odd.x, odd.y, odd.z};
        for (int c = 0; c < 3; ++c) {
            f.direct[c] = fmax(f.direct[c] - ec[c], 0.0f);
            oc[c] = fmax(oc[c] - eoc[c], 0.0f);
            if (share < 1.0f && peak > 0.0f) f.albedo[c] = fmax(f.albedo[c] - share * ec[c] / peak, 0.0f);
        }
        odd = (float4)(oc[0], oc[1], oc[2], odd.w);
    }
    fv_out[i] = f;
    odd_out[i] = odd;
}

// The variance of a pixel's mean E from its half buffers, averaged over the channels.
inline float bmfr_emission_variance_raw(float4 e, float4 eo, float spp) {
    float n_odd = eo.w, n_even = spp - n_odd;
    if (n_odd <= 0.0f || n_even <= 0.0f) return 0.0f;
    float ec[3] = {e.x, e.y, e.z}, oc[3] = {eo.x, eo.y, eo.z};
    float v = 0.0f;
    for (int c = 0; c < 3; ++c) {
        float even = (ec[c] * spp - oc[c] * n_odd) / n_even;
        v += (even - oc[c]) * (even - oc[c]) * 0.25f;
    }
    return v * (1.0f / 3.0f);
}

// Per pixel: (E's luminance, its variance averaged over the 3 x 3 pixels around).
__kernel void bmfr_emission_prep(__global const float4* emission,
                                 __global const float4* odd_emission, uint width, uint height,
                                 float spp, __global float2* prep) {
    int x = get_global_id(0), y = get_global_id(1), w = width, h = height;
    if (x >= w || y >= h) return;
    float sum = 0.0f, n = 0.0f;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            int u = x + dx, v = y + dy;
            if (u >= 0 && v >= 0 && u < w && v < h) {
                int j = v * w + u;
                sum += bmfr_emission_variance_raw(emission[j], odd_emission[j], spp);
                n += 1.0f;
            }
        }
    float4 e = emission[y * w + x];
    prep[y * w + x] = (float2)((e.x + e.y + e.z) * (1.0f / 3.0f), sum / n);
}

// E filtered by non-local means, added to the filtered reflected light in `out`. A window
// without light gives 0 and is skipped.
__kernel void bmfr_emission_nlm(__global const float4* emission, __global const float2* prep,
                                uint width, uint height, __global float4* out) {
    int x = get_global_id(0), y = get_global_id(1), w = width, h = height;
    if (x >= w || y >= h) return;
    const int r = BMFR_EMISSION_RADIUS, pr = BMFR_EMISSION_PATCH;
    bool lit = false;
    for (int v = max(y - r, 0); v <= min(y + r, h - 1) && !lit; ++v)
        for (int u = max(x - r, 0); u <= min(x + r, w - 1); ++u)
            if (prep[v * w + u].x > 0.0f) { lit = true; break; }
    if (!lit) return;
    const float k2 = BMFR_EMISSION_K * BMFR_EMISSION_K;
    float3 acc = (float3)(0.0f);
    float wsum = 0.0f;
    for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
            int u = x + dx, v = y + dy;
            if (u < 0 || v < 0 || u >= w || v >= h) continue;
            float d = 0.0f, n = 0.0f;
            for (int py = -pr; py <= pr; ++py)
                for (int px = -pr; px <= pr; ++px) {
                    int a1 = x + px, b1 = y + py, a2 = u + px, b2 = v + py;
                    if (a1 < 0 || b1 < 0 || a1 >= w || b1 >= h || a2 < 0 || b2 < 0 || a2 >= w || b2 >= h)
                        continue;
                    float2 p = prep[b1 * w + a1], q = prep[b2 * w + a2];
                    float diff = p.x - q.x;
                    d += (diff * diff - (p.y + fmin(p.y, q.y)))
                         / (BMFR_EMISSION_EPSILON + k2 * (p.y + q.y));
                    n += 1.0f;
                }
            float wt = exp(-fmax(d / n, 0.0f));
            float4 e = emission[v * w + u];
            acc.x += wt * e.x;
            acc.y += wt * e.y;
            acc.z += wt * e.z;
            wsum += wt;
        }
    float4 o = out[y * w + x];
    out[y * w + x] = (float4)(o.x + acc.x / wsum, o.y + acc.y / wsum, o.z + acc.z / wsum, o.w);
}
