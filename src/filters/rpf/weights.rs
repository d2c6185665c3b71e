//! Statistical dependencies and the weights α, β (thesis §5.1.3, eqs. 5.4-5.14) and the
//! variance of the filter (§5.1.4, eqs. 5.15-5.17).
//!
//! Readings (the printed equations mix up indices):
//!
//! * **Eqs. 5.4-5.7** are sums of per-pair mutual informations over the n = 6 random
//!   parameters (u, v, t, x, y, z) and the 2 screen coordinates, as printed. t is always 0, so
//!   its terms are 0 ([`super::mi`]).
//! * **D^f_{c,k}** (item 3 of the list in §5.1.3, used by eq. 5.11) is
//!   Σ_{l ≤ 15} μ(c̄_k; f̄_l), the dependency of colour channel k on all features, by analogy with
//!   eqs. 5.4/5.5. Eq. 5.10's `D^{f,k}_c` is Σ_{l ≤ 3} μ(c̄_l; f̄_k).
//! * **Eq. 5.11** is printed with `Σ_{1≤l≤3} D^r_{c,k}`; we read Σ_k D^r_{c,k} (the sum over
//!   the colour channels), likewise D^p_c and D^f_c.
//! * **Eq. 5.12** is printed as `W^{f,k}_c = D^{f,k}_c / (D^r_{c,k} + D^p_{c,k} + ε)`, whose
//!   denominator uses a colour index k that does not exist there and never uses the D^r_c,
//!   D^p_c, D^f_c that eq. 5.11 defines for it. We read
//!   `W^{f,k}_c = D^{f,k}_c / (D^r_c + D^p_c + D^f_c + ε)`: the share of everything the colour
//!   depends on that comes from feature k (Sen & Darabi's formulation; the NVIDIA reference
//!   implementation does the same). Only this reading keeps β in [0, 1] as §5.1.3 states
//!   ("All values of α and β are always between 0 and 1"), since D^{f,k}_c ≤ D^f_c.
//! * **Eqs. 5.9 / 5.14: t** is the iteration index, 0 for the first (box 55) to 3 for the last
//!   (box 7); "(1 + 0.1t) ... increase[s] the fractional contribution weight with increasing
//!   filter iteration t".
//! * **ε** in eqs. 5.8, 5.12, 5.13 is [`EPSILON`] = 1e-10 bits: it only matters when every
//!   dependency is 0 (then W = 0, α = 1, β = 0).
//! * **Eq. 5.16** divides by (1 − W^r_c)², which is 0 when the colour depends on the random
//!   parameters only; we compute the reciprocal 1/(2σ_c²) = (1 − W^r_c)² / (2σ²), which is
//!   then 0 (no range or feature term: the neighbourhood is averaged), never a division by 0.

/// Screen position coordinates (x, y).
pub const POSITIONS: usize = 2;
/// Random parameters u, v, t, x, y, z (Table 5.1).
pub const RANDOMS: usize = 6;
/// Scene features (Table 5.1).
pub const FEATURES: usize = super::preprocess::FEATURES;
/// Colour channels.
pub const COLORS: usize = 3;
/// ε of eqs. 5.8, 5.12 and 5.13.
pub const EPSILON: f64 = 1e-10;

/// Every mutual information the weights need, in bits.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Dependencies {
    /// μ(c̄_k; r̄_l), `[k][l]` (eq. 5.4).
    pub color_random: [[f64; RANDOMS]; COLORS],
    /// μ(c̄_k; p̄_l), `[k][l]` (eq. 5.5).
    pub color_position: [[f64; POSITIONS]; COLORS],
    /// μ(c̄_l; f̄_k), `[l][k]` (eq. 5.10 and D^f_{c,l}).
    pub color_feature: [[f64; FEATURES]; COLORS],
    /// μ(f̄_k; r̄_l), `[k][l]` (eq. 5.6).
    pub feature_random: [[f64; RANDOMS]; FEATURES],
    /// μ(f̄_k; p̄_l), `[k][l]` (eq. 5.7).
    pub feature_position: [[f64; POSITIONS]; FEATURES],
}

