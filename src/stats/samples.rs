//! The per-sample output of a render: the RPF sample vectors of one image (thesis §5.1.1,
//! Table 5.1), their memory budget and the `samples.bin` file that stores them with a record of
//! the render ([`RenderRecord`]), so that `noisefree filter samples.bin` repeats what the
//! render did.
//!
//! # The `samples.bin` format (version 2)
//!
//! Everything is little-endian. A 28-byte header:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic, the ASCII bytes `NFRPFSMP` |
//! | 8 | 4 | version, `u32` = 2 (1: the same without the record) |
//! | 12 | 4 | width in pixels, `u32` ≥ 1 |
//! | 16 | 4 | height in pixels, `u32` ≥ 1 |
//! | 20 | 4 | samples per pixel, `u32` ≥ 1 |
//! | 24 | 4 | floats per sample, `u32` = 26 |
//!
//! then (version 2) a `u32` byte count and that many bytes of UTF-8 TOML: the render record
//! (scene information and filter settings, as text attributes), then `width · height · spp`
//! sample vectors of 26 `f32` each (104 bytes), pixel-major:
//! sample `s` of pixel `(x, y)` is vector number `(y · width + x) · spp + s`. The 26 floats of
//! a vector are the fields of [`SampleVector`] in declaration order: `position[2]`,
//! `random[6]` (u, v, t, x, y, z), `world1[3]`, `normal1[3]`, `world2[3]`, `normal2[3]`,
//! `texture1[3]`, `color[3]`. Every float is finite. The file is exactly
//! `28 + 4 + record bytes + 104 · width · height · spp` bytes long (version 1: `28 + 104 ·
//! width · height · spp`); anything else is an error.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::Path;

use anyhow::{Context as _, Result, bail};

use super::RenderRecord;
use crate::layout::SampleVector;
use crate::layout::outputs::{BufferId, Output, OutputSet};
pub use crate::memory::{available_memory_bytes, human_bytes};
use crate::render::{Frame, FrameInfo, HostBuffer, SceneInfo, VarianceForm};

/// Floats per sample vector (Table 5.1): 2 + 6 + 15 + 3.
pub const FLOATS_PER_SAMPLE: usize = 26;
/// Bytes per sample vector.
pub const BYTES_PER_SAMPLE: u64 = (FLOATS_PER_SAMPLE * 4) as u64;
/// First eight bytes of a `samples.bin` file.
pub const MAGIC: [u8; 8] = *b"NFRPFSMP";
/// The version this code writes (it reads 1 and 2).
pub const VERSION: u32 = 2;
/// Longest render record a file may carry.
pub const MAX_RECORD_BYTES: u32 = 1 << 20;
/// Header bytes before the first sample vector.
pub const HEADER_BYTES: u64 = 28;

/// Names of the 26 floats of a sample vector, in file order (for error messages).
pub const FIELD_NAMES: [&str; FLOATS_PER_SAMPLE] = [
    "position.x",
    "position.y",
    "random.u",
    "random.v",
    "random.t",
    "random.x",
    "random.y",
    "random.z",
    "world1.x",
    "world1.y",
    "world1.z",
    "normal1.x",
    "normal1.y",
    "normal1.z",
    "world2.x",
    "world2.y",
    "world2.z",
    "normal2.x",
    "normal2.y",
    "normal2.z",
    "texture1.r",
    "texture1.g",
    "texture1.b",
    "color.r",
    "color.g",
    "color.b",
];

/// The 26 floats of a sample vector in file order.
pub fn to_floats(s: &SampleVector) -> [f32; FLOATS_PER_SAMPLE] {
    let mut a = [0.0f32; FLOATS_PER_SAMPLE];
    a[0..2].copy_from_slice(&s.position);
    a[2..8].copy_from_slice(&s.random);
    a[8..11].copy_from_slice(&s.world1);
    a[11..14].copy_from_slice(&s.normal1);
    a[14..17].copy_from_slice(&s.world2);
    a[17..20].copy_from_slice(&s.normal2);
    a[20..23].copy_from_slice(&s.texture1);
    a[23..26].copy_from_slice(&s.color);
    a
}

