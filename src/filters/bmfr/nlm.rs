//! The selection's third candidate (`nlm`): non-local means of the light, with its error
//! estimated by cross-filtering the two half buffers. The plain Rust reference of
//! kernels/filters/bmfr_nlm.cl, the same float operations in the same order.
//!
//! Why. The fit has a bias where its features do not explain the light (a glossy reflection,
//! glass, a defocused edge), and there the two-way selection (select.rs) can only fall back to
//! the unfiltered, noisy light: on Cornell glossy (512², 8 spp) the pixels with no direct light
//! held 5.6 of bmfr's MSE-LUV of 7.46, against OIDN-high's 1.8. Non-local means (Rousselle,
//! Knaus, Zwicker, SIGGRAPH Asia 2012) average pixels whose patches of light (5 × 5,
//! `nlm_patch`) agree up to their noise, whatever the features say, so they smooth a
//! reflection without blurring it into its surroundings.
//!
//! The error estimate is what makes a third candidate pay. A smoother's output depends on the
//! pixel's own samples, so its residual against the frame's mean misses the noise it keeps (a
//! prototype that estimated à-trous' error that way made Outside and Cornell glossy worse,
//! results/README.md). NFOR's answer (Bitterli et al., EGSR 2016 §4): filter each half buffer
//! alone; nlm(o) is independent of the even half e, so
//! E[(nlm(o) − e)²] = E[(nlm(o) − μ)²] + var(e), and subtracting var(e) leaves the error of
//! the filter run on half the samples. N averages that over both halves (`residual`). The
//! frame's own non-local means, which is the candidate, has about half that variance and the
//! same bias: E_n = N / 2.
//!
//! The blend (`select`): over the selection window, E_y = V (the unfiltered light's variance),
//! E_f = (R − V) / κ (the fit's, trusted κ times more, as in select.rs) and E_n, each relative
//! to V and floored at 1e-6, weighted 1 / E². The choices were measured on one 8-spp 512² AOV
//! file per scene with a host prototype of these equations (not in the repository; the
//! filter's figures are in results/README.md), MSE-LUV of Cornell glossy / Outside /
//! Cornell plane DOF / Cornell diffuse against the current two-way selection's 7.46 / 3.59 /
//! 8.63 / 1.49:
//! - weights 1 / E² rather than 1 / E: 5.25 / 2.28 / 8.09 / 1.53 against 5.38 / 2.31 / 8.16 /
//!   1.61 (window radius 3);
//! - the fit's estimate from its residual (one fit, as select.rs) rather than from fitting each
//!   half too: 5.25 / 2.28 / 8.09 / 1.53 against 5.11 / 2.38 / 8.09 / 1.43, without a second
//!   and third fit;
//! - each half filtered with its own weights rather than the frame's weights applied to both
//!   halves (a third of the cost): with shared weights the estimate sees less than the
//!   filter's noise and picks it too often (Cornell diffuse 1.70);
//! - search radius 5 and k 0.7 (`nlm_radius`, `nlm_k`). The frame's nlm alone, Cornell
//!   glossy / Outside / Cornell plane DOF / Cornell diffuse: radius 3, k 0.7: 8.50 / 2.60 /
//!   10.17 / 2.39; radius 5, k 0.7: 6.67 / 2.42 / 8.85 / 1.91; radius 7, k 0.7: 6.40 / 2.49 /
//!   8.83 / 1.86; radius 5, k 1.0: 6.10 / 2.68 / 8.38 / 1.88; radius 7, k 0.45 (the 2012
//!   paper's): 9.20 / 2.50 / 10.54 / 2.45. Radius 5 is 121 offsets against radius 7's 225.
//!   (The prototype's non-local means equal this reference's to 2.4e-6, relative.)
//! - k with a lens (`nlm_k` auto: [`LENS_NLM_K`] with a thin lens, [`PINHOLE_NLM_K`] 0.7
//!   without; stop 42, with 3 × 3 patches; 0.8 with 5 × 5 since stop 46, "Patches" below).
//!   With the emission filtered apart (emission.rs), k 1.0 lowered bmfr's
//!   error on every depth-of-field scene (the 8-spp 512² frames at `render`'s seed, `noisefree
//!   filter S.exr --filter bmfr --bmfr-nlm-k K`, MSE-LUV / relMSE at k 0.7 → 1.0):
//!   cornell_diffuse_dof 1.613 / 0.00255 → 1.516 / 0.00242, cornell_glossy_dof 4.912 / 0.00840
//!   → 4.590 / 0.00689, cornell_plane_dof 3.600 / 0.00594 → 3.369 / 0.00562, conference_dof
//!   3.320 / 0.00763 → 3.058 / 0.00659, outside_dof 1.597 / 0.00381 → 1.595 / 0.00374,
//!   toasters_dof 1.808 / 0.00286 → 1.746 / 0.00279 (k 1.4: better on conference_dof, worse on
//!   the others; 2.0 worse still). Without a lens it helped the Cornell boxes and conference
//!   (cornell_diffuse 1.485 → 1.436, cornell_glossy 5.011 → 4.811, conference 3.768 → 3.556)
//!   but not Outside (2.284 / 0.00515 → 2.480 / 0.00560), where the non-local means alone was
//!   already best at 0.7 (above), so a pinhole camera keeps 0.7. Out of focus the light varies
//!   slowly over the patch, so a wider tolerance finds more of the same light.
//! - the selection window radius 4 (`select_radius`; the two-way blend's best was 2): with
//!   this filter, radius 2 / 3 / 4 gave Cornell glossy 5.60 / 5.25 / 5.10, Outside 2.30 /
//!   2.28 / 2.28, Cornell plane DOF 6.44 / 6.28 / 6.29, Cornell diffuse 1.61 / 1.53 / 1.50
//!   (`noisefree filter a.exr --filter bmfr --bmfr-select-radius R` on the same files).
//! - the halves' search window radius 3 (`nlm_estimate_radius`), the frame's 5: the halves
//!   only estimate the candidate's error, and their outer 72 offsets changed the selection's
//!   result by about 1 % while taking two thirds of the non-local means' work there. With this
//!   reference on the same files (a scratch program cutting the halves' window, written before
//!   the setting existed; `noisefree filter a.exr --filter bmfr --bmfr-nlm-estimate-radius R`
//!   now runs the same choice on the device), MSE-LUV with estimate radius 5 / 3 / 2 / 1
//!   (— not measured): Cornell glossy 5.10 / 5.01 / 4.99 / —, Cornell diffuse 1.50 / 1.49 /
//!   1.45 / 1.39, Outside 2.28 / 2.29 / 2.32 / 2.48, Outside DOF 3.06 / 3.07 / 3.13 / 3.31, Cornell plane 5.04 / 5.09 / 5.29 / 5.58,
//!   Cornell plane DOF 6.29 / 6.32 / 6.42 / 6.67. The packed kernel: 104 -> 77 ms on Cornell
//!   diffuse 512² (`noisefree filter --profile`, binaries alternating). The quality study's
//!   rows with the new default are in results/README.md (bmfr, "Stop 34").
//!
//! The floor (`select_floor`, c). R − V is summed over the window before it is compared with
//! V, so one pixel whose residual falls far below its variance outweighs its neighbours'
//! evidence against the fit. Through a lens that pixel exists beside every defocused light:
//! the share of its samples that hit the light moves its mean position and its light
//! together, the block's polynomial follows it (prefilter.rs), R ≈ 0 against a V of the
//! emission's size, and E_f floors at 1e-6 over the whole window, so the ceiling pixels beside
//! the light, which no light sample reached, take the fit's bleed of the light (on one 8-spp
//! 512² frame of cornell_diffuse_dof, pixel (192, 10): 0.51 where the reference has 0.012).
//! With c > 0 each pixel's R − V enters a second sum no lower than −c × the window's mean V;
//! the estimate stays unbiased where the window's variances are alike (a term below −c V̄ is
//! then rare). One 8-spp 512² AOV file per scene (`noisefree render S --spp 8 --filter bmfr
//! --aovs a.exr`, `noisefree filter a.exr --filter bmfr --bmfr-select-floor C --exr b.exr`,
//! `noisefree compare b.exr <the 2048-spp reference>`), MSE-LUV / relMSE at c = 0 / 3 / 6 / 12:
//!
//! | scene | 0 (no floor) | 3 | 6 | 12 |
//! |---|---|---|---|---|
//! | cornell_diffuse_dof | 2.180 / 0.00778 | 2.110 / 0.00476 | 2.092 / 0.00593 | 2.143 / 0.00712 |
//! | cornell_glossy_dof | 5.576 / 0.01498 | 5.510 / 0.01153 | 5.427 / 0.01219 | 5.505 / 0.01385 |
//! | cornell_plane_dof | 4.017 / 0.01235 | 3.981 / 0.00923 | 3.928 / 0.01076 | 3.991 / 0.01213 |
//! | outside_dof | 1.589 / 0.00379 | 1.614 / 0.00387 | 1.597 / 0.00381 | 1.591 / 0.00380 |
//! | cornell_diffuse | 1.485 / 0.00145 | 1.596 / 0.00155 | 1.504 / 0.00146 | 1.485 / 0.00145 |
//! | cornell_glossy | 5.011 / 0.00819 | 5.150 / 0.00839 | 5.029 / 0.00820 | 5.006 / 0.00818 |
//! | outside | 2.284 / 0.00515 | 2.308 / 0.00520 | 2.293 / 0.00517 | 2.285 / 0.00515 |
//!
//! Without a lens the floor only costs (a small c cuts the heavy tail of ordinary pixels'
//! estimates, and the fit is trusted less), and its second pass over the window took
//! `bmfr_select_nlm` from 10.6 to 25.8 ms (`noisefree filter a.exr --filter bmfr --repeat 5
//! --profile`, Cornell diffuse DOF, PoCL, 2 cores), so it is on with a thin lens only
//! ([`LENS_SELECT_FLOOR`]). Tried in scratch changes to this function, not in the repository
//! (so these figures cannot be re-run), and not kept: weighting
//! each window pixel by 1 / (V_i + V_j + ε) (Cornell diffuse DOF MSE-LUV 5.17 at ε 1e-3, the
//! weights favour pixels whose V came out small by chance), a floor at −c V_j of the pixel's
//! own variance (c 0: 2.46, c 0.5: 2.33; Cornell diffuse 1.93 / 1.74), and the same floor
//! on the non-local means' N as well (no better).
//!
//! Relative sums (`select_relative`, stop 44). V, R and N are sums of squared errors over the
//! window, so a window that holds bright and dark pixels takes the bright ones' verdict: where
//! a block's fit leaks light into a dark corner or an umbra beside lit pixels, the lit pixels'
//! evidence (the fit is good there) outweighs the dark ones' (it is not), whose errors are
//! small in absolute terms but are what MSE in CIELUV (L* grows as Y^(1/3)) and relMSE weigh
//! most. So each channel's three terms are first divided by l² + ε ([`RELATIVE_EPSILON`],
//! 1e-3), l the larger of the fit and the frame's non-local means (the non-local means alone
//! on an open pixel): the blend's ratios E / V then average relative errors, and stay what
//! they were in a window whose pixels share one level. Measured with a host prototype of this
//! change before the kernels (not in the repository, so these figures cannot be re-run; the
//! filter's own are in results/README.md, bmfr, "Stop 44") on one 8-spp 512² AOV file per
//! scene at `render`'s seed, MSE-LUV / relMSE, without the outliers' replacement
//! (outliers.rs), l from the fit / the non-local means' minimum with the fit / the larger of
//! the two: grids 3.55 / 3.52 / 3.41 and 0.00651 / 0.00658 / 0.00624 (4.69 / 0.00739 without
//! the weights), cornell_glossy 4.94 / 5.11 / 4.61 and 0.00863 / 0.00903 / 0.00687 (5.01 /
//! 0.00819), conference 3.70 / 4.42 / 3.84 and 0.0163 / 0.0618 / 0.0334 (3.77 / 0.0165): a
//! firefly on conference, weighed by the small level of its neighbours, made its windows
//! worse, which the outliers' replacement removes (3.20 / 0.00716 with both); l from the
//! non-local means alone: grids 3.55 / 0.00654, cornell_glossy 5.01 / 0.00842, conference
//! 5.18 / 0.143. With both,
//! ε 1e-3 against 3e-3: grids 3.41 / 3.61, curved 1.14 / 1.16, room_gi 1.255 / 1.261, the
//! other eight scenes within 0.5 %.
//!
//! The relative sums do much of what the floor was for: the unlit pixels beside a defocused
//! light no longer let their lit neighbours vouch for the fit. With them, the floor's c 6 / 0 /
//! 3 on the six depth-of-field scenes' 8-spp frames (`noisefree filter S.aov.exr --filter bmfr
//! --bmfr-select-floor C`, MSE-LUV / relMSE): cornell_diffuse_dof 1.507 / 0.00241, 1.502 /
//! 0.00241, 1.545 / 0.00245; outside_dof 1.575 / 0.00362, 1.573 / 0.00362, 1.579 / 0.00364;
//! cornell_glossy_dof 4.429 / 0.00630, 4.403 / 0.00593, 4.537 / 0.00647; cornell_plane_dof
//! 3.310 / 0.00522, 3.308 / 0.00523, 3.359 / 0.00528; conference_dof 2.853 / 0.00480, 2.829 /
//! 0.00472, 2.976 / 0.00525; toasters_dof 1.735 / 0.00278, 1.745 / 0.00280, 1.740 / 0.00278.
//! So `select_floor` auto is 6 only with a thin lens and `select_relative` off; without the
//! floor the selection makes no second pass over its window.
//!
//! Open margin (`open_margin`, stop 45; [`classes`]). Out of focus, a silhouette against the
//! sky leaves a band of partly covered pixels many pixels wide (Outside DOF: the horizon and
//! the glass sphere's rim). Whether a pixel in it is [`SURFACE`] or [`OPEN`] is decided by its
//! own 8 samples: now and then all of them hit the wall, and the pixel, a surface among open
//! neighbours, found few patches of its class in its window and kept about its own light, the
//! wall's, where the reference holds the band's mix of wall and sky. On one 8-spp 512² frame of
//! outside_dof (scratch analysis of the AOV file, the reference's candidates and the
//! 2048-spp reference, not in the repository): 320 pixels came out below 0.6 × the reference's
//! luminance, 300 of them such surfaces, 0.18 of bmfr's MSE-LUV of 1.57 (visible as dark
//! specks along the horizon). With `open_margin` a surface pixel with an open pixel among its
//! eight neighbours counts as open: its light is averaged as it is with the open pixels', and
//! the selection blends it with its unfiltered light only. `noisefree filter S.aov.exr --filter
//! bmfr --bmfr-open-margin=B` on the 8-spp frames at `render`'s seed, MSE-LUV / relMSE off → on:
//! outside_dof 1.573 / 0.00362 → 1.287 / 0.00284; the other depth-of-field scenes have no open
//! pixels once the emission is split off and are the same bytes. With a pinhole camera the
//! band is a pixel wide and the pixel beside it a surface: outside 2.282 → 2.277 (relMSE
//! 0.00505 both), curved 1.141 → 1.130, grids 3.405 → 3.431, two_lights_shadows 1.536 → 1.538,
//! so auto turns it on with a thin lens only. Also tried on the reference (scratch changes, not
//! kept): at least 2 open neighbours of 8, outside_dof 1.296 / 0.00287; at least 4 in the 5 × 5
//! window, 1.281 / 0.00282 (within 0.5 %, and a second window size); the variance of a pixel
//! counted open averaged over its neighbours' own classes rather than the counted ones, 1.338 /
//! 0.00335. Cost: `bmfr_nlm_prep` evaluates its neighbours' classes, 0.8 → 2.5 ms on
//! outside_dof 512² (`--profile`).
//!
//! Patches (`nlm_patch`, stop 46). At 8 spp a 3 × 3 patch's distance is a mean of 27 noisy
//! terms, so two patches of the same light often differ by more than k allows and two of
//! different light by less: the weights vary by chance from pixel to pixel, and the output
//! keeps blotches of the noise (the soft shadows of curved's grid on its floor). A 5 × 5
//! patch averages 75 terms. `noisefree filter S.aov.exr --filter bmfr --bmfr-nlm-patch P
//! [--bmfr-nlm-k K]` on the 8-spp 512² frames at `render`'s seed, scored with `noisefree
//! compare` against the 2048-spp references, MSE-LUV / relMSE at patch half width 1 / 2 / 3
//! (k as it was, 0.7 without a lens and 1.0 with one; then 5 × 5 at k 0.8):
//!
//! | scene | 3 × 3 | 5 × 5 | 7 × 7 | 5 × 5, k 0.8 |
//! |---|---|---|---|---|
//! | cornell_diffuse | 1.445 / 0.00140 | 1.332 / 0.00127 | 1.324 / 0.00126 | |
//! | outside | 2.282 / 0.00505 | 2.382 / 0.00533 | 2.497 / 0.00578 | |
//! | cornell_glossy | 4.631 / 0.00687 | 4.216 / 0.00577 | 4.239 / 0.00605 | |
//! | cornell_plane | 5.072 / 0.00654 | 4.800 / 0.00648 | 4.927 / 0.00738 | |
//! | conference | 3.198 / 0.00716 | 2.935 / 0.00655 | 2.934 / 0.00674 | |
//! | grids | 3.405 / 0.00624 | 3.389 / 0.00595 | 3.470 / 0.00604 | |
//! | curved | 1.141 / 0.00237 | 1.033 / 0.00203 | 1.018 / 0.00196 | |
//! | two_lights_shadows | 1.536 / 0.00279 | 1.261 / 0.00259 | 1.241 / 0.00272 | |
//! | room_gi | 1.255 / 0.00235 | 1.088 / 0.00194 | 1.069 / 0.00191 | |
//! | cornell_diffuse_dof | 1.502 / 0.00241 | 1.471 / 0.00238 | 1.477 / 0.00240 | 1.452 / 0.00235 |
//! | outside_dof | 1.287 / 0.00284 | 1.262 / 0.00278 | 1.286 / 0.00283 | 1.223 / 0.00266 |
//! | cornell_glossy_dof | 4.403 / 0.00593 | 4.146 / 0.00559 | 4.271 / 0.00585 | 4.008 / 0.00539 |
//! | cornell_plane_dof | 3.308 / 0.00523 | 3.165 / 0.00505 | 3.146 / 0.00521 | 3.161 / 0.00476 |
//! | conference_dof | 2.829 / 0.00472 | 2.747 / 0.00445 | 2.739 / 0.00444 | 2.765 / 0.00447 |
//! | toasters_dof | 1.745 / 0.00280 | 1.686 / 0.00271 | 1.685 / 0.00272 | 1.640 / 0.00262 |
//!
//! 5 × 5 is better than 3 × 3 on fourteen scenes in both metrics; 7 × 7 gains a little more
//! on cornell_diffuse, curved, room_gi and conference_dof and loses on most others (outside,
//! the glossy and plane scenes' relMSE, grids). Outside loses with wider patches (the brick
//! wall seen through the glass sphere, whose refracted texture few wider patches match) and is
//! left so. k again, 5 × 5 (same command with `--bmfr-nlm-k K`): through a lens 0.7 / 0.8 /
//! 0.9 / 1.0 sum to 14.32 / 14.25 / 14.32 / 14.48 over the six scenes' MSE-LUV, 0.8 best or
//! within 1 % of the best on each, so [`LENS_NLM_K`] is 0.8; without, against 0.7, 0.6 wins
//! only outside (2.353 / 0.00533) and two_lights_shadows' relMSE (0.00246), 0.85 only room_gi
//! (1.071 / 0.00191) and curved's and grids' relMSE, so [`PINHOLE_NLM_K`] stays 0.7. Found
//! with a scratch change to this reference (not kept); the kernels give the same figures to
//! the digits shown. Cost: `bmfr_nlm_packed` 26.8 → 35.5 ms, bmfr 50 →
//! 58-60 ms on cornell_diffuse 512² (`--repeat 7 --profile`, medians, two runs each): its
//! work-items filter 12 pixels of their 16 lanes, not 14, and each row sum takes five taps.
//!
//! Cost: 121 offsets for the frame and 49 for each half per pixel, most of bmfr's time on a
//! CPU. Two kernels do the same float operations in the same order (each patch row's taps
//! summed first, then the rows): `bmfr_nlm` (kernels/filters/bmfr_nlm.cl; 16 × 16
//! work-groups share each tap's distance through local memory) and, on CPU devices
//! (`packed_nlm`), `bmfr_nlm_packed` (bmfr_nlm_packed.cl; one work-item per 12 × 32 pixels on
//! float16 lanes with 5 × 5 patches, the taps shifted between lanes, each output row's five
//! row sums added from a buffer of the work-item's rows). With 3 × 3 patches (the figures
//! that follow): on PoCL (2 cores, Cornell glossy 512², 8 spp, `noisefree filter a.exr
//! --filter bmfr --repeat 5`, medians): bmfr takes 190 ms with the packed kernel, 839 ms
//! with the work-group one (`--bmfr-packed-nlm=false`) and 72 ms with `--bmfr-nlm-radius 0`
//! (one offset), so the other 120 offsets cost about 120 ms packed and 770 ms in
//! work-groups. On variants of the packed kernel not kept in the repository, shifting the
//! lanes through private memory instead of `shuffle2` cost 50 ms more;
//! 4, 8, 16 or 32 rows per work-item (`NLM_PACKED_ROWS`) were within 5 % (later, after the
//! kernel's stack traffic was removed: 8 / 16 / 32 / 64 rows 114 / 110 / 106 / 106 ms on
//! Cornell diffuse, binaries alternating, so 32: its (32 + 2) / 32 row evaluations per output
//! row against 18 / 16). Radius 4 would take a third less and
//! measured 1-4 % more MSE-LUV on Cornell glossy, Outside, Cornell plane DOF and Cornell
//! diffuse (5.80 / 2.32 / 6.58 / 1.67 against 5.59 / 2.30 / 6.44 / 1.61).
//! `--bmfr-nlm=false` gives the two-way blend back (with `--bmfr-select-radius 2`).

