// The path-density outlier filter (DeCoro 2009, "Rendering Filters for Controlling Detail and
// Creating Effects", ch. 5 §5.3): every camera sample's density in the joint space of film
// position and CIELAB colour, from the mean distance to its k nearest neighbours; samples of
// low density are down-weighted or rejected before the pixel is reconstructed.
//
// Three launches (src/filters/path_density/device.rs), each mirrored line by line by the plain
// Rust reference in src/filters/path_density/reference.rs:
//   pd_lab          one work-item per stored sample: CIELAB of its HDR RGB (w = 1), or w = 0
//                   for a sample whose colour (or its Lab) is not finite: it is never a
//                   neighbour and weighs 0.
//   pd_density      one work-item per stored sample: sigma = mean distance to its k nearest
//                   neighbours (self excluded), d = |dxy| / w_W + |dLab| / w_c, found exactly
//                   by scanning rings of pixels outward; then the weight ramp on sigma.
//   pd_reconstruct  one work-item per pixel: sum w L / sum w per frame group, the plain mean of
//                   the group when every weight is 0; the groups' values averaged.
//
// Exact kNN by rings: ring r holds the pixels at Chebyshev distance r from the sample's pixel.
// A sample lies inside its pixel ([x, x + 1) x [y, y + 1) with its jitter), so every sample of
// ring r + 1 is more than r pixels away along one axis, hence at distance > r / w_W whatever
// its colour (the colour term is >= 0). After ring r, once k neighbours are held and
// r / w_W >= the k-th best distance, no later ring can improve the k best: stop. The result is
// the k smallest distances over the whole image (the same multiset whatever the scan order).
//
// epsilon-approximate kNN (the seed's [5], Arya et al.): stop once r / w_W >= d_k / (1 + eps)
// (`shrink` = 1 / (1 + eps)). Every unseen sample is then farther than d_j / (1 + eps) for every
// held j-th distance d_j, so d_j <= (1 + eps) times the true j-th distance, and d_j >= it (a
// subset's j-th smallest): sigma is over-estimated by at most the factor 1 + eps (more rejection,
// the seed's "slightly underestimate density"). eps = 0 is the exact scan.
//
// Build options:
//   PD_K   k, the number of neighbours (the size of the private sorted array).
//   PD_RGB defined: the colour coordinates are 100 x linear RGB instead of CIELAB (the seed's
//          Fig. 5.9 comparison); a sample is valid when its Lab and those are finite.
//
// Float operations are written out in a fixed order (FP_CONTRACT OFF) so that the reference
// performs the same ones; only cbrt may differ from Rust's by an ulp (tests/path_density.rs).
#pragma OPENCL FP_CONTRACT OFF

#include "layout.cl"

#if !defined(PD_K)
#error "noisefree: PD_K is missing from the build options"
#endif

// CIELAB of linear Rec. 709 RGB, D65 white with Y_n = 1 (seed digest §3.2 item 5: HDR values
// give L* > 100, which the cube root handles; Y <= 0 takes the linear segment, so any finite
// input gives a finite Lab unless the products overflow).
inline float pd_lab_f(float t) {
    return t > 0.008856452f ? cbrt(t) : t * 7.787037f + 0.13793103f;
}

inline float4 pd_lab_of(float r, float g, float b) {
    float x = 0.4124564f * r + 0.3575761f * g + 0.1804375f * b;
    float y = 0.2126729f * r + 0.7151522f * g + 0.0721750f * b;
    float z = 0.0193339f * r + 0.1191920f * g + 0.9503041f * b;
    float fx = pd_lab_f(x / 0.95047f);
    float fy = pd_lab_f(y);
    float fz = pd_lab_f(z / 1.08883f);
    float l = 116.0f * fy - 16.0f;
    float a = 500.0f * (fx - fy);
    float bb = 200.0f * (fy - fz);
    bool ok = isfinite(l) && isfinite(a) && isfinite(bb);
#if defined(PD_RGB)
    l = 100.0f * r;
    a = 100.0f * g;
    bb = 100.0f * b;
    ok = ok && isfinite(l) && isfinite(a) && isfinite(bb);
#endif
    return ok ? (float4)(l, a, bb, 1.0f) : (float4)(0.0f);
}

// Stored sample i = pixel * spp + s of the frame's sample vectors (capacity per pixel).
inline __global const float* pd_vector(__global const float* sv, uint i, uint spp, uint capacity) {
    uint p = i / spp, s = i - p * spp;
    return sv + ((size_t)p * capacity + s) * SAMPLE_VECTOR_FLOATS;
}

__kernel void pd_lab(__global const float* sv, uint count, uint spp, uint capacity,
                     __global float4* lab, __global float2* xy) {
    uint i = get_global_id(0);
    if (i >= count) return;
    __global const float* v = pd_vector(sv, i, spp, capacity);
    lab[i] = pd_lab_of(v[SAMPLE_VECTOR_COLOR], v[SAMPLE_VECTOR_COLOR + 1], v[SAMPLE_VECTOR_COLOR + 2]);
    xy[i] = (float2)(v[SAMPLE_VECTOR_POSITION], v[SAMPLE_VECTOR_POSITION + 1]);
}

