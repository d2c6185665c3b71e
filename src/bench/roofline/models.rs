//! What each measured filter kernel must do: its arithmetic (flops and `exp`s) counted from
//! the kernel source, and its compulsory memory traffic (every input read once, every output
//! written once; what a perfect cache would leave). Taps are counted exactly from the frame:
//! the kernels skip taps outside the image and sky pixels, so the count depends on the image.

use crate::layout::{FilterVector, SKY_DEPTH};

/// A kernel's work on one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Work {
    /// Taps (neighbour visits) over the whole run.
    pub taps: u64,
    /// Flops other than `exp`.
    pub flops: f64,
    /// `exp` evaluations.
    pub exps: f64,
    /// Compulsory bytes read and written.
    pub bytes: f64,
}

impl Work {
    /// Flops with each `exp` counted at `exp_flops` (Peaks::exp_flops).
    pub fn flop_equivalents(&self, exp_flops: f64) -> f64 {
        self.flops + self.exps * exp_flops
    }
}

/// How many of the offsets -half, -half + step, ..., half land in [0, n) from `x`.
fn inside(x: i64, n: i64, half: i64, step: i64) -> u64 {
    let mut k = 0;
    let mut d = -half;
    while d <= half {
        if (0..n).contains(&(x + d)) {
            k += 1;
        }
        d += step;
    }
    k
}

/// One neighbour of kernels/filters/ddf.cl `ddf_neighbour`, counted from the source:
/// e_dc and e_ic (a squared distance of 3 lanes: 3 sub, 3 mul, 2 add; times sigma: 9 each),
/// the depth difference scaled (2), e_fd (sigma dd dd: 2 mul; two 9-flop terms; 2 add: 22),
/// e_fi = e_fd + the printed direction factor (1 add), the two exponents (add and negate: 4)
/// and the accumulations (two rgb multiply-adds and two weight sums: 14), and two `exp`s.
pub const DDF_TAP_FLOPS: f64 = 61.0;
/// The texture2 term of eq. 6.14 (a 9-flop squared distance and its add).
pub const DDF_TEXTURE2_FLOPS: f64 = 10.0;
/// The direction term on the mean directions (DDF_DIRECTION 1): a 9-flop squared distance
/// instead of the printed constant.
pub const DDF_DIRECTION_DIFFERENCE_FLOPS: f64 = 9.0;
/// The neighbour's own sigma2_f,3 (DDF_DIRECTION 2): its variance (3 mul, 2 add), eq. 6.10
/// (mul, clamp as max and min, sub, mul).
pub const DDF_DIRECTION_NEIGHBOUR_FLOPS: f64 = 10.0;
/// Once per filtered pixel: `ddf_centre` (16 lanes times the variance factor, the depth
/// variance scaled twice, four 3-lane sums, eq. 6.10 for five features at 6 flops) and
/// `ddf_output` (two rgb divisions and the sum): 16 + 2 + 8 + 30 + 9.
pub const DDF_PIXEL_FLOPS: f64 = 65.0;

/// The data-driven filter's work on `fv` (w x h) with the kernel half-width `half`, tap
/// spacing `step` (2 with holes), `keeps_sky` (sky pixels copied, not filtered) and the extra
/// flops of the texture2 / direction terms per tap.
pub fn ddf_work(
    fv: &[FilterVector],
    width: u32,
    height: u32,
    half: u32,
    step: u32,
    keeps_sky: bool,
    extra_tap_flops: f64,
) -> Work {
    let (w, h) = (width as i64, height as i64);
    let (half, step) = (half as i64, step.max(1) as i64);
    let cols: Vec<u64> = (0..w).map(|x| inside(x, w, half, step)).collect();
    let rows: Vec<u64> = (0..h).map(|y| inside(y, h, half, step)).collect();
    // With holes and an odd half the grid skips offset 0: the centre is visited once more.
    let centre_extra = u64::from(half % step != 0);
    let (mut taps, mut filtered) = (0u64, 0u64);
    for y in 0..h {
        for x in 0..w {
            let f = &fv[(y * w + x) as usize];
            if keeps_sky && f.depth >= SKY_DEPTH {
                continue;
            }
            filtered += 1;
            taps += rows[y as usize] * cols[x as usize] + centre_extra;
        }
    }
    let pixels = (w * h) as f64;
    let copied = pixels - filtered as f64;
    Work {
        taps,
        flops: taps as f64 * (DDF_TAP_FLOPS + extra_tap_flops)
            + filtered as f64 * DDF_PIXEL_FLOPS
            + copied * 3.0,
        exps: 2.0 * taps as f64,
        // F (64 B) and the variance sums (one float16, 64 B) read, the colour (16 B) written;
        // a copied sky pixel reads F and writes its colour.
        bytes: filtered as f64 * 144.0 + copied * 80.0,
    }
}

