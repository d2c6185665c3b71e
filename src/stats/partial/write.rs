//! Writing partial files (the format is in the module above): a render's pieces, or pieces
//! of other files bundled as they are; always through a temporary file.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context as _, Result, bail};

use super::{
    BufferLayout, FORMAT, Header, MAGIC, MAX_HEADER_BYTES, PREFIX_BYTES, PartialFile, Piece,
    PieceHeader, PieceInfo, RenderIdentity, VERSION, buffer_bytes, data_start, hex,
};

/// Writes a partial file of `pieces`, each with the buffers of `identity.outputs` (in table
/// order) sized for its tile and samples; through a temporary file, so a failed write never
/// leaves a half-written file under `path`.
pub fn write(path: &Path, identity: &RenderIdentity, pieces: &[Piece]) -> Result<()> {
    for p in pieces {
        let want: Vec<_> = buffer_bytes(identity, p.info.tile, p.info.count())
            .into_iter()
            .map(|(b, n)| (b.id, n))
            .collect();
        let have: Vec<_> = p
            .buffers
            .iter()
            .map(|(id, b)| (*id, b.len_bytes() as u64))
            .collect();
        if want != have {
            bail!(
                "a piece of {} holds buffers {have:?}, its outputs need {want:?}",
                p.info.describe(identity.width, identity.height)
            );
        }
    }
    let entries = pieces
        .iter()
        .map(|p| (p.info.clone(), p.bytes(), p.checksum()))
        .collect();
    write_with(path, identity, entries, |i, w| {
        for (_, b) in &pieces[i].buffers {
            w.write_all(b.as_bytes())?;
        }
        Ok(())
    })
}

/// Writes the pieces `sources` (file, piece index) of files of one render into one partial
/// file, payloads copied as they are (checksums verified on the way).
pub fn write_bundle(
    path: &Path,
    identity: &RenderIdentity,
    sources: &[(&PartialFile, usize)],
) -> Result<()> {
    let entries = sources
        .iter()
        .map(|(f, i)| {
            let e = &f.pieces[*i];
            (e.info.clone(), e.bytes, e.checksum)
        })
        .collect();
    write_with(path, identity, entries, |i, w| {
        let (f, k) = sources[i];
        w.write_all(&f.read_payload(k)?)?;
        Ok(())
    })
}

fn write_with(
    path: &Path,
    identity: &RenderIdentity,
    entries: Vec<(PieceInfo, u64, u64)>,
    mut payload: impl FnMut(usize, &mut dyn Write) -> Result<()>,
) -> Result<()> {
    let mut offset = 0u64;
    let pieces = entries
        .iter()
        .map(|(info, bytes, checksum)| {
            let p = PieceHeader {
                tile: info.tile,
                samples: [info.samples.start, info.samples.end],
                offset,
                bytes: *bytes,
                fnv1a: hex(*checksum),
                rays: info.rays,
                seconds: info.seconds,
                device: info.device.clone(),
            };
            offset += bytes;
            p
        })
        .collect();
    let header = Header {
        format: FORMAT.into(),
        version: VERSION,
        scene: identity.scene.clone(),
        scene_hash: hex(identity.scene_hash),
        kernel_hash: hex(identity.kernel_hash),
        width: identity.width,
        height: identity.height,
        seed: identity.seed,
        spp: identity.spp,
        outputs: identity
            .outputs
            .names()
            .into_iter()
            .map(String::from)
            .collect(),
        shadow_lights: identity.shadow_lights.clone(),
        light_field: identity.outputs.light_field().map(|k| k.name().to_string()),
        buffers: identity.outputs.buffers().map(BufferLayout::of).collect(),
        record: identity.record.to_attributes(),
        pieces,
    };
    let text = toml::to_string(&header).context("writing the partial-file header")?;
    if text.len() > MAX_HEADER_BYTES as usize {
        bail!(
            "the header is {} bytes, more than a partial file holds",
            text.len()
        );
    }
    crate::imaging::write_atomically(path, |tmp| {
        let file = File::create(tmp).with_context(|| format!("creating {}", tmp.display()))?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        w.write_all(&MAGIC)?;
        w.write_all(&VERSION.to_le_bytes())?;
        w.write_all(&(text.len() as u32).to_le_bytes())?;
        w.write_all(text.as_bytes())?;
        let pad = data_start(text.len() as u64) - PREFIX_BYTES - text.len() as u64;
        w.write_all(&vec![0u8; pad as usize])?;
        for i in 0..entries.len() {
            payload(i, &mut w)?;
        }
        w.flush()?;
        w.into_inner()
            .map_err(|e| e.into_error())?
            .sync_all()
            .context("syncing the partial file")
    })
}
