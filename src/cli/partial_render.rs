//! The partial side of `noisefree render` (`--samples A..B`, `--tile`, `--partial`, `--gather`):
//! its flags, and writing the render's outputs as one piece of a partial file
//! (src/stats/partial/) for `noisefree merge`.

use std::path::Path;

use anyhow::{Result, bail};

use super::render_cmd::{RenderArgs, RenderSummary};
use crate::layout::outputs::{OUTPUTS, Output};
use crate::render::Frame;
use crate::stats::RenderRecord;
use crate::stats::partial::{self, Piece, PieceInfo, RenderIdentity};

/// `A..B`: samples A to B-1.
pub fn parse_range(s: &str) -> std::result::Result<std::ops::Range<u32>, String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("expected A..B (samples A to B-1), e.g. 0..64, got {s:?}"))?;
    let n = |t: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|_| format!("{t:?} in {s:?} is not a sample number"))
    };
    let (a, b) = (n(a)?, n(b)?);
    if a >= b {
        return Err(format!("{s:?} is empty: A..B needs A < B"));
    }
    Ok(a..b)
}

pub fn parse_output(s: &str) -> std::result::Result<Output, String> {
    OUTPUTS
        .iter()
        .find(|o| o.name == s.trim())
        .map(|o| o.output)
        .ok_or_else(|| {
            let names: Vec<&str> = OUTPUTS.iter().map(|o| o.name).collect();
            format!("no output named {s:?}; outputs: {}", names.join(", "))
        })
}

/// Refuses the flags a partial render does not use (it writes no image: its merge does).
pub fn check_partial_flags(args: &RenderArgs) -> Result<()> {
    if args.partial.is_none() {
        if args.samples.is_some() || args.tile.is_some() {
            bail!(
                "--samples and --tile render a part of an image: give --partial FILE.nfp, and \
                 merge the parts with `noisefree merge`"
            );
        }
        return Ok(());
    }
    let images = [
        (args.out.is_some(), "--out"),
        (args.exr.is_some(), "--exr"),
        (args.exr_unfiltered.is_some(), "--exr-unfiltered"),
        (args.aovs.is_some(), "--aovs"),
        (args.aov_png.is_some(), "--aov-png"),
        (args.save_samples.is_some(), "--save-samples"),
        (args.timings, "--timings"),
        (args.time_limit.is_some(), "--time-limit"),
        (args.save_partial, "--save-partial"),
    ];
    if let Some((_, flag)) = images.iter().find(|(given, _)| *given) {
        bail!(
            "{flag} does not go with --partial: a partial render writes its samples' \
             accumulators, not images (`noisefree merge` writes the images, AOVs and filtered \
             result; --gather samples keeps the sample vectors, and every part renders all of \
             its range)"
        );
    }
    Ok(())
}

/// Writes the render's outputs (`frame`) as the one piece `info` of the render `identity`
/// to `path`, with the render's `record`, and says what was rendered.
pub fn write_part(
    path: &Path,
    mut identity: RenderIdentity,
    record: RenderRecord,
    frame: &Frame,
    info: PieceInfo,
    summary: &RenderSummary,
) -> Result<()> {
    identity.record = record;
    // The record's spp is the whole render's, as the merge will have.
    let spp = identity.spp;
    identity.record.extra.insert("spp".into(), spp.to_string());
    let what = if info.tile.is_whole(identity.width, identity.height) {
        "image".to_string()
    } else {
        format!("tile {}", info.tile)
    };
    let samples = info.samples.clone();
    let piece = Piece::of_frame(frame, info)?;
    partial::write(path, &identity, &[piece])?;
    say!(
        "{what} of {}x{}: samples {}..{} of {spp} in {:.2} s (kernel {:.2} s): {:.2} spp/s, \
         {:.2} Mrays/s -> {}",
        identity.width,
        identity.height,
        samples.start,
        samples.end,
        summary.seconds,
        summary.kernel_seconds,
        summary.spp_per_second(),
        summary.mrays_per_second(),
        path.display()
    );
    Ok(())
}