inline float pd_distance(float2 a, float4 la, float2 b, float4 lb, float inv_w, float inv_c) {
    float dx = a.x - b.x, dy = a.y - b.y;
    float dl = la.x - lb.x, da = la.y - lb.y, db = la.z - lb.z;
    return sqrt(dx * dx + dy * dy) * inv_w + sqrt(dl * dl + da * da + db * db) * inv_c;
}

// frame_spp: samples per frame group (spp for the accumulated mode: one group).
__kernel void pd_density(__global const float4* lab, __global const float2* xy, uint width,
                         uint height, uint spp, uint frame_spp, float inv_w, float inv_c,
                         float shrink, float keep, float reject, __global float* sigma_out,
                         __global float* weight_out) {
    uint i = get_global_id(0);
    if (i >= width * height * spp) return;
    float4 li = lab[i];
    if (li.w == 0.0f) {                         // not finite: never kept
        sigma_out[i] = INFINITY;
        weight_out[i] = 0.0f;
        return;
    }
    float2 pi = xy[i];
    uint p = i / spp, s = i - p * spp;
    int px = (int)(p % width), py = (int)(p / width);
    uint g0 = (s / frame_spp) * frame_spp, g1 = min(g0 + frame_spp, spp);
    float best[PD_K];
    uint count = 0u;
    int rmax = (int)max(width, height);
    for (int r = 0; r <= rmax; ++r) {
        for (int dy = -r; dy <= r; ++dy) {
            int qy = py + dy;
            if (qy < 0 || qy >= (int)height) continue;
            bool edge_row = dy == -r || dy == r;
            int step = edge_row || r == 0 ? 1 : 2 * r;
            for (int dx = -r; dx <= r; dx += step) {
                int qx = px + dx;
                if (qx < 0 || qx >= (int)width) continue;
                uint q = (uint)(qy * (int)width + qx) * spp;
                for (uint t = g0; t < g1; ++t) {
                    uint j = q + t;
                    if (j == i) continue;
                    float4 lj = lab[j];
                    if (lj.w == 0.0f) continue;
                    float d = pd_distance(pi, li, xy[j], lj, inv_w, inv_c);
                    if (count == PD_K && !(d < best[PD_K - 1])) continue;
                    // Insertion into the sorted array (the last one drops out when full).
                    uint at = count < PD_K ? count : PD_K - 1u;
                    while (at > 0u && best[at - 1u] > d) {
                        best[at] = best[at - 1u];
                        --at;
                    }
                    best[at] = d;
                    if (count < PD_K) ++count;
                }
            }
        }
        if (count == PD_K && (float)r * inv_w >= best[PD_K - 1] * shrink) break;
    }
    float sum = 0.0f;
    for (uint k = 0u; k < count; ++k) sum += best[k];
    // No neighbour at all (a one-sample image or group): nothing contradicts the sample.
    float sigma = count > 0u ? sum / (float)count : 0.0f;
    float w;
    if (sigma <= keep) w = 1.0f;
    else if (sigma >= reject) w = 0.0f;
    else w = (reject - sigma) / (reject - keep);
    sigma_out[i] = sigma;
    weight_out[i] = w;
}

__kernel void pd_reconstruct(__global const float* sv, __global const float4* lab,
                             __global const float* weight, uint width, uint height, uint spp,
                             uint capacity, uint frame_spp, __global float4* out) {
    uint p = get_global_id(0);
    if (p >= width * height) return;
    uint groups = (spp + frame_spp - 1u) / frame_spp;
    float3 acc = (float3)(0.0f);
    float3 single = (float3)(0.0f);
    for (uint g = 0u; g < groups; ++g) {
        uint g0 = g * frame_spp, g1 = min(g0 + frame_spp, spp);
        float3 wl = (float3)(0.0f), plain = (float3)(0.0f);
        float ws = 0.0f, n = 0.0f;
        for (uint s = g0; s < g1; ++s) {
            uint i = p * spp + s;
            if (lab[i].w == 0.0f) continue;
            __global const float* v = pd_vector(sv, i, spp, capacity);
            float3 c = (float3)(v[SAMPLE_VECTOR_COLOR], v[SAMPLE_VECTOR_COLOR + 1],
                                v[SAMPLE_VECTOR_COLOR + 2]);
            float w = weight[i];
            wl += w * c;
            ws += w;
            plain += c;
            n += 1.0f;
        }
        // Every weight 0: the plain mean of the group (0 when no sample is finite).
        float3 value = ws > 0.0f ? wl / ws : (n > 0.0f ? plain / n : (float3)(0.0f));
        single = value;
        acc += value * (float)(g1 - g0);
    }
    float3 result = groups == 1u ? single : acc / (float)spp;
    out[p] = (float4)(result, 0.0f);
}