use rayon::prelude::*;

use super::reference::{albedo, light};
use super::select::{fit_terms, surface, window_for_each, window_sum};
use crate::layout::{FilterVector, Float4};

/// Classes of pixels for the non-local means (kernels/filters/bmfr_nlm.cl `bmfr_nlm_class`):
/// a pixel averages pixels of its own class only.
///
/// * [`SURFACE`] (select.rs `surface`): fitted, its light demodulated by the albedo;
/// * [`OPEN`]: sky, and pixels whose samples did not all hit a surface (silhouettes against
///   the sky, out-of-focus edges), with samples in both halves. The fit keeps them as they are
///   (mod.rs), and without a lens they are nearly noise-free; through a lens the sky's texture
///   and the edges are as noisy as any surface (Outside DOF 512², 8 spp: kept, they held 1.50
///   of bmfr's MSE-LUV of 3.07; examples/bmfr_pixel_classes.rs, results/README.md). Their
///   light is averaged as it is (no albedo), and the selection blends it with the unfiltered
///   light only (there is no fit);
/// * 0: anything else (lights seen directly, a half without samples): passed through.
pub const SURFACE: f32 = 1.0;
pub const OPEN: f32 = 2.0;

/// The pixel's class ([`SURFACE`], [`OPEN`] or 0); `split`: the emission was taken out of F
/// (reference.rs `light`).
pub fn class(f: &FilterVector, pos: &Float4, odd: &Float4, spp: f32, split: bool) -> f32 {
    if surface(f, pos, odd, spp, split) {
        SURFACE
    } else if !light(f, split) && odd.0[3] >= 1.0 && spp - odd.0[3] >= 1.0 {
        OPEN
    } else {
        0.0
    }
}

