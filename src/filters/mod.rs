//! Denoising filters as plug-ins over the renderer's declared outputs.
//!
//! A filter is one module (and its kernel file under kernels/filters/) that implements
//! [`FilterKind`]: its name, its settings struct (declared once with [`filter_settings!`]), the
//! outputs it needs from the renderer, how it adapts to the scene, and how it is prepared for
//! a frame size and run on a [`Frame`] — the one input type that the live renderer and the AOV
//! reader both build. Adding a filter is its own files plus one line in [`builtin_filters!`]
//! below; `render`, `filter` and `bench` find it through the [`Registry`].

pub mod aaf_pass;
pub mod placement;
pub mod registry;
pub mod settings;
pub mod shadow_lights;

use std::sync::Arc;
use std::time::Duration;

use anyhow::Result;

use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::layout::outputs::OutputSet;
use crate::render::{Frame, FrameInfo, RenderOptions, SceneInfo};
pub use placement::{DeviceFilter, MultiDeviceArgs, Placement};
pub use registry::{Configured, FilterRequest, Registry};
pub use settings::{Auto, DeclaredSettings, FieldDoc};

/// The filters noisefree has: one line each (module :: type), in the order of `--help`, of
/// the registry and of the studies' tables.
macro_rules! builtin_filters {
    ($($module:ident :: $kind:ident),* $(,)?) => {
        $(pub mod $module;)*

        /// Every built-in filter.
        pub fn builtin() -> Vec<&'static dyn Filter> {
            vec![$(&$module::$kind as &'static dyn Filter),*]
        }
    };
}

builtin_filters! {
    ddf::Ddf,       // the data-driven filter (thesis ch. 6)
    rpf::Rpf,       // Random Parameter Filtering (thesis ch. 5)
    atrous::Atrous, // the edge-avoiding à-trous wavelet filter (Dammertz et al. 2010)
    bmfr::Bmfr,     // blockwise feature regression (single-frame BMFR, Koskela et al. 2019)
    aaf_shadows::AafShadows, // axis-aligned filtering of soft shadows (Wang 2013 ch. 3)
    aaf_indirect::AafIndirect, // axis-aligned filtering of diffuse indirect light (Wang 2013 ch. 4)
    path_density::PathDensity, // the path-density outlier filter (DeCoro 2009 ch. 5)
    trimmed::Trimmed, // α-trimmed means of the samples (DeCoro 2009 §5.2 baselines)
    stylized::StylizedShadows, // stylized shadows of one sphere light (DeCoro 2009 ch. 3)
    sheared::Sheared, // 4-D sheared filtering of soft shadows (Yan et al. 2015)
}

/// What a filter is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// It estimates the converged image from a noisy one: compared with the ground truth.
    Denoise,
    /// It changes the look on purpose (DeCoro's stylized shadows): its error against the
    /// ground truth measures the style, not the filter, so the error studies leave it out.
    Stylize,
}

/// A filter, as its module declares it. Implement this; the registry sees it as a [`Filter`].
pub trait FilterKind: Send + Sync + 'static {
    type Settings: DeclaredSettings;
    /// The name on the command line (`--filter NAME`), in scene files (`[filter.NAME]`) and in
    /// reports.
    const NAME: &'static str;
    /// One line for `--help` and reports.
    const SUMMARY: &'static str;
    /// What the filter is for; the error studies compare only [`Purpose::Denoise`] filters
    /// with the ground truth.
    const PURPOSE: Purpose = Purpose::Denoise;

    /// Checks settings; the error names the setting and the allowed values.
    fn check(_settings: &Self::Settings) -> Result<()> {
        Ok(())
    }

    /// Decides what `auto` means for this scene (the filters' "simulate only what a scene calls
    /// for"): returns one note per decision, for `--explain`.
    fn specialise(_settings: &mut Self::Settings, _scene: &SceneInfo) -> Vec<String> {
        Vec::new()
    }

    /// Whether these settings, specialised to a scene, change anything: false where the
    /// image passes through as rendered (a shadow filter on a scene without a sphere light).
    /// The studies leave such a filter out of that scene, so that a row never repeats the
    /// unfiltered image under a filter's name.
    fn applies(_settings: &Self::Settings, _scene: &SceneInfo) -> bool {
        true
    }

    /// The outputs the renderer must gather for these settings.
    fn needs(settings: &Self::Settings) -> OutputSet;

    /// How the renderer gathers them, where that is the filter's choice (AAF's sample
    /// counts); most filters leave the options as they are.
    fn render_options(_settings: &Self::Settings, _options: &mut RenderOptions) {}

    /// Builds the filter for frames like `frame` (size, scene) on `gpu`.
    fn prepare(
        settings: &Self::Settings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>>;
}

