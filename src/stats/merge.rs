//! Merging partial renders (src/stats/partial.rs) into the render of all their samples: the
//! parts of one render, each a range of the samples of a tile of the image, combine into the
//! outputs a single render of every sample would have left, to float rounding.
//!
//! How each buffer merges is declared with it ([`Merge`] in src/layout/outputs.rs) and applied
//! here by an exhaustive match, so a new output cannot be forgotten. Means combine weighted by
//! their sample counts; Welford's S_n by the parallel update of Chan, Golub & LeVeque
//! ("Updating formulae and a pairwise algorithm for computing sample variances", 1979):
//! S = S_a + S_b + δ² n_a n_b / n, δ = mean_b − mean_a. Everything is accumulated in double
//! precision (the parts' S_n with their Kahan compensation, s − c) and rounded to float once,
//! at the end.
//!
//! The order is fixed, whatever order the files are given in: every pixel folds its pieces in
//! the order of their samples, and which file's record the result carries is decided by the
//! pieces too (the one holding sample 0 of the top-left-most tile). A bundle written by
//! `merge --partial` keeps its pieces as they are, so merging in groups folds the same pieces in
//! the same order: any order or grouping of the same parts gives the same bytes.
//!
//! Everything a user can get wrong is checked from the headers, before a payload is read:
//! parts of another scene, kernel, resolution, seed, length or set of outputs, the same file
//! twice, duplicate or overlapping pieces, and missing samples anywhere in the image.

use std::collections::BTreeMap;
use std::mem::{offset_of, size_of};
use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

use super::RenderRecord;
use super::partial::{self, PartialFile, Piece, PieceInfo, RenderIdentity};
use crate::layout::outputs::{BufferId, Merge, Output, WELFORD_MEANS};
use crate::layout::{DepthShift, FilterVector, WelfordState, WelfordSums};
use crate::render::{Frame, FrameInfo, HostBuffer, SceneInfo, VarianceForm};

const F_DEPTH: usize = offset_of!(FilterVector, depth) / 4;
const K: usize = offset_of!(DepthShift, shift) / 4;
const K_MEAN: usize = offset_of!(DepthShift, mean) / 4;
const W_DIRECTION: Range<usize> = {
    let d = offset_of!(WelfordState, direction_mean) / 4;
    d..d + 3
};
const W_COMPENSATION: usize = offset_of!(WelfordState, s_compensation) / 4;
const S_LANES: usize = offset_of!(WelfordSums, pad) / 4;

/// The parts to merge, checked against each other, and their pieces in merge order.
#[derive(Debug)]
pub struct Plan {
    pub files: Vec<PartialFile>,
    /// (file, piece) in the order they are folded: by first sample, then tile position.
    pub order: Vec<(usize, usize)>,
    /// The render the parts make up (the record of the file holding the first piece).
    pub identity: RenderIdentity,
}

/// What rendering the pieces cost.
#[derive(Clone, Debug, Default)]
pub struct CostSummary {
    pub pieces: usize,
    pub rays: u64,
    /// Device seconds of each piece, in merge order.
    pub seconds: Vec<f64>,
    /// Devices that rendered them.
    pub devices: Vec<String>,
}

fn order_key(p: &PieceInfo) -> (u32, u32, u32, u32, u32, u32) {
    let t = p.tile;
    (p.samples.start, t.y, t.x, p.samples.end, t.height, t.width)
}

impl Plan {
    /// Opens every part and checks that they make up exactly one render: compatible headers,
    /// no file twice, no sample of any pixel twice or missing. Errors name the files.
    pub fn new(paths: &[PathBuf]) -> Result<Plan> {
        Plan::build(paths, true)
    }

    /// As [`Plan::new`] for parts of one render that need not make up all of it (a bundle:
    /// `merge --partial`): only overlaps are refused.
    pub fn bundle(paths: &[PathBuf]) -> Result<Plan> {
        Plan::build(paths, false)
    }

    fn build(paths: &[PathBuf], complete: bool) -> Result<Plan> {
        if paths.is_empty() {
            bail!("no parts to merge");
        }
        let mut seen: BTreeMap<PathBuf, &Path> = BTreeMap::new();
        for p in paths {
            let key = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
            if let Some(first) = seen.insert(key, p) {
                bail!(
                    "{} is given twice (also as {})",
                    p.display(),
                    first.display()
                );
            }
        }
        let files = paths
            .iter()
            .map(|p| PartialFile::open(p))
            .collect::<Result<Vec<_>>>()?;
        let mut order: Vec<(usize, usize)> = files
            .iter()
            .enumerate()
            .flat_map(|(f, file)| (0..file.pieces.len()).map(move |k| (f, k)))
            .collect();
        let info = |(f, k): (usize, usize)| &files[f].pieces[k].info;
        // File paths break ties only between identical pieces, which coverage refuses.
        order.sort_by(|&a, &b| {
            order_key(info(a))
                .cmp(&order_key(info(b)))
                .then_with(|| files[a.0].path.cmp(&files[b.0].path))
        });
        let first = &files[order[0].0];
        for f in &files {
            check_compatible(first, f)?;
        }
        let plan = Plan {
            identity: first.identity.clone(),
            files,
            order,
        };
        plan.check_coverage(complete)?;
        Ok(plan)
    }

