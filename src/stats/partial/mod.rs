//! Partial renders: the outputs of a range of the samples (and a tile of the image) of one
//! render, in a file that `noisefree merge` combines with the others into the whole render
//! (src/stats/merge/). `render --samples A..B --partial part.nfp` writes one; `merge
//! --partial` writes the pieces of several into one file.
//!
//! A part holds every accumulator of every output buffer the render gathered, exactly as the
//! renderer left them (running means, depth shifts, Welford S_n with their Kahan compensation,
//! hit counts, sample vectors: src/layout/outputs.rs), plus what decides whether parts belong
//! together: the scene and kernel hashes, seed, resolution and the samples per pixel of the
//! whole render.
//!
//! # The partial-file format (`.nfp`, version 1)
//!
//! Little-endian throughout. A 16-byte prefix:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic, the ASCII bytes `NFPARTAL` |
//! | 8 | 4 | version, `u32` = 1 |
//! | 12 | 4 | header length L in bytes, `u32` (at most 16 MiB) |
//!
//! then L bytes of UTF-8 TOML, the header:
//!
//! | key | meaning |
//! |---|---|
//! | `format` | `"noisefree partial render"` |
//! | `version` | 1, as in the prefix |
//! | `scene` | the scene file (for messages) |
//! | `scene_hash` | 16 hex digits: FNV-1a of the scene as uploaded (geometry, materials, textures, lights, camera, resolution, seed; `render::scene_hash`) |
//! | `kernel_hash` | 16 hex digits: FNV-1a of the megakernel's program text (`render::kernel_hash`) |
//! | `width`, `height` | the whole image, pixels |
//! | `seed` | the render's seed |
//! | `spp` | samples per pixel of the whole render (the ranges of all parts make 0..spp) |
//! | `outputs` | the outputs gathered, by name (`colour`, `features`, `variance`, `position`, `samples`) |
//! | `light_field` | with the light-field output: the field it holds, `shadows`, `lens` or `gi` (`FieldKind`); absent in files written before it was recorded |
//! | `[[buffers]]` | per gathered buffer, in the kernel's order: `name`, `element` (its struct), `element_bytes`, `per` (`pixel` or `sample`); a file whose layout differs from this build's is refused |
//! | `[record]` | the render record (scene information, filter, settings: src/stats/record.rs) as text |
//! | `[[pieces]]` | per piece: `tile` (`x`, `y`, `width`, `height`), `samples` = [A, B] (samples A..B−1), `offset` and `bytes` of its payload, `fnv1a` (16 hex digits, its checksum), `rays` traced, device `seconds`, `device` |
//!
//! Zero bytes pad the file to the next multiple of 64: there, at D = ⌈(16 + L) / 64⌉ · 64, the
//! payloads begin, piece after piece (piece i at D + `offset`, the offsets consecutive). A
//! piece's payload is each gathered buffer in turn, in `[[buffers]]` order, as the renderer
//! leaves it: per-pixel buffers one element per pixel of the tile, row by row; per-sample
//! buffers B − A elements per pixel, pixel-major (pixel p's sample A + s at p · (B − A) + s).
//! Elements are the shared structs of src/layout/mod.rs, f32 lanes. The checksum is FNV-1a over
//! the buffers, each followed by the byte 0xff (`gpu::fnv1a` with one part per buffer). The
//! file is exactly D + Σ `bytes` long; anything else is an error.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, anyhow, bail};
use serde::{Deserialize, Serialize};

use super::RenderRecord;
use crate::gpu::Fnv1a;
use crate::layout::outputs::{BufferDecl, OUTPUTS, Output, OutputSet, Per};
use crate::render::{Frame, HostBuffer, Tile};

// Payloads are the host's f32 bytes as they are.
const _: () = assert!(cfg!(target_endian = "little"));

/// First eight bytes of a partial file.
pub const MAGIC: [u8; 8] = *b"NFPARTAL";
/// The version this code reads and writes.
pub const VERSION: u32 = 1;
/// The header's `format`.
pub const FORMAT: &str = "noisefree partial render";
/// Longest header a file may carry.
pub const MAX_HEADER_BYTES: u32 = 16 << 20;
const PREFIX_BYTES: u64 = 16;
const PAYLOAD_ALIGN: u64 = 64;

mod write;
pub use write::{write, write_bundle};