/// Every pixel's class as the non-local means and the selection use it: [`class`], and with
/// `open_margin` a [`SURFACE`] pixel with an [`OPEN`] pixel among its eight neighbours counted
/// open (kernels/filters/bmfr_nlm.cl `bmfr_nlm_class_at`; module docs, "Open margin"); `split`
/// as in [`class`].
pub fn classes(
    fv: &[FilterVector],
    pos: &[Float4],
    odd: &[Float4],
    (w, h): (u32, u32),
    spp: f32,
    open_margin: bool,
    split: bool,
) -> Vec<f32> {
    let own: Vec<f32> = (0..fv.len())
        .into_par_iter()
        .map(|i| class(&fv[i], &pos[i], &odd[i], spp, split))
        .collect();
    if !open_margin {
        return own;
    }
    let (wi, hi) = (w as i32, h as i32);
    (0..own.len())
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let beside_open = || {
                ((y - 1).max(0)..=(y + 1).min(hi - 1)).any(|yy| {
                    ((x - 1).max(0)..=(x + 1).min(wi - 1))
                        .any(|xx| own[(yy as u32 * w + xx as u32) as usize] == OPEN)
                })
            };
            if own[i] == SURFACE && beside_open() { OPEN } else { own[i] }
        })
        .collect()
}

