//! The numbers of a merge (see the module above): every pixel's outputs of the whole render,
//! accumulated piece by piece in double precision and rounded to float once. How each buffer
//! merges is declared with it ([`Merge`] in src/layout/outputs.rs) and applied here by
//! exhaustive matches, so a new output cannot be forgotten.

use std::mem::{offset_of, size_of};
use std::ops::Range;

use crate::layout::outputs::{BufferId, Merge, WELFORD_MEANS};
use crate::layout::{DepthShift, FilterVector, WelfordState, WelfordSums};
use crate::render::HostBuffer;
use crate::stats::partial::{Piece, RenderIdentity};

const F_DEPTH: usize = offset_of!(FilterVector, depth) / 4;
const K: usize = offset_of!(DepthShift, shift) / 4;
const K_MEAN: usize = offset_of!(DepthShift, mean) / 4;
const W_DIRECTION: Range<usize> = {
    let d = offset_of!(WelfordState, direction_mean) / 4;
    d..d + 3
};
const W_COMPENSATION: usize = offset_of!(WelfordState, s_compensation) / 4;
const S_LANES: usize = offset_of!(WelfordSums, pad) / 4;

/// Floats of a WelfordSums element.
const FS: usize = size_of::<WelfordSums>() / 4;

/// The merged state of every pixel, in double precision; per-sample buffers as they will be
/// written.
pub(super) struct Accumulator {
    width: u32,
    spp: u32,
    /// Samples folded so far, per pixel.
    count: Vec<u32>,
    /// Per gathered buffer, in table order.
    state: Vec<(BufferId, State)>,
}

enum State {
    /// A per-pixel buffer: its lanes, `floats` per pixel.
    Lanes { floats: usize, v: Vec<f64> },
    /// A per-sample buffer: the final bytes.
    Samples(HostBuffer),
}

/// Pixel `t` of a piece's tile, pixel `p` of the image, which `na` samples were folded into
/// before this piece's `nb`.
struct PiecePixel<'a> {
    piece: &'a Piece,
    t: usize,
    p: usize,
    na: u32,
    nb: u32,
}

impl PiecePixel<'_> {
    fn buffer(&self, id: BufferId) -> &HostBuffer {
        &self
            .piece
            .buffers
            .iter()
            .find(|(i, _)| *i == id)
            .expect("a piece holds every gathered buffer")
            .1
    }

    /// This pixel's element of a per-pixel buffer.
    fn element(&self, id: BufferId) -> &[f32] {
        // Every lane of the pixel: one element, or one per light plane (Per::Light).
        let all = self.buffer(id).floats();
        let floats = all.len() / self.piece.info.tile.pixels();
        &all[self.t * floats..(self.t + 1) * floats]
    }
}

impl Accumulator {
    pub(super) fn new(id: &RenderIdentity) -> Accumulator {
        let pixels = id.width as usize * id.height as usize;
        let state = id
            .outputs
            .buffers()
            .map(|b| {
                // Per::Light buffers: every plane's element of the pixel, merged lane by lane.
                let floats = b.element_bytes / 4 * b.per_pixel(0, id.shadow_planes());
                let s = match b.merge {
                    Merge::PerSample => State::Samples(HostBuffer::zeroed(
                        b.bytes(id.width, id.height, id.spp, 0) as usize,
                    )),
                    Merge::Means
                    | Merge::DepthShift
                    | Merge::WelfordSums
                    | Merge::WelfordState
                    | Merge::HitMeans
                    | Merge::Identical => State::Lanes {
                        floats,
                        v: vec![0.0; pixels * floats],
                    },
                };
                (b.id, s)
            })
            .collect();
        Accumulator {
            width: id.width,
            spp: id.spp,
            count: vec![0; pixels],
            state,
        }
    }

    /// Pixel `p`'s merged element of a per-pixel buffer, if gathered.
    fn element(&self, id: BufferId, p: usize) -> Option<&[f64]> {
        self.state.iter().find_map(|(i, s)| match s {
            State::Lanes { floats, v } if *i == id => Some(&v[p * floats..(p + 1) * floats]),
            _ => None,
        })
    }

