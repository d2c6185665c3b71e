//! Intel Open Image Denoise beside our filters in the studies: the denoiser users pick, on the
//! same input. It runs through `scripts/oidn/denoise.py` in the Python environment that
//! `scripts/oidn/setup.sh` makes (pyoidn from PyPI bundles the OIDN 2.5 CPU library); nothing
//! else in noisefree uses Python. The colour is the frame's beauty (linear HDR), the
//! auxiliaries its mean first-hit albedo and normal, prefiltered by OIDN's own filters as its
//! documentation recommends for noisy auxiliaries. Times are OIDN's own (filter executions,
//! after one warm-up call), not the process start.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context as _, Result, bail};

use crate::imaging::RgbImage;
use crate::layout::FilterVector;
use crate::render::Frame;

/// OIDN's quality modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quality {
    Fast,
    Balanced,
    High,
}

impl Quality {
    pub const ALL: [Quality; 3] = [Quality::High, Quality::Balanced, Quality::Fast];

    fn arg(self) -> &'static str {
        match self {
            Quality::Fast => "fast",
            Quality::Balanced => "balanced",
            Quality::High => "high",
        }
    }

    /// The method's name in the studies' tables.
    pub fn label(self) -> String {
        format!("oidn-{}", self.arg())
    }
}

/// A denoised image and what it cost.
pub struct OidnRun {
    pub image: RgbImage,
    /// The colour filter's execution, per call.
    pub seconds: Vec<f64>,
    /// Prefiltering the albedo and the normal, per call.
    pub prefilter_seconds: Vec<f64>,
}

impl OidnRun {
    /// The median time of one denoise, prefiltering included (what a user pays per frame).
    pub fn median_total(&self) -> f64 {
        let mut t: Vec<f64> = self
            .seconds
            .iter()
            .zip(&self.prefilter_seconds)
            .map(|(a, b)| a + b)
            .collect();
        t.sort_by(f64::total_cmp);
        t.get(t.len() / 2).copied().unwrap_or(f64::NAN)
    }
}

/// The Python environment with pyoidn.
pub struct Oidn {
    python: PathBuf,
    script: PathBuf,
}

/// What to do when OIDN is not set up.
pub const NOT_SET_UP: &str = "OIDN is not set up: run scripts/oidn/setup.sh (a Python virtual \
     environment with pyoidn, in cache/oidn-venv or $NOISEFREE_OIDN_VENV) to compare with it";

impl Oidn {
    /// The environment of `$NOISEFREE_OIDN_VENV`, else `cache/oidn-venv` under the current
    /// folder, else under the source tree the binary was built from.
    pub fn find() -> Option<Oidn> {
        let source = Path::new(env!("CARGO_MANIFEST_DIR"));
        let script = source.join("scripts/oidn/denoise.py");
        let candidates = std::env::var_os("NOISEFREE_OIDN_VENV")
            .map(PathBuf::from)
            .into_iter()
            .chain([
                PathBuf::from("cache/oidn-venv"),
                source.join("cache/oidn-venv"),
            ]);
        for venv in candidates {
            let python = venv.join("bin/python");
            if python.is_file() && script.is_file() {
                return Some(Oidn { python, script });
            }
        }
        None
    }

    /// Denoises the frame's beauty with its albedo and normal `repeat` times.
    pub fn denoise(&self, frame: &Frame, quality: Quality, repeat: u32) -> Result<OidnRun> {
        let (w, h) = (frame.width(), frame.height());
        let fv: &[FilterVector] = frame
            .filter_vectors()
            .context("OIDN needs the frame's colour, albedo and normal")?;
        let dir = std::env::temp_dir().join(format!(
            "noisefree-oidn-{}-{}",
            std::process::id(),
            quality.arg()
        ));
        std::fs::create_dir_all(&dir)?;
        let write = |name: &str, f: &dyn Fn(&FilterVector) -> [f32; 3]| -> Result<PathBuf> {
            let path = dir.join(name);
            let bytes: Vec<u8> = fv
                .iter()
                .flat_map(|v| f(v).into_iter().flat_map(f32::to_le_bytes))
                .collect();
            std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
            Ok(path)
        };
        let color = write("color.f32", &|v| {
            std::array::from_fn(|c| v.direct[c] + v.indirect[c])
        })?;
        let albedo = write("albedo.f32", &|v| v.albedo)?;
        let normal = write("normal.f32", &|v| v.normal)?;
        let out = dir.join("out.f32");
        let run = Command::new(&self.python)
            .arg(&self.script)
            .args(["--width", &w.to_string(), "--height", &h.to_string()])
            .arg("--color")
            .arg(&color)
            .arg("--albedo")
            .arg(&albedo)
            .arg("--normal")
            .arg(&normal)
            .arg("--out")
            .arg(&out)
            .args([
                "--quality",
                quality.arg(),
                "--repeat",
                &repeat.max(1).to_string(),
            ])
            .output()
            .with_context(|| format!("running {}", self.python.display()))?;
        if !run.status.success() {
            bail!(
                "OIDN ({}) failed: {}",
                self.script.display(),
                String::from_utf8_lossy(&run.stderr).trim()
            );
        }
        #[derive(serde::Deserialize)]
        struct Times {
            seconds: Vec<f64>,
            prefilter_seconds: Vec<f64>,
        }
        let times: Times = serde_json::from_slice(&run.stdout).with_context(|| {
            format!(
                "reading OIDN's timings: {:?}",
                String::from_utf8_lossy(&run.stdout)
            )
        })?;
        let bytes = std::fs::read(&out).with_context(|| format!("reading {}", out.display()))?;
        let _ = std::fs::remove_dir_all(&dir);
        if bytes.len() != w as usize * h as usize * 12 {
            bail!("OIDN wrote {} bytes for a {w}x{h} image", bytes.len());
        }
        let pixels = bytes
            .chunks_exact(12)
            .map(|p| {
                std::array::from_fn(|c| f32::from_le_bytes(p[4 * c..4 * c + 4].try_into().unwrap()))
            })
            .collect();
        Ok(OidnRun {
            image: RgbImage {
                width: w,
                height: h,
                pixels,
            },
            seconds: times.seconds,
            prefilter_seconds: times.prefilter_seconds,
        })
    }
}