/// What the light of a pixel of class `class` is divided by before averaging (and multiplied
/// by after): its albedo on a surface, 1 elsewhere.
fn modulation(f: &FilterVector, class: f32) -> [f32; 3] {
    if class == OPEN { [1.0; 3] } else { albedo(f) }
}

/// ε of the patch distance (as the albedo prefilter's): noise-free pixels (v = 0) are only
/// averaged with patches of exactly the same light.
pub const NLM_EPSILON: f32 = 1.0e-10;

/// Side of the non-local means kernel's square work-groups (kernels/filters/bmfr_nlm.cl
/// `bmfr_nlm`): the tile whose tap distances are shared through local memory.
pub const NLM_TILE: u32 = 16;

/// Rows of pixels per work-item of the packed non-local means (kernels/filters/
/// bmfr_nlm_packed.cl BMFR_NLM_ROWS); its lanes are 16 pixels of each row.
pub const NLM_PACKED_ROWS: u32 = 32;

/// Floats of padding left of every line of the packed non-local means' input; twice as many
/// follow the image's width rounded up to 16 (bmfr_nlm_packed.cl BMFR_NLM_PAD).
pub const NLM_PACKED_PAD: u32 = 16;

/// Lines per image row of the packed non-local means' input (bmfr_nlm_packed.cl
/// BMFR_NLM_LINES).
pub const NLM_PACKED_LINES: u32 = 14;

