//! Lights seen directly, treated apart from the reflected light (`emission`; on with a thin
//! lens). The render's emission output (src/layout/outputs.rs `Output::Emission`) holds, per
//! pixel, the mean light of the emitters the camera ray hit E (part of F's direct light), the
//! share f of samples that hit one, and E over the odd-numbered samples alone.
//!
//! Why. Out of focus a light's edge spreads over a band of pixels, each of whose samples either
//! hit the light (E ≫ the reflected light) or the ceiling beside it. Fitted with the reflected
//! light, these pixels bend each block's fit, which spreads part of the light over the block's
//! pixels that saw none of it; the selection then trusts the fit there (results/README.md,
//! bmfr's light-edge analysis). So with `emission`:
//!
//! 1. [`reflected`] (kernels/filters/bmfr_emission.cl `bmfr_reflected`): the fit, the
//!    selection and the non-local means work on a copy of F whose direct light is less E, whose
//!    odd half is less E's odd half, and whose mean albedo is less the emitter samples' share of
//!    it, f · E / max(E) (a light's albedo is its emission's chromaticity, largest channel 1,
//!    kernels/render/materials.cl; exact when a pixel's emitter samples all hit lights of one
//!    colour): the mean over the samples of the albedo of the surface samples and 0 for the
//!    others, so that albedo times the fitted demodulated light is the reflected light's mean.
//!    A pixel all of whose samples hit a light keeps its albedo, so the fit keeps it out as
//!    before (`bmfr_light`).
//! 2. [`emission_nlm`] (`bmfr_emission_nlm`): E filtered by non-local means (Buades et al.
//!    2005, with the noise-aware distance of Rousselle et al. 2012 eq. 4) over a
//!    (2 `emission_radius` + 1)² window with (2 [`EMISSION_PATCH`] + 1)² patches of E's
//!    luminance, the variance of each pixel's mean from E's two half buffers, averaged over 3 × 3
//!    pixels; the result is added to the filtered reflected light. Along a defocused edge the
//!    patches find the pixels of the same coverage, so E is averaged along the edge, not
//!    across it. A pixel whose window holds no light is left alone (most of the image).
//! 3. Through a pinhole, the pixel's own E weighs `emission_self_weight` more than the window
//!    gives it ([`self_weight`]), and a patch whose taps differ one way from the pixel's more
//!    than their noise explains is kept apart ([`mean_test`]): see "A light's edge through a
//!    pinhole" and "A few samples per pixel" below.
//!
//! The kernels compute it in the box-filter form of non-local means: a patch term depends only
//! on the pixel a = p + t and the offset q − p, so for one offset each term is evaluated once
//! and summed along the patch's rows and then its columns, shared by the 25 patches that hold
//! it (in local memory over a work-group's tile, `bmfr_emission_nlm`; on 16 float lanes over a
//! work-item's 12 × 16 pixels on CPU devices, `bmfr_emission_nlm_packed`, `packed_nlm`). The
//! reference sums in their order: each patch row's taps left to right, then the rows. On the
//! 8-spp 512² frame of cornell_diffuse_dof (PoCL, 2 cores, `noisefree filter S.exr --filter bmfr
//! --repeat 5 --profile`, binaries alternating), the first kernel, 25 terms per pixel and
//! offset, took 155-162 ms; the box form in work-groups 44 ms; packed 6.1-6.3 ms
//! (conference_dof: 219-221, 64-67 and 11.7-12.0 ms; results/README.md, "Its cost").
//!
//! Measured on the 8-spp 512² frame of cornell_diffuse_dof at `render`'s seed, a scratch
//! prototype of these two steps (not in the repository) before the kernels: MSE-LUV / relMSE
//! 2.09 / 0.00593 without, 4.64 / 0.0101 with step 1 and E unfiltered (binomial noise of 8
//! samples on the partly covered pixels), 1.61 / 0.00255 with both at radius 7, k 0.7, 5 × 5
//! patches (radius 5, k 1, 3 × 3 patches: 1.85 / 0.00327; a Gaussian blur of E instead: 2.76 /
//! 0.0208 at σ 0.7, worse with σ, as it spreads the light over pixels that truly see none).
//!
//! **A light's edge through a pinhole** (stop 50). There the edge is one pixel wide, and the
//! light's inside, all of whose samples hit it, has no noise at all: two patches whose lit
//! pixels lie alike match exactly there, whatever the sub-pixel position of the edge in their
//! partly covered pixels, and these are the only pixels whose E carries it. Along a straight
//! edge that position is the same for the whole row, so averaging along it is right (the
//! conference's and cornell_plane's light panels). Along a sphere light's round rim it changes
//! from pixel to pixel, and 8 samples cannot tell 0.4 % coverage from 25 %: on the 8-spp 512²
//! frame of cornell_diffuse a rim pixel none of whose samples hit the light matched a pixel
//! two of whose did with the weight of itself (1.0), and came out with E 1.08 where the
//! reference's is about 0.04 (its relMSE term alone 8.8 % of the frame's). So the pixel's own
//! E, unbiased, weighs `emission_self_weight` more than the window gives it (where it has
//! weight 1, as its patch distance is at most 0, and no other pixel more than 1; auto: 4
//! through a pinhole at stop 50, 2 since stop 51's mean test, below; 0 through a lens, whose
//! defocused edges are smooth and wide). Measured on the 8-spp 512² AOV files of `noisefree
//! render S --spp 8 --filter bmfr --bmfr-emission=true --aovs F`, filtered with
//! `--bmfr-emission-self-weight W` (or `--bmfr-emission=false`) and compared against the
//! 2048-spp references; MSE-LUV / relMSE, self weight 0 → 4 (emission off, for comparison):
//! cornell_diffuse 1.107 / 0.00154 → 1.148 / 0.00126 (off: 1.332 / 0.00127), cornell_glossy
//! 4.003 / 0.00609 → 4.043 / 0.00583 (4.216 / 0.00577), cornell_plane 4.078 / 0.00632 → 4.171
//! / 0.00607 (4.798 / 0.00648), conference 2.661 / 0.00537 → 2.759 / 0.00531 (2.935 /
//! 0.00655); stop 50, without the mean test below.
//! In a scratch program (not in the repository) that swapped only the filtered E: keeping
//! only the pixel's own E where none of its samples hit a light (no filtering there) lost
//! MSE-LUV along the panels' straight edges (cornell_plane 4.910); E's variance from a
//! binomial model of each pixel's hits instead of the halves, 3 × 3 patches, or
//! Gaussian-weighted patch distances were worse on both metrics or on one. Through a lens the
//! same self weight made the depth-of-field frames worse on both metrics (cornell_diffuse_dof
//! 1.452 / 0.00235 → 1.582 / 0.00266, conference_dof and cornell_glossy_dof by 1-6 %).
//!
//! **A few samples per pixel** (stop 51). With the self weight of 4, cornell_diffuse's relMSE at 2
//! spp was 4x stop 49's (accuracy-time study, 0.0043 → 0.0181). The pixels: a one-pixel dark seam
//! (reference about 0.0003) along the straight top edge of the sphere light, where it meets the
//! ceiling, came out at 1.0-1.3 (relMSE terms (t − r)² / (r² + 0.01) near 100: the frame's 15
//! largest, 14 of them on the seam, held 21 % of its relMSE). The seam's samples all missed the
//! light; the row below, about 60 % covered, mostly had 1 of 2 on it. A 5 × 5 patch shifted one row
//! down differs from the seam pixel's in two tap rows by about half the light's luminance (0
//! against half, half against all); at 2 samples the variances there (the halves' estimate,
//! averaged over 3 × 3 pixels) are of the order of those differences squared, and the taps where
//! both sides agree but one carries variance give negative terms, so the taps' mean term came out
//! about 0.3 and the shifted patches matched with weights up to 0.95 (a scratch program that
//! printed the window's weights and each pixel's E, hits and variance; not in the repository). The
//! self weight cannot help there: it only weighs the seam pixel's own 0 against ten other pixels
//! that match as well. What the taps' terms lose is that all the differences have the same sign. So
//! [`mean_test`]: the taps' differences summed, S, and their variances summed, V (S² has
//! expectation V where both patches see the same light); the patch distance is the larger of the
//! taps' mean term and `emission_mean_test` · (S² − V) / (k² V). Shifted by one row across the
//! edge, S² is about 12 times V, the distance at the test's weight of 0.25 about 6 and the weight
//! about 0.003 (worked by hand from that program's values at pixel (270, 11) of the 2-spp frame);
//! shifted along the edge, S is noise around 0. Measured on the AOV files of `noisefree render
//! scenes/cornell_diffuse.toml --spp N --filter bmfr --bmfr-emission=true --aovs F` at 512²,
//! filtered with `--bmfr-emission-mean-test T --bmfr-emission-self-weight W` (MSE-LUV / relMSE,
//! every pixel counted; results/README.md, "Stop 51"): at 2 spp, T 0, W 4 (stop 50): 4.761 /
//! 0.0253; T 0.25, W 4: 3.530 / 0.00411; T 0.25, W 2: 3.443 / 0.00446 (emission off: 5.592 /
//! 0.00377); at 4 spp 2.241 / 0.00358 → 1.938 / 0.00206 (off 2.560 / 0.00221); at 8, 16 and 32 spp
//! within 1.5 % of stop 50 in relMSE (+0.8 % at 8) and 0.7-2.2 % better in MSE-LUV. With the test,
//! a self weight of 4 instead of 2 gained relMSE only at 2-8 spp and lost it from 16 spp on, and
//! lost MSE-LUV everywhere, and the test's weight of 0.5 instead of 0.25 gave about the same; hence
//! 2 and 0.25. On the other pinhole scenes' 8-spp frames (cornell_glossy, cornell_plane,
//! conference, two_lights_shadows) both metrics moved by at most 1.5 %, mostly down. Through a lens
//! the test is off: on cornell_diffuse_dof it raised relMSE 0.00235 → 0.00263 (0.25), as the
//! defocused edge's neighbouring patches truly differ a little, one way. It costs the packed kernel
//! two more box sums: 4.9 → 6.4 ms on cornell_diffuse's 8-spp frame (`noisefree filter F --filter
//! bmfr --bmfr-emission-mean-test T --repeat 7 --profile`, T 0 and 0.25 alternating).

