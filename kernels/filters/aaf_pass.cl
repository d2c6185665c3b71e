// The 1-D pass of axis-aligned filtering (Wang 2013 eq. 3.7; ch. 4 "does not change from
// section 3.3"), shared by the soft-shadow filter (kernels/filters/aaf_shadows.cl) and the
// diffuse-indirect filter (kernels/filters/aaf_indirect.cl): each filter's prepare kernel
// writes the guide and the values, this pass runs twice (rows, then columns of the first
// pass's result), and the filter's compose kernel reads the result. src/filters/aaf_pass is
// the same code in Rust and says why each test is what it is.
//
// guide, three float4 per pixel: (position, kind), (normal, beta), (axis, group). The distance
// between two pixels is measured in the plane perpendicular to `axis` (shadows: the direction
// to the light, the "plane parallel to the light"; indirect light: the receiver's normal, its
// tangent plane); offsets along it beyond depth_tolerance * beta reject the neighbour, and so
// does a neighbour of another group (indirect light: the other lobe, diffuse or glossy, which
// the seed filters as a separate buffer; shadows: all 0).
// Values are float4 (shadows use x, indirect light rgb); the weights are those of the pixel
// being written, the sum normalised (sum w v / sum w).
#pragma OPENCL FP_CONTRACT OFF

// What a pixel is to the filter (guide[0].w).
#define AAF_NONE 0.0f      // nothing to filter: lends nothing, keeps its value
#define AAF_LIT 1.0f       // its value stands and is lent to neighbours, not filtered
#define AAF_FILTERED 2.0f  // filtered with its beta

__kernel void aaf_pass(__global const float4* guide, __global const float4* in,
                       __global float4* out, uint width, uint height, int radius, uint axis,
                       float normal_cos, float depth_tolerance, float beta_tolerance) {
    int x = (int)get_global_id(0), y = (int)get_global_id(1);
    if (x >= (int)width || y >= (int)height) return;
    int i = y * (int)width + x;
    float4 g0 = guide[3 * i];
    if (g0.w != AAF_FILTERED) {
        out[i] = in[i];
        return;
    }
    float4 g1 = guide[3 * i + 1];
    float3 pos = g0.xyz;
    float3 normal = g1.xyz;
    float4 g2 = guide[3 * i + 2];
    float3 dir = g2.xyz;
    float beta = g1.w;
    // Finite for any beta > 0, so that 0 * it is 0, never NaN.
    float inv_two_beta2 = fmin(1.0f / (2.0f * beta * beta), FLT_MAX);
    int c = (axis == 0u) ? x : y;
    int n = (axis == 0u) ? (int)width : (int)height;
    int stride = (axis == 0u) ? 1 : (int)width;
    float4 sum = in[i];
    float sum_w = 1.0f;   // the pixel itself weighs exp(0) = 1
    for (int k = max(0, c - radius); k <= min(n - 1, c + radius); ++k) {
        if (k == c) continue;
        int j = i + (k - c) * stride;
        float4 q0 = guide[3 * j];
        if (q0.w == AAF_NONE || guide[3 * j + 2].w != g2.w) continue;
        float4 q1 = guide[3 * j + 1];
        if (dot(normal, q1.xyz) < normal_cos) continue;
        float3 delta = q0.xyz - pos;
        float along = dot(delta, dir);
        if (fabs(along) > depth_tolerance * beta) continue;
        if (q0.w == AAF_FILTERED
            && fabs(beta - q1.w) > beta_tolerance * fmax(beta, q1.w)) continue;
        float r2 = fmax(dot(delta, delta) - along * along, 0.0f);
        float w = exp(-r2 * inv_two_beta2);
        sum += w * in[j];
        sum_w += w;
    }
    out[i] = sum / sum_w;
}