/// k of the non-local means with a pinhole camera (`nlm_k` auto; module docs).
pub const PINHOLE_NLM_K: f64 = 0.7;

/// k of the non-local means with a thin lens (`nlm_k` auto; module docs, "k with a lens").
pub const LENS_NLM_K: f64 = 0.8;

/// c of the selection's floor with a thin lens and absolute sums (`select_floor` auto; module
/// docs, "The floor" and "Relative sums").
pub const LENS_SELECT_FLOOR: f32 = 6.0;

/// ε of the relative sums (`select_relative`; module docs, "Relative sums"), in the units of
/// the light squared: levels below about √ε ≈ 0.03 are weighed as that level.
pub const RELATIVE_EPSILON: f32 = 1.0e-3;

/// The largest search window half width (a 21 × 21 window).
pub const MAX_NLM_RADIUS: u32 = 10;

/// The largest patch half width (7 × 7 patches; `nlm_patch`).
pub const MAX_NLM_PATCH: u32 = 3;

pub(super) fn beauty(f: &FilterVector) -> [f32; 3] {
    std::array::from_fn(|c| f.direct[c] + f.indirect[c])
}


/// kernels/filters/bmfr_nlm.cl `bmfr_even`.
pub(super) fn even(beauty: [f32; 3], odd: &Float4, spp: f32) -> [f32; 3] {
    let n_even = spp - odd.0[3];
    if n_even >= 1.0 {
        std::array::from_fn(|c| (spp * beauty[c] - odd.0[3] * odd.0[c]) / n_even)
    } else {
        beauty
    }
}