/// The inverse of [`to_floats`].
pub fn from_floats(a: &[f32; FLOATS_PER_SAMPLE]) -> SampleVector {
    let mut s = SampleVector::default();
    s.position.copy_from_slice(&a[0..2]);
    s.random.copy_from_slice(&a[2..8]);
    s.world1.copy_from_slice(&a[8..11]);
    s.normal1.copy_from_slice(&a[11..14]);
    s.world2.copy_from_slice(&a[14..17]);
    s.normal2.copy_from_slice(&a[17..20]);
    s.texture1.copy_from_slice(&a[20..23]);
    s.color.copy_from_slice(&a[23..26]);
    s
}

/// Bytes the sample vectors of a `width × height` image at `spp` samples per pixel take:
/// 26 · 4 · spp · W · H (§5.1.1; 1280 × 720 at 8 spp is 766,771,200 bytes ≈ 731 MiB).
/// Saturates instead of overflowing.
pub fn memory_bytes(width: u32, height: u32, spp: u32) -> u64 {
    BYTES_PER_SAMPLE
        .saturating_mul(width as u64)
        .saturating_mul(height as u64)
        .saturating_mul(spp as u64)
}

/// Checks, before anything is allocated, that the sample vectors of a `width × height` image at
/// `spp` fit in `budget` bytes; the error says how much is needed and how many samples per
/// pixel (or rows, for rendering in tiles) would fit.
pub fn check_memory(width: u32, height: u32, spp: u32, budget: u64) -> Result<()> {
    let need = memory_bytes(width, height, spp);
    if need <= budget {
        return Ok(());
    }
    let per_pixel = memory_bytes(1, 1, spp).max(1);
    let per_row = per_pixel.saturating_mul(width as u64).max(1);
    let spp_fit = budget / memory_bytes(width, height, 1).max(1);
    bail!(
        "RPF sample vectors of {width}x{height} at {spp} spp need {} ({need} bytes = 26 floats x 4 \
         bytes x spp x W x H) but only {} are available: use at most {spp_fit} spp, or process \
         at most {} rows at a time",
        human_bytes(need),
        human_bytes(budget),
        budget / per_row
    )
}

/// The sample vectors of one image, pixel-major: `samples[(y · width + x) · spp + s]`, and
/// what the render recorded about itself.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleSet {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub samples: Vec<SampleVector>,
    pub record: RenderRecord,
}

