//! The path-density outlier filter (DeCoro 2009, "Rendering Filters for Controlling Detail and
//! Creating Effects", ch. 5; digest in shared/notes/seed-decoro.md §3): fireflies are removed
//! per sample, before the pixel is reconstructed, by the density of each camera sample in the
//! joint space of film position and CIELAB colour.
//!
//! For each stored sample i (film position with its jitter, HDR RGB; the RPF sample vectors,
//! see "Input" below):
//! 1. d(i, j) = ‖Δxy‖ / w_W + ‖ΔLab‖ / w_c, "the sum of Euclidean distance between their image
//!    space coordinates, and their color coordinates in CIELAB space" (§5.3, Distance Metric),
//!    the image term "weighted to correspond to the width of the sensor response W", the
//!    colour weight "fixed to 20".
//! 2. σ_i = mean distance to the k nearest neighbours, self excluded ("σ is equal to the mean
//!    absolute distance from x to the k-nearest neighbors"); k = 10, 50, 200 in Fig. 5.8.
//! 3. ρ_i = G(σ_i), the standard normal density; "reduce the influence of all samples more
//!    than 2 standard deviations away, and reject samples 3 standard deviations away".
//! 4. I(p) = Σ w_i L_i / Σ w_i over the pixel's samples (eq. 5.1 with the weights), the plain
//!    mean when every weight is 0.
//!
//! # Choices where the seed is open (each a setting)
//!
//! - **Colour weight as a divisor** (`color_weight` = 20): ΔE / 20. Read as a product, any
//!   ΔE above 0.15 gives σ > 3 and every sample would be rejected (digest §3.2 item 1).
//! - **w_W** (`sensor_width` = 1 pixel): the renderer reconstructs each pixel with a box of
//!   one pixel (the film's running mean), so W is one pixel wide.
//! - **The ramp** between 2 and 3 "standard deviations": G is monotone, so thresholds on ρ at
//!   G(2) and G(3) are thresholds on σ at 2 and 3; the weight is linear in σ,
//!   w = clamp((3 − σ) / (3 − 2), 0, 1) (`keep`, `reject`): continuous, so a small change of σ
//!   never switches a sample on or off (the seed's reason for the soft band).
//! - **Self excluded** from the k neighbours; **rejected samples leave the normaliser**.
//! - **CIELAB** of linear Rec. 709 RGB, D65 white with Y_n = 1 (HDR values give L* > 100; a
//!   firefly of Y = 10 has L* ≈ 234). A sample whose colour or Lab is not finite is never a
//!   neighbour and weighs 0.
//! - **An RGB distance** for comparison only (`color_space = "rgb"`, the seed's Fig. 5.9):
//!   the colour coordinates are 100 × linear RGB, so that the colour weight 20 is the same
//!   share of a [0, 1] colour's range as of L*'s [0, 100]. The seed shows that it "poorly
//!   distinguishes colors across edges": dark colours all sit near black, so the cell samples
//!   next to a black line are rejected and the line grows (scenes/decoro/color_grid.toml,
//!   tests/path_density_scenes.rs). Validity stays that of the Lab (and of the scaled RGB), so
//!   both spaces drop the same samples.
//! - **Fewer than k samples** in the image (or frame group): σ is the mean over those there
//!   are; none at all gives σ = 0 (nothing contradicts the sample).
//! - **Exact kNN** on the device by rings of pixels with an early stop
//!   (kernels/filters/path_density.cl), not a space-partitioning tree: the samples are already
//!   stored pixel-major, so image space needs no tree. `epsilon` > 0 gives the seed's
//!   ε-approximate kNN (its ref. [5]) as an earlier stop of the same scan: every held distance
//!   is within 1 + ε of the true one, so σ is over-estimated by at most 1 + ε.
//!
//! # Accumulated (consistent) and per-frame (biased) modes
//!
//! The filter is "progressive" and consistent only when the densities are taken over every
//! sample gathered so far (`mode = "accumulated"`, the default and the seed's method): as spp
//! grows, neighbours crowd in, σ → 0, ρ → 1/√(2π), nothing is rejected and the result tends
//! to the plain mean. `mode = "per-frame"` is what a progressive viewer that filters each
//! frame of `frame_spp` samples and then averages the frames would do: each group of
//! `frame_spp` consecutive samples of a pixel sees only its own group's samples as neighbours,
//! so a rare but correct sample (a caustic) is rejected in every frame and the average never
//! converges to it. It is **biased** and offered to measure that bias.
//!
//! # Whole frames
//!
//! A sample's k nearest neighbours may lie any number of rows away (the ring scan runs until
//! it has k), so the filter has no bounded reach: split across devices it runs on the merged
//! film ([`PreparedFilter::reach`] is None), like every filter of the stored samples.
//!
//! # Input
//!
//! The RPF sample vectors (the `samples` output, src/layout/outputs.rs): film position with
//! its jitter and HDR colour are two of their fields, so the filter reuses that buffer (and the
//! samples.bin file for offline filtering) instead of a second per-sample output. It costs
//! 104 bytes per sample where 20 would do.
//!
//! # Chains
//!
//! `then = "ddf"`, `"atrous"` or `"bmfr"` runs that filter on the cleaned image (the seed: outlier
//! removal first "make[s] the task of smoothing inter-pixel variance amenable to existing
//! filtering methods"). The registry runs one filter per render, so a chain is a setting of
//! this filter rather than a registry feature: the chained filter runs with its defaults,
//! specialised to the scene like any filter, on a frame whose colour is the cleaned image and
//! whose features are the render's. The cleaned image replaces the mean of direct + indirect
//! light; the change goes to the indirect part first (outliers are paths that bounce to a
//! light, §5.1), as far as it stays ≥ 0, the rest to the direct part. A chain needs the
//! samples and the chained filter's outputs in one frame, so it runs at the end of a render;
//! offline, neither the samples file nor the AOV file holds both (an error says so).

