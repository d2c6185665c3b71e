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

impl std::ops::AddAssign for Work {
    /// Two kernels' (or two lights') work together.
    fn add_assign(&mut self, o: Work) {
        self.taps += o.taps;
        self.flops += o.flops;
        self.exps += o.exps;
        self.bytes += o.bytes;
    }
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

/// bmfr's settings the models need (src/filters/bmfr, after specialisation to the scene).
#[derive(Clone, Copy, Debug)]
pub struct BmfrShape {
    /// Features K and columns C = K + 6 targets of the fit.
    pub features: usize,
    pub block: u32,
    pub grids: u32,
    /// The non-local means' search radius, the half buffers' (`estimate_radius`), and the
    /// selection's window radius.
    pub nlm_radius: u32,
    pub estimate_radius: u32,
    pub select_radius: u32,
    /// The non-local means' patch half width P (patches of (2 P + 1)² pixels).
    pub nlm_patch: u32,
}

/// One offset of the frame's non-local means in bmfr_nlm_packed.cl, per pixel, in its box form
/// (each tap's term evaluated once per pixel and offset and shared by the patches holding it),
/// with patches of half width `patch` (P): the term (per channel: the variance cancellation's
/// add and min, the denominator's add, multiply, add and reciprocal, the difference, its
/// square less the cancellation times the reciprocal: 10; the channels' 2 adds; the inside
/// product: 33), the patch row's and column's sums (2 P + 2 P) and the taps' count
/// (2 P + 2 P + 1 shared), the weight (division, max, negation: 3) and the accumulation
/// (three multiply-adds and the weight sum: 7); one `exp`. 52 with 3 × 3 patches, 60 with
/// 5 × 5.
pub fn bmfr_nlm_frame_flops(patch: u32) -> f64 {
    44.0 + 8.0 * patch as f64
}
/// The same for one half buffer within the estimate's window: its term (per channel the
/// difference, square, halving, cancellation and reciprocal product: 5; 2 adds), its sums
/// (2 P + 2 P) and its weight and accumulation (10); one `exp`. 31 with 3 × 3 patches.
pub fn bmfr_nlm_half_flops(patch: u32) -> f64 {
    27.0 + 4.0 * patch as f64
}
/// Once per pixel: the three images' rgb means (9 divisions) times the modulation (9).
pub const BMFR_NLM_PIXEL_FLOPS: f64 = 18.0;

/// The non-local means of bmfr's selection (bmfr_nlm_packed) on a frame whose pixels have
/// the non-local means' `classes` (nlm.rs `class`; 0 passes through): useful work only (the
/// lanes the packed kernel computes and masks out are not counted, as for à-trous).
pub fn bmfr_nlm_work(classes: &[f32], width: u32, height: u32, shape: &BmfrShape) -> Work {
    let (w, h) = (width as i64, height as i64);
    let (r, re) = (shape.nlm_radius as i64, shape.estimate_radius as i64);
    let cols = |rad| -> Vec<u64> { (0..w).map(|x| inside(x, w, rad, 1)).collect() };
    let rows = |rad| -> Vec<u64> { (0..h).map(|y| inside(y, h, rad, 1)).collect() };
    let (cols_r, rows_r, cols_e, rows_e) = (cols(r), rows(r), cols(re), rows(re));
    let (mut frame, mut halves, mut filtered) = (0u64, 0u64, 0u64);
    for y in 0..h as usize {
        for x in 0..w as usize {
            if classes[y * w as usize + x] == 0.0 {
                continue;
            }
            filtered += 1;
            frame += cols_r[x] * rows_r[y];
            halves += 2 * cols_e[x] * rows_e[y];
        }
    }
    Work {
        taps: frame + halves,
        flops: frame as f64 * bmfr_nlm_frame_flops(shape.nlm_patch)
            + halves as f64 * bmfr_nlm_half_flops(shape.nlm_patch)
            + filtered as f64 * BMFR_NLM_PIXEL_FLOPS,
        exps: (frame + halves) as f64,
        // The 14 input lines read, F read for the modulation, three float4 means written.
        bytes: (w * h) as f64 * (56.0 + 64.0 + 48.0),
    }
}

/// One window position of bmfr_select_nlm (packed): the class test and the four sums (V, R,
/// N, count).
pub const BMFR_SELECT_TAP_FLOPS: f64 = 5.0;
/// Once per pixel: the beauty (3), E_n, E_f and their weights (10), the blend of three rgb
/// candidates (9 multiplies, 6 adds, the weights' sum 2, 3 divisions).
pub const BMFR_SELECT_PIXEL_FLOPS: f64 = 33.0;

/// The selection's window sums and blend (bmfr_select_nlm_packed) without the floor (a pinhole
/// camera): every pixel's window inside the image.
pub fn bmfr_select_work(width: u32, height: u32, shape: &BmfrShape) -> Work {
    let (w, h) = (width as i64, height as i64);
    let r = shape.select_radius as i64;
    let cols: u64 = (0..w).map(|x| inside(x, w, r, 1)).sum();
    let rows: u64 = (0..h).map(|y| inside(y, h, r, 1)).sum();
    let taps = cols * rows;
    let pixels = (w * h) as f64;
    Work {
        taps,
        flops: taps as f64 * BMFR_SELECT_TAP_FLOPS + pixels * BMFR_SELECT_PIXEL_FLOPS,
        exps: 0.0,
        // Residuals, F, the non-local means read; the fit read and the blend written.
        bytes: pixels * (16.0 + 64.0 + 16.0 + 32.0),
    }
}

/// bmfr's fit (bmfr_fit_packed, paper Algorithm 1) over every block of every grid: per row of
/// a block, the four raw columns' minimum and maximum (8) and the features (rescaling 8,
/// squares 3, each feature's regularisation noise 4); Householder QR over all N = B² rows (for
/// column j, the dot products with columns j .. C − 1 and the updates of j + 1 .. C − 1, a
/// multiply and an add or subtract per row each); back-substitution per target (K² flops).
pub fn bmfr_fit_work(width: u32, height: u32, shape: &BmfrShape) -> Work {
    use crate::filters::bmfr::{grid_blocks, grid_offset};
    let (k, c) = (shape.features as f64, (shape.features + 6) as f64);
    let n = (shape.block * shape.block) as f64;
    let per_row = 8.0 + 11.0 + 4.0 * (k - 1.0);
    let qr: f64 = (0..shape.features)
        .map(|j| 2.0 * n * (c - j as f64) + 2.0 * n * (c - j as f64 - 1.0))
        .sum();
    let per_block = n * per_row + qr + 6.0 * k * k;
    let blocks: u32 = (0..shape.grids)
        .map(|g| {
            let (a, d) = grid_blocks(
                width,
                height,
                shape.block,
                grid_offset(g, shape.grids, shape.block),
            );
            a * d
        })
        .sum();
    Work {
        taps: blocks as u64,
        flops: blocks as f64 * per_block,
        exps: 0.0,
        // Every pixel's C columns read once per grid; the weights and block ranges written.
        bytes: shape.grids as f64 * (width * height) as f64 * c * 4.0
            + blocks as f64 * (6.0 * k + 9.0) * 4.0,
    }
}

/// bmfr_apply (and bmfr_apply_packed, the same operations per lane; a work-item whose lanes
/// span two blocks also computes the other block's fits, not counted) per pixel that is
/// fitted (not kept): per grid the features (11), the six fits
/// (a multiply and an add per feature, and the clamp: 12 K + 6), the light (6), the tent
/// weight (16) and the accumulation (7); the division at the end (3).
pub fn bmfr_apply_work(fitted: u64, width: u32, height: u32, shape: &BmfrShape) -> Work {
    let k = shape.features as f64;
    let per_grid = 11.0 + 12.0 * k + 6.0 + 6.0 + 16.0 + 7.0;
    Work {
        taps: fitted * shape.grids as u64,
        flops: fitted as f64 * (shape.grids as f64 * per_grid + 3.0),
        exps: 0.0,
        // F and the position read, the output written (the weights, per block, are small).
        bytes: (width * height) as f64 * (64.0 + 16.0 + 16.0),
    }
}

/// One contour sample of st_distance's lanes (kernels/filters/stylized.cl, DeCoro eq. 3.2) in
/// pass 1: the 45° rule (a 3-lane dot: 5, its compare: 1), the distance (3 sub, 3 mul, 2 add,
/// the square root: 9) and the running minimum (1).
pub const ST_PASS1_SAMPLE_FLOPS: f64 = 16.0;
/// The stratified draw's entry when the samples are a subset of the contour: u scaled, k + u,
/// times count/n (3; the conversions are not counted).
pub const ST_DRAW_FLOPS: f64 = 3.0;
/// One sample in pass 2 (read back from pass 1's cache): the keep test (1), m/d and its eighth
/// power (4), the d > m test (1), w·occ (1) and the two sums (2).
pub const ST_PASS2_SAMPLE_FLOPS: f64 = 9.0;
/// Once per pixel with a pass 2: the mean (1), D = m / mean^(1/8) (three square roots and the
/// division: 4) and d(x) (1).
pub const ST_PIXEL_FLOPS: f64 = 6.0;

/// st_distance (the lanes) for one light on its `pixels` (the light's plane of the shadow
/// output), with the kernel's `distance` out (D: finite where pass 2 ran), `points` contour
/// points and `n` = contour_samples. Useful work only: pass 1 over the matte's pixels, pass 2
/// over those with a contour point on their side; the lanes past the last sample, and a
/// work-item's idle second pixel, compute and mask out, not counted; nor does the scalar loop
/// (GPUs) get credit for drawing and measuring each sample again in pass 2.
pub fn stylized_distance_work(
    pixels: &[crate::layout::ShadowPixel],
    distance: &[f32],
    points: u32,
    n: u32,
) -> Work {
    use crate::filters::stylized::contour::in_matte;
    let samples = points.min(n) as u64;
    let draw = if points > n { ST_DRAW_FLOPS } else { 0.0 };
    let matte = pixels.iter().filter(|p| in_matte(p)).count() as u64;
    let summed = distance.iter().filter(|d| d.is_finite()).count() as u64;
    let pixels_all = pixels.len() as f64;
    Work {
        taps: (matte + summed) * samples,
        flops: (matte * samples) as f64 * (ST_PASS1_SAMPLE_FLOPS + draw)
            + (summed * samples) as f64 * ST_PASS2_SAMPLE_FLOPS
            + summed as f64 * ST_PIXEL_FLOPS,
        exps: 0.0,
        // Every pixel's normal (the matte test) and the two outputs; the matte's position,
        // V and occluder distance; the contour's seven planes and the draws' hash table once.
        bytes: pixels_all * (12.0 + 8.0)
            + matte as f64 * 20.0
            + points as f64 * 28.0
            + n as f64 * 4.0,
    }
}
