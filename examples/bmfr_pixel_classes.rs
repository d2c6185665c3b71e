//! Where a filtered image's error lies, by the pixel classes bmfr's non-local means use
//! (src/filters/bmfr/nlm.rs `class`): sky, partly covered pixels (samples that did not all hit
//! a surface) and surfaces. For each class the filtered pixels of that class are replaced by
//! the reference's, and the fall of the whole image's MSE in CIELUV is the class's share:
//! `cargo run --release --example bmfr_pixel_classes -- AOVS.exr FILTERED.exr REFERENCE.exr`,
//! AOVS.exr from `noisefree render SCENE --aovs AOVS.exr` (it holds the features and hit
//! counts), FILTERED.exr from `noisefree filter AOVS.exr --filter bmfr --exr FILTERED.exr`
//! (results/README.md, bmfr's "open" rows).

use std::path::Path;

use anyhow::{Result, bail};
use noisefree::imaging::read_exr_rgb;
use noisefree::layout::outputs::BufferId;
use noisefree::layout::{Float4, SKY_DEPTH};
use noisefree::metrics::mse_luv;
use noisefree::stats::aov::read_aov_exr;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [aovs, filtered, reference_path] = args.as_slice() else {
        bail!("usage: bmfr_pixel_classes AOVS.exr FILTERED.exr REFERENCE.exr");
    };
    let (frame, _) = read_aov_exr(Path::new(aovs))?;
    let test = read_exr_rgb(Path::new(filtered))?;
    let reference = read_exr_rgb(Path::new(reference_path))?;
    let fv = frame.filter_vectors()?;
    let pos: &[Float4] = frame.host_slice(BufferId::Positions)?;
    let spp = frame.info().spp as f32;
    if fv.len() != test.pixels.len() || test.pixels.len() != reference.pixels.len() {
        bail!("{aovs}, {filtered} and {reference_path} are not the same size");
    }
    let whole = mse_luv(&test, &reference)?;
    println!("whole image: MSE-LUV {whole:.4}");
    let sky = |i: usize| fv[i].depth >= SKY_DEPTH;
    let classes: [(&str, &dyn Fn(usize) -> bool); 3] = [
        ("sky", &sky),
        ("partly covered", &|i| !sky(i) && pos[i].0[3] < spp),
        ("surface", &|i| !sky(i) && pos[i].0[3] >= spp),
    ];
    for (name, in_class) in classes {
        let mut oracle = test.clone();
        let mut count = 0;
        for (i, p) in oracle.pixels.iter_mut().enumerate() {
            if in_class(i) {
                *p = reference.pixels[i];
                count += 1;
            }
        }
        let rest = mse_luv(&oracle, &reference)?;
        println!(
            "{name}: {count} pixels, share {:.4} (MSE-LUV {rest:.4} with them set to the reference)",
            whole - rest
        );
    }
    Ok(())
}
