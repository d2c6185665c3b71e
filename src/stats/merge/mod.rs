//! Merging partial renders (src/stats/partial/) into the render of all their samples: the
//! parts of one render, each a range of the samples of a tile of the image, combine into the
//! outputs a single render of every sample would have left, to float rounding.
//!
//! How each buffer merges is declared with it (`Merge` in src/layout/outputs.rs) and applied
//! by exhaustive matches (accumulate.rs), so a new output cannot be forgotten. Means combine weighted by
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
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

use super::RenderRecord;
use super::partial::{self, PartialFile, PieceInfo, RenderIdentity};
use crate::layout::outputs::Output;
use crate::render::{Frame, FrameInfo, SceneInfo, VarianceForm};

mod accumulate;
use accumulate::Accumulator;

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
            acc.fold(&self.files[f].read_piece(k)?)?;
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
            shadow_lights: id.shadow_lights.clone(),
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