mod device;
pub mod reference;

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, bail};
use serde::{Deserialize, Serialize};

use super::{Configured, FilterKind, FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::layout::FilterVector;
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::render::{Frame, FrameInfo, HostBuffer, SceneInfo};
pub use device::{DeviceRun, PathDensityKernel};
pub use reference::{Densities, FilmSamples};

/// The largest k (the kernel keeps the k best distances in a private array).
pub const MAX_K: u32 = 256;

/// Whose samples are a sample's neighbours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DensityMode {
    /// Every sample of the render so far (the seed's consistent, progressive filter).
    Accumulated,
    /// Only the samples of the same frame of `frame_spp` samples (biased).
    PerFrame,
}

/// The space of the colour term of the distance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ColorSpace {
    /// CIELAB (the seed's metric).
    Cielab,
    /// 100 × linear RGB (the seed's Fig. 5.9 counter-example; for comparison only).
    Rgb,
}

/// The filter run on the cleaned image, if any.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Then {
    None,
    Ddf,
    Atrous,
    /// The regression filter (bmfr): its fit reads the cleaned colour; its per-pixel selection
    /// reads the two half buffers as rendered (the outlier filter cleans the whole pixel, not
    /// its halves), so fireflies still raise its noise estimate there.
    Bmfr,
}

crate::filter_settings! {
    /// The path-density filter's parameters (DeCoro 2009 ch. 5; the defaults are the seed's).
    pub struct PathDensitySettings, flags "pd-" {
        /// k, the neighbours whose mean distance is σ (the seed: 10, 50, 200; 1 to 256).
        pub k: u32 = 10,
        /// w_W: the image distance is divided by it, in pixels (the width of the pixel
        /// filter: 1 for the renderer's box).
        pub sensor_width: f32 = 1.0,
        /// w_c: the CIELAB distance is divided by it (the seed's 20).
        pub color_weight: f32 = 20.0,
        /// σ up to which a sample keeps its full weight (2 standard deviations).
        pub keep: f32 = 2.0,
        /// σ from which a sample is rejected (3); the weight is linear between.
        pub reject: f32 = 3.0,
        /// ε of the approximate kNN: σ at most 1 + ε times the exact one (0: exact).
        pub epsilon: f32 = 0.0,
        /// "cielab" (the seed's) or "rgb" (100 x linear RGB: the seed's Fig. 5.9 comparison,
        /// which grows dark lines).
        pub color_space: ColorSpace = ColorSpace::Cielab,
        /// "accumulated" (every sample so far; consistent) or "per-frame" (biased).
        pub mode: DensityMode = DensityMode::Accumulated,
        /// Samples per frame in the per-frame mode.
        pub frame_spp: u32 = 1,
        /// A filter run on the cleaned image: "none", "ddf", "atrous" or "bmfr".
        pub then: Then = Then::None,
    }
}