/// Which render a part belongs to: what every part of one render shares.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderIdentity {
    /// The scene file (for messages).
    pub scene: String,
    pub scene_hash: u64,
    pub kernel_hash: u64,
    pub width: u32,
    pub height: u32,
    pub seed: u32,
    /// Samples per pixel of the whole render.
    pub spp: u32,
    /// The outputs gathered (closed under their requirements, as the renderer gathers them).
    pub outputs: OutputSet,
    /// The sphere light of each plane of the shadow output (empty without it).
    pub shadow_lights: Vec<u32>,
    pub record: RenderRecord,
}

impl RenderIdentity {
    pub fn shadow_planes(&self) -> u32 {
        self.shadow_lights.len() as u32
    }
}

/// Samples `samples` of the pixels of `tile`, and what rendering them cost.
#[derive(Clone, Debug, PartialEq)]
pub struct PieceInfo {
    pub tile: Tile,
    pub samples: Range<u32>,
    pub rays: u64,
    /// Device (kernel) time.
    pub seconds: f64,
    pub device: String,
}

impl PieceInfo {
    pub fn count(&self) -> u32 {
        self.samples.end - self.samples.start
    }

    /// "samples 8..16 of tile 256x256+0+0" (no tile for the whole image).
    pub fn describe(&self, width: u32, height: u32) -> String {
        let samples = format!("samples {}..{}", self.samples.start, self.samples.end);
        if self.tile.is_whole(width, height) {
            samples
        } else {
            format!("{samples} of tile {}", self.tile)
        }
    }
}

/// A piece with its buffers: one per gathered buffer, in table order.
#[derive(Clone, Debug)]
pub struct Piece {
    pub info: PieceInfo,
    pub buffers: Vec<(crate::layout::outputs::BufferId, HostBuffer)>,
}

impl Piece {
    /// The piece a render's frame holds: every buffer of its outputs, for `info`'s tile and
    /// samples (a per-sample buffer must hold exactly those samples).
    pub fn of_frame(frame: &Frame, info: PieceInfo) -> Result<Piece> {
        let f = frame.info();
        if (f.width, f.height) != (info.tile.width, info.tile.height) || f.spp != info.count() {
            bail!(
                "a {}x{} frame of {} spp is not {} ({} samples)",
                f.width,
                f.height,
                f.spp,
                info.tile,
                info.count()
            );
        }
        if frame.outputs().contains(Output::Samples) && f.sample_capacity != info.count() {
            bail!(
                "the frame keeps {} samples per pixel, its range has {}",
                f.sample_capacity,
                info.count()
            );
        }
        let buffers = frame
            .outputs()
            .buffers()
            .map(|b| Ok((b.id, frame.host(b.id)?.clone())))
            .collect::<Result<_>>()?;
        Ok(Piece { info, buffers })
    }

    fn checksum(&self) -> u64 {
        let mut h = Fnv1a::new();
        for (_, b) in &self.buffers {
            h.update(b.as_bytes());
            h.end_part();
        }
        h.finish()
    }

    fn bytes(&self) -> u64 {
        self.buffers.iter().map(|(_, b)| b.len_bytes() as u64).sum()
    }
}

/// Bytes of each gathered buffer of a piece covering `tile` and `count` samples.
fn buffer_bytes(
    identity: &RenderIdentity,
    tile: Tile,
    count: u32,
) -> Vec<(&'static BufferDecl, u64)> {
    let planes = identity.shadow_planes();
    identity
        .outputs
        .buffers()
        .map(|b| (b, b.bytes(tile.width, tile.height, count, planes)))
        .collect()
}

#[derive(Serialize, Deserialize, PartialEq, Debug)]
struct BufferLayout {
    name: String,
    element: String,
    element_bytes: u32,
    per: String,
}

impl BufferLayout {
    fn of(b: &BufferDecl) -> BufferLayout {
        BufferLayout {
            name: b.name.into(),
            element: b.element.into(),
            element_bytes: b.element_bytes as u32,
            per: match b.per {
                Per::Pixel => "pixel",
                Per::Sample => "sample",
                Per::Light => "light",
            }
            .into(),
        }
    }
}

#[derive(Serialize, Deserialize, Debug)]
struct PieceHeader {
    tile: Tile,
    samples: [u32; 2],
    offset: u64,
    bytes: u64,
    fnv1a: String,
    rays: u64,
    seconds: f64,
    device: String,
}

#[derive(Serialize, Deserialize, Debug)]
struct Header {
    format: String,
    version: u32,
    scene: String,
    scene_hash: String,
    kernel_hash: String,
    width: u32,
    height: u32,
    seed: u32,
    spp: u32,
    outputs: Vec<String>,
    /// The sphere light of each plane of the shadow output.
    #[serde(default)]
    shadow_lights: Vec<u32>,
    /// What the light-field output holds ([`crate::layout::outputs::FieldKind::name`]); files
    /// written before it was recorded have none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    light_field: Option<String>,
    buffers: Vec<BufferLayout>,
    record: BTreeMap<String, String>,
    pieces: Vec<PieceHeader>,
}