use anyhow::Result;
use rayon::prelude::*;

use super::BmfrSettings;
use crate::layout::outputs::BufferId;
use crate::layout::{FilterVector, Float4};
use crate::render::Frame;

/// Half width of the patches the emission's non-local means compare (a 5 × 5 patch).
pub const EMISSION_PATCH: i32 = 2;

/// Side of the emission's non-local means' square work-groups (kernels/filters/
/// bmfr_emission.cl `bmfr_emission_nlm`): the tile whose patch terms are shared through local
/// memory.
pub const EMISSION_TILE: u32 = 16;

/// Lines per image row of the emission's inputs (kernels/filters/bmfr_emission.cl: E's rgb, its
/// luminance, its variance, inside).
pub const EMISSION_LINES: u32 = 6;

/// Rows of pixels per work-item of the packed emission kernel (`bmfr_emission_nlm_packed`,
/// `packed_nlm`); its lanes are 16 pixels of each row, 12 of them its own.
pub const EMISSION_PACKED_ROWS: u32 = 16;

/// Pixels of a row per work-item of the packed emission kernel (16 lanes less the patch's
/// border either side).
pub const EMISSION_PACKED_STEP: u32 = 16 - 2 * EMISSION_PATCH as u32;

/// The largest `emission_radius` (a 25 × 25 window).
pub const MAX_EMISSION_RADIUS: u32 = 12;