/// The numbers the kernels and the reference run with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathDensityParams {
    pub k: u32,
    pub sensor_width: f32,
    pub color_weight: f32,
    pub keep: f32,
    pub reject: f32,
    /// ε of the approximate kNN (0: exact).
    pub epsilon: f32,
    /// The colour term's space.
    pub color_space: ColorSpace,
    /// Samples per frame group; `u32::MAX` (accumulated): all of a pixel's samples.
    pub frame_spp: u32,
}

impl PathDensityParams {
    pub fn inv_w(&self) -> f32 {
        1.0 / self.sensor_width
    }

    pub fn inv_c(&self) -> f32 {
        1.0 / self.color_weight
    }

    /// 1 / (1 + ε): the ring scan stops once the ring's distance reaches the k-th best times
    /// this.
    pub fn shrink(&self) -> f32 {
        1.0 / (1.0 + self.epsilon)
    }

    /// The group size for `spp` stored samples per pixel.
    pub fn frame_spp_for(&self, spp: u32) -> u32 {
        self.frame_spp.min(spp).max(1)
    }

    /// These parameters for `spp` stored samples (the reference takes the group size as is).
    pub fn for_spp(mut self, spp: u32) -> Self {
        self.frame_spp = self.frame_spp_for(spp);
        self
    }

    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_K).contains(&self.k) {
            bail!(
                "the path-density k must be 1 to {MAX_K} (the seed uses 10, 50, 200), got {}",
                self.k
            );
        }
        for (v, name) in [
            (self.sensor_width, "sensor_width"),
            (self.color_weight, "color_weight"),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                bail!("the path-density {name} must be a positive number, got {v}");
            }
        }
        if !(self.keep >= 0.0 && self.reject >= self.keep && self.reject.is_finite()) {
            bail!(
                "the path-density thresholds need 0 <= keep <= reject (the seed: 2 and 3), got \
                 keep = {} and reject = {}",
                self.keep,
                self.reject
            );
        }
        if !(self.epsilon >= 0.0 && self.epsilon.is_finite()) {
            bail!(
                "the path-density epsilon must be a finite number >= 0 (0: exact kNN), got {}",
                self.epsilon
            );
        }
        if self.frame_spp == 0 {
            bail!("the path-density frame_spp must be at least 1");
        }
        Ok(())
    }
}

impl PathDensitySettings {
    pub fn params(&self) -> PathDensityParams {
        PathDensityParams {
            k: self.k,
            sensor_width: self.sensor_width,
            color_weight: self.color_weight,
            keep: self.keep,
            reject: self.reject,
            epsilon: self.epsilon,
            color_space: self.color_space,
            frame_spp: match self.mode {
                DensityMode::Accumulated => u32::MAX,
                DensityMode::PerFrame => self.frame_spp,
            },
        }
    }
}

/// The path-density filter in the registry.
pub struct PathDensity;

impl FilterKind for PathDensity {
    type Settings = PathDensitySettings;
    const NAME: &'static str = "path-density";
    const SUMMARY: &'static str =
        "the path-density outlier filter of DeCoro 2009 ch. 5 (per sample, on the device)";

    fn check(s: &PathDensitySettings) -> Result<()> {
        if s.mode == DensityMode::PerFrame && s.frame_spp == 0 {
            bail!("the path-density frame_spp must be at least 1");
        }
        s.params().validate()
    }