impl SampleSet {
    /// A set with its dimensions checked against `samples.len()` and every value checked finite.
    pub fn new(width: u32, height: u32, spp: u32, samples: Vec<SampleVector>) -> Result<SampleSet> {
        let set = SampleSet {
            width,
            height,
            spp,
            samples,
            record: RenderRecord::default(),
        };
        set.validate()?;
        Ok(set)
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The samples of pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> &[SampleVector] {
        let s = self.spp as usize;
        let p = y as usize * self.width as usize + x as usize;
        &self.samples[p * s..(p + 1) * s]
    }

    /// Checks the dimensions (none zero, `width · height · spp` vectors) and that every value is
    /// finite; the error names the first offending sample, its pixel and field.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 || self.spp == 0 {
            bail!(
                "RPF sample set of {}x{} at {} spp: width, height and spp must be at least 1",
                self.width,
                self.height,
                self.spp
            );
        }
        let expected = self.width as u64 * self.height as u64 * self.spp as u64;
        if self.samples.len() as u64 != expected {
            bail!(
                "RPF sample set of {}x{} at {} spp needs {expected} sample vectors but has {}",
                self.width,
                self.height,
                self.spp,
                self.samples.len()
            );
        }
        for (i, s) in self.samples.iter().enumerate() {
            let f = to_floats(s);
            if let Some(k) = f.iter().position(|v| !v.is_finite()) {
                bail!("{}", self.describe_bad_value(i, k, f[k]));
            }
        }
        Ok(())
    }

    fn describe_bad_value(&self, index: usize, field: usize, value: f32) -> String {
        let spp = self.spp as usize;
        let pixel = index / spp;
        let w = self.width as usize;
        format!(
            "sample vector {index} (pixel {}, {}, sample {}) has a non-finite {} = {value}",
            pixel % w,
            pixel / w,
            index % spp,
            FIELD_NAMES[field]
        )
    }

    /// Writes the set as `samples.bin` (format in the module docs) through a temporary file, so
    /// a failed write never leaves a half-written file under `path`.
    pub fn write(&self, path: &Path) -> Result<()> {
        self.validate()?;
        crate::imaging::write_atomically(path, |tmp| {
            let file = File::create(tmp).with_context(|| format!("creating {}", tmp.display()))?;
            let mut w = BufWriter::with_capacity(1 << 20, file);
            self.write_to(&mut w)?;
            w.flush()?;
            w.into_inner()
                .map_err(|e| e.into_error())?
                .sync_all()
                .context("syncing the sample file")?;
            Ok(())
        })
    }

    /// Writes header and vectors to any writer.
    pub fn write_to(&self, w: &mut impl Write) -> Result<()> {
        w.write_all(&MAGIC)?;
        for v in [
            VERSION,
            self.width,
            self.height,
            self.spp,
            FLOATS_PER_SAMPLE as u32,
        ] {
            w.write_all(&v.to_le_bytes())?;
        }
        let record = toml::to_string(&self.record.to_attributes())?;
        if record.len() > MAX_RECORD_BYTES as usize {
            bail!(
                "the render record is {} bytes, more than a samples file holds",
                record.len()
            );
        }
        w.write_all(&(record.len() as u32).to_le_bytes())?;
        w.write_all(record.as_bytes())?;
        let mut buf = Vec::with_capacity(BYTES_PER_SAMPLE as usize * 4096);
        for chunk in self.samples.chunks(4096) {
            buf.clear();
            for s in chunk {
                for v in to_floats(s) {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
            }
            w.write_all(&buf)?;
        }
        Ok(())
    }

    /// Reads a `samples.bin` file. Checks magic, version, dimensions and the file length before
    /// allocating, the memory the vectors need against the memory available, and every value;
    /// errors say which.
    pub fn read(path: &Path) -> Result<SampleSet> {
        let file = File::open(path).with_context(|| format!("opening {}", path.display()))?;
        let len = file
            .metadata()
            .with_context(|| format!("reading the size of {}", path.display()))?
            .len();
        let mut r = BufReader::with_capacity(1 << 20, file);
        Self::read_from(&mut r, len, available_memory_bytes())
            .with_context(|| format!("reading RPF samples from {}", path.display()))
    }

    /// Reads from any reader holding `len` bytes; `memory_budget` (bytes), if given, bounds the
    /// allocation.
    pub fn read_from(r: &mut impl Read, len: u64, memory_budget: Option<u64>) -> Result<SampleSet> {
        if len < HEADER_BYTES {
            bail!(
                "truncated file: {len} bytes, shorter than the {HEADER_BYTES}-byte header of an \
                 RPF sample file"
            );
        }
        let mut header = [0u8; HEADER_BYTES as usize];
        r.read_exact(&mut header).context("reading the header")?;
        if header[0..8] != MAGIC {
            bail!(
                "bad magic {:?}: not an RPF sample file (expected {:?})",
                String::from_utf8_lossy(&header[0..8]),
                String::from_utf8_lossy(&MAGIC)
            );
        }
        let word = |i: usize| u32::from_le_bytes(header[8 + 4 * i..12 + 4 * i].try_into().unwrap());
        let (version, width, height, spp, floats) = (word(0), word(1), word(2), word(3), word(4));
        if version != 1 && version != VERSION {
            bail!(
                "unsupported RPF sample file version {version} (this build reads 1 and {VERSION})"
            );
        }
        let (record, record_bytes) = if version >= 2 {
            if len < HEADER_BYTES + 4 {
                bail!("truncated file: the header ends before the render record's length");
            }
            let mut n = [0u8; 4];
            r.read_exact(&mut n)
                .context("reading the render record's length")?;
            let n = u32::from_le_bytes(n);
            if n > MAX_RECORD_BYTES || HEADER_BYTES + 4 + n as u64 > len {
                bail!("the render record claims {n} bytes: a damaged or truncated file");
            }
            let mut text = vec![0u8; n as usize];
            r.read_exact(&mut text)
                .context("reading the render record")?;
            let text = String::from_utf8(text).context("the render record is not UTF-8 text")?;
            let attributes: std::collections::BTreeMap<String, String> = toml::from_str(&text)
                .map_err(|e| anyhow::anyhow!("the render record: {}", e.message()))?;
            (RenderRecord::from_attributes(&attributes)?, 4 + n as u64)
        } else {
            (RenderRecord::default(), 0)
        };
        if floats as usize != FLOATS_PER_SAMPLE {
            bail!("the header says {floats} floats per sample; RPF sample vectors have 26");
        }
        if width == 0 || height == 0 || spp == 0 {
            bail!("the header says {width}x{height} at {spp} spp: every size must be at least 1");
        }
        let payload = memory_bytes(width, height, spp);
        let expected = (HEADER_BYTES + record_bytes).saturating_add(payload);
        if len < expected {
            bail!(
                "truncated file: {width}x{height} at {spp} spp needs {expected} bytes but the \
                 file has {len}"
            );
        }
        if len > expected {
            bail!(
                "sizes do not match: {width}x{height} at {spp} spp needs {expected} bytes but the \
                 file has {len} ({} bytes too many)",
                len - expected
            );
        }
        if let Some(budget) = memory_budget {
            check_memory(width, height, spp, budget)?;
        }
        let count = usize::try_from(width as u64 * height as u64 * spp as u64)
            .context("the sample count does not fit this machine's address space")?;
        let mut samples: Vec<SampleVector> = Vec::new();
        samples.try_reserve_exact(count).map_err(|_| {
            anyhow::anyhow!(
                "cannot allocate {} for {count} sample vectors",
                human_bytes(payload)
            )
        })?;
        let mut buf = vec![0u8; BYTES_PER_SAMPLE as usize * 4096];
        let mut done = 0usize;
        while done < count {
            let n = (count - done).min(4096);
            let bytes = &mut buf[..n * BYTES_PER_SAMPLE as usize];
            r.read_exact(bytes).with_context(|| {
                format!("truncated file: sample vectors end before vector {done} of {count}")
            })?;
            for v in bytes.chunks_exact(BYTES_PER_SAMPLE as usize) {
                let mut a = [0.0f32; FLOATS_PER_SAMPLE];
                for (k, f) in a.iter_mut().enumerate() {
                    *f = f32::from_le_bytes(v[4 * k..4 * k + 4].try_into().unwrap());
                }
                samples.push(from_floats(&a));
            }
            done += n;
        }
        let set = SampleSet {
            width,
            height,
            spp,
            samples,
            record,
        };
        set.validate()?;
        Ok(set)
    }
}

