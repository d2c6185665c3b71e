//! One interface over every filter, for the command line and the benchmarks: what a filter
//! needs the renderer to gather, how it is specialised to the scene, and how it runs on the
//! renderer's buffers after a frame.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;

use super::atrous::{AtrousCamera, AtrousFilter, AtrousSettings};
use super::ddf::{DdfFilter, DdfSettings, Variant};
use super::rpf::{self, RpfSettings, SampleSet};
use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::render::{Outputs, Renderer};
use crate::scene::{MaterialKind, Scene};

/// A filter and its parameters.
#[derive(Clone, Debug)]
pub enum Method {
    /// The data-driven filter (thesis ch. 6).
    Ddf {
        settings: DdfSettings,
        variant: Variant,
    },
    /// Random Parameter Filtering (thesis ch. 5), on the host.
    Rpf(RpfSettings),
    /// The edge-avoiding à-trous wavelet filter (Dammertz et al. 2010).
    Atrous(AtrousSettings),
}

/// A filter's result on one frame.
pub struct FilterRun {
    pub image: RgbImage,
    /// Wall-clock time of the filter, including reading buffers back where it needs to.
    pub wall_time: Duration,
    /// Device kernel time (OpenCL profiling events), for device filters.
    pub kernel_time: Option<Duration>,
}

impl Method {
    pub fn name(&self) -> &'static str {
        match self {
            Method::Ddf { .. } => "ddf",
            Method::Rpf(_) => "rpf",
            Method::Atrous(_) => "atrous",
        }
    }

    /// What the renderer must gather for this filter, rendering `spp` samples per pixel.
    pub fn outputs(&self, spp: u32) -> Outputs {
        match self {
            Method::Ddf { .. } => Outputs {
                features: true,
                variance: true,
                sample_vectors: None,
            },
            Method::Atrous(_) => Outputs {
                features: true,
                variance: false,
                sample_vectors: None,
            },
            Method::Rpf(_) => Outputs {
                features: true,
                variance: false,
                sample_vectors: Some(spp),
            },
        }
    }

    /// Builds the filter for `renderer`'s frame size, specialised to `scene` like the
    /// megakernel: no sky branch without an environment light (§6.3.4), no texture2 term when
    /// nothing in the scene reflects or refracts (§6.2.1: texture2 exists to keep detail seen
    /// in mirrors and through glass); RPF's sigma^2_8 from the scene's indoor/outdoor setting
    /// unless the settings say otherwise.
    pub fn prepare(&self, gpu: &Arc<Gpu>, scene: &Scene, renderer: &Renderer) -> Result<Prepared> {
        let (w, h) = (renderer.width(), renderer.height());
        Ok(match self {
            Method::Ddf { settings, variant } => {
                let mut s = settings.clone();
                specialise_ddf(&mut s, scene);
                Prepared::Ddf(DdfFilter::new(gpu.clone(), &s, *variant, w, h)?)
            }
            Method::Atrous(settings) => {
                let camera = AtrousCamera::from(&renderer.arrays.params);
                Prepared::Atrous(AtrousFilter::new(gpu.clone(), settings, &camera, w, h)?)
            }
            Method::Rpf(settings) => Prepared::Rpf {
                settings: settings.clone(),
                progress: false,
            },
        })
    }
}

/// The scene-dependent switches of the data-driven filter.
pub fn specialise_ddf(s: &mut DdfSettings, scene: &Scene) {
    s.sky &= scene.environment.is_some();
    let reflects = scene.materials.iter().any(|m| {
        !m.is_emissive()
            && matches!(
                m.kind,
                MaterialKind::Specular { .. }
                    | MaterialKind::Glass { .. }
                    | MaterialKind::Metal { .. }
            )
    });
    s.texture2 &= reflects;
}

/// A filter ready to run on frames of one size.
pub enum Prepared {
    Ddf(DdfFilter),
    Atrous(AtrousFilter),
    /// RPF runs on the host; `progress` shows a progress bar while it does.
    Rpf {
        settings: RpfSettings,
        progress: bool,
    },
}

/// RPF on a sample set, with a progress bar if asked.
pub fn run_rpf(set: &SampleSet, settings: &RpfSettings, progress: bool) -> Result<RgbImage> {
    if !progress {
        return rpf::filter(set, settings);
    }
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg:32} [{elapsed_precise}] {bar:30} ETA {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let callback = rpf::progress_bar_callback(&bar, &settings.box_sizes);
    let out = rpf::filter_with_progress(set, settings, &callback);
    bar.finish_and_clear();
    Ok(out?.image)
}

impl Prepared {
    /// Shows a progress bar while slow host filters (RPF) run.
    pub fn show_progress(&mut self, on: bool) {
        if let Prepared::Rpf { progress, .. } = self {
            *progress = on;
        }
    }

    /// A device filter, fast enough to run after every frame.
    pub fn on_device(&self) -> bool {
        !matches!(self, Prepared::Rpf { .. })
    }

    /// Filters the renderer's current frame.
    pub fn run(&mut self, renderer: &Renderer) -> Result<FilterRun> {
        let start = Instant::now();
        match self {
            Prepared::Ddf(f) => {
                let out = f.run(&renderer.device_buffers())?;
                Ok(FilterRun {
                    image: out.image,
                    wall_time: start.elapsed(),
                    kernel_time: Some(out.kernel_time),
                })
            }
            Prepared::Atrous(f) => {
                let out = f.run(&renderer.device_buffers())?;
                Ok(FilterRun {
                    image: out.image,
                    wall_time: start.elapsed(),
                    kernel_time: Some(out.kernel_time),
                })
            }
            Prepared::Rpf { settings, progress } => {
                let (spp, samples) = renderer.read_sample_vectors()?;
                let set = SampleSet::new(renderer.width(), renderer.height(), spp, samples)?;
                let image = run_rpf(&set, settings, *progress)?;
                Ok(FilterRun {
                    image,
                    wall_time: start.elapsed(),
                    kernel_time: None,
                })
            }
        }
    }
}