    fn piece(&self, i: usize) -> (&PartialFile, &PieceInfo) {
        let (f, k) = self.order[i];
        (&self.files[f], &self.files[f].pieces[k].info)
    }

    fn describe(&self, i: usize) -> String {
        let (file, info) = self.piece(i);
        let id = &self.identity;
        format!(
            "{} ({})",
            file.path.display(),
            info.describe(id.width, id.height)
        )
    }

    /// Every pixel must get each sample 0..spp from exactly one piece (at most one, unless
    /// `complete`).
    fn check_coverage(&self, complete: bool) -> Result<()> {
        let id = &self.identity;
        let pixels = id.width as usize * id.height as usize;
        let mut next = vec![0u32; pixels];
        let mut last = vec![u32::MAX; pixels];
        // Missing range → (pixels, bounding box x0, y0, x1, y1).
        let mut gaps: BTreeMap<(u32, u32), (u64, [u32; 4])> = BTreeMap::new();
        let mut gap = |range: (u32, u32), p: usize| {
            let (x, y) = (
                (p % id.width as usize) as u32,
                (p / id.width as usize) as u32,
            );
            let e = gaps.entry(range).or_insert((0, [x, y, x, y]));
            e.0 += 1;
            e.1 = [e.1[0].min(x), e.1[1].min(y), e.1[2].max(x), e.1[3].max(y)];
        };
        for i in 0..self.order.len() {
            let (_, info) = self.piece(i);
            for t in 0..info.tile.pixels() {
                let p = info.tile.image_pixel(t, id.width);
                let a = info.samples.start;
                if next[p] > a {
                    let other = last[p] as usize;
                    let (_, o) = self.piece(other);
                    let how = if o == info {
                        "duplicate pieces"
                    } else {
                        "overlapping pieces"
                    };
                    bail!(
                        "{how}: {} and {} both hold samples of pixel ({}, {}); each sample \
                         must come from one part",
                        self.describe(other),
                        self.describe(i),
                        p % id.width as usize,
                        p / id.width as usize
                    );
                }
                if next[p] < a {
                    gap((next[p], a), p);
                }
                next[p] = info.samples.end;
                last[p] = i as u32;
            }
        }
        for (p, &n) in next.iter().enumerate() {
            if n < id.spp {
                gap((n, id.spp), p);
            }
        }
        if gaps.is_empty() || !complete {
            return Ok(());
        }
        let list: Vec<String> = gaps
            .iter()
            .map(|(&(a, b), &(count, [x0, y0, x1, y1]))| {
                let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
                let whole = count == pixels as u64;
                let region = if whole {
                    "of the whole image".to_string()
                } else if count == w as u64 * h as u64 {
                    format!("of tile {w}x{h}+{x0}+{y0}")
                } else {
                    format!("of {count} pixels within {w}x{h}+{x0}+{y0}")
                };
                format!("samples {a}..{b} {region}")
            })
            .collect();
        bail!(
            "missing {}: the {} part(s) given do not make up the {} spp of {} (render the \
             missing range with `noisefree render SCENE --spp {} --samples A..B --partial \
             FILE.nfp`, with --tile for a tile)",
            list.join(", "),
            self.files.len(),
            id.spp,
            id.scene,
            id.spp
        )
    }

    /// What rendering the pieces cost, in merge order.
    pub fn cost(&self) -> CostSummary {
        let mut c = CostSummary {
            pieces: self.order.len(),
            ..Default::default()
        };
        for i in 0..self.order.len() {
            let (_, info) = self.piece(i);
            c.rays += info.rays;
            c.seconds.push(info.seconds);
            if !c.devices.contains(&info.device) {
                c.devices.push(info.device.clone());
            }
        }
        c
    }

    /// Writes every piece into one partial file (payloads as they are, in merge order).
    pub fn write_bundle(&self, path: &Path) -> Result<()> {
        let sources: Vec<(&PartialFile, usize)> = self
            .order
            .iter()
            .map(|&(f, k)| (&self.files[f], k))
            .collect();
        partial::write_bundle(path, &self.identity, &sources)
    }

