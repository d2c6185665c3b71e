//! The plain Rust reference of kernels/filters/path_density.cl: the same equations, the same
//! ring scan and the same float operations in the same order (the kernel's `cbrt` may differ
//! from Rust's by an ulp), plus a brute-force kNN over the whole image that the ring scan must
//! equal (tests/path_density.rs).

use super::{ColorSpace, PathDensityParams};
use crate::imaging::RgbImage;

/// The stored samples of one image, pixel-major: sample `s` of pixel `p` is `p · spp + s`.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSamples {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Film position: pixel coordinates plus the jitter inside the pixel.
    pub xy: Vec<[f32; 2]>,
    /// HDR linear RGB radiance of the sample.
    pub rgb: Vec<[f32; 3]>,
}

impl FilmSamples {
    pub fn len(&self) -> usize {
        self.xy.len()
    }

    pub fn is_empty(&self) -> bool {
        self.xy.is_empty()
    }

    /// Film samples of an RPF sample set (position and colour of each vector).
    pub fn from_set(set: &crate::stats::samples::SampleSet) -> FilmSamples {
        FilmSamples {
            width: set.width,
            height: set.height,
            spp: set.spp,
            xy: set.samples.iter().map(|s| s.position).collect(),
            rgb: set.samples.iter().map(|s| s.color).collect(),
        }
    }
}

fn lab_f(t: f32) -> f32 {
    if t > 0.008856452 {
        t.cbrt()
    } else {
        t * 7.787037 + 0.137_931_03
    }
}

/// CIELAB of linear Rec. 709 RGB (D65, Y_n = 1); None when it is not finite (`pd_lab_of`).
pub fn lab(rgb: [f32; 3]) -> Option<[f32; 3]> {
    let [r, g, b] = rgb;
    let x = 0.4124564 * r + 0.3575761 * g + 0.1804375 * b;
    let y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
    let z = 0.0193339 * r + 0.119192 * g + 0.9503041 * b;
    let fx = lab_f(x / 0.95047);
    let fy = lab_f(y);
    let fz = lab_f(z / 1.08883);
    let l = 116.0 * fy - 16.0;
    let a = 500.0 * (fx - fy);
    let bb = 200.0 * (fy - fz);
    (l.is_finite() && a.is_finite() && bb.is_finite()).then_some([l, a, bb])
}

/// The colour coordinates of the distance in `space` (`pd_lab_of`): the Lab, or 100 × RGB
/// (valid when the Lab and they are finite); None when not valid.
pub fn coords(rgb: [f32; 3], space: ColorSpace) -> Option<[f32; 3]> {
    let lab = lab(rgb)?;
    match space {
        ColorSpace::Cielab => Some(lab),
        ColorSpace::Rgb => {
            let c = rgb.map(|v| 100.0 * v);
            c.iter().all(|v| v.is_finite()).then_some(c)
        }
    }
}

/// The joint distance d = ‖Δxy‖ / w_W + ‖ΔLab‖ / w_c (`pd_distance`).
pub fn distance(a: [f32; 2], la: [f32; 3], b: [f32; 2], lb: [f32; 3], inv_w: f32, inv_c: f32) -> f32 {
    let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
    let (dl, da, db) = (la[0] - lb[0], la[1] - lb[1], la[2] - lb[2]);
    (dx * dx + dy * dy).sqrt() * inv_w + (dl * dl + da * da + db * db).sqrt() * inv_c
}

/// The weight ramp on σ: 1 up to `keep`, 0 from `reject`, linear between.
pub fn ramp(sigma: f32, keep: f32, reject: f32) -> f32 {
    if sigma <= keep {
        1.0
    } else if sigma >= reject {
        0.0
    } else {
        (reject - sigma) / (reject - keep)
    }
}

/// The seed's density ρ = G(σ), the standard normal density of σ (range (0, 1/√(2π)]).
pub fn density(sigma: f32) -> f32 {
    (-0.5 * sigma * sigma).exp() / (2.0 * std::f32::consts::PI).sqrt()
}

