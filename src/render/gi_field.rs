//! The GI field of sheared filtering (Yan et al. 2015 §3.1 "Diffuse Indirect Illumination",
//! eq. 2, §5 "Sampling/Filtering for Indirect Illumination"; digest
//! /work/shared/notes/seeds-aaf-sheared.md §3; issue 16): l × l indirect samples per pixel on a
//! jittered grid over the v-plane, kept in the light-field output
//! ([`crate::layout::LightFieldPixel`]) when the sheared filter's effect is GI
//! ([`super::ShadowSampling::light_field_gi`]). The kernel is kernels/render/gi_field.cl (run by
//! [`super::lens_field`]'s pass); this module is its v-plane sampler in Rust, with the same
//! float operations.
//!
//! **Lanes** (the depth-of-field names, GI meanings): `samples`/`green`/`blue` lane b·l + a: the
//! weighted demodulated indirect radiance w(v) L_i(v) of grid point (a, b) (a along the tangent
//! t of the receiver's shading normal, b along n × t); `jitter`; `slopes`: s_min, s_max of s = z
//! (the first bounce's hit distance) over the samples that hit something (0, 0: none did, so
//! z_max > 0 tells a pixel whose samples met a reflector); `extra_samples`: 0 (depth of
//! field's fallback count; GI takes no extra samples); `extra` rgb: the mean albedo of the samples' receiver points;
//! `position`, `normal`: the pixel centre's receiver; `scale`: its pixel's world size d;
//! `dir1`, `dir2`: the image row and column (the filter walks them); `count`: l² for a
//! receiver, 0 for none (sky, emitter or a glossy first hit).
//!
//! **Sampling** (§5: "we importance sample along the (v1, v2) plane and apply appropriate
//! weights to make it equivalent to cosine-hemisphere sampling"): the seed's "cubic function
//! and a scaling" is not given; we use the exact inverse CDF of the marginal of γ, per axis
//! p(v) ∝ (1 + v²)^(−3/2) on [−V, V] (V = 5), and weight each sample by
//! γ(v) / (π K p(v1) p(v2)) (bounded: 1.26 at v = 0, 8.54 at the corners).
//!
//! **Truncation** (digest §3.2 (v)): the square keeps
//! K = ∫_{[−V,V]²} γ / π = 4 c atan(c) / π, c = V/√(1+V²): 0.9683 for V = 5 (the seed's "over
//! 99%" holds for ∫γ², not for the irradiance ∫γ). Measured (tests/sheared_gi.rs
//! `truncation_keeps_96_8_percent`): 0.9683 in a uniform environment before renormalising. We
//! divide the weights by K, so a uniform environment gives exactly its radiance (the 3.2%
//! darkening is gone); what is lost is the radiance's deviation from its mean over the
//! grazing directions beyond θ = atan(5√2) … atan(5) (78.7°-82°), where cos θ is ≤ 0.2.

/// Half side V of the truncated v-square (Yan et al. §5: [−5, 5]²); kernels/render/gi_field.cl
/// `GI_V_MAX`.
pub const V_MAX: f32 = 5.0;

/// kernels/render/gi_field.cl `GI_SAMPLE_BASE`.
pub const GI_SAMPLE_BASE: u32 = 0xFFFF_FD00;

/// c = V / √(1 + V²), the per-axis CDF's half range (`gi_c`).
pub fn c() -> f32 {
    V_MAX / (1.0 + V_MAX * V_MAX).sqrt()
}

/// Grid coordinate u ∈ [0, 1) → v ∈ [−V, V] (`gi_v`).
pub fn v_of(u: f32) -> f32 {
    let t = c() * (2.0 * u - 1.0);
    t / (1.0 - t * t).sqrt()
}

/// γ(v) / (π K p(v1) p(v2)) (`gi_weight`).
pub fn weight(v1: f32, v2: f32) -> f32 {
    let (a, b, r) = (1.0 + v1 * v1, 1.0 + v2 * v2, 1.0 + v1 * v1 + v2 * v2);
    let ab = a * b;
    c() / c().atan() * (ab * ab.sqrt()) / (r * r)
}

/// The kept fraction K = ∫_{[−V,V]²} γ dv / π of the cosine-weighted hemisphere.
pub fn kept_fraction() -> f32 {
    4.0 * c() * c().atan() / std::f32::consts::PI
}

/// The grid coordinate of point `a` of `side` with jitter `j` (u = (a + j)/l), as the kernel.
pub fn grid_v(a: u32, j: f32, side: u32) -> f32 {
    v_of((a as f32 + j) * (1.0 / side as f32))
}

/// γ(v) = 1 / (1 + |v|²)² (eq. 2): cos θ dω = γ dv.
pub fn gamma(v1: f32, v2: f32) -> f32 {
    let r = 1.0 + v1 * v1 + v2 * v2;
    1.0 / (r * r)
}