/// `emission_self_weight` with a pinhole camera (the module's "A light's edge through a
/// pinhole"; 4 at stop 50, 2 since the mean-difference test, "A few samples per pixel").
pub const PINHOLE_SELF_WEIGHT: f64 = 2.0;

/// `emission_mean_test` with a pinhole camera (the module's "A few samples per pixel").
pub const PINHOLE_MEAN_TEST: f64 = 0.25;

/// Added to the denominator of the patch distance: no pixel's E has a variance estimate when
/// none of its samples saw a light.
pub const EMISSION_EPSILON: f32 = 1.0e-4;

/// A frame's light split in two, as the kernels split it (the reference's input).
pub struct Split {
    /// F less the light of lights seen directly ([`reflected`]).
    pub fv: Vec<FilterVector>,
    /// The odd half less the emission's.
    pub odd: Vec<Float4>,
    /// The emission filtered by its non-local means ([`emission_nlm`]), added to the output.
    pub emitted: Vec<[f32; 3]>,
}

/// The frame's [`Split`] with the settings' window and k.
pub fn split(frame: &Frame, s: &BmfrSettings) -> Result<Split> {
    let (w, h, spp) = (frame.width(), frame.height(), frame.info().spp as f32);
    let fv = frame.filter_vectors()?;
    let odd: &[Float4] = frame.host_slice(BufferId::OddHalves)?;
    let e: &[Float4] = frame.host_slice(BufferId::FirstEmission)?;
    let e_odd: &[Float4] = frame.host_slice(BufferId::OddEmission)?;
    let (fv, odd) = (0..fv.len())
        .map(|i| reflected(&fv[i], &odd[i], &e[i], &e_odd[i]))
        .unzip();
    let patches = prep(e, e_odd, (w, h), spp);
    let emitted = emission_nlm(e, &patches, (w, h), NlmParams::of(s));
    Ok(Split { fv, odd, emitted })
}