/// Per stored sample: σ (mean distance to the k nearest neighbours; ∞ for a non-finite
/// sample) and its weight.
#[derive(Clone, Debug, PartialEq)]
pub struct Densities {
    pub sigma: Vec<f32>,
    pub weight: Vec<f32>,
}

impl Densities {
    /// Fraction of the finite samples with weight 0 (rejected) and with 0 < w < 1
    /// (down-weighted).
    pub fn fractions(&self) -> (f64, f64) {
        let finite = self.sigma.iter().filter(|s| s.is_finite()).count().max(1) as f64;
        let mut rejected = 0usize;
        let mut reduced = 0usize;
        for (s, w) in self.sigma.iter().zip(&self.weight) {
            if s.is_finite() {
                rejected += (*w == 0.0) as usize;
                reduced += (*w > 0.0 && *w < 1.0) as usize;
            }
        }
        (rejected as f64 / finite, reduced as f64 / finite)
    }
}

/// The colour coordinates of every sample in `space` (None: not valid).
pub fn labs(samples: &FilmSamples, space: ColorSpace) -> Vec<Option<[f32; 3]>> {
    samples.rgb.iter().map(|&c| coords(c, space)).collect()
}

/// The k smallest distances kept sorted, as the kernel's private array.
struct Best {
    d: Vec<f32>,
    k: usize,
}

impl Best {
    fn push(&mut self, d: f32) {
        if self.d.len() == self.k && !(d < self.d[self.k - 1]) {
            return;
        }
        if self.d.len() == self.k {
            self.d.pop();
        }
        let at = self.d.partition_point(|&b| b <= d);
        self.d.insert(at, d);
    }

    fn full(&self) -> bool {
        self.d.len() == self.k
    }

    /// σ: the mean of the held distances, summed in ascending order; 0 without any.
    fn mean(&self) -> f32 {
        if self.d.is_empty() {
            return 0.0;
        }
        let mut sum = 0.0f32;
        for &d in &self.d {
            sum += d;
        }
        sum / self.d.len() as f32
    }
}

/// σ of every sample by the kernel's ring scan (ε-approximate when `p.epsilon` > 0), and the
/// weights.
pub fn densities(samples: &FilmSamples, p: &PathDensityParams) -> Densities {
    let labs = labs(samples, p.color_space);
    let n = samples.len();
    let mut sigma = vec![0.0f32; n];
    let mut weight = vec![0.0f32; n];
    use rayon::prelude::*;
    sigma
        .par_iter_mut()
        .zip(weight.par_iter_mut())
        .enumerate()
        .for_each(|(i, (s, w))| {
            *s = match labs[i] {
                None => f32::INFINITY,
                Some(li) => ring_sigma(samples, &labs, p, i, li),
            };
            *w = if s.is_finite() {
                ramp(*s, p.keep, p.reject)
            } else {
                0.0
            };
        });
    Densities { sigma, weight }
}

/// The frame group of sample `s` (of `spp`): its first and one-past-last sample numbers.
fn group(s: usize, spp: usize, frame_spp: usize) -> (usize, usize) {
    let g0 = (s / frame_spp) * frame_spp;
    (g0, (g0 + frame_spp).min(spp))
}

fn ring_sigma(
    samples: &FilmSamples,
    labs: &[Option<[f32; 3]>],
    p: &PathDensityParams,
    i: usize,
    li: [f32; 3],
) -> f32 {
    let (w, h, spp) = (
        samples.width as i64,
        samples.height as i64,
        samples.spp as usize,
    );
    let (pix, s) = (i / spp, i % spp);
    let (px, py) = ((pix as i64) % w, (pix as i64) / w);
    let (g0, g1) = group(s, spp, p.frame_spp as usize);
    let mut best = Best {
        d: Vec::with_capacity(p.k as usize + 1),
        k: p.k as usize,
    };
    let rmax = w.max(h);
    for r in 0..=rmax {
        for dy in -r..=r {
            let qy = py + dy;
            if qy < 0 || qy >= h {
                continue;
            }
            let step = if dy == -r || dy == r || r == 0 {
                1
            } else {
                2 * r
            };
            let mut dx = -r;
            while dx <= r {
                let qx = px + dx;
                if qx >= 0 && qx < w {
                    let q = (qy * w + qx) as usize * spp;
                    for (j, lab_j) in labs.iter().enumerate().take(q + g1).skip(q + g0) {
                        if j == i {
                            continue;
                        }
                        if let Some(lj) = *lab_j {
                            best.push(distance(
                                samples.xy[i],
                                li,
                                samples.xy[j],
                                lj,
                                p.inv_w(),
                                p.inv_c(),
                            ));
                        }
                    }
                }
                dx += step;
            }
        }
        if best.full() && r as f32 * p.inv_w() >= best.d[best.k - 1] * p.shrink() {
            break;
        }
    }
    best.mean()
}