    /// The piece's mean in lane `lane` of buffer `id`, in the merged state's terms: depth means
    /// are of x − K, and a piece's K is the depth of its own first sample, so its mean moves
    /// by K_piece − K_merged (K_merged is the first piece's: sample 0's depth, as in a single
    /// render).
    fn piece_mean(&self, px: &PiecePixel, id: BufferId, lane: usize) -> f64 {
        let own = px.element(id);
        match id.decl().merge {
            Merge::DepthShift if lane == K_MEAN => {
                let k_piece = own[K] as f64;
                let k = match px.na {
                    0 => k_piece,
                    _ => self.element(id, px.p).expect("gathered")[K],
                };
                own[K_MEAN] as f64 + (k_piece - k)
            }
            Merge::Means | Merge::DepthShift | Merge::WelfordState | Merge::HitMeans => {
                own[lane] as f64
            }
            Merge::WelfordSums | Merge::PerSample | Merge::Identical => {
                unreachable!("{} holds no means", id.decl().name)
            }
        }
    }

    /// Every S_n after folding the piece in (Chan, Golub & LeVeque), from the means before it
    /// moves them, split as film.cl splits it: S = s − c, s a float. A part's S_n is s − c;
    /// the merged one is kept the same way, s the float nearest to the double-precision sum and
    /// c (in double precision until the end) the rest, so that a pixel's first piece is taken
    /// as it is, bit for bit.
    fn merged_sums(&self, px: &PiecePixel) -> Option<[(f64, f64); FS]> {
        let merged = self.element(BufferId::WelfordSums, px.p)?;
        let state = self.element(BufferId::WelfordState, px.p)?;
        let (s, c) = (
            px.element(BufferId::WelfordSums),
            px.element(BufferId::WelfordState),
        );
        let (na, nb) = (px.na as f64, px.nb as f64);
        let mut out = [(0f64, 0f64); FS];
        for &(lane, id, mean_lane) in WELFORD_MEANS {
            let (s_b, c_b) = (s[lane] as f64, c[W_COMPENSATION + lane] as f64);
            if px.na == 0 {
                out[lane] = (s_b, c_b);
                continue;
            }
            let mean = self
                .element(id, px.p)
                .expect("the variances need their means")[mean_lane];
            let delta = self.piece_mean(px, id, mean_lane) - mean;
            let s_a = merged[lane] - state[W_COMPENSATION + lane];
            let sum = s_a + (s_b - c_b) + delta * delta * na * nb / (na + nb);
            let float = (sum as f32) as f64;
            out[lane] = (float, float - sum);
        }
        Some(out)
    }

    /// The lanes of a per-pixel buffer that are means, and what each is a mean over.
    fn is_mean(merge: Merge, lane: usize) -> bool {
        match merge {
            Merge::Means => true,
            Merge::DepthShift => lane == K_MEAN,
            Merge::WelfordState => W_DIRECTION.contains(&lane),
            Merge::HitMeans => lane < 3,
            Merge::WelfordSums | Merge::PerSample | Merge::Identical => false,
        }
    }

