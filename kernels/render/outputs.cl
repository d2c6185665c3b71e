// GENERATED from src/layout/outputs.rs by `NOISEFREE_BLESS=1 cargo test --test layout`.
// Do not edit: change src/layout/outputs.rs instead. tests/layout.rs checks that this file
// is current and that the device lays every struct out exactly as Rust does.
#ifndef NOISEFREE_OUTPUTS_CL
#define NOISEFREE_OUTPUTS_CL

// Every output buffer of the megakernel, one parameter each, in table order. A
// buffer whose output is off is bound to a one-element stand-in.
#define RENDER_OUTPUT_PARAMS __global float* filter_vectors, __global float* depth_shifts, __global float* welford_sums, __global float* welford_state, __global float* positions, __global float* sample_vectors, __global float* shadow_terms, __global float* shadow_pixels, __global float* odd_halves, __global float* light_field, __global float* indirect_pixels, __global float* lens_field, __global float* lens_shadow, __global float* first_emission, __global float* odd_emission
#define RENDER_OUTPUT_ARGS filter_vectors, depth_shifts, welford_sums, welford_state, positions, sample_vectors, shadow_terms, shadow_pixels, odd_halves, light_field, indirect_pixels, lens_field, lens_shadow, first_emission, odd_emission

#if !defined(OUTPUT_FEATURES) || !defined(OUTPUT_VARIANCE) || !defined(OUTPUT_POSITION) || !defined(OUTPUT_SAMPLES) || !defined(OUTPUT_SHADOWS) || !defined(OUTPUT_HALVES) || !defined(OUTPUT_LIGHT_FIELD) || !defined(OUTPUT_INDIRECT) || !defined(OUTPUT_LENS_SHADOWS) || !defined(OUTPUT_EMISSION)
#error "noisefree: an output switch is missing from the build options"
#endif
#if OUTPUT_VARIANCE && !OUTPUT_FEATURES
#error "noisefree: OUTPUT_VARIANCE needs OUTPUT_FEATURES (variance needs features)"
#endif
#if OUTPUT_SAMPLES && !OUTPUT_FEATURES
#error "noisefree: OUTPUT_SAMPLES needs OUTPUT_FEATURES (samples needs features)"
#endif
#if OUTPUT_LENS_SHADOWS && !OUTPUT_SHADOWS
#error "noisefree: OUTPUT_LENS_SHADOWS needs OUTPUT_SHADOWS (lens-shadows needs shadows)"
#endif
#if OUTPUT_LENS_SHADOWS && !OUTPUT_LIGHT_FIELD
#error "noisefree: OUTPUT_LENS_SHADOWS needs OUTPUT_LIGHT_FIELD (lens-shadows needs light-field)"
#endif

#endif
