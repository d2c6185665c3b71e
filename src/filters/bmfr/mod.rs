//! Blockwise feature regression, a single-frame adaptation of BMFR (Koskela, Immonen, Mäkitalo,
//! Foi, Viitanen, Jääskeläinen, Kultala, Takala, "Blockwise Multi-Order Feature Regression for
//! Real-Time Path-Tracing Reconstruction", ACM TOG 38(5), 2019): settings here, the OpenCL
//! kernels of kernels/filters/bmfr.cl in `device.rs`, and the plain Rust reference of the same
//! operations in the same order in `reference.rs`.
//!
//! Per block of `block_size`² pixels, a least-squares fit of the noisy light to per-pixel
//! features (paper §3): the light divided by the first-hit albedo (both direct and indirect
//! are reflected by it; the albedo mean is noise-free after a few samples, so texture comes back
//! exactly when it is multiplied back), fitted as a linear combination of
//! `1, n_x, n_y, n_z, p_x, p_y, p_z, p_x², p_y², p_z²` (mean shading normal, mean first-hit
//! world position rescaled to [0, 1] by the block's minimum and maximum, as the paper does),
//! and optionally the first-hit depth (rescaled the same way), the albedo ("texture") and the
//! albedo of the second hit ("texture2") of our FilterVector. Direct and indirect light are
//! fitted separately (six right-hand sides of one factorisation): their dependence on the
//! features differs (shadow edges against colour bleeding).
//!
//! The fit is a Householder QR of the block's `pixels × (features + 6)` matrix in local memory,
//! one work-group per block (paper §3.2, Algorithm 1), then back-substitution per right-hand
//! side. On CPU devices (`packed_fit`, kernels/filters/bmfr_fit_packed.cl) one work-item per
//! block does the same float operations with the work-group's work-items as float16 lanes:
//! the same bytes, 2.4-5.8x faster on PoCL (results/README.md). Sky pixels and pixels outside the image are zero rows (they take no part). A small
//! noise, uniform in ±`noise`/2 from a counter-based hash of (pixel, feature), is added to the
//! feature columns before the factorisation (the paper's stochastic regularisation, §3.3): a
//! block whose features are collinear (a flat wall: constant normal, one position axis
//! constant) still has a well-posed fit, and evaluating without the noise only drops its tiny
//! share.
//!
//! Seams. The paper shifts the block grid every frame and hides the seams by temporal
//! blending. One frame has no history, so this filter fits `grids` grids shifted by half a
//! block (1: none; 2: (0, 0) and (B/2, B/2); 4: every combination of 0 and B/2 in x and y) and
//! blends the fits per pixel with the weight `t(x) t(y) · min(1, m / (4 K))`: t is a tent that
//! is 1 at the block centre and 1/B at its edge, so each pixel is led by the grids whose block
//! is centred on it; m is the block's count of surface pixels and K the number of features,
//! so a block with few surface pixels (an image corner, a small object against the sky), whose
//! fit is nearly an interpolation of the noise, counts less.
//!
//! Fitted values are clamped below at 0 (as the paper does), multiplied by the albedo (clamped
//! below at [`ALBEDO_EPSILON`], the same clamp as the division). Kept by the fit as they are,
//! bit for bit, and no row of any fit (kernels/filters/bmfr.cl `bmfr_kept`): sky; lights seen directly
//! (their albedo is the emission's chromaticity, largest channel exactly 1, their indirect
//! light exactly 0, as paths end at emitters, and their direct light their emission, unless
//! `emission` took it out: clear glass whose samples all ended black is not one (reference.rs
//! `light`); fitted, a light spread a halo over its blocks: 4
//! grids on Cornell diffuse at 512², 8 spp, MSE-LUV 1.711 with, 1.534 without; surfaces of
//! albedo 1 in a channel, white texels and clear glass, are fitted); and pixels whose samples
//! did not all hit a surface (hits below the frame's spp: silhouettes against the sky,
//! out-of-focus edges), whose sky light divided by a
//! small mean albedo made outliers of their blocks' fits (outside_dof 512², 8 spp, MSE-LUV:
//! 34.5 against 20.4 unfiltered before, in the quality study of results/README.md; 12.3
//! against 20.8 unfiltered after, at `render`'s default seed).
//!
//! Selection (`select`, select.rs): each pixel is then blended between the fit and its
//! unfiltered light by the fit's error and the light's variance, both estimated over a small
//! window from the residual and the two half buffers (even and odd samples, NFOR), so that
//! where the fit is biased the output follows the samples as they converge. With `nlm`
//! (nlm.rs) a third candidate joins the blend: non-local means of the light, whose error is
//! estimated by filtering each half buffer alone, so that where the fit is biased the output
//! follows a smoothed light rather than the noisy samples. The non-local means also cover the
//! sky and the partly covered pixels that the fit keeps (nlm.rs `OPEN`), each averaged with
//! its own kind only and blended with its unfiltered light alone: through a lens these are as
//! noisy as the surfaces (Outside DOF 512², 8 spp: MSE-LUV 3.07 → 1.78, results/README.md).
//! With `open_margin` (on with a thin lens; nlm.rs, "Open margin") a surface pixel beside an
//! open one counts as open too: out of focus the partly covered band is wide, and a pixel in
//! it whose few samples all hit the surface holds the band's mix.
//!
//! Outliers (`outliers`, outliers.rs): before everything else, a surface pixel whose light
//! stands far above its neighbours' in one half buffer only (a single sample's firefly) takes
//! its other half's light, so that it bends no fit and vouches for nothing in the selection.
//! With `select_relative` (nlm.rs, "Relative sums") the selection's window sums weigh each
//! pixel's errors relative to its light, so that dark pixels beside bright ones decide for
//! themselves.
//!
//! Albedo prefilter (`albedo_prefilter`, prefilter.rs; on with a thin lens): before the fit,
//! each pixel's mean albedo is averaged with the neighbours' whose albedo differs by no more
//! than the two means' noise explains, so that a defocused texture's noisy mean is not
//! multiplied back into the output unfiltered; with `prefilter_geometry` the normal, depth and
//! position are averaged too, so that the fit cannot reproduce the light's noise through them
//! (a defocused light's edge: the share of a pixel's samples that hit the light moves its mean
//! position and its light together).

