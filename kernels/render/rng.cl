// Counter-based random numbers (no state, no thread ids).
//
// Every random number is a hash of (seed, pixel, sample, bounce, dimension), so the same seed
// gives the same bytes on any device, any work-group size and any launch batching, and a
// feature that is compiled out does not shift the numbers the others draw. The hash is
// Wellons' "lowbias32" integer finaliser; src/render/cpu/rng.rs is the same code in Rust.
#ifndef NOISEFREE_RNG_CL
#define NOISEFREE_RNG_CL

// Dimensions drawn at one path vertex ("bounce"). The camera uses bounce 0, dims 0-3.
#define DIM_PIXEL_X 0u
#define DIM_PIXEL_Y 1u
#define DIM_LENS_U 2u
#define DIM_LENS_V 3u
#define DIM_RUSSIAN_ROULETTE 4u
#define DIM_LIGHT_SELECT 5u
#define DIM_LIGHT_U 6u
#define DIM_LIGHT_V 7u
#define DIM_BSDF_LOBE 8u
#define DIM_BSDF_U 9u
#define DIM_BSDF_V 10u

inline uint hash_u32(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

// The per-(seed, pixel, sample) key; computed once per sample.
inline uint rng_sample_key(uint seed, uint pixel, uint sample) {
    return hash_u32(hash_u32(hash_u32(seed ^ 0x9e3779b9u) ^ pixel) ^ sample);
}

// A uniform float in [0, 1) with 24 random bits.
inline float rng_uniform(uint key, uint bounce, uint dim) {
    uint h = hash_u32(key ^ hash_u32((bounce << 8) | dim));
    return (float)(h >> 8) * 0x1.0p-24f;
}

#endif