    /// Folds every piece, in merge order, into the outputs of the whole render; `progress` is
    /// called after each piece with the number done. The plan must be complete ([`Plan::new`]).
    pub fn merge(&self, mut progress: impl FnMut(usize)) -> Result<Merged> {
        let mut acc = Accumulator::new(&self.identity);
        for i in 0..self.order.len() {
            let (f, k) = self.order[i];
            acc.fold(&self.files[f].read_piece(k)?);
            progress(i + 1);
        }
        let id = &self.identity;
        let info = FrameInfo {
            width: id.width,
            height: id.height,
            spp: id.spp,
            sample_capacity: if id.outputs.contains(Output::Samples) {
                id.spp
            } else {
                0
            },
            scene: id.record.scene.clone().unwrap_or_else(SceneInfo::unknown),
        };
        let frame = Frame::on_host(info, id.outputs, VarianceForm::Sums, acc.finish())?;
        let mut record = id.record.clone();
        record.extra.insert("spp".into(), id.spp.to_string());
        Ok(Merged {
            frame,
            record,
            cost: self.cost(),
        })
    }
}

/// A merged render.
pub struct Merged {
    pub frame: Frame,
    pub record: RenderRecord,
    pub cost: CostSummary,
}

/// Refuses parts of another render, naming both files and what differs.
fn check_compatible(a: &PartialFile, b: &PartialFile) -> Result<()> {
    let (x, y) = (&a.identity, &b.identity);
    let (pa, pb) = (a.path.display(), b.path.display());
    if (x.width, x.height) != (y.width, y.height) {
        bail!(
            "{pa} and {pb} are parts of renders at different resolutions ({}x{} and {}x{})",
            x.width,
            x.height,
            y.width,
            y.height
        );
    }
    if x.seed != y.seed {
        bail!(
            "{pa} and {pb} are parts of renders with different seeds ({} and {})",
            x.seed,
            y.seed
        );
    }
    if x.scene_hash != y.scene_hash {
        bail!(
            "{pa} and {pb} are parts of different scenes: {} (scene hash {:016x}) and {} \
             (scene hash {:016x})",
            x.scene,
            x.scene_hash,
            y.scene,
            y.scene_hash
        );
    }
    if x.kernel_hash != y.kernel_hash {
        bail!(
            "{pa} and {pb} were rendered by different kernels (kernel hashes {:016x} and \
             {:016x}: different versions of noisefree); render every part with one build",
            x.kernel_hash,
            y.kernel_hash
        );
    }
    if x.spp != y.spp {
        bail!(
            "{pa} and {pb} are parts of renders of different lengths ({} and {} spp)",
            x.spp,
            y.spp
        );
    }
    if x.outputs != y.outputs {
        bail!(
            "{pa} and {pb} gathered different outputs ({} and {}); render every part with the \
             same --filter and --gather",
            x.outputs.names().join(", "),
            y.outputs.names().join(", ")
        );
    }
    Ok(())
}

/// Floats of a WelfordSums element.
const FS: usize = size_of::<WelfordSums>() / 4;

/// The merged state of every pixel, in double precision; per-sample buffers as they will be
/// written.
struct Accumulator {
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
        let floats = id.decl().element_bytes / 4;
        &self.buffer(id).floats()[self.t * floats..(self.t + 1) * floats]
    }
}

impl Accumulator {
    fn new(id: &RenderIdentity) -> Accumulator {
        let pixels = id.width as usize * id.height as usize;
        let state = id
            .outputs
            .buffers()
            .map(|b| {
                let floats = b.element_bytes / 4;
                let s = match b.merge {
                    Merge::PerSample => State::Samples(HostBuffer::zeroed(
                        b.bytes(id.width, id.height, id.spp) as usize,
                    )),
                    Merge::Means
                    | Merge::DepthShift
                    | Merge::WelfordSums
                    | Merge::WelfordState
                    | Merge::HitMeans => State::Lanes {
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
            Merge::WelfordSums | Merge::PerSample => {
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
            Merge::WelfordSums | Merge::PerSample => false,
        }
    }

    fn fold(&mut self, piece: &Piece) {
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
                            Merge::Means | Merge::DepthShift | Merge::PerSample => {}
                        }
                    }
                }
            }
            self.count[p] += px.nb;
        }
    }

    /// The buffers, rounded to float, and F.depth = K + mean(x − K) formed as film.cl forms it.
    fn finish(self) -> Vec<(BufferId, HostBuffer)> {
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
                Merge::Means => {
                    if let Some(d) = self.lanes(BufferId::DepthShifts) {
                        for p in 0..pixels {
                            let k = d[p * 2 + K] as f32;
                            f[p * floats + F_DEPTH] = k + d[p * 2 + K_MEAN] as f32;
                        }
                    }
                }
                Merge::DepthShift
                | Merge::WelfordSums
                | Merge::WelfordState
                | Merge::HitMeans
                | Merge::PerSample => {}
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