mod device;
pub mod emission;
pub mod guided;
pub mod nlm;
pub mod outliers;
pub mod prefilter;
mod reference;
pub mod select;

use std::sync::Arc;

use anyhow::{Result, bail};

use super::{Auto, FilterKind, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::{Output, OutputSet};
use crate::render::{FrameInfo, SceneInfo};
pub use device::{BmfrKernel, emission_local_bytes};
pub use nlm::{MAX_NLM_PATCH, MAX_NLM_RADIUS};
pub use prefilter::MAX_ALBEDO_RADIUS;
pub use reference::{kept, reference};

/// Albedo channels are clamped below at this before the light is divided by them (and the same
/// clamp is multiplied back), as in the à-trous filter.
pub const ALBEDO_EPSILON: f32 = 1.0e-3;

/// Right-hand sides of the fit: direct rgb and indirect rgb, each divided by the albedo.
pub const TARGETS: usize = 6;

/// Work-items per block: each holds `block_size² / WORK_GROUP` rows of the block's matrix.
/// 64 rather than the paper's 256 (a GPU choice): on PoCL (2 cores, loaded machine, 256 x 256,
/// 8 spp Cornell diffuse) one grid took 49-64 ms against 63-91 ms with 256, four grids
/// 214-259 ms against 246-488 ms: fewer work-items leave shorter serial sums over the
/// work-items' partial dot products.
pub const WORK_GROUP: u32 = 64;

/// A pivot |R_jj| at or below this gives weight 0 to its feature: the column is a combination
/// of the others even with the regularisation noise (a block with fewer surface pixels than
/// features). The noise alone gives a column norm of about noise · √(m / 12) ≈ 3e-3 for one
/// pixel at the default noise, rounding about 1e-6 · the column norm (≤ 32).
pub const PIVOT_MIN: f32 = 1.0e-4;

/// Block sizes the kernel supports: block_size² must be a multiple of [`WORK_GROUP`]. The
/// matrix (block_size² × up to 23 floats, 368 KiB at 64) is in local memory where it fits,
/// else in global memory (`local_matrix`).
pub const BLOCK_SIZES: [u32; 3] = [16, 32, 64];

crate::filter_settings! {
    /// The regression filter's parameters.
    pub struct BmfrSettings, flags "bmfr-" {
        /// Side of the square blocks fitted, pixels: 16, 32 or 64 (the paper's 32).
        pub block_size: u32 = 32,
        /// Block grids, shifted by half a block, fitted and blended per pixel: 1, 2 or 4.
        pub grids: u32 = 4,
        /// Amplitude of the regularisation noise added to the features (the paper's 1e-2).
        pub noise: f64 = 0.01,
        /// Also fit to the first-hit depth (rescaled per block like the positions).
        pub depth: bool = false,
        /// Also fit to the first-hit albedo ("texture").
        pub texture: bool = false,
        /// Also fit to the albedo of the second hit ("texture2").
        pub texture2: bool = false,
        /// Blend each pixel between the fit and its unfiltered light by the errors the two
        /// half buffers estimate (select.rs), so the error keeps falling with spp.
        pub select: bool = true,
        /// Half width of the window the selection's estimates are summed over, pixels.
        pub select_radius: u32 = 4,
        /// κ, the trust in the fit: the blend weight is min(1, κ V / R) (select.rs); with
        /// `nlm`, the fit's error estimate is divided by κ (nlm.rs).
        pub select_scale: f64 = 2.0,
        /// c, the floor of the fit's evidence (with `nlm`): each pixel's R − V enters the
        /// window's sum no lower than −c × the window's mean V, so that a few pixels whose
        /// noise the fit reproduces cannot vouch for the fit over their whole window (nlm.rs);
        /// 0: no floor; auto: 6 with a thin lens and `select_relative` off, else none
        /// (nlm.rs, "Relative sums").
        pub select_floor: Auto<f32> = Auto::Auto,
        /// A third candidate of the selection: non-local means of the light, its error
        /// estimated by filtering each half buffer alone (nlm.rs).
        pub nlm: bool = true,
        /// Replace the light of each surface pixel that stands far above its neighbours' in
        /// one half buffer only (a single sample's firefly) by its other half's, before the
        /// fit (outliers.rs).
        pub outliers: bool = true,
        /// τ of the outlier test: a pixel is an outlier when its luminance exceeds τ times
        /// its neighbours' (the 3 × 3 largest or the 7 × 7 mean) and one half's does not
        /// (outliers.rs).
        pub outlier_ratio: f64 = 30.0,
        /// With `nlm`: each pixel's terms of the selection's window sums divided by the square
        /// of its light's level (the larger of the fit and the non-local means, plus a small
        /// ε), so that dark pixels count as much as bright ones (nlm.rs, "Relative sums").
        pub select_relative: bool = true,
        /// Count a surface pixel with an open pixel (sky, or samples that did not all hit a
        /// surface) among its eight neighbours as open in the non-local means and the
        /// selection: out of focus, a silhouette's band of partly covered pixels is wide, and a
        /// pixel in it whose few samples all hit the surface holds the band's mix, not the
        /// surface's light (nlm.rs, "Open margin"). auto: on when the camera has a thin lens.
        pub open_margin: Auto<bool> = Auto::Auto,
        /// Half width of the non-local means' search window, pixels.
        pub nlm_radius: u32 = 5,
        /// Half width of the window of the two half buffers' non-local means, which only
        /// estimate the candidate's error (nlm.rs), pixels; `nlm_radius` where that is smaller.
        pub nlm_estimate_radius: u32 = 3,
        /// Half width of the non-local means' patches, pixels: 1 (3 × 3 patches) to 3 (7 × 7;
        /// nlm.rs, "Patches").
        pub nlm_patch: u32 = 2,
        /// k of the non-local means' patch distance: how many standard deviations of a
        /// difference count as noise; auto: 0.8 with a thin lens, 0.7 with a pinhole camera
        /// (nlm.rs).
        pub nlm_k: Auto<f64> = Auto::Auto,
        /// Filter each pixel's mean albedo by the neighbours whose albedo differs by no more
        /// than its noise explains, before the fit (prefilter.rs): out of focus each lens
        /// sample sees another texel. auto: on when the camera has a thin lens.
        pub albedo_prefilter: Auto<bool> = Auto::Auto,
        /// Half width of the albedo prefilter's window, pixels. Measured at k = 1 (MSE-LUV,
        /// 512², 8 spp): radius 1 / 2 / 5 / 7 gave 6.08 / 5.72 / 6.03 / 6.33 on
        /// cornell_diffuse_dof; 3 was 0.2-1.1 % worse than 2 on the four depth-of-field scenes.
        pub albedo_radius: u32 = 2,
        /// With the albedo prefilter, also average the first hit's normal, depth and
        /// position over its window, each pixel with the neighbours whose albedo, normal and
        /// depth differ by no more than their noise explains (prefilter.rs): out of focus
        /// their noise is the light's, and the fit would reproduce it.
        pub prefilter_geometry: bool = true,
        /// k of the geometry's distance: how many standard deviations of a difference of
        /// albedo, normal or depth count as noise (prefilter.rs).
        pub geometry_k: f64 = prefilter::GEOMETRY_K as f64,
        /// The fit with one work-item per block, its rows on float16 lanes
        /// (kernels/filters/bmfr_fit_packed.cl), and its application with one work-item per
        /// 16 pixels of a row (bmfr_apply_packed.cl): the same bytes as the work-group fit
        /// (paper Algorithm 1) and the per-pixel application, which PoCL runs on scalar
        /// floats. auto: on CPU devices whose local memory holds the block's matrix.
        pub packed_fit: Auto<bool> = Auto::Auto,
        /// The work-group fit keeps its block's matrix (block_size² × (features + 6) floats)
        /// in local memory; off, in a global buffer, one slice per block, as the paper's own
        /// code does: the same bytes. auto: where it fits (not at block_size 32 on NVIDIA's
        /// 48 KiB), and always with the packed fit.
        pub local_matrix: Auto<bool> = Auto::Auto,
        /// The non-local means (the selection's candidate, the albedo prefilter and the
        /// emission's) and the selection's window sums on float16 lanes, one work-item per
        /// 14 × 32, 16 × 1, 12 × 16 or 16 × 1 pixels (kernels/filters/bmfr_nlm_packed.cl,
        /// bmfr_prefilter_packed.cl, bmfr_emission.cl, bmfr_select_packed.cl): the same float
        /// operations in the same order as the kernels with one work-item per pixel, which
        /// PoCL runs on scalar floats. auto: on CPU devices.
        pub packed_nlm: Auto<bool> = Auto::Auto,
        /// Take the light of lights seen directly (the render's emission output) out of the
        /// light the fit, the selection and the non-local means see, and filter it apart by
        /// non-local means over its own half buffers (emission.rs): a light's edge no longer
        /// bends the fit. auto: on when the camera has a thin lens or the scene has sphere or
        /// triangle lights (a camera ray can hit them; the sky alone is left in the fit).
        pub emission: Auto<bool> = Auto::Auto,
        /// Half width of the emission's non-local means' search window, pixels.
        pub emission_radius: u32 = 7,
        /// k of the emission's patch distance: how many standard deviations of a difference
        /// count as noise.
        pub emission_k: f64 = 0.7,
        /// Extra weight of the pixel's own E in the emission's non-local means, on top of the 1
        /// its window gives it and at most 1 to any other pixel (emission.rs, "A light's edge
        /// through a pinhole"); auto: 2 with a pinhole camera, 0 with a thin lens.
        pub emission_self_weight: Auto<f64> = Auto::Auto,
        /// Weight of the patches' mean-difference test in the emission's patch distance: the
        /// taps' differences summed, squared, against their summed variances, which sees a
        /// patch shifted across a light's one-pixel edge where each tap's own noise hides it
        /// at a few samples per pixel (emission.rs, "A few samples per pixel"); 0: none.
        /// auto: 0.25 with a pinhole camera, 0 with a thin lens.
        pub emission_mean_test: Auto<f64> = Auto::Auto,
        /// With `nlm`: a fourth candidate of the selection, a guided filter of the light on the
        /// normal and position over sliding windows, its error estimated by filtering each
        /// half buffer alone (guided.rs). Off by default: relMSE lower on 11 of 13 scenes (by
        /// up to 12 %) but higher on two (by up to 2.7 %), for 35-45 % more of bmfr's time on
        /// grids on PoCL (results/README.md, bmfr, "Stop 57" and "Stop 58"; `bench` shows it
        /// as bmfr-guided).
        pub guided: bool = false,
        /// Half width of the guided filter's windows, pixels.
        pub guided_radius: u32 = 3,
        /// ε, the ridge added to the guides' covariance in each window (guided.rs).
        pub guided_ridge: f64 = 1.0e-4,
        /// What the first-hit positions are multiplied by before they guide; auto: 1 / the
        /// scene's size, so that ε means the same in every scene.
        pub guided_scale: Auto<f64> = Auto::Auto,
    }
}

impl BmfrSettings {
    /// The outputs the filter reads.
    pub fn needs(&self) -> OutputSet {
        let mut outputs = vec![Output::Colour, Output::Features, Output::Position];
        // With `emission`, bmfr_reflected reads the odd half (and writes it less the
        // emission's, for the selection); with `outliers`, bmfr_outliers compares the halves.
        if self.select || self.splits_emission() || self.outliers {
            outputs.push(Output::Halves);
        }
        if self.prefilters_albedo() {
            outputs.push(Output::Variance);
        }
        if self.splits_emission() {
            outputs.push(Output::Emission);
        }
        OutputSet::of(&outputs)
    }

    /// Whether the non-local means candidate runs (it is part of the selection).
    pub fn uses_nlm(&self) -> bool {
        self.select && self.nlm
    }

    /// The half buffers' search radius: `nlm_estimate_radius`, at most `nlm_radius`.
    pub fn estimate_radius(&self) -> u32 {
        self.nlm_estimate_radius.min(self.nlm_radius)
    }

    /// Whether the albedo prefilter runs (`auto` reads as off until specialised).
    pub fn prefilters_albedo(&self) -> bool {
        self.albedo_prefilter.or(false)
    }

    /// Whether the light of lights seen directly is filtered apart (`auto` reads as off until
    /// specialised).
    pub fn splits_emission(&self) -> bool {
        self.emission.or(false)
    }

    /// The pixel's own extra weight in the emission's non-local means (`emission_self_weight`;
    /// auto: the pinhole camera's, as [`Bmfr`] resolves it without a lens).
    pub fn emission_self_weight(&self) -> f64 {
        self.emission_self_weight.or(emission::PINHOLE_SELF_WEIGHT)
    }

    /// The weight of the emission's mean-difference test (`emission_mean_test`; auto: the
    /// pinhole camera's, as [`Bmfr`] resolves it without a lens).
    pub fn emission_mean_test(&self) -> f64 {
        self.emission_mean_test.or(emission::PINHOLE_MEAN_TEST)
    }

    /// Whether surface pixels beside open pixels count as open (`open_margin`; `auto` reads
    /// as off until specialised).
    pub fn open_margin(&self) -> bool {
        self.open_margin.or(false)
    }

    /// c of the selection's floor (`select_floor`; auto: none, as [`Bmfr`] resolves it
    /// for a pinhole camera).
    pub fn select_floor(&self) -> f32 {
        self.select_floor.or(0.0)
    }

    /// k of the non-local means (`nlm_k`; auto: the pinhole camera's, as [`Bmfr`] resolves
    /// it without a lens).
    pub fn nlm_k(&self) -> f64 {
        self.nlm_k.or(nlm::PINHOLE_NLM_K)
    }

    /// The guided filter's position scale (`guided_scale`; auto: 1 until specialised to a
    /// scene's size).
    pub fn guided_scale(&self) -> f64 {
        self.guided_scale.or(1.0)
    }

    /// Number of features K (columns of the fit, the constant included).
    pub fn features(&self) -> usize {
        10 + self.depth as usize + 3 * self.texture as usize + 3 * self.texture2 as usize
    }

    pub fn validate(&self) -> Result<()> {
        if !BLOCK_SIZES.contains(&self.block_size) {
            bail!(
                "the bmfr block_size must be one of {BLOCK_SIZES:?} pixels, got {}",
                self.block_size
            );
        }
        if ![1, 2, 4].contains(&self.grids) {
            bail!("the bmfr grids must be 1, 2 or 4, got {}", self.grids);
        }
        if self.select_radius > MAX_SELECT_RADIUS {
            bail!(
                "the bmfr select_radius must be at most {MAX_SELECT_RADIUS} pixels, got {}",
                self.select_radius
            );
        }
        if !(self.select_scale >= 1.0 && self.select_scale <= 100.0) {
            bail!(
                "the bmfr select_scale must be a number in [1, 100], got {}",
                self.select_scale
            );
        }
        if !(self.select_floor() >= 0.0 && self.select_floor() <= 1000.0) {
            bail!(
                "the bmfr select_floor must be a number in [0, 1000], got {}",
                self.select_floor()
            );
        }
        if self.nlm_radius > MAX_NLM_RADIUS {
            bail!(
                "the bmfr nlm_radius must be at most {MAX_NLM_RADIUS} pixels, got {}",
                self.nlm_radius
            );
        }
        if !(1..=MAX_NLM_PATCH).contains(&self.nlm_patch) {
            bail!(
                "the bmfr nlm_patch must be 1 to {MAX_NLM_PATCH} pixels, got {}",
                self.nlm_patch
            );
        }
        if !(self.nlm_k() > 0.0 && self.nlm_k() <= 100.0) {
            bail!(
                "the bmfr nlm_k must be a number in (0, 100], got {}",
                self.nlm_k()
            );
        }
        if self.albedo_radius > MAX_ALBEDO_RADIUS {
            bail!(
                "the bmfr albedo_radius must be at most {MAX_ALBEDO_RADIUS} pixels, got {}",
                self.albedo_radius
            );
        }
        if self.emission_radius > emission::MAX_EMISSION_RADIUS {
            bail!(
                "the bmfr emission_radius must be at most {} pixels, got {}",
                emission::MAX_EMISSION_RADIUS,
                self.emission_radius
            );
        }
        if !(self.emission_k > 0.0 && self.emission_k <= 100.0) {
            bail!(
                "the bmfr emission_k must be a number in (0, 100], got {}",
                self.emission_k
            );
        }
        let own = self.emission_self_weight();
        if !(0.0..=1000.0).contains(&own) {
            bail!("the bmfr emission_self_weight must be a number in [0, 1000], got {own}");
        }
        let mean_test = self.emission_mean_test();
        if !(0.0..=100.0).contains(&mean_test) {
            bail!("the bmfr emission_mean_test must be a number in [0, 100], got {mean_test}");
        }
        if !(self.geometry_k > 0.0 && self.geometry_k <= 1000.0) {
            bail!(
                "the bmfr geometry_k must be a number in (0, 1000], got {}",
                self.geometry_k
            );
        }
        if !(self.outlier_ratio >= 1.0 && self.outlier_ratio <= 1.0e6) {
            bail!(
                "the bmfr outlier_ratio must be a number in [1, 1e6], got {}",
                self.outlier_ratio
            );
        }
        if !(1..=MAX_GUIDED_RADIUS).contains(&self.guided_radius) {
            bail!(
                "the bmfr guided_radius must be 1 to {MAX_GUIDED_RADIUS} pixels, got {}",
                self.guided_radius
            );
        }
        if !(self.guided_ridge > 0.0 && self.guided_ridge <= 1.0) {
            bail!(
                "the bmfr guided_ridge must be a number in (0, 1], got {}",
                self.guided_ridge
            );
        }
        let scale = self.guided_scale();
        if !(scale > 0.0 && scale.is_finite()) {
            bail!("the bmfr guided_scale must be a positive number, got {scale}");
        }
        if !(self.noise >= 0.0 && self.noise <= 1.0) {
            bail!(
                "the bmfr noise must be a number in [0, 1], got {}",
                self.noise
            );
        }
        Ok(())
    }
}

/// The shift of grid `g` of `grids`, pixels: block (bx, by) of the grid covers
/// x in [bx·B − ox, (bx + 1)·B − ox) (kernels/filters/bmfr.cl `bmfr_grid_offset`).
pub fn grid_offset(g: u32, grids: u32, block: u32) -> (i32, i32) {
    let half = (block / 2) as i32;
    match grids {
        2 => (g as i32 * half, g as i32 * half),
        4 => ((g & 1) as i32 * half, (g >> 1) as i32 * half),
        _ => (0, 0),
    }
}

/// Blocks of a grid shifted by `offset` across a `width` × `height` image: (across, down).
pub fn grid_blocks(width: u32, height: u32, block: u32, offset: (i32, i32)) -> (u32, u32) {
    (
        (width + offset.0 as u32).div_ceil(block),
        (height + offset.1 as u32).div_ceil(block),
    )
}

/// The largest count of blocks of any grid: the stride of one grid in the weight buffers.
pub fn blocks_per_grid(width: u32, height: u32, block: u32) -> u32 {
    (width.div_ceil(block) + 1) * (height.div_ceil(block) + 1)
}

/// The largest window half width of the guided filter (a 17 × 17 window).
pub const MAX_GUIDED_RADIUS: u32 = 8;

/// The largest window half width of the selection (a 33 × 33 window).
pub const MAX_SELECT_RADIUS: u32 = 16;

/// Floats per block in the block-information buffer: the minimum and 1 / range of the four
/// rescaled features (position xyz, depth), and the count of surface pixels.
pub const INFO_FLOATS: usize = 9;

/// The regression filter in the registry.
pub struct Bmfr;

impl FilterKind for Bmfr {
    type Settings = BmfrSettings;
    const NAME: &'static str = "bmfr";
    const SUMMARY: &'static str = "blockwise feature regression, single-frame BMFR of Koskela et al. 2019 \
         (on the device)";

    fn check(s: &BmfrSettings) -> Result<()> {
        s.validate()
    }

    fn specialise(s: &mut BmfrSettings, scene: &SceneInfo) -> Vec<String> {
        let mut notes = Vec::new();
        let lens = scene.camera.lens_radius > 0.0;
        if s.albedo_prefilter.is_auto() {
            s.albedo_prefilter = Auto::Set(lens);
            notes.push(format!(
                "albedo_prefilter = {lens}: {}",
                if lens {
                    "a thin lens, so defocused pixels' mean albedo is noisy (prefilter.rs)"
                } else {
                    "a pinhole camera, so every pixel's mean albedo is exact after a few samples"
                }
            ));
        }
        if s.emission.is_auto() {
            let lights = scene.has("HAS_SPHERE_LIGHTS") || scene.has("HAS_TRIANGLE_LIGHTS");
            s.emission = Auto::Set(lens || lights);
            notes.push(format!(
                "emission = {}: {}",
                lens || lights,
                if lens {
                    "a thin lens, so a defocused light's edge spreads over pixels whose samples \
                     partly hit it (emission.rs)"
                } else if lights {
                    "sphere or triangle lights, whose edges would bend the fit where the camera \
                     sees them (emission.rs)"
                } else {
                    "a pinhole camera and no light but the sky"
                }
            ));
        }
        if s.emission_self_weight.is_auto() {
            let own = if lens { 0.0 } else { emission::PINHOLE_SELF_WEIGHT };
            s.emission_self_weight = Auto::Set(own);
            notes.push(format!(
                "emission_self_weight = {own}: {}",
                if lens {
                    "a thin lens, so a defocused light's edge is smooth along and across"
                } else {
                    "a pinhole camera, so a light's one-pixel edge matches along its length \
                     whatever its coverage (emission.rs)"
                }
            ));
        }
        if s.emission_mean_test.is_auto() {
            let test = if lens { 0.0 } else { emission::PINHOLE_MEAN_TEST };
            s.emission_mean_test = Auto::Set(test);
            notes.push(format!(
                "emission_mean_test = {test}: {}",
                if lens {
                    "a thin lens, so a defocused light's edge changes little from pixel to pixel"
                } else {
                    "a pinhole camera, so a patch shifted across a light's one-pixel edge must \
                     not match at a few samples per pixel (emission.rs)"
                }
            ));
        }
        if s.open_margin.is_auto() {
            s.open_margin = Auto::Set(lens);
            notes.push(format!(
                "open_margin = {lens}: {}",
                if lens {
                    "a thin lens, so defocused silhouettes leave wide bands of partly covered \
                     pixels (nlm.rs, \"Open margin\")"
                } else {
                    "a pinhole camera, so a silhouette's partly covered pixels are one pixel wide"
                }
            ));
        }
        if s.guided && s.guided_scale.is_auto() {
            let size = scene.scene_size as f64;
            let scale = if size > 0.0 && size.is_finite() { 1.0 / size } else { 1.0 };
            s.guided_scale = Auto::Set(scale);
            notes.push(format!("guided_scale = {scale:e}: 1 / the scene's size (guided.rs)"));
        }
        if s.nlm_k.is_auto() {
            s.nlm_k = Auto::Set(if lens { nlm::LENS_NLM_K } else { nlm::PINHOLE_NLM_K });
            notes.push(if lens {
                format!(
                    "nlm_k = {}: a thin lens, so the light is smooth over wider patches (nlm.rs)",
                    nlm::LENS_NLM_K
                )
            } else {
                format!("nlm_k = {}: a pinhole camera (nlm.rs)", nlm::PINHOLE_NLM_K)
            });
        }
        if s.select_floor.is_auto() {
            let floor = lens && !s.select_relative;
            s.select_floor = Auto::Set(if floor { nlm::LENS_SELECT_FLOOR } else { 0.0 });
            notes.push(if floor {
                format!(
                    "select_floor = {}: a thin lens, so a defocused light's edge has pixels whose \
                     noise the fit reproduces, and absolute window sums (nlm.rs)",
                    nlm::LENS_SELECT_FLOOR
                )
            } else if lens {
                "select_floor = 0: the relative sums let the pixels beside a defocused light's \
                 edge decide for themselves (nlm.rs, \"Relative sums\")"
                    .to_string()
            } else {
                "select_floor = 0: a pinhole camera (the floor cost error there, nlm.rs)".to_string()
            });
        }
        notes
    }

    /// Colour, normals and albedos of F, and the mean world positions; with `select`, the
    /// odd samples' half buffer.
    fn needs(s: &BmfrSettings) -> OutputSet {
        s.needs()
    }

    fn prepare(
        s: &BmfrSettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        Ok(Box::new(BmfrKernel::new(
            gpu.clone(),
            s,
            frame.width,
            frame.height,
        )?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn specialised(lens_radius: f32, effects: &[&str]) -> BmfrSettings {
        let mut scene = SceneInfo::unknown();
        scene.camera.lens_radius = lens_radius;
        for e in effects {
            scene.effects.insert(e.to_string(), true);
        }
        let mut s = BmfrSettings::default();
        Bmfr::specialise(&mut s, &scene);
        s
    }

    /// `emission` auto: on through a lens, and through a pinhole where the scene has lights a
    /// camera ray can hit (not for the sky alone); the self weight and the mean-difference
    /// test only through a pinhole.
    #[test]
    fn emission_follows_the_lens_and_the_lights() {
        let s = specialised(0.0, &["HAS_ENV"]);
        assert!(!s.splits_emission() && !s.needs().contains(Output::Emission));
        for light in ["HAS_SPHERE_LIGHTS", "HAS_TRIANGLE_LIGHTS"] {
            let s = specialised(0.0, &[light]);
            assert!(s.splits_emission() && s.needs().contains(Output::Emission), "{light}");
            assert_eq!(s.emission_self_weight(), emission::PINHOLE_SELF_WEIGHT);
            assert_eq!(s.emission_mean_test(), emission::PINHOLE_MEAN_TEST);
        }
        let s = specialised(0.05, &[]);
        assert!(s.splits_emission());
        assert_eq!(s.emission_self_weight(), 0.0);
        assert_eq!(s.emission_mean_test(), 0.0);
        // What the user sets stays.
        let mut s = BmfrSettings {
            emission: Auto::Set(false),
            emission_self_weight: Auto::Set(1.5),
            emission_mean_test: Auto::Set(0.0),
            ..Default::default()
        };
        Bmfr::specialise(&mut s, &SceneInfo::unknown());
        assert!(!s.splits_emission());
        assert_eq!(s.emission_self_weight(), 1.5);
        assert_eq!(s.emission_mean_test(), 0.0);
    }
}