/// σ of sample `i` by brute force over every sample of its frame group in the whole image
/// (the definition the exact ring scan must reproduce; `p.epsilon` is ignored).
pub fn brute_force_sigma(samples: &FilmSamples, p: &PathDensityParams, i: usize) -> f32 {
    let labs = labs(samples, p.color_space);
    let Some(li) = labs[i] else {
        return f32::INFINITY;
    };
    let spp = samples.spp as usize;
    let (g0, g1) = group(i % spp, spp, p.frame_spp as usize);
    let mut all: Vec<f32> = (0..samples.len())
        .filter(|&j| j != i && (g0..g1).contains(&(j % spp)))
        .filter_map(|j| {
            labs[j].map(|lj| distance(samples.xy[i], li, samples.xy[j], lj, p.inv_w(), p.inv_c()))
        })
        .collect();
    all.sort_by(f32::total_cmp);
    all.truncate(p.k as usize);
    let mut best = Best {
        d: all,
        k: p.k as usize,
    };
    best.k = best.k.max(1);
    best.mean()
}

/// The reconstruction (`pd_reconstruct`): per pixel and frame group Σ w·L / Σ w, the group's
/// plain mean when every weight is 0, the groups averaged by their sample counts (CIELAB
/// validity).
pub fn reconstruct(samples: &FilmSamples, weight: &[f32], frame_spp: u32) -> RgbImage {
    reconstruct_in(samples, weight, frame_spp, ColorSpace::Cielab)
}

/// [`reconstruct`] with the validity of `space`'s coordinates.
pub fn reconstruct_in(
    samples: &FilmSamples,
    weight: &[f32],
    frame_spp: u32,
    space: ColorSpace,
) -> RgbImage {
    let spp = samples.spp as usize;
    let fs = frame_spp as usize;
    let groups = spp.div_ceil(fs);
    let pixels = (0..samples.width as usize * samples.height as usize)
        .map(|p| {
            let mut acc = [0.0f32; 3];
            let mut single = [0.0f32; 3];
            for g in 0..groups {
                let (g0, g1) = (g * fs, ((g + 1) * fs).min(spp));
                let (mut wl, mut plain) = ([0.0f32; 3], [0.0f32; 3]);
                let (mut ws, mut n) = (0.0f32, 0.0f32);
                for s in g0..g1 {
                    let i = p * spp + s;
                    if coords(samples.rgb[i], space).is_none() {
                        continue;
                    }
                    let c = samples.rgb[i];
                    let w = weight[i];
                    for k in 0..3 {
                        wl[k] += w * c[k];
                        plain[k] += c[k];
                    }
                    ws += w;
                    n += 1.0;
                }
                let value: [f32; 3] = std::array::from_fn(|k| {
                    if ws > 0.0 {
                        wl[k] / ws
                    } else if n > 0.0 {
                        plain[k] / n
                    } else {
                        0.0
                    }
                });
                single = value;
                for k in 0..3 {
                    acc[k] += value[k] * (g1 - g0) as f32;
                }
            }
            if groups == 1 {
                single
            } else {
                acc.map(|v| v / spp as f32)
            }
        })
        .collect();
    RgbImage {
        width: samples.width,
        height: samples.height,
        pixels,
    }
}

/// The whole filter: densities, then the reconstruction.
pub fn filter(samples: &FilmSamples, p: &PathDensityParams) -> (RgbImage, Densities) {
    let d = densities(samples, p);
    let image = reconstruct_in(samples, &d.weight, p.frame_spp, p.color_space);
    (image, d)
}
