// Sixteen adjacent floats as one vector load or store, at any float's address (issue 14).
//
// Why: PoCL 3.1 compiles vload16 and vstore16 at an address it cannot prove 64-byte aligned as
// eight 8-byte loads joined by inserts (`perf annotate` of bmfr_nlm_packed: vmovsd, vmovlhps,
// vinsertf128 and vinsertf64x4 were a quarter of its instructions). Through a pointer to a
// float16 type declared 4-byte aligned the same bytes are read by one unaligned vector load
// (vmovups): bmfr_nlm_packed on Cornell diffuse 512², 44 -> 27 ms, the same output bytes
// (results/README.md, "Unaligned vector loads"). The packed kernels (filters/*_packed.cl and
// the packed emission kernel) read their lines at every pixel offset, so those addresses are
// never 64-byte aligned. They run on CPU devices; the kernels meant for GPUs keep vload16,
// whose 16-byte alignment a GPU compiler may use for wider loads.
//
// The typedef is used where the program is compiled for a CPU (PoCL's clang defines the host
// ISA's macros, __x86_64__ here; it defines no macro of its own that a kernel can test);
// other targets get vload16 and vstore16, which every OpenCL C compiler takes (these
// programs also hold the GPU kernels).
#ifndef NOISEFREE_VECTORS_CL
#define NOISEFREE_VECTORS_CL

#if defined(__x86_64__) || defined(__i386__) || defined(__aarch64__) || defined(__arm__)

typedef float16 float16_unaligned __attribute__((aligned(4)));

// p[0..16] as one vector.
inline float16 load16(__global const float* p) {
    return *(__global const float16_unaligned*)p;
}

// v into p[0..16].
inline void store16(float16 v, __global float* p) {
    *(__global float16_unaligned*)p = v;
}

// The same from and to local memory.
inline float16 load16_local(__local const float* p) {
    return *(__local const float16_unaligned*)p;
}

inline void store16_local(float16 v, __local float* p) {
    *(__local float16_unaligned*)p = v;
}

#else

inline float16 load16(__global const float* p) { return vload16(0, p); }
inline void store16(float16 v, __global float* p) { vstore16(v, 0, p); }
inline float16 load16_local(__local const float* p) { return vload16(0, p); }
inline void store16_local(float16 v, __local float* p) { vstore16(v, 0, p); }

#endif

#endif