/// Whether the file at `path` starts with the RPF sample magic (for commands that take either
/// an AOV EXR or a sample file).
pub fn is_sample_file(path: &Path) -> bool {
    let mut magic = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && magic == MAGIC
}

impl SampleSet {
    /// The sample vectors of a frame: the samples stored so far, pixel-major (a live frame's
    /// buffer holds `sample_capacity` per pixel; only the first `spp` are taken).
    pub fn from_frame(frame: &Frame, record: RenderRecord) -> Result<SampleSet> {
        let info = frame.info();
        let all: &[SampleVector] = frame.host_slice(BufferId::SampleVectors)?;
        let (stored, capacity) = (
            info.samples_stored() as usize,
            info.sample_capacity as usize,
        );
        let samples = if stored == capacity {
            all.to_vec()
        } else {
            all.chunks(capacity)
                .flat_map(|px| px[..stored].iter().copied())
                .collect()
        };
        let mut set = SampleSet::new(info.width, info.height, stored as u32, samples)?;
        set.record = record;
        Ok(set)
    }

    /// A frame that holds these samples (and nothing else), with the recorded scene
    /// information where there is one.
    pub fn into_frame(self) -> Result<Frame> {
        let info = FrameInfo {
            width: self.width,
            height: self.height,
            spp: self.spp,
            sample_capacity: self.spp,
            shadow_lights: Vec::new(),
            scene: self.record.scene.clone().unwrap_or_else(SceneInfo::unknown),
        };
        Frame::on_host(
            info,
            OutputSet::of(&[Output::Samples]),
            VarianceForm::Variances,
            vec![(
                BufferId::SampleVectors,
                HostBuffer::from_slice(&self.samples),
            )],
        )
    }
}