/// One tap of kernels/filters/atrous.cl `atrous_pass` between two surface pixels: three
/// scaled squared distances (3 x 9) and their 2 adds, the weight (negate, fmin, two B3
/// factors: 4) and the accumulation (an rgb multiply-add and the weight sum: 7); one `exp`.
pub const ATROUS_TAP_FLOPS: f64 = 40.0;
/// Once per surface pixel and pass: three 1/sigma^2 (mul, clamp, div: 12), the colour
/// sigma's ldexp, the position sigma's footprint product, the rgb division at the end: 17.
pub const ATROUS_PASS_PIXEL_FLOPS: f64 = 17.0;
/// `atrous_init` per surface pixel: the beauty (3 add), the pixel direction (screen
/// coordinates 14, the combination 12, the length 6, its division 3), the footprint (3),
/// the demodulation (3 max, 3 div) and the position (3 mul): 50; `atrous_finish`: 3 max and
/// 3 mul.
pub const ATROUS_INIT_PIXEL_FLOPS: f64 = 50.0;
pub const ATROUS_FINISH_PIXEL_FLOPS: f64 = 6.0;

/// The à-trous filter's work on `fv` (w x h) over `iterations` passes of 5 x 5 taps 2^i apart.
/// The same for both kernels: the packed one (kernels/filters/atrous_packed.cl) does each
/// counted tap's arithmetic on one float16 lane, with the same flops per lane; the lanes it
/// computes and masks out (sky neighbours, neighbours and lanes past the image's edge) and its
/// per-tap selects are not useful work, so they are not counted.
pub fn atrous_work(fv: &[FilterVector], width: u32, height: u32, iterations: u32) -> Work {
    let (w, h) = (width as i64, height as i64);
    let surface: Vec<bool> = fv.iter().map(|f| f.depth < SKY_DEPTH).collect();
    let surfaces = surface.iter().filter(|s| **s).count() as f64;
    let mut taps = 0u64;
    for i in 0..iterations {
        let step = 1i64 << i;
        for y in 0..h {
            for x in 0..w {
                if !surface[(y * w + x) as usize] {
                    continue;
                }
                for ky in -2..=2 {
                    let ny = y + ky * step;
                    if !(0..h).contains(&ny) {
                        continue;
                    }
                    for kx in -2..=2 {
                        let nx = x + kx * step;
                        if (0..w).contains(&nx) && surface[(ny * w + nx) as usize] {
                            taps += 1;
                        }
                    }
                }
            }
        }
    }
    let pixels = (w * h) as f64;
    let n = iterations as f64;
    Work {
        taps,
        flops: taps as f64 * ATROUS_TAP_FLOPS
            + surfaces * (n * ATROUS_PASS_PIXEL_FLOPS + ATROUS_INIT_PIXEL_FLOPS)
            + surfaces * ATROUS_FINISH_PIXEL_FLOPS,
        exps: taps as f64,
        // init: F read, colour/position/normal written (64 + 48); each pass: colour, position
        // and normal read, colour written (64); finish: F and the colour read, colour written
        // (96).
        bytes: pixels * (112.0 + 64.0 * n + 96.0),
    }
}
