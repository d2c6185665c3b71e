// Micro-kernels that measure the device's own ceilings for the roofline study
// (src/bench/roofline.rs; Williams, Waterman & Patterson, "Roofline: an insightful visual
// performance model for multicore architectures", CACM 2009): the arithmetic peak (fused
// multiply-adds), the cost of one `exp` in those units (the filters' weights are exponentials),
// and the streaming memory bandwidth (McCalpin's STREAM triad).
//
// Each work-item runs ROOFLINE_CHAINS independent chains so that the arithmetic units never
// wait on one chain's latency (an FMA takes ~4 cycles on x86 and GPUs alike; 8 chains cover
// 2 ports x 4 cycles), of floats (`*_scalar`) or of float16s. The chains converge to a fixed
// point, so no value overflows however many iterations run (a <- a b + c with |b| < 1 tends to
// c / (1 - b); a <- exp(-a) to the omega constant 0.567...), and every result is stored, so
// nothing can be optimised away. The plain Rust reference of every kernel is in
// src/bench/roofline/peaks.rs (`reference_*`).
#pragma OPENCL FP_CONTRACT OFF

#define ROOFLINE_CHAINS 8

// The initial value of chain k in lane l of work-item i (the Rust reference's `initial`).
#define ROOFLINE_INITIAL(i, k, l) ((float)(((i) + (k) * 16 + (l)) & 15) * 0.0625f)

// One step of the 8 chains `a`.
#define ROOFLINE_STEP(a, OP) \
    a[0] = OP(a[0]); a[1] = OP(a[1]); a[2] = OP(a[2]); a[3] = OP(a[3]); \
    a[4] = OP(a[4]); a[5] = OP(a[5]); a[6] = OP(a[6]); a[7] = OP(a[7]);

#define ROOFLINE_FMA(x) fma(x, b, c)
#define ROOFLINE_EXP(x) exp(-(x))

// Scalar chains: each work-item's 8 floats. A device that runs work-items in SIMD lanes
// reaches its peak with these; PoCL's CPU vectoriser packs work-items into lanes only when the
// kernel has no loop of its own, so on PoCL this is the ceiling of a kernel that loops per
// work-item (as every filter does).
__kernel void peak_fma_scalar(__global float* out, const int iterations, const float b,
                              const float c) {
    uint i = get_global_id(0);
    float a[ROOFLINE_CHAINS];
    for (int k = 0; k < ROOFLINE_CHAINS; ++k) a[k] = ROOFLINE_INITIAL(i, k, 0);
    for (int n = 0; n < iterations; ++n) { ROOFLINE_STEP(a, ROOFLINE_FMA) }
    float s = 0.0f;
    for (int k = 0; k < ROOFLINE_CHAINS; ++k) s += a[k];
    out[i] = s;
}

__kernel void peak_exp_scalar(__global float* out, const int iterations) {
    uint i = get_global_id(0);
    float a[ROOFLINE_CHAINS];
    for (int k = 0; k < ROOFLINE_CHAINS; ++k) a[k] = ROOFLINE_INITIAL(i, k, 0);
    for (int n = 0; n < iterations; ++n) { ROOFLINE_STEP(a, ROOFLINE_EXP) }
    float s = 0.0f;
    for (int k = 0; k < ROOFLINE_CHAINS; ++k) s += a[k];
    out[i] = s;
}

// float16 chains: explicit SIMD, the hardware's peak whatever the compiler does with
// work-items (a GPU runs the 16 lanes as 16 independent instructions of one thread).
inline float16 roofline_initial16(uint i, int k) {
    return (float16)(ROOFLINE_INITIAL(i, k, 0), ROOFLINE_INITIAL(i, k, 1),
                     ROOFLINE_INITIAL(i, k, 2), ROOFLINE_INITIAL(i, k, 3),
                     ROOFLINE_INITIAL(i, k, 4), ROOFLINE_INITIAL(i, k, 5),
                     ROOFLINE_INITIAL(i, k, 6), ROOFLINE_INITIAL(i, k, 7),
                     ROOFLINE_INITIAL(i, k, 8), ROOFLINE_INITIAL(i, k, 9),
                     ROOFLINE_INITIAL(i, k, 10), ROOFLINE_INITIAL(i, k, 11),
                     ROOFLINE_INITIAL(i, k, 12), ROOFLINE_INITIAL(i, k, 13),
                     ROOFLINE_INITIAL(i, k, 14), ROOFLINE_INITIAL(i, k, 15));
}

// The chains summed chain by chain, then lane by lane (the reference's order).
inline float roofline_sum16(const float16* a) {
    float16 v = a[0];
    for (int k = 1; k < ROOFLINE_CHAINS; ++k) v += a[k];
    float l[16];
    vstore16(v, 0, l);
    float s = 0.0f;
    for (int k = 0; k < 16; ++k) s += l[k];
    return s;
}

__kernel void peak_fma(__global float* out, const int iterations, const float b,
                       const float c) {
    uint i = get_global_id(0);
    float16 a[ROOFLINE_CHAINS];
    for (int k = 0; k < ROOFLINE_CHAINS; ++k) a[k] = roofline_initial16(i, k);
    for (int n = 0; n < iterations; ++n) { ROOFLINE_STEP(a, ROOFLINE_FMA) }
    out[i] = roofline_sum16(a);
}

__kernel void peak_exp(__global float* out, const int iterations) {
    uint i = get_global_id(0);
    float16 a[ROOFLINE_CHAINS];
    for (int k = 0; k < ROOFLINE_CHAINS; ++k) a[k] = roofline_initial16(i, k);
    for (int n = 0; n < iterations; ++n) { ROOFLINE_STEP(a, ROOFLINE_EXP) }
    out[i] = roofline_sum16(a);
}

// STREAM's triad a = b + s c on float4s: 32 bytes read and 16 written per element (STREAM's
// count; a CPU's write-allocate also reads `a`, which STREAM does not count either).
__kernel void stream_triad(__global float4* a, __global const float4* b,
                           __global const float4* c, const float s) {
    uint i = get_global_id(0);
    a[i] = b[i] + s * c[i];
}
