//! The viewer's state and one frame of it (thesis §4.2): the film on one or more devices, the
//! chosen filter, what is shown, and what a change does: every change of the camera or of a
//! setting empties the film and rendering starts again from one sample per pixel (§4.2.2
//! "Film": "The buffers are emptied when the camera updates").

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow};

use super::camera::{self, CameraInput};
use super::controls::Command;
use crate::bench::ground_truth;
use crate::filters::{Configured, DeviceFilter, Filter, FilterRequest, MultiDeviceArgs, Registry};
use crate::gpu::Gpu;
use crate::imaging::{RgbImage, srgb_to_linear, to_srgb8};
use crate::layout::outputs::{Output, OutputSet};
use crate::metrics::{self, ErrorScale};
use crate::render::{RenderOptions, SceneArrays, SceneInfo, SplitRenderer};
use crate::scene::{Camera, Scene};

/// How many pictures [`crate::stats::aov::aov_pictures`] makes of a film with features and
/// variances: beauty, direct, indirect, depth, normal, albedo, albedo2 and five variances.
const AOV_PICTURES: usize = 12;

/// The image of a frame as shown.
pub struct Shown {
    /// 8-bit sRGB, 3 bytes a pixel.
    pub rgb8: Vec<u8>,
    /// Linear values (for the EXR of a screenshot).
    pub linear: RgbImage,
}

/// Timings of the last frame, for the heads-up line.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// Wall time of adding the frame's samples (all devices, merging included).
    pub render: Duration,
    /// Wall time of the filter, when it ran.
    pub filter: Option<Duration>,
    /// Samples added this frame (pixels × samples per pixel).
    pub samples: u64,
}

/// Everything the viewer renders and shows.
pub struct Viewer<'r> {
    registry: &'r Registry,
    pub scene: Scene,
    pub scene_path: PathBuf,
    initial_camera: Camera,
    pub options: RenderOptions,
    gpus: Vec<Arc<Gpu>>,
    multi: MultiDeviceArgs,
    request: FilterRequest,
    /// 0: no filter; k: the registry's k-th filter.
    filter_index: usize,
    configured: Option<Configured>,
    filter: Option<DeviceFilter>,
    pub film: SplitRenderer,
    pub unfiltered: bool,
    pub error: bool,
    /// Which AOV picture (src/stats/aov.rs) is shown instead of the image.
    pub aov: Option<usize>,
    pub exposure: f32,
    /// Samples per pixel added each frame.
    pub spf: u32,
    /// Stop adding samples here (a film storing every sample holds no more).
    pub max_spp: Option<u32>,
    reference_cache: PathBuf,
    /// The cached reference for the current camera: looked up once per camera.
    reference: Option<Option<(RgbImage, PathBuf)>>,
    pub stats: FrameStats,
    /// A line for the heads-up display (what the last key did).
    pub message: String,
}