fn hex(v: u64) -> String {
    format!("{v:016x}")
}

fn parse_hex(s: &str, what: &str) -> Result<u64> {
    u64::from_str_radix(s, 16).map_err(|_| anyhow!("{what} {s:?} is not a hexadecimal hash"))
}

/// A piece as a file lists it.
#[derive(Clone, Debug)]
pub struct PieceEntry {
    pub info: PieceInfo,
    offset: u64,
    bytes: u64,
    checksum: u64,
}

/// A partial file, its header read and checked; the payloads are read piece by piece.
#[derive(Debug)]
pub struct PartialFile {
    pub path: PathBuf,
    pub identity: RenderIdentity,
    pub pieces: Vec<PieceEntry>,
    data_start: u64,
}

fn data_start(header_bytes: u64) -> u64 {
    (PREFIX_BYTES + header_bytes).div_ceil(PAYLOAD_ALIGN) * PAYLOAD_ALIGN
}

/// Whether the file at `path` starts with the partial-file magic.
pub fn is_partial_file(path: &Path) -> bool {
    let mut magic = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && magic == MAGIC
}

impl PartialFile {
    /// Opens a partial file and checks its header: magic, version, the buffer layout against
    /// this build's, every piece inside the image and the render's samples, the payload sizes
    /// and the file length. Errors name the file.
    pub fn open(path: &Path) -> Result<PartialFile> {
        Self::open_inner(path).with_context(|| format!("{}", path.display()))
    }

    fn open_inner(path: &Path) -> Result<PartialFile> {
        let mut file = File::open(path).context("cannot open it")?;
        let len = file.metadata().context("cannot read its size")?.len();
        if len < PREFIX_BYTES {
            bail!("not a partial render: {len} bytes, shorter than the {PREFIX_BYTES}-byte prefix");
        }
        let mut prefix = [0u8; PREFIX_BYTES as usize];
        file.read_exact(&mut prefix)?;
        if prefix[..8] != MAGIC {
            bail!(
                "not a partial render (it starts with {:?}, a partial file with {:?})",
                String::from_utf8_lossy(&prefix[..8]),
                String::from_utf8_lossy(&MAGIC)
            );
        }
        let word = |i: usize| u32::from_le_bytes(prefix[i..i + 4].try_into().expect("4 bytes"));
        let (version, header_len) = (word(8), word(12));
        if version != VERSION {
            bail!("partial-file version {version}; this build reads version {VERSION}");
        }
        if header_len > MAX_HEADER_BYTES || PREFIX_BYTES + header_len as u64 > len {
            bail!("the header claims {header_len} bytes: a damaged or truncated file");
        }
        let mut text = vec![0u8; header_len as usize];
        file.read_exact(&mut text)?;
        let text = String::from_utf8(text).context("the header is not UTF-8 text")?;
        let h: Header =
            toml::from_str(&text).map_err(|e| anyhow!("the header: {}", e.message().trim_end()))?;
        let identity = check_header(&h)?;
        let start = data_start(header_len as u64);
        let mut pieces = Vec::with_capacity(h.pieces.len());
        let mut next = 0u64;
        for (i, p) in h.pieces.iter().enumerate() {
            let info = PieceInfo {
                tile: p.tile,
                samples: p.samples[0]..p.samples[1],
                rays: p.rays,
                seconds: p.seconds,
                device: p.device.clone(),
            };
            let what = format!("piece {i} ({})", info.describe(h.width, h.height));
            info.tile
                .check_within(h.width, h.height)
                .with_context(|| what.clone())?;
            if info.samples.start >= info.samples.end || info.samples.end > h.spp {
                bail!(
                    "{what}: the range is empty or runs past the render's {} samples",
                    h.spp
                );
            }
            let want: u64 = buffer_bytes(&identity, info.tile, info.count())
                .iter()
                .map(|(_, n)| n)
                .sum();
            if p.bytes != want || p.offset != next {
                bail!(
                    "{what}: its payload is listed as {} bytes at offset {}, its outputs take \
                     {want} bytes at offset {next}: a damaged header",
                    p.bytes,
                    p.offset
                );
            }
            next += want;
            pieces.push(PieceEntry {
                info,
                offset: p.offset,
                bytes: p.bytes,
                checksum: parse_hex(&p.fnv1a, &format!("{what}: fnv1a"))?,
            });
        }
        if pieces.is_empty() {
            bail!("the header lists no pieces");
        }
        let expected = start + next;
        if len != expected {
            bail!(
                "{} file: the header and payloads take {expected} bytes, the file has {len}",
                if len < expected {
                    "truncated"
                } else {
                    "damaged"
                }
            );
        }
        Ok(PartialFile {
            path: path.to_path_buf(),
            identity,
            pieces,
            data_start: start,
        })
    }