/// kernels/filters/bmfr_emission.cl `bmfr_reflected`: pixel `i`'s F and odd half with the
/// light of emitters seen directly taken out.
pub fn reflected(f: &FilterVector, odd: &Float4, e: &Float4, e_odd: &Float4) -> (FilterVector, Float4) {
    let (mut f, mut odd) = (*f, *odd);
    let share = e.0[3];
    if share > 0.0 {
        let peak = e.0[0].max(e.0[1].max(e.0[2]));
        for c in 0..3 {
            f.direct[c] = (f.direct[c] - e.0[c]).max(0.0);
            odd.0[c] = (odd.0[c] - e_odd.0[c]).max(0.0);
            if share < 1.0 && peak > 0.0 {
                f.albedo[c] = (f.albedo[c] - share * e.0[c] / peak).max(0.0);
            }
        }
    }
    (f, odd)
}

/// The mean of E's three channels, the quantity the patches compare.
fn luminance(e: &Float4) -> f32 {
    (e.0[0] + e.0[1] + e.0[2]) * (1.0 / 3.0)
}

/// kernels/filters/bmfr_emission.cl `bmfr_emission_variance_raw`: the variance of pixel `e`'s
/// mean E, (even − odd)² / 4 per channel (the halves' means differ by twice the mean's
/// standard deviation when they hold half the samples each), averaged over the channels.
fn variance_raw(e: &Float4, e_odd: &Float4, spp: f32) -> f32 {
    // No sample saw a light: both halves' E are 0 (the kernel skips reading the odd half).
    if e.0[3] == 0.0 {
        return 0.0;
    }
    let n_odd = e_odd.0[3];
    let n_even = spp - n_odd;
    if n_odd <= 0.0 || n_even <= 0.0 {
        return 0.0;
    }
    let mut v = 0.0f32;
    for c in 0..3 {
        let o = e_odd.0[c];
        let even = (e.0[c] * spp - o * n_odd) / n_even;
        v += (even - o) * (even - o) * 0.25;
    }
    v * (1.0 / 3.0)
}

/// kernels/filters/bmfr_emission.cl `bmfr_emission_prep`: per pixel (E's luminance, its
/// variance averaged over the 3 × 3 pixels around inside the image).
pub fn prep(e: &[Float4], e_odd: &[Float4], (w, h): (u32, u32), spp: f32) -> Vec<[f32; 2]> {
    let (w, h) = (w as i32, h as i32);
    (0..e.len())
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i as i32 % w, i as i32 / w);
            let (mut sum, mut n) = (0.0f32, 0.0f32);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (u, v) = (x + dx, y + dy);
                    if u >= 0 && v >= 0 && u < w && v < h {
                        let j = (v * w + u) as usize;
                        sum += variance_raw(&e[j], &e_odd[j], spp);
                        n += 1.0;
                    }
                }
            }
            [luminance(&e[i]), sum / n]
        })
        .collect()
}

/// Whether any pixel of the window around (x, y) saw a light (a window without is 0, and
/// skipped: most of the image).
fn lit_window(prep: &[[f32; 2]], (w, h): (i32, i32), (x, y): (i32, i32), radius: i32) -> bool {
    let rows = (y - radius).max(0)..=(y + radius).min(h - 1);
    rows.into_iter().any(|v| {
        let cols = (x - radius).max(0)..=(x + radius).min(w - 1);
        cols.into_iter().any(|u| prep[(v * w + u) as usize][0] > 0.0)
    })
}

/// How many of a patch's taps along one axis lie inside [0, n) both at c + t and at c + dc
/// (kernels/filters/bmfr_emission.cl `bmfr_emission_taps`): the patch distance's count is the
/// product of the two axes'.
fn taps(c: i32, dc: i32, n: i32) -> i32 {
    let lo = (-EMISSION_PATCH).max(-c).max(-c - dc);
    let hi = EMISSION_PATCH.min(n - 1 - c).min(n - 1 - c - dc);
    (hi - lo + 1).max(0)
}

/// The emission's non-local means' settings (`emission_radius`, `emission_k`,
/// `emission_self_weight`, `emission_mean_test`).
#[derive(Clone, Copy, Debug)]
pub struct NlmParams {
    pub radius: i32,
    pub k: f32,
    /// The pixel's own extra weight ([`self_weight`]).
    pub own: f32,
    /// The weight of the patches' mean-difference test ([`mean_test`]); 0: none.
    pub mean_test: f32,
}