impl<'r> Viewer<'r> {
    /// A viewer of `scene` rendered with `options` on `gpus`, starting with the filter named
    /// `filter` ("none" for none).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        registry: &'r Registry,
        scene: Scene,
        scene_path: &Path,
        options: RenderOptions,
        gpus: Vec<Arc<Gpu>>,
        multi: MultiDeviceArgs,
        request: FilterRequest,
        filter: &str,
    ) -> Result<Viewer<'r>> {
        registry.check_request(&request)?;
        let filter_index = if filter == "none" {
            0
        } else {
            let names = registry.names();
            1 + names.iter().position(|n| *n == filter).ok_or_else(|| {
                anyhow!(
                    "no filter named {filter:?}; noisefree has: none, {}",
                    names.join(", ")
                )
            })?
        };
        let arrays = SceneArrays::build(&scene, &options.frame)?;
        let film = multi.film(&gpus, &scene, arrays, &options)?;
        let mut v = Viewer {
            registry,
            initial_camera: scene.camera.clone(),
            scene,
            scene_path: scene_path.to_path_buf(),
            options,
            gpus,
            multi,
            request,
            filter_index,
            configured: None,
            filter: None,
            film,
            unfiltered: false,
            error: false,
            aov: None,
            exposure: 0.0,
            spf: 1,
            max_spp: None,
            reference_cache: ground_truth::default_cache(),
            reference: None,
            stats: FrameStats::default(),
            message: String::new(),
        };
        v.configure()?;
        Ok(v)
    }

    pub fn set_reference_cache(&mut self, dir: PathBuf) {
        self.reference_cache = dir;
        self.reference = None;
    }

    fn chosen(&self) -> Option<&'static dyn Filter> {
        self.filter_index
            .checked_sub(1)
            .and_then(|i| self.registry.filters().get(i).copied())
    }

    /// The filter shown and its requested settings (None without one or when the unfiltered
    /// image is shown): what a saved scene file asks `render` to run.
    pub fn filter_for_render(&self) -> Option<(&'static str, &toml::Table)> {
        let c = self.configured.as_ref()?;
        (!self.unfiltered).then(|| (c.name(), c.requested()))
    }

    /// Configures and prepares the chosen filter for the current camera (rebuilding the film
    /// when the filter needs outputs it lacks or another light field: [`film_must_change`])
    /// and empties the film.
    fn configure(&mut self) -> Result<()> {
        let info = SceneInfo::new(&self.scene, &self.film.primary().arrays);
        self.configured = match self.chosen() {
            Some(f) => Some(self.registry.configure(f, &self.request, &info)?),
            None => None,
        };
        // The AOV pictures read the features and their variances; the filter samples as it
        // asks, from the defaults, as `render --filter` does.
        let mut wanted = self.options.clone();
        wanted.outputs =
            OutputSet::colour().union(OutputSet::of(&[Output::Features, Output::Variance]));
        (wanted.shadows, wanted.indirect) = Default::default();
        if let Some(c) = &self.configured {
            wanted.outputs = wanted.outputs.union(c.needs());
            c.adjust_render(&mut wanted);
        }
        if film_must_change(&self.options, &wanted) {
            if wanted.outputs.contains(Output::Samples) {
                // A film of every sample holds a fixed number of them.
                let cap = self.max_spp.unwrap_or(16);
                wanted.sample_capacity = cap;
                self.max_spp = Some(cap);
                crate::stats::samples::check_memory(
                    wanted.frame.width,
                    wanted.frame.height,
                    cap,
                    crate::memory::available_memory_bytes().unwrap_or(u64::MAX),
                )?;
            }
            let arrays = self.film.primary().arrays.clone();
            self.film = self.multi.film(&self.gpus, &self.scene, arrays, &wanted)?;
            self.options = wanted;
        }
        self.filter = match &self.configured {
            Some(c) => Some(DeviceFilter::prepare(
                c,
                &mut self.film,
                self.multi.filter_placement,
            )?),
            None => None,
        };
        self.film.reset()
    }

    /// Applies a frame's camera input and commands; returns whether the film was emptied.
    pub fn update(
        &mut self,
        input: &CameraInput,
        dt: f32,
        focus: Option<(f32, f32)>,
    ) -> Result<bool> {
        let size = self.film.scene_info().scene_size;
        let mut moved = camera::apply(&mut self.scene.camera, input, dt, size);
        if let Some((x, y)) = focus {
            let (w, h) = (self.film.width(), self.film.height());
            match camera::focus_at(&self.film.primary().arrays, w, h, x, y) {
                Some(d) => {
                    self.scene.camera.focal_distance = Some(d);
                    self.scene.camera.autofocus = false;
                    if self.scene.camera.lens_radius == 0.0 {
                        self.scene.camera.lens_radius = 2e-3 * size;
                    }
                    self.message = format!("focus at pixel ({x:.0}, {y:.0}): distance {d:.3}");
                    moved = true;
                }
                None => self.message = format!("nothing to focus on at ({x:.0}, {y:.0})"),
            }
        }
        if moved {
            self.camera_changed()?;
        }
        Ok(moved)
    }

    fn camera_changed(&mut self) -> Result<()> {
        self.film.set_camera(&self.scene)?;
        self.reference = None;
        // The filters specialise to the camera (SceneInfo): prepared again, as `render` would.
        self.configure()
    }

    /// Runs a command; Screenshot and SaveScene are the caller's (they need the window).
    pub fn command(&mut self, c: Command) -> Result<()> {
        let count = self.registry.filters().len();
        match c {
            Command::Filter(n) if n <= count => self.set_filter(n)?,
            Command::Filter(n) => self.message = format!("no filter {n}: 0-{count}"),
            Command::NextFilter => self.set_filter((self.filter_index + 1) % (count + 1))?,
            Command::ToggleHoles => self.edit_setting("holes", |v| match v {
                toml::Value::Boolean(b) => Some(toml::Value::Boolean(!b)),
                _ => None,
            })?,
            Command::KernelWidth(step) => self.edit_setting("kw", |v| match v {
                toml::Value::Integer(k) => Some(toml::Value::Integer((k + 2 * step as i64).max(1))),
                _ => None,
            })?,
            // What is shown changes, the film stays: the same samples filtered and not, or
            // against the reference, side by side in time.
            Command::ToggleUnfiltered => self.unfiltered = !self.unfiltered,
            Command::ToggleError => self.error = !self.error,
            Command::Aov(step) => {
                // The image, then each AOV picture, then the image again.
                let n = AOV_PICTURES as i64;
                let now = self.aov.map_or(-1, |a| a as i64);
                let next = (now + 1 + step as i64).rem_euclid(n + 1) - 1;
                self.aov = (next >= 0).then_some(next as usize);
            }
            Command::Exposure(step) => self.exposure += 0.5 * step as f32,
            Command::ResetCamera => {
                self.scene.camera = self.initial_camera.clone();
                self.camera_changed()?;
            }
            Command::Screenshot | Command::SaveScene | Command::ToggleHelp | Command::Quit => {}
        }
        Ok(())
    }

    fn set_filter(&mut self, index: usize) -> Result<()> {
        self.filter_index = index;
        self.configure()?;
        self.message = format!("filter: {}", self.filter_name());
        Ok(())
    }

    /// Changes one setting of the chosen filter (as a command-line flag would); a filter
    /// without it, or a value it refuses, leaves everything as it was.
    fn edit_setting(
        &mut self,
        key: &str,
        change: impl Fn(&toml::Value) -> Option<toml::Value>,
    ) -> Result<()> {
        let Some(c) = &self.configured else {
            self.message = format!("no filter: {key} applies to a filter's settings");
            return Ok(());
        };
        let name = c.name();
        let Some(new) = c.effective().get(key).and_then(&change) else {
            self.message = format!("the {name} filter has no {key} setting");
            return Ok(());
        };
        let before = self.request.flags.get(name).cloned();
        self.request
            .flags
            .entry(name.to_string())
            .or_default()
            .insert(key.to_string(), new.clone());
        match self.configure() {
            Ok(()) => self.message = format!("{name}: {key} = {new}"),
            Err(e) => {
                match before {
                    Some(t) => self.request.flags.insert(name.to_string(), t),
                    None => self.request.flags.remove(name),
                };
                self.configure()?;
                self.message = format!("{name}: {key} = {new} refused: {e:#}");
            }
        }
        Ok(())
    }

    pub fn filter_name(&self) -> &'static str {
        self.chosen().map_or("none", |f| f.name())
    }

    /// "ddf (kw 15, holes)".
    pub fn filter_label(&self) -> String {
        let Some(c) = &self.configured else {
            return "no filter".into();
        };
        let e = c.effective();
        let mut extra = Vec::new();
        if let Some(k) = e.get("kw").and_then(|v| v.as_integer()) {
            extra.push(format!("kw {k}"));
        }
        if e.get("holes").and_then(|v| v.as_bool()) == Some(true) {
            extra.push("holes".into());
        }
        if extra.is_empty() {
            c.name().to_string()
        } else {
            format!("{} ({})", c.name(), extra.join(", "))
        }
    }

    /// Adds the frame's samples (unless the film is full) and makes the image to show.
    pub fn step(&mut self) -> Result<Shown> {
        let start = Instant::now();
        let room = self
            .max_spp
            .map_or(u32::MAX, |m| m.saturating_sub(self.film.samples_done()));
        let count = self.spf.min(room);
        self.film.render_samples(count)?;
        self.stats.render = start.elapsed();
        self.stats.samples = count as u64 * self.film.width() as u64 * self.film.height() as u64;
        self.stats.filter = None;
        let (w, h) = (self.film.width(), self.film.height());
        if let Some(k) = self.aov {
            let pictures = crate::stats::aov::aov_pictures(&self.film.frame()?, self.exposure)?;
            let (name, rgb8) = pictures
                .into_iter()
                .nth(k)
                .ok_or_else(|| anyhow!("AOV picture {k} is not there"))?;
            self.message = format!("AOV: {name} (M/N: next/previous)");
            return Ok(from_rgb8(rgb8, w, h));
        }
        let image = match (&mut self.filter, self.unfiltered) {
            (Some(f), false) => {
                let out = f.run(&self.film)?;
                self.stats.filter = Some(out.wall_time);
                out.image
            }
            _ => self.film.frame()?.beauty()?,
        };
        if self.error {
            return self.error_image(&image);
        }
        Ok(Shown {
            rgb8: to_srgb8(&image, self.exposure),
            linear: image,
        })
    }

    /// The per-pixel CIELUV error against the cached reference of the current camera, on the
    /// fixed scale of the error maps (src/metrics/error_map.rs).
    fn error_image(&mut self, image: &RgbImage) -> Result<Shown> {
        if self.reference.is_none() {
            let found = ground_truth::find_cached(
                &self.reference_cache,
                &self.scene_path,
                &self.film.primary().arrays,
            );
            self.reference = Some(match found {
                Some(p) => Some((crate::imaging::read_exr_rgb(&p)?, p)),
                None => None,
            });
        }
        match self.reference.as_ref().and_then(|r| r.as_ref()) {
            Some((reference, path)) => {
                let map = metrics::error_map(image, reference, ErrorScale::default())?;
                let mse = metrics::mse_luv(image, reference)?;
                self.message = format!(
                    "error vs {} : MSE (CIELUV) {mse:.3}",
                    path.file_name().unwrap_or_default().to_string_lossy()
                );
                Ok(from_rgb8(map.rgb8, image.width, image.height))
            }
            None => {
                self.message = format!(
                    "no cached reference for this camera in {} (`noisefree reference SCENE` \
                     renders one for the scene's own camera)",
                    self.reference_cache.display()
                );
                Ok(Shown {
                    rgb8: to_srgb8(image, self.exposure),
                    linear: image.clone(),
                })
            }
        }
    }
}

