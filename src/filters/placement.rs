//! Where a filter runs when several devices render one frame (src/render/split.rs). The thesis
//! splits the path tracing by device speed (§4.2) but says nothing of the filter; two
//! placements give the same bytes, and `noisefree bench --study balance` measures which is
//! faster (results/*/balance.md):
//!
//! - [`Placement::Merged`]: every band is copied to the primary device after each frame, and
//!   the primary filters the whole film. Costs: the film's bytes of every other band through
//!   the host, and the primary filters alone.
//! - [`Placement::Bands`]: each device filters its own band, reading the rows within the
//!   filter's reach ([`PreparedFilter::reach`]) that its neighbours rendered, copied over
//!   first; the filtered rows are put together on the host. Costs: the border rows, and each
//!   band's filter recomputes what its reach needs (à-trous: 62 rows either side at 5
//!   passes). Filters without a bounded reach (RPF, on the host) always run merged.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow};
use clap::Args;

use super::{Configured, FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::layout::outputs::OutputSet;
use crate::render::{RenderOptions, SceneArrays, SplitRenderer};
use crate::scene::Scene;

/// Where the filter runs with several devices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Placement {
    /// The primary device filters the merged film.
    Merged,
    /// Each device filters its own band (with the border its filter reads).
    Bands,
}

impl Placement {
    /// What `--filter-placement` defaults to. On this project's machine the two placements
    /// filter in the same time within the noise (results/pocl-cpu/balance.md: both PoCL
    /// devices share the same two cores, so the bands' filters cannot run faster side by side);
    /// merged prepares the filter once, on one device, and gives every other reader of the film
    /// (AOVs, images) the merged film without a further copy.
    pub const DEFAULT: Placement = Placement::Merged;

    pub fn name(self) -> &'static str {
        match self {
            Placement::Merged => "merged",
            Placement::Bands => "bands",
        }
    }
}

/// Several devices rendering one frame (thesis §4.2), for render, view and bench.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct MultiDeviceArgs {
    /// Render each frame on several devices (numbers from `noisefree devices`, e.g. 0,1),
    /// split by rows in proportion to their measured speed; the image is the same.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "N,N,...",
        conflicts_with = "device"
    )]
    pub devices: Vec<usize>,
    /// With several devices: filter the merged film on the first device, or each device its
    /// own band.
    #[arg(long, value_enum, default_value_t = Placement::DEFAULT)]
    pub filter_placement: Placement,
    /// With several devices: keep the first split (by compute units × clock) instead of
    /// re-balancing from measured kernel times.
    #[arg(long)]
    pub no_rebalance: bool,
}

impl MultiDeviceArgs {
    /// The devices to render with: `--devices`, else `--device` (or the default choice).
    pub fn open(&self, device: Option<usize>) -> Result<Vec<Arc<Gpu>>> {
        if self.devices.is_empty() {
            Ok(vec![Gpu::open(device)?])
        } else {
            Gpu::open_all(&self.devices)
        }
    }

    /// The flags that give these arguments again (for a command line that runs elsewhere).
    pub fn to_args(&self) -> Vec<String> {
        let mut v = Vec::new();
        if !self.devices.is_empty() {
            let list: Vec<String> = self.devices.iter().map(|d| d.to_string()).collect();
            v.extend(["--devices".to_string(), list.join(",")]);
        }
        if self.filter_placement != Placement::DEFAULT {
            v.extend([
                "--filter-placement".to_string(),
                self.filter_placement.name().to_string(),
            ]);
        }
        if self.no_rebalance {
            v.push("--no-rebalance".to_string());
        }
        v
    }

    /// A film on `gpus`, re-balanced unless --no-rebalance.
    pub fn film(
        &self,
        gpus: &[Arc<Gpu>],
        scene: &Scene,
        arrays: SceneArrays,
        options: &RenderOptions,
    ) -> Result<SplitRenderer> {
        let mut film = SplitRenderer::new(gpus, scene, arrays, options)?;
        film.balancer.enabled = !self.no_rebalance;
        Ok(film)
    }
}

/// A filter prepared for a film on one or more devices.
pub struct DeviceFilter {
    name: &'static str,
    needs: OutputSet,
    placement: Placement,
    /// One per device with [`Placement::Bands`]; the primary's alone otherwise.
    filters: Vec<Box<dyn PreparedFilter>>,
}

impl DeviceFilter {
    /// Prepares `configured` for `film` where `placement` asks, and tells the film whether to
    /// merge after every frame. One device, or a filter without a bounded reach, runs merged.
    pub fn prepare(
        configured: &Configured,
        film: &mut SplitRenderer,
        placement: Placement,
    ) -> Result<DeviceFilter> {
        let primary = film.primary();
        let first = configured.prepare(primary.frame().info(), &primary.gpu)?;
        let mut filters = vec![first];
        let bands =
            placement == Placement::Bands && film.parts().len() > 1 && filters[0].reach().is_some();
        if bands {
            for part in &film.parts()[1..] {
                filters.push(configured.prepare(part.frame().info(), &part.gpu)?);
            }
        }
        film.set_merge_each_frame(!bands);
        Ok(DeviceFilter {
            name: configured.name(),
            needs: configured.needs(),
            placement: if bands {
                Placement::Bands
            } else {
                Placement::Merged
            },
            filters,
        })
    }

    pub fn name(&self) -> &'static str {
        self.name
    }

    /// Where the filter actually runs.
    pub fn placement(&self) -> Placement {
        self.placement
    }

    /// Fast enough for every frame (see [`PreparedFilter::interactive`]).
    pub fn interactive(&self) -> bool {
        self.filters[0].interactive()
    }

    pub fn show_progress(&mut self, on: bool) {
        for f in &mut self.filters {
            f.show_progress(on);
        }
    }

    /// Filters the film as it is now. With bands, the kernel time is the slowest device's
    /// and the wall time includes the border copies.
    pub fn run(&mut self, film: &SplitRenderer) -> Result<FilterRun> {
        if self.placement == Placement::Merged {
            return self.filters[0].run(&film.frame()?);
        }
        let start = Instant::now();
        let reach = self.filters[0].reach().unwrap_or(0);
        film.exchange_borders(reach, self.needs)?;
        let frames: Vec<_> = film.parts().iter().map(|p| p.frame()).collect();
        let bands = film.bands();
        let runs: Vec<FilterRun> = std::thread::scope(|s| {
            let handles: Vec<_> = self
                .filters
                .iter_mut()
                .zip(frames)
                .zip(bands)
                .map(|((f, frame), band)| s.spawn(move || f.run_rows(&frame, band.clone())))
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join()
                        .unwrap_or_else(|_| Err(anyhow!("a filter thread panicked")))
                })
                .collect::<Result<Vec<_>>>()
        })?;
        let (w, h) = (film.width(), film.height());
        let mut image = RgbImage {
            width: w,
            height: h,
            pixels: vec![[0.0; 3]; w as usize * h as usize],
        };
        let mut kernel_time: Option<Duration> = None;
        for (run, band) in runs.iter().zip(bands) {
            let (a, b) = (
                band.start as usize * w as usize,
                band.end as usize * w as usize,
            );
            image.pixels[a..b].copy_from_slice(&run.image.pixels[a..b]);
            if let Some(t) = run.kernel_time {
                kernel_time = Some(kernel_time.map_or(t, |k| k.max(t)));
            }
        }
        Ok(FilterRun {
            image,
            wall_time: start.elapsed(),
            kernel_time,
        })
    }
}