/// A filter as the registry sees it (object safe; implemented for every [`FilterKind`]).
pub trait Filter: Send + Sync {
    fn name(&self) -> &'static str;
    fn summary(&self) -> &'static str;
    fn purpose(&self) -> Purpose;
    fn fields(&self) -> &'static [FieldDoc];
    fn flag_prefix(&self) -> &'static str;
    /// The default settings as a table.
    fn defaults(&self) -> toml::Table;
    /// The filter with `requested` settings (a full table: defaults with every layer on
    /// top), checked and specialised to `scene`.
    fn configure(&self, requested: toml::Table, scene: &SceneInfo) -> Result<Configured>;
}

impl<K: FilterKind> Filter for K {
    fn name(&self) -> &'static str {
        K::NAME
    }

    fn summary(&self) -> &'static str {
        K::SUMMARY
    }

    fn purpose(&self) -> Purpose {
        K::PURPOSE
    }

    fn fields(&self) -> &'static [FieldDoc] {
        K::Settings::fields()
    }

    fn flag_prefix(&self) -> &'static str {
        K::Settings::FLAG_PREFIX
    }

    fn defaults(&self) -> toml::Table {
        settings::to_table(&K::Settings::default())
    }

    fn configure(&self, requested: toml::Table, scene: &SceneInfo) -> Result<Configured> {
        // The registry says which layer a bad setting came from (scene file, command line).
        let mut typed: K::Settings = settings::from_table(&requested)?;
        K::check(&typed)?;
        let notes = K::specialise(&mut typed, scene);
        Ok(Configured::new::<K>(requested, typed, notes, scene))
    }
}

/// A filter ready to run on frames of one size. `Send`, so that with several devices each
/// can filter its own band from its own thread (src/filters/placement.rs).
pub trait PreparedFilter: Send {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun>;

    /// How many rows beyond a band of the frame the filter reads to give the band's pixels
    /// exactly the bytes that filtering the whole frame gives them; None (the default): any
    /// pixel may depend on the whole frame, and only whole frames are filtered.
    fn reach(&self) -> Option<u32> {
        None
    }

    /// Filters the pixels of `rows` only, reading the frame's rows within [`reach`] of them;
    /// the image's other rows are black. Called only when [`reach`] is Some.
    ///
    /// [`reach`]: PreparedFilter::reach
    fn run_rows(&mut self, frame: &Frame, rows: std::ops::Range<u32>) -> Result<FilterRun> {
        let _ = rows;
        self.run(frame)
    }

    /// Fast enough to run after every frame of a progressive render (the device filters).
    fn interactive(&self) -> bool {
        true
    }

    /// Shows a progress bar while a slow (host) filter runs.
    fn show_progress(&mut self, _on: bool) {}

    /// Forgets what the filter keeps from the frames it filtered, so that its next run does
    /// the whole work of a new frame. `filter --repeat` and the benchmarks call it before
    /// every timed run of the same frame; only a filter that skips work on an unchanged frame
    /// (stylized-shadows: the contour and D of the same shadow output, the thesis's fast
    /// edits of the controls) has anything to forget.
    fn forget(&mut self) {}
}

/// A filter's result on one frame.
pub struct FilterRun {
    pub image: RgbImage,
    /// Wall-clock time of the filter, including reading buffers back where it needs to.
    pub wall_time: Duration,
    /// Device kernel time (OpenCL profiling events), for device filters.
    pub kernel_time: Option<Duration>,
}

impl FilterRun {
    /// The kernel time where there is one, else the wall-clock time.
    pub fn time(&self) -> Duration {
        self.kernel_time.unwrap_or(self.wall_time)
    }
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