    /// The samples, and what the chained filter reads.
    fn needs(s: &PathDensitySettings) -> OutputSet {
        let samples = OutputSet::of(&[Output::Samples]);
        match chained(s.then, &SceneInfo::unknown()) {
            // bmfr's albedo prefilter and its emission split (both on with a thin lens) read
            // the variances and the emission; which camera the frame has is known only when
            // the filter is prepared, so they are gathered.
            Some(c) if s.then == Then::Bmfr => samples
                .union(c.needs())
                .union(OutputSet::of(&[Output::Variance, Output::Emission])),
            Some(c) => samples.union(c.needs()),
            None => samples,
        }
    }

    fn prepare(
        s: &PathDensitySettings,
        frame: &FrameInfo,
        gpu: &Arc<Gpu>,
    ) -> Result<Box<dyn PreparedFilter>> {
        let then = match chained(s.then, &frame.scene) {
            Some(c) => {
                let info = FrameInfo {
                    sample_capacity: 0,
                    ..frame.clone()
                };
                Some((c.needs(), c.prepare(&info, gpu)?))
            }
            None => None,
        };
        Ok(Box::new(PathDensityRun {
            kernel: PathDensityKernel::new(gpu.clone(), s.params())?,
            then,
        }))
    }
}

/// The chained filter with its defaults, specialised to `scene`.
fn chained(then: Then, scene: &SceneInfo) -> Option<Configured> {
    use super::atrous::{Atrous, AtrousSettings};
    use super::bmfr::{Bmfr, BmfrSettings};
    use super::ddf::{Ddf, DdfSettings};
    let c = match then {
        Then::None => return None,
        Then::Ddf => Configured::typed::<Ddf>(DdfSettings::default(), scene),
        Then::Atrous => Configured::typed::<Atrous>(AtrousSettings::default(), scene),
        Then::Bmfr => Configured::typed::<Bmfr>(BmfrSettings::default(), scene),
    };
    Some(c.expect("the defaults of the chained filters are valid"))
}

/// The path-density filter ready to run.
pub struct PathDensityRun {
    kernel: PathDensityKernel,
    then: Option<(OutputSet, Box<dyn PreparedFilter>)>,
}

impl PathDensityRun {
    /// The kernels (for the last run's densities).
    pub fn kernel(&self) -> &PathDensityKernel {
        &self.kernel
    }
}

impl PreparedFilter for PathDensityRun {
    fn forget(&mut self) {
        if let Some((_, next)) = &mut self.then {
            next.forget();
        }
    }

    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        let start = Instant::now();
        let run = self.kernel.run(frame)?;
        let Some((needs, next)) = &mut self.then else {
            return Ok(FilterRun {
                image: run.image,
                wall_time: start.elapsed(),
                kernel_time: Some(run.kernel_time),
            });
        };
        let cleaned = with_colour(frame, &run.image, *needs)?;
        let after = next.run(&cleaned)?;
        let kernel_time = Some(run.kernel_time + after.time());
        Ok(FilterRun {
            image: after.image,
            wall_time: start.elapsed(),
            kernel_time,
        })
    }
}

/// A host frame with `needs` of `frame` whose colour is `image`: the change to direct +
/// indirect goes to the indirect part as far as it stays ≥ 0, the rest to the direct part.
pub fn with_colour(frame: &Frame, image: &RgbImage, needs: OutputSet) -> Result<Frame> {
    let needs = needs.closed();
    frame.require(needs, "the filter chained after the path-density filter")?;
    let mut fv: Vec<FilterVector> = frame.filter_vectors()?.to_vec();
    for (f, c) in fv.iter_mut().zip(&image.pixels) {
        for (k, &ck) in c.iter().enumerate() {
            let indirect = (f.indirect[k] + (ck - (f.direct[k] + f.indirect[k]))).max(0.0);
            f.indirect[k] = indirect;
            f.direct[k] = ck - indirect;
        }
    }
    let mut buffers = vec![(BufferId::FilterVectors, HostBuffer::from_slice(&fv))];
    for b in needs.buffers().filter(|b| b.id != BufferId::FilterVectors) {
        buffers.push((b.id, frame.host(b.id)?.clone()));
    }
    let info = FrameInfo {
        sample_capacity: 0,
        ..frame.info().clone()
    };
    Frame::on_host(info, needs, frame.variance_form(), buffers)
}