/// Whether a film gathered with `film` must be built again to serve a filter that asks for
/// `wanted` (its outputs, and how the renderer samples them: [`Configured::adjust_render`]):
/// it lacks an output, its light-field output holds another field than the filter reads
/// ([`RenderOptions::recorded_outputs`]: the shadow fields where depth of field reads the lens
/// field, say, after a click gave the camera a lens), or an output the filter reads is sampled
/// otherwise than it asks. Outputs the film has and the filter does not read stay.
pub fn film_must_change(film: &RenderOptions, wanted: &RenderOptions) -> bool {
    let (have, want) = (film.recorded_outputs(), wanted.recorded_outputs());
    let shadows = want.contains(Output::Shadows) || want.contains(Output::LightField);
    !have.covers(want)
        || (shadows && film.shadows != wanted.shadows)
        || (want.contains(Output::Indirect) && film.indirect != wanted.indirect)
}

/// A false-colour picture, shown as it is; its linear values for the EXR.
fn from_rgb8(rgb8: Vec<u8>, width: u32, height: u32) -> Shown {
    let pixels = rgb8
        .chunks_exact(3)
        .map(|c| [0, 1, 2].map(|i| srgb_to_linear(c[i] as f32 / 255.0)))
        .collect();
    Shown {
        rgb8,
        linear: RgbImage {
            width,
            height,
            pixels,
        },
    }
}