/// The non-local means of the frame (search window half width `radius`), the odd half and the
/// even half (`estimate_radius`), per pixel (`bmfr_nlm_prep`, `bmfr_nlm_inputs`, `bmfr_nlm`),
/// over patches of (2 `patch` + 1)² pixels, each pixel of its class in `classes`
/// ([`classes`]).
#[allow(clippy::too_many_arguments)]
pub fn nlm(
    fv: &[FilterVector],
    odd: &[Float4],
    (w, h): (u32, u32),
    spp: f32,
    (radius, estimate_radius, patch): (u32, u32, u32),
    k: f32,
    classes: &[f32],
) -> Vec<[[f32; 3]; 3]> {
    let n = fv.len();
    let raw: Vec<[f32; 4]> = (0..n)
        .into_par_iter()
        .map(|i| {
            let class = classes[i];
            if class == 0.0 {
                return [0.0; 4];
            }
            let e = even(beauty(&fv[i]), &odd[i], spp);
            let factor = odd[i].0[3] * (spp - odd[i].0[3]) / (spp * spp);
            let d: [f32; 3] = std::array::from_fn(|c| odd[i].0[c] - e[c]);
            [d[0] * d[0] * factor, d[1] * d[1] * factor, d[2] * d[2] * factor, class]
        })
        .collect();
    let (wi, hi) = (w as i32, h as i32);
    // Per pixel: demodulated frame mean, odd half, even half, variance; and the class.
    let inputs: Vec<([[f32; 3]; 4], f32)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let al = modulation(&fv[i], raw[i][3]);
            let b = beauty(&fv[i]);
            // The variance from the 3 × 3 pixels of the pixel's class (a pixel of class 0
            // takes its surface neighbours', as its taps enter their patches).
            let class = if raw[i][3] == OPEN { OPEN } else { SURFACE };
            let mut sum = [0f32; 3];
            let mut count = 0f32;
            for yy in (y - 1).max(0)..=(y + 1).min(hi - 1) {
                for xx in (x - 1).max(0)..=(x + 1).min(wi - 1) {
                    let r = raw[(yy as u32 * w + xx as u32) as usize];
                    if r[3] != class {
                        continue;
                    }
                    for c in 0..3 {
                        sum[c] += r[c];
                    }
                    count += 1.0;
                }
            }
            let v: [f32; 3] = std::array::from_fn(|c| {
                if count > 0.0 {
                    sum[c] / count / (al[c] * al[c])
                } else {
                    0.0
                }
            });
            let e = even(b, &odd[i], spp);
            let u = [
                std::array::from_fn(|c| b[c] / al[c]),
                std::array::from_fn(|c| odd[i].0[c] / al[c]),
                std::array::from_fn(|c| e[c] / al[c]),
                v,
            ];
            (u, raw[i][3])
        })
        .collect();
    let k2 = k * k;
    let (r, re, pr) = (radius as i32, estimate_radius as i32, patch as i32);
    (0..n)
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let class = inputs[i].1;
            let al = modulation(&fv[i], class);
            let b = beauty(&fv[i]);
            if class == 0.0 {
                let o = [odd[i].0[0], odd[i].0[1], odd[i].0[2]];
                return [b, o, even(b, &odd[i], spp)];
            }
            let mut acc = [[0f32; 3]; 3];
            let mut wsum = [0f32; 3];
            for qy in (y - r)..=(y + r) {
                if qy < 0 || qy >= hi {
                    continue;
                }
                for qx in (x - r)..=(x + r) {
                    if qx < 0 || qx >= wi {
                        continue;
                    }
                    let j = (qy as u32 * w + qx as u32) as usize;
                    if inputs[j].1 != class {
                        continue;
                    }
                    // The halves (m = 1, 2) only within the estimate's window.
                    let images = if (qx - x).abs() <= re && (qy - y).abs() <= re {
                        3
                    } else {
                        1
                    };
                    let mut d2 = [0f32; 3];
                    let mut taps = 0f32;
                    for ty in -pr..=pr {
                        let (ay, by) = (y + ty, qy + ty);
                        if ay < 0 || ay >= hi || by < 0 || by >= hi {
                            continue;
                        }
                        // Each patch row's taps first, then the rows (bmfr_nlm's order).
                        let mut row = [0f32; 3];
                        for tx in -pr..=pr {
                            let (ax, bx) = (x + tx, qx + tx);
                            if ax < 0 || ax >= wi || bx < 0 || bx >= wi {
                                continue;
                            }
                            let a = &inputs[(ay as u32 * w + ax as u32) as usize].0;
                            let bb = &inputs[(by as u32 * w + bx as u32) as usize].0;
                            let (va, vb) = (a[3], bb[3]);
                            let s: [f32; 3] = std::array::from_fn(|c| va[c] + va[c].min(vb[c]));
                            let inv: [f32; 3] = std::array::from_fn(|c| {
                                1.0 / (NLM_EPSILON + k2 * (va[c] + vb[c]))
                            });
                            for m in 0..3 {
                                let t: [f32; 3] = std::array::from_fn(|c| {
                                    let diff = a[m][c] - bb[m][c];
                                    if m == 0 {
                                        (diff * diff - s[c]) * inv[c]
                                    } else {
                                        (0.5 * (diff * diff) - s[c]) * inv[c]
                                    }
                                });
                                row[m] += t[0] + t[1] + t[2];
                            }
                            taps += 3.0;
                        }
                        for m in 0..3 {
                            d2[m] += row[m];
                        }
                    }
                    for m in 0..images {
                        let wt = (-(d2[m] / taps).max(0.0)).exp();
                        for (a, v) in acc[m].iter_mut().zip(&inputs[j].0[m]) {
                            *a += wt * v;
                        }
                        wsum[m] += wt;
                    }
                }
            }
            std::array::from_fn(|m| std::array::from_fn(|c| acc[m][c] / wsum[m] * al[c]))
        })
        .collect()
}

