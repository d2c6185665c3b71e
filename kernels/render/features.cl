// Compile-time feature switches (see src/render/features.rs, which derives them from the scene).
//
// The host passes every switch as -D NAME=0|1, so disabled code is not compiled at all:
// "simulate only the effects a scene calls for". A switch that is missing is a host bug, so
// it stops the build instead of silently meaning 0.
#ifndef NOISEFREE_FEATURES_CL
#define NOISEFREE_FEATURES_CL

#if !defined(HAS_TRIANGLES) || !defined(HAS_SPHERES) || !defined(HAS_TEXTURES) \
    || !defined(HAS_ENV) || !defined(HAS_ENV_TEXTURE) || !defined(HAS_SPHERE_LIGHTS) \
    || !defined(HAS_TRIANGLE_LIGHTS) || !defined(HAS_DIFFUSE) || !defined(HAS_SPECULAR) \
    || !defined(HAS_GLASS) || !defined(HAS_METAL) || !defined(HAS_DOF) \
    || !defined(HAS_RUSSIAN_ROULETTE) || !defined(NEXT_EVENT_ESTIMATION)
#error "noisefree: a feature switch is missing from the build options"
#endif

#define HAS_LIGHTS (HAS_SPHERE_LIGHTS || HAS_TRIANGLE_LIGHTS)

// The OUTPUT_* switches are checked by the generated render/outputs.cl.

#endif