impl NlmParams {
    pub fn of(s: &BmfrSettings) -> NlmParams {
        NlmParams {
            radius: s.emission_radius as i32,
            k: s.emission_k as f32,
            own: s.emission_self_weight() as f32,
            mean_test: s.emission_mean_test() as f32,
        }
    }
}

/// kernels/filters/bmfr_emission.cl `bmfr_emission_nlm`: E of every pixel filtered by
/// non-local means over the (2 radius + 1)² window (0 where the window holds no light), the
/// pixel's own E weighing `own` more than the window gives it (see [`self_weight`]), a pair of
/// patches whose taps differ one way more than their noise explains kept apart by
/// [`mean_test`]. The kernel's order of float operations (its box-filter form): each patch
/// row's taps left to right, an invalid tap adding 0, then the rows top to bottom, the pixel's
/// own extra weight last.
pub fn emission_nlm(e: &[Float4], prep: &[[f32; 2]], (w, h): (u32, u32), p: NlmParams) -> Vec<[f32; 3]> {
    let (w, h) = (w as i32, h as i32);
    let (radius, k2) = (p.radius, p.k * p.k);
    // A tap's (term, difference, summed variance); 0s outside the image.
    let tap = |a: (i32, i32), b: (i32, i32)| {
        let inside = |(x, y): (i32, i32)| x >= 0 && y >= 0 && x < w && y < h;
        if !inside(a) || !inside(b) {
            return [0.0; 3];
        }
        let p = prep[(a.1 * w + a.0) as usize];
        let q = prep[(b.1 * w + b.0) as usize];
        let diff = p[0] - q[0];
        let term = (diff * diff - (p[1] + p[1].min(q[1]))) / (EMISSION_EPSILON + k2 * (p[1] + q[1]));
        [term, diff, p[1] + q[1]]
    };
    (0..e.len())
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i as i32 % w, i as i32 / w);
            let mut acc = [0.0f32; 3];
            if !lit_window(prep, (w, h), (x, y), radius) {
                return acc;
            }
            let mut wsum = 0.0f32;
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    let (u, v) = (x + dx, y + dy);
                    if u < 0 || v < 0 || u >= w || v >= h {
                        continue;
                    }
                    // The patch's sums of the three: [term, difference, variance].
                    let mut d = [0.0f32; 3];
                    for py in -EMISSION_PATCH..=EMISSION_PATCH {
                        let mut row = [0.0f32; 3];
                        for px in -EMISSION_PATCH..=EMISSION_PATCH {
                            let t = tap((x + px, y + py), (u + px, v + py));
                            for c in 0..3 {
                                row[c] += t[c];
                            }
                        }
                        for c in 0..3 {
                            d[c] += row[c];
                        }
                    }
                    let n = (taps(x, dx, w) * taps(y, dy, h)) as f32;
                    let mut dist = d[0] / n;
                    if p.mean_test > 0.0 {
                        dist = dist.max(mean_test(d[1], d[2], k2, p.mean_test));
                    }
                    let wt = (-dist.max(0.0)).exp();
                    let j = (v * w + u) as usize;
                    for (a, v) in acc.iter_mut().zip(&e[j].0) {
                        *a += wt * v;
                    }
                    wsum += wt;
                }
            }
            if p.own > 0.0 {
                self_weight(&mut acc, &mut wsum, &e[i], p.own);
            }
            acc.map(|a| a / wsum)
        })
        .collect()
}

/// The patches' mean-difference test (`emission_mean_test`, the module's "A few samples per
/// pixel"): the sum of the taps' differences squared, less the sum of their variances (its
/// expectation where both patches see the same light), over k² times that sum, scaled by
/// `weight`; the patch distance is the larger of this and the taps' mean term.
pub fn mean_test(diff_sum: f32, var_sum: f32, k2: f32, weight: f32) -> f32 {
    weight * (diff_sum * diff_sum - var_sum) / (EMISSION_EPSILON + k2 * var_sum)
}

/// The pixel's own E weighs `own` more than the window gave it (`emission_self_weight`; the
/// module's "A light's edge through a pinhole"): the kernels' last step before dividing, and
/// only when `own` is above 0 (so that 0 is the bytes of the filter without it).
fn self_weight(acc: &mut [f32; 3], wsum: &mut f32, e: &Float4, own: f32) {
    for (a, v) in acc.iter_mut().zip(&e.0) {
        *a += own * v;
    }
    *wsum += own;
}