/// kernels/filters/bmfr_nlm.cl `bmfr_residuals_nlm` for one pixel of class `class` (from
/// [`classes`]): (V, R, N, class). An [`OPEN`] pixel has no fit: R = 0. With `relative` each
/// channel's terms are divided by l² + [`RELATIVE_EPSILON`] first (module docs, "Relative
/// sums").
#[allow(clippy::too_many_arguments)]
pub fn residual(
    f: &FilterVector,
    odd: &Float4,
    spp: f32,
    fit: [f32; 3],
    nlm: &[[f32; 3]; 3],
    relative: bool,
    class: f32,
) -> [f32; 4] {
    if class == 0.0 {
        return [0.0; 4];
    }
    let (n_odd, n_even) = (odd.0[3], spp - odd.0[3]);
    let b = beauty(f);
    let e = even(b, odd, spp);
    // select.rs `fit_terms` (an open pixel's "fit" is its light: R = 0).
    let fit = if class == OPEN { b } else { fit };
    let (mut rr, mut v) = fit_terms(b, fit, odd, spp);
    let mut n: [f32; 3] = std::array::from_fn(|c| {
        let oe = odd.0[c] - e[c];
        let (v_odd, v_even) = (oe * oe * (n_even / spp), oe * oe * (n_odd / spp));
        let (no, ne) = (nlm[1][c] - e[c], nlm[2][c] - odd.0[c]);
        0.5 * ((no * no - v_even) + (ne * ne - v_odd))
    });
    if relative {
        for c in 0..3 {
            let level = if class == OPEN {
                nlm[0][c]
            } else {
                fit[c].max(nlm[0][c])
            };
            let weight = 1.0 / (level * level + RELATIVE_EPSILON);
            v[c] *= weight;
            rr[c] *= weight;
            n[c] *= weight;
        }
    }
    [v[0] + v[1] + v[2], rr[0] + rr[1] + rr[2], n[0] + n[1] + n[2], class]
}

