// What the kernels that put 16 pixels or samples on vector lanes share (bmfr_fit_packed.cl,
// stylized.cl). Kept apart from render/rng.cl: that file is part of the megakernel's program,
// whose text keys the reference cache (src/render/mod.rs `render_hash`), so an edit there would invalidate
// every cached reference.
#ifndef NOISEFREE_FILTERS_LANES_CL
#define NOISEFREE_FILTERS_LANES_CL

// render/rng.cl hash_u32 on 16 lanes: each lane the scalar function's bits.
inline uint16 hash_u32_16(uint16 x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

#endif