    /// Folds one piece in. Fails when a buffer that every part holds identically
    /// ([`Merge::Identical`]) differs from the parts folded before it.
    pub(super) fn fold(&mut self, piece: &Piece) -> anyhow::Result<()> {
        let info = &piece.info;
        for t in 0..info.tile.pixels() {
            let p = info.tile.image_pixel(t, self.width);
            let px = PiecePixel {
                piece,
                t,
                p,
                na: self.count[p],
                nb: info.count(),
            };
            let sums = self.merged_sums(&px);
            // The piece's means, before any state moves.
            let means: Vec<(BufferId, usize, f64)> = self
                .state
                .iter()
                .filter_map(|(id, s)| match s {
                    State::Lanes { floats, .. } => Some((*id, *floats)),
                    State::Samples(_) => None,
                })
                .flat_map(|(id, floats)| (0..floats).map(move |l| (id, l)))
                .filter(|&(id, l)| Self::is_mean(id.decl().merge, l))
                .map(|(id, l)| (id, l, self.piece_mean(&px, id, l)))
                .collect();
            for (id, s) in self.state.iter_mut() {
                let merge = id.decl().merge;
                match s {
                    State::Samples(out) => {
                        debug_assert_eq!(merge, Merge::PerSample);
                        let bytes = id.decl().element_bytes * px.nb as usize;
                        let own = &px.buffer(*id).as_bytes()[t * bytes..(t + 1) * bytes];
                        let to = (p * self.spp as usize + info.samples.start as usize)
                            * id.decl().element_bytes;
                        out.as_bytes_mut()[to..to + bytes].copy_from_slice(own);
                    }
                    State::Lanes { floats, v } => {
                        let v = &mut v[p * *floats..(p + 1) * *floats];
                        let own = px.element(*id);
                        // Count-weighted means: mean_a + (mean_b − mean_a) n_b / (n_a + n_b).
                        let (a, b) = match merge {
                            Merge::HitMeans => (v[3], own[3] as f64),
                            _ => (px.na as f64, px.nb as f64),
                        };
                        let w = if b > 0.0 { b / (a + b) } else { 0.0 };
                        for &(_, l, mean) in means.iter().filter(|m| m.0 == *id) {
                            v[l] += (mean - v[l]) * w;
                        }
                        let split = || sums.expect("the state comes with the sums");
                        match merge {
                            Merge::DepthShift if px.na == 0 => v[K] = own[K] as f64,
                            Merge::HitMeans => v[3] += own[3] as f64,
                            Merge::WelfordSums => {
                                for (lane, (s, _)) in split().iter().enumerate() {
                                    v[lane] = *s;
                                }
                            }
                            Merge::WelfordState => {
                                for (lane, (_, c)) in split().iter().enumerate().take(S_LANES) {
                                    v[W_COMPENSATION + lane] = *c;
                                }
                            }
                            Merge::Identical if px.na == 0 => {
                                for (v, &o) in v.iter_mut().zip(own) {
                                    *v = o as f64;
                                }
                            }
                            Merge::Identical => {
                                // Bitwise: NaN lanes (no receiver) must agree too.
                                if v.iter()
                                    .zip(own)
                                    .any(|(&v, &o)| (v as f32).to_bits() != o.to_bits())
                                {
                                    anyhow::bail!(
                                        "the parts' {} differ at pixel ({}, {}), which every \
                                         part computes the same way: they were rendered with \
                                         different settings of the filter that asked for it \
                                         (e.g. --aaf-sparse-spp); render them again with one",
                                        id.decl().name,
                                        p as u32 % self.width,
                                        p as u32 / self.width
                                    );
                                }
                            }
                            Merge::Means | Merge::DepthShift | Merge::PerSample => {}
                        }
                    }
                }
            }
            self.count[p] += px.nb;
        }
        Ok(())
    }

    /// The buffers, rounded to float, and F.depth = K + mean(x − K) formed as film.cl forms it.
    pub(super) fn finish(self) -> Vec<(BufferId, HostBuffer)> {
        let pixels = self.count.len();
        let mut out = Vec::new();
        for (id, s) in &self.state {
            let v = match s {
                State::Samples(h) => {
                    out.push((*id, h.clone()));
                    continue;
                }
                State::Lanes { v, .. } => v,
            };
            let floats = id.decl().element_bytes / 4;
            let mut h = HostBuffer::zeroed(v.len() * 4);
            let f = h.floats_mut();
            for (o, x) in f.iter_mut().zip(v) {
                *o = *x as f32;
            }
            match id.decl().merge {
                // F.depth; other buffers of means (ShadowTerms) have no depth lane.
                Merge::Means if *id == BufferId::FilterVectors => {
                    if let Some(d) = self.lanes(BufferId::DepthShifts) {
                        for p in 0..pixels {
                            let k = d[p * 2 + K] as f32;
                            f[p * floats + F_DEPTH] = k + d[p * 2 + K_MEAN] as f32;
                        }
                    }
                }
                Merge::Means
                | Merge::DepthShift
                | Merge::WelfordSums
                | Merge::WelfordState
                | Merge::HitMeans
                | Merge::PerSample
                | Merge::Identical => {}
            }
            out.push((*id, h));
        }
        out
    }

    fn lanes(&self, id: BufferId) -> Option<&[f64]> {
        self.state.iter().find_map(|(i, s)| match s {
            State::Lanes { v, .. } if *i == id => Some(v.as_slice()),
            _ => None,
        })
    }
}