    /// The payload of piece `i`, its checksum verified.
    fn read_payload(&self, i: usize) -> Result<Vec<u8>> {
        let e = &self.pieces[i];
        let mut file = BufReader::new(File::open(&self.path)?);
        file.seek(SeekFrom::Start(self.data_start + e.offset))?;
        let mut bytes = Vec::new();
        bytes
            .try_reserve_exact(e.bytes as usize)
            .map_err(|_| anyhow!("cannot allocate {} bytes for a piece", e.bytes))?;
        file.take(e.bytes).read_to_end(&mut bytes)?;
        let mut h = Fnv1a::new();
        let mut at = 0usize;
        for (_, n) in buffer_bytes(&self.identity, e.info.tile, e.info.count()) {
            h.update(&bytes[at..at + n as usize]);
            h.end_part();
            at += n as usize;
        }
        if at != bytes.len() || h.finish() != e.checksum {
            bail!(
                "{}: the payload of {} does not match its checksum: a damaged file",
                self.path.display(),
                e.info.describe(self.identity.width, self.identity.height)
            );
        }
        Ok(bytes)
    }

    /// Piece `i` with its buffers.
    pub fn read_piece(&self, i: usize) -> Result<Piece> {
        let e = &self.pieces[i];
        let bytes = self.read_payload(i)?;
        let mut at = 0usize;
        let buffers = buffer_bytes(&self.identity, e.info.tile, e.info.count())
            .into_iter()
            .map(|(b, n)| {
                let mut h = HostBuffer::zeroed(n as usize);
                h.as_bytes_mut()
                    .copy_from_slice(&bytes[at..at + n as usize]);
                at += n as usize;
                (b.id, h)
            })
            .collect();
        Ok(Piece {
            info: e.info.clone(),
            buffers,
        })
    }
}

/// The identity a header describes, checked against this build's output layout.
fn check_header(h: &Header) -> Result<RenderIdentity> {
    if h.format != FORMAT || h.version != VERSION {
        bail!(
            "the header says format {:?} version {}, expected {FORMAT:?} version {VERSION}",
            h.format,
            h.version
        );
    }
    if h.width == 0 || h.height == 0 || h.spp == 0 {
        bail!(
            "the header says {}x{} at {} spp: every size must be at least 1",
            h.width,
            h.height,
            h.spp
        );
    }
    let mut outputs = OutputSet::default();
    for name in &h.outputs {
        let o = OUTPUTS
            .iter()
            .find(|o| o.name == name)
            .with_context(|| format!("the header lists an unknown output {name:?}"))?;
        outputs = outputs.with(o.output);
    }
    if let Some(name) = &h.light_field {
        outputs = outputs.with_field_named(name).with_context(|| {
            format!(
                "the header says the light-field output holds {name:?}, which its outputs ({}) \
                 cannot hold",
                h.outputs.join(", ")
            )
        })?;
    }
    if outputs != outputs.closed() || !outputs.contains(Output::Colour) {
        bail!(
            "the header's outputs ({}) lack what they need ({})",
            h.outputs.join(", "),
            outputs.closed().names().join(", ")
        );
    }
    if outputs.contains(Output::Shadows) == h.shadow_lights.is_empty() {
        bail!(
            "the header's shadow output has {} light plane(s) (shadow_lights = {:?}): a file \
             with the shadow output names the light of each plane (files written before the \
             output had planes do not; render them again)",
            h.shadow_lights.len(),
            h.shadow_lights
        );
    }
    let layout: Vec<BufferLayout> = outputs.buffers().map(BufferLayout::of).collect();
    if h.buffers != layout {
        bail!(
            "its buffers are laid out differently from this build's (another version of \
             noisefree wrote it): {:?}, this build: {:?}",
            h.buffers,
            layout
        );
    }
    Ok(RenderIdentity {
        scene: h.scene.clone(),
        scene_hash: parse_hex(&h.scene_hash, "scene_hash")?,
        kernel_hash: parse_hex(&h.kernel_hash, "kernel_hash")?,
        width: h.width,
        height: h.height,
        seed: h.seed,
        spp: h.spp,
        outputs,
        shadow_lights: h.shadow_lights.clone(),
        record: RenderRecord::from_attributes(&h.record)?,
    })
}
