//! Denoising filters over the shared per-pixel buffers ([`crate::stats::PixelBuffers`] on the
//! host, [`DeviceBuffers`] on the device). Every filter reads the same buffers and produces an
//! RGB image, so new filters (the axis-aligned, sheared and path-density filters of the other
//! papers) plug in beside the data-driven one.

pub mod atrous;
pub mod ddf;
pub mod method;
pub mod rpf;

use std::time::Duration;

use anyhow::Result;
use ocl::Buffer;

use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::layout::{FilterVector, GBuffer, StatsState};
use crate::stats::PixelBuffers;

/// The per-pixel buffers on the device, as the renderer leaves them or as uploaded from an
/// AOV file.
pub struct DeviceBuffers<'a> {
    pub width: u32,
    pub height: u32,
    pub filter_vectors: &'a Buffer<FilterVector>,
    /// Welford sums S_n or variances, per `variance_factor`.
    pub gbuffers: &'a Buffer<GBuffer>,
    /// Mean first-bounce directions (StatsState).
    pub stats_state: &'a Buffer<StatsState>,
    /// Multiplies `gbuffers` to give variances: 1/(n-1) for sums, 1 for variances.
    pub variance_factor: f32,
    /// Multiplies depths before comparing them ([`crate::stats::depth_scale`]).
    pub depth_scale: f32,
}

/// Device copies of host buffers (for filtering offline, e.g. from an AOV file).
pub struct UploadedBuffers {
    pub filter_vectors: Buffer<FilterVector>,
    pub gbuffers: Buffer<GBuffer>,
    pub stats_state: Buffer<StatsState>,
    pub width: u32,
    pub height: u32,
    pub scene_size: f32,
}

impl UploadedBuffers {
    pub fn new(gpu: &Gpu, b: &PixelBuffers) -> Result<UploadedBuffers> {
        let variances = b
            .variances
            .clone()
            .unwrap_or_else(|| vec![GBuffer::default(); b.filter_vectors.len()]);
        let states: Vec<StatsState> = match &b.directions {
            Some(d) => d
                .iter()
                .map(|d| StatsState {
                    direction_mean: *d,
                    ..Default::default()
                })
                .collect(),
            None => vec![StatsState::default(); b.filter_vectors.len()],
        };
        Ok(UploadedBuffers {
            filter_vectors: gpu.upload(&b.filter_vectors)?,
            gbuffers: gpu.upload(&variances)?,
            stats_state: gpu.upload(&states)?,
            width: b.width,
            height: b.height,
            scene_size: b.scene_size,
        })
    }

    pub fn view(&self) -> DeviceBuffers<'_> {
        DeviceBuffers {
            width: self.width,
            height: self.height,
            filter_vectors: &self.filter_vectors,
            gbuffers: &self.gbuffers,
            stats_state: &self.stats_state,
            variance_factor: 1.0,
            depth_scale: crate::stats::depth_scale(self.scene_size),
        }
    }
}

/// A filtered image and the kernel time it took.
pub struct Filtered {
    pub image: RgbImage,
    pub kernel_time: Duration,
}

/// min / median / max of a list of durations (the thesis reports lower and upper bounds).
pub fn time_summary(times: &[Duration]) -> Option<(Duration, Duration, Duration)> {
    if times.is_empty() {
        return None;
    }
    let mut t = times.to_vec();
    t.sort();
    Some((t[0], t[t.len() / 2], t[t.len() - 1]))
}