/// The weights of eq. 5.2 for one pixel and the fractional contributions behind them.
#[derive(Clone, Debug, PartialEq)]
pub struct Weights {
    /// α_k, eq. 5.9.
    pub alpha: [f32; COLORS],
    /// β_k, eq. 5.14.
    pub beta: [f32; FEATURES],
    /// W^r_{c,k}, eq. 5.8.
    pub w_r_ck: [f32; COLORS],
    /// W^r_c, eq. 5.15.
    pub w_r_c: f32,
    /// W^{f,k}_c, eq. 5.12.
    pub w_c_fk: [f32; FEATURES],
    /// W^r_{f,k}, eq. 5.13.
    pub w_r_fk: [f32; FEATURES],
}

/// max(1 − (1 + 0.1t)·W, 0), the factor of eqs. 5.9 and 5.14, in [0, 1] for W in [0, 1].
#[inline]
fn damp(w: f64, t: u32) -> f64 {
    (1.0 - (1.0 + 0.1 * t as f64) * w).clamp(0.0, 1.0)
}

/// Non-negative and finite (a mutual information estimate that is not is taken as 0).
#[inline]
fn clean(d: f64) -> f64 {
    if d.is_finite() && d > 0.0 { d } else { 0.0 }
}

/// Eqs. 5.4-5.15 for iteration `t` (0-based).
pub fn weights(d: &Dependencies, t: u32) -> Weights {
    let sum = |v: &[f64]| v.iter().map(|&x| clean(x)).sum::<f64>();
    // Eqs. 5.4, 5.5 and D^f_{c,k}.
    let d_r_ck: [f64; COLORS] = std::array::from_fn(|k| sum(&d.color_random[k]));
    let d_p_ck: [f64; COLORS] = std::array::from_fn(|k| sum(&d.color_position[k]));
    let d_f_ck: [f64; COLORS] = std::array::from_fn(|k| sum(&d.color_feature[k]));
    // Eq. 5.10: D^{f,k}_c = Σ_l μ(c_l; f_k).
    let d_c_fk: [f64; FEATURES] =
        std::array::from_fn(|k| (0..COLORS).map(|l| clean(d.color_feature[l][k])).sum());
    // Eq. 5.11.
    let (d_r_c, d_p_c, d_f_c) = (
        d_r_ck.iter().sum::<f64>(),
        d_p_ck.iter().sum::<f64>(),
        d_f_ck.iter().sum::<f64>(),
    );
    // Eq. 5.8 and 5.9.
    let w_r_ck: [f64; COLORS] =
        std::array::from_fn(|k| (d_r_ck[k] / (d_r_ck[k] + d_p_ck[k] + EPSILON)).clamp(0.0, 1.0));
    let alpha = w_r_ck.map(|w| damp(w, t) as f32);
    // Eq. 5.12 (reading in the module docs).
    let all = d_r_c + d_p_c + d_f_c + EPSILON;
    let w_c_fk: [f64; FEATURES] = std::array::from_fn(|k| (d_c_fk[k] / all).clamp(0.0, 1.0));
    // Eqs. 5.6, 5.7, 5.13, 5.14.
    let w_r_fk: [f64; FEATURES] = std::array::from_fn(|k| {
        let r = sum(&d.feature_random[k]);
        let p = sum(&d.feature_position[k]);
        (r / (r + p + EPSILON)).clamp(0.0, 1.0)
    });
    let beta: [f32; FEATURES] = std::array::from_fn(|k| (w_c_fk[k] * damp(w_r_fk[k], t)) as f32);
    // Eq. 5.15.
    let w_r_c = (w_r_ck.iter().sum::<f64>() / COLORS as f64) as f32;
    Weights {
        alpha,
        beta,
        w_r_ck: w_r_ck.map(|w| w as f32),
        w_r_c,
        w_c_fk: w_c_fk.map(|w| w as f32),
        w_r_fk: w_r_fk.map(|w| w as f32),
    }
}

/// σ² of eq. 5.17: 8σ²_8 / spp.
pub fn base_variance(sigma2_8: f32, spp: u32) -> f64 {
    8.0 * sigma2_8 as f64 / spp.max(1) as f64
}

/// 1 / (2σ_c²) = 1 / (2σ_f²) of eq. 5.16 with σ² from eq. 5.17, as (1 − W^r_c)² / (2σ²).
pub fn inverse_two_sigma2(w_r_c: f32, sigma2: f64) -> f64 {
    let one_minus = (1.0 - w_r_c as f64).clamp(0.0, 1.0);
    one_minus * one_minus / (2.0 * sigma2)
}
