//! Outlier replacement (`outliers`): before the fit, a surface pixel whose light stands far
//! above its neighbours' in one of its two half buffers only takes the light of the other half.
//! The plain Rust reference of kernels/filters/bmfr_outliers.cl, the same float operations in
//! the same order.
//!
//! Why. A single sample that found a bright light through an unlikely path (a "firefly") gives
//! its pixel a mean hundreds of times its neighbours'. Every step of the filter then spreads
//! it: the block's least-squares fit bends towards it, the non-local means' variance of its
//! 3 × 3 neighbours grows so that their patches match anything, and in the selection's window
//! its R − V, a difference of two numbers of the firefly's square, outweighs every other
//! pixel's evidence, so the window trusts a fit the firefly bent. On conference's 8-spp 512²
//! frame at `render`'s seed one such pixel (V ≈ 1.0e6 against its neighbours' 0-13) left
//! pixels around (265, 127) at 4.8-5.7 where the reference has 0.29-0.33 and the samples
//! 0.2-0.5: the frame's eight largest relMSE terms, a third of its relMSE (found with a
//! scratch print of the selection's window sums, not in the repository; the filter's figures
//! with and without the replacement are in results/README.md).
//!
//! The test. A surface pixel (select.rs `surface`) of luminance l is an outlier when
//! l > L = τ · max(largest luminance of its 3 × 3 neighbours, mean luminance of its 7 × 7
//! neighbours) (surface pixels only, itself left out, at least [`NEIGHBOURS`] of them; τ =
//! `outlier_ratio`), and one of its two half buffers has a luminance ≤ L: the light is in one
//! half only. It then takes that half's light (each channel's direct and indirect parts scaled
//! alike, so the fit's two right-hand sides keep their shares), and its odd half becomes its
//! mean: it has no variance left to estimate.
//!
//! The second condition keeps the filter consistent: a real small highlight (a glint of a
//! light in a glossy sphere, one pixel wide) is in both halves once a few samples find it, so
//! it stays; a firefly is one sample's, in one half. As the sample count grows the halves'
//! means converge and a pixel stops being an outlier. The light of the removed sample is lost
//! (the frame's mean is biased low by it), which at 8 spp costs far less than spreading it.
//!
//! The filter's figures with and without (`--bmfr-outliers=false`) on every bundled scene are in
//! results/README.md (bmfr, "Stop 44"); there it lowered conference's relMSE from 0.0165 to
//! 0.0078 and took the bump at 64 spp out of conference_dof's error against time. τ
//! (`outlier_ratio`) was chosen with a scratch prototype of the test before the kernels (not in
//! the repository, so these figures cannot be re-run), on one 8-spp 512² AOV file per scene at
//! `render`'s seed, outliers / MSE-LUV / relMSE at τ 10 and 30: conference 3 / 3.33 / 0.00779
//! and 2 / 3.33 / 0.00779 against 3.77 / 0.0165 without; cornell_glossy 219 / 5.27 / 0.00831
//! and 18 / 5.02 / 0.00819 against 5.01 / 0.00819; at τ 30 no pixel on cornell_diffuse, grids,
//! outside, room_gi and outside_dof, 2 on curved. A first test on the pixel's variance against
//! its neighbours' (instead of its light, and without the halves' condition), the pixels left
//! out of the fit instead of replaced, flagged 21-2060 pixels per scene at τ 100 (a penumbra
//! pixel beside unlit ones has a variance far above theirs) and made cornell_glossy 5.01 →
//! 6.22.

use rayon::prelude::*;

use super::select::surface;
use crate::layout::{FilterVector, Float4};

/// Half width of the window whose mean luminance the test compares with (a 7 × 7 window).
pub const OUTLIER_RADIUS: i32 = 3;

/// Surface pixels the 7 × 7 window must hold (the pixel left out) for the test to apply: a
/// pixel without neighbours of its kind (a thin wire against the sky) is nobody's outlier.
pub const NEIGHBOURS: f32 = 8.0;

/// Rec. 709 luminance (kernels/filters/bmfr_outliers.cl `bmfr_luminance`).
fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

fn beauty(f: &FilterVector) -> [f32; 3] {
    std::array::from_fn(|c| f.direct[c] + f.indirect[c])
}

/// `bmfr_outlier_levels` and `bmfr_outliers`: copies of F and of the odd half, each outlier's
/// light replaced by its darker half's (module docs). `ratio`: τ.
pub fn replace(
    fv: &[FilterVector],
    pos: &[Float4],
    odd: &[Float4],
    (w, h): (u32, u32),
    spp: f32,
    split: bool,
    ratio: f32,
) -> (Vec<FilterVector>, Vec<Float4>) {
    let levels: Vec<f32> = (0..fv.len())
        .into_par_iter()
        .map(|i| match surface(&fv[i], &pos[i], &odd[i], spp, split) {
            true => luminance(beauty(&fv[i])),
            false => -1.0,
        })
        .collect();
    let (wi, hi) = (w as i32, h as i32);
    let level = |x: i32, y: i32| levels[(y as u32 * w + x as u32) as usize];
    (0..fv.len())
        .into_par_iter()
        .map(|i| {
            let (mut f, mut o) = (fv[i], odd[i]);
            let l = levels[i];
            if !(l > 0.0) {
                return (f, o);
            }
            let (x, y) = ((i as u32 % w) as i32, (i as u32 / w) as i32);
            let mut largest = 0f32;
            for yy in (y - 1).max(0)..=(y + 1).min(hi - 1) {
                for xx in (x - 1).max(0)..=(x + 1).min(wi - 1) {
                    if (xx, yy) != (x, y) {
                        largest = largest.max(level(xx, yy));
                    }
                }
            }
            if !(l > ratio * largest) {
                return (f, o);
            }
            let (mut sum, mut count) = (0f32, 0f32);
            for yy in (y - OUTLIER_RADIUS).max(0)..=(y + OUTLIER_RADIUS).min(hi - 1) {
                for xx in (x - OUTLIER_RADIUS).max(0)..=(x + OUTLIER_RADIUS).min(wi - 1) {
                    let n = level(xx, yy);
                    if (xx, yy) == (x, y) || n < 0.0 {
                        continue;
                    }
                    sum += n;
                    count += 1.0;
                }
            }
            let bound = ratio * largest.max(sum / count);
            let b = beauty(&f);
            let n_even = spp - o.0[3];
            let even: [f32; 3] = std::array::from_fn(|c| (spp * b[c] - o.0[3] * o.0[c]) / n_even);
            let odd3 = [o.0[0], o.0[1], o.0[2]];
            let (lo, le) = (luminance(odd3), luminance(even));
            if count >= NEIGHBOURS && l > bound && lo.min(le) <= bound {
                let clean = if lo <= le { odd3 } else { even };
                for c in 0..3 {
                    let scale = if b[c] > 0.0 { clean[c] / b[c] } else { 0.0 };
                    f.direct[c] *= scale;
                    f.indirect[c] *= scale;
                }
                o = Float4([
                    f.direct[0] + f.indirect[0],
                    f.direct[1] + f.indirect[1],
                    f.direct[2] + f.indirect[2],
                    o.0[3],
                ]);
            }
            (f, o)
        })
        .unzip()
}

/// The number of pixels [`replace`] changes (for tests and reports).
pub fn count(before: &[FilterVector], after: &[FilterVector]) -> usize {
    before
        .iter()
        .zip(after)
        .filter(|(a, b)| a.direct != b.direct || a.indirect != b.indirect)
        .count()
}