/// kernels/filters/bmfr_nlm.cl `bmfr_select_nlm` (and on CPU devices bmfr_select_packed.cl,
/// the same bytes) for pixel (x, y): the window sums over the pixels of its class, then the
/// blend of the light, the fit and the non-local means (an [`OPEN`] pixel: of the light and
/// the non-local means). `(scale, floor)`: κ and c (`select_scale`, `select_floor`; module
/// docs). The kernels skip the floor's second pass where no term lies below the floor (its
/// sum is then the first pass's R − V, bit for bit); this reference always takes it.
/// Also returns the sum W of the three candidates' weights where it blends all three (0
/// elsewhere): guided.rs adds a fourth candidate to that blend.
#[allow(clippy::too_many_arguments)]
pub fn select(
    f: &FilterVector,
    residuals: &[[f32; 4]],
    (width, height): (u32, u32),
    (x, y): (i32, i32),
    radius: i32,
    (scale, floor): (f32, f32),
    fit: [f32; 3],
    nlm: [f32; 3],
) -> ([f32; 3], f32) {
    let class = residuals[(y as u32 * width + x as u32) as usize][3];
    let sum = window_sum(residuals, (width, height), (x, y), radius, |e| e[3] == class);
    let b = beauty(f);
    if !(sum[0] > 0.0) {
        return (if sum[1] > 0.0 { b } else { fit }, 0.0);
    }
    let e_y = 1f32;
    let e_n = (0.5 * sum[2] / sum[0]).max(1.0e-6);
    let (w_y, w_n) = (1.0 / (e_y * e_y), 1.0 / (e_n * e_n));
    if class == OPEN {
        return (std::array::from_fn(|c| (w_y * b[c] + w_n * nlm[c]) / (w_y + w_n)), 0.0);
    }
    let mut excess = sum[1] - sum[0];
    if floor > 0.0 {
        // The floor (module docs): the window's pixels of the class counted, as the kernel's
        // first loop does, then R − V summed again with each term floored.
        let mut count = 0f32;
        window_for_each(residuals, (width, height), (x, y), radius, |e| {
            if e[3] == class {
                count += 1.0;
            }
        });
        let floor = -floor * (sum[0] / count);
        excess = 0.0;
        window_for_each(residuals, (width, height), (x, y), radius, |e| {
            if e[3] == class {
                excess += (e[1] - e[0]).max(floor);
            }
        });
    }
    let e_f = (excess / scale / sum[0]).max(1.0e-6);
    let w_f = 1.0 / (e_f * e_f);
    let weight = w_y + w_f + w_n;
    (std::array::from_fn(|c| (w_y * b[c] + w_f * fit[c] + w_n * nlm[c]) / weight), weight)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::SKY_DEPTH;

    /// A 5 × 3 frame at 8 spp, 4 of them odd: surfaces, one sky pixel at (0, 1) (open) and a
    /// light seen directly at (1, 0) (class 0).
    fn frame() -> (Vec<FilterVector>, Vec<Float4>, Vec<Float4>) {
        let (w, h, spp) = (5, 3, 8.0);
        let mut fv = vec![
            FilterVector {
                depth: 2.0,
                albedo: [0.5; 3],
                direct: [0.3; 3],
                indirect: [0.1; 3],
                ..Default::default()
            };
            w * h
        ];
        fv[w].depth = SKY_DEPTH;
        fv[1].albedo = [1.0, 0.8, 0.6];
        fv[1].indirect = [0.0; 3];
        let pos = vec![Float4([0.0, 0.0, 2.0, spp]); w * h];
        let odd = vec![Float4([0.3, 0.3, 0.3, 4.0]); w * h];
        (fv, pos, odd)
    }

    #[test]
    fn open_margin_counts_surfaces_beside_open_pixels_as_open() {
        let (fv, pos, odd) = frame();
        let (s, o) = (SURFACE, OPEN);
        let own = classes(&fv, &pos, &odd, (5, 3), 8.0, false, false);
        #[rustfmt::skip]
        assert_eq!(own, [s, 0.0, s, s, s,
                         o, s,   s, s, s,
                         s, s,   s, s, s]);
        // The surfaces of columns 0 and 1 touch the sky pixel; the light stays class 0.
        let margin = classes(&fv, &pos, &odd, (5, 3), 8.0, true, false);
        #[rustfmt::skip]
        assert_eq!(margin, [o, 0.0, s, s, s,
                            o, o,   s, s, s,
                            o, o,   s, s, s]);
    }
}
