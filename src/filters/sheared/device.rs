//! The sheared soft-shadow filter on the device (kernels/filters/sheared.cl): per filtered
//! light, prepare, steps 1a, 1b, 2a, 2b, then the compose (kernels/filters/aaf_shadows.cl
//! `aaf_compose_sheared`, which reads the kind from the same guide lane; each light's compose
//! on the image of the lights before it).

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

use super::ShearedSettings;
use super::reference::{g_floats, p_floats};
use crate::filters::aaf_shadows::{AafShadowSettings, compose_kernel};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue_rows, event_duration, read_rgb_rows};
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{AafShadowParams, Float4, ShearedParams};
use crate::render::Frame;

/// Names of the six launches, in order (per-step times in [`ShearedKernel::step_times`]).
pub const STEPS: [&str; 6] = ["prepare", "1a", "1b", "2a", "2b", "compose"];

/// What each step left on the device, read back (tests compare them with the reference).
pub struct Intermediates {
    pub guide: Vec<[f32; 4]>,
    pub p1a: Vec<f32>,
    pub g1b: Vec<f32>,
    pub q2a: Vec<f32>,
    pub visibility: Vec<f32>,
}

/// One filtered light's launches: its parameters (centre, radius, frame, σ_y, bins' range) in
/// the six kernels, which read its plane of the shadow output and of the light field.
struct LightPasses {
    /// The scene's sphere light (its plane is looked up in each frame).
    light: u32,
    kernels: [Kernel; 6],
    _params: Buffer<ShearedParams>,
    _compose_params: Buffer<AafShadowParams>,
}

/// The filter's kernels and buffers for one image size: the steps' buffers, shared by the
/// lights, which run one after another, each composing onto the image of the ones before.
struct Passes {
    lights: Vec<LightPasses>,
    guide: Buffer<Float4>,
    p1a: Buffer<f32>,
    g1b: Buffer<f32>,
    q2a: Buffer<f32>,
    visibility: Buffer<f32>,
    image: Buffer<Float4>,
    /// With depth of field as well: the lens field each light's combine adds its filtered
    /// term to (a [`crate::layout::LightFieldPixel`] per pixel), which the depth-of-field
    /// filter reads; None: each light composes onto `image`.
    combined: Option<Buffer<u8>>,
}

/// The sheared filter, built for an image size and its lights (none: the image passes
/// through).
pub struct ShearedKernel {
    gpu: Arc<Gpu>,
    passes: Option<Passes>,
    width: u32,
    height: u32,
    /// Most steps of a 1-D gather: the rows 1b and 2b each read beyond a band.
    max_radius: u32,
    step_times: [Duration; 6],
}

impl ShearedKernel {
    /// `lights`: the filtered sphere lights (number, centre and radius), in increasing order
    /// (empty: none), in a scene centred at `scene_centre` (each light's frame,
    /// [`crate::render::shadows::light_field::light_frame`]).
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &ShearedSettings,
        lights: &[(u32, [f32; 4])],
        scene_centre: [f32; 3],
        width: u32,
        height: u32,
    ) -> Result<ShearedKernel> {
        Self::build(gpu, settings, lights, scene_centre, width, height, false)
    }

    /// The shadow half of sheared shadows with depth of field (Yan et al.'s appendix): each
    /// light's last launch, in place of the compose, adds its filtered direct term to the lens
    /// field of the frame's lens-shadows output (kernels/filters/sheared_lens_shadows.cl),
    /// into [`Self::combined_field`].
    pub fn with_lens(
        gpu: Arc<Gpu>,
        settings: &ShearedSettings,
        lights: &[(u32, [f32; 4])],
        scene_centre: [f32; 3],
        width: u32,
        height: u32,
    ) -> Result<ShearedKernel> {
        if lights.is_empty() {
            bail!(
                "sheared shadows with depth of field need a filtered sphere light (light = -1 \
                 filters none): use effect = \"dof\" for depth of field alone"
            );
        }
        Self::build(gpu, settings, lights, scene_centre, width, height, true)
    }

    fn build(
        gpu: Arc<Gpu>,
        settings: &ShearedSettings,
        lights: &[(u32, [f32; 4])],
        scene_centre: [f32; 3],
        width: u32,
        height: u32,
        lens: bool,
    ) -> Result<ShearedKernel> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let passes = if lights.is_empty() {
            None
        } else {
            Some(Passes::new(
                &gpu,
                settings,
                lights,
                scene_centre,
                width,
                height,
                lens,
            )?)
        };
        Ok(ShearedKernel {
            gpu,
            passes,
            width,
            height,
            max_radius: settings.max_radius,
            step_times: [Duration::ZERO; 6],
        })
    }

    /// With [`Self::with_lens`]: the lens field with the lights' filtered terms put back, as
    /// the last run left it on the rows it filtered.
    pub fn combined_field(&self) -> Option<&Buffer<u8>> {
        self.passes.as_ref()?.combined.as_ref()
    }

    /// Kernel time of each launch of the last run, in the order of [`STEPS`], summed over
    /// the lights.
    pub fn step_times(&self) -> [Duration; 6] {
        self.step_times
    }

    /// Filters `frame` (width × height, with the light-field output unless there is no light)
    /// and reads the image back.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    /// Filters the pixels of `rows` only (one band of a frame split across devices): 2b reads
    /// q up to max_radius rows away (a step moves at most one row), 1b reads p and the guide
    /// up to max_radius rows further, so prepare and 1a run on the band widened by twice that,
    /// 1b and 2a by once, and the band's pixels get the bytes of the whole frame's filtering.
    /// The image's other rows are black. Each light runs the six launches on its planes.
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        frame.check_size(self.width, self.height, "the sheared filter")?;
        let rows = rows.start.min(self.height)..rows.end.min(self.height);
        let Some(p) = &self.passes else {
            let mut image = frame.beauty()?;
            for (y, row) in image.pixels.chunks_mut(self.width as usize).enumerate() {
                if !rows.contains(&(y as u32)) {
                    row.fill([0.0; 3]);
                }
            }
            return Ok(FilterRun {
                image,
                wall_time: start.elapsed(),
                kernel_time: Some(Duration::ZERO),
            });
        };
        if p.combined.is_some() {
            bail!(
                "this sheared filter was built for shadows with depth of field: its lights' \
                 terms go into the lens field (run_lights), not into an image"
            );
        }
        self.run_lights(frame, rows.clone())?;
        let p = self.passes.as_ref().expect("checked above");
        Ok(FilterRun {
            image: read_rgb_rows(&p.image, self.width, self.height, rows)?,
            wall_time: start.elapsed(),
            kernel_time: Some(self.step_times.iter().sum()),
        })
    }

    /// Every light's six launches for the pixels of `rows`: the compose (or, with
    /// [`Self::with_lens`], the combine into [`Self::combined_field`]) of each on the rows
    /// themselves, the steps before on the rows they read (see [`Self::filter_rows`]).
    pub fn run_lights(&mut self, frame: &Frame, rows: Range<u32>) -> Result<()> {
        let h = self.height;
        let rows = rows.start.min(h)..rows.end.min(h);
        let widen = |r: u32| rows.start.saturating_sub(r)..(rows.end + r).min(h);
        let (wide, wider) = (widen(self.max_radius), widen(2 * self.max_radius));
        frame.check_size(self.width, self.height, "the sheared filter")?;
        let Some(p) = &mut self.passes else {
            return Ok(());
        };
        let lens = p.combined.is_some();
        let mut needs = OutputSet::of(&[Output::Colour, Output::Shadows, Output::LightField]);
        if lens {
            needs = needs.with(Output::LensShadows);
        }
        frame.require(needs, "the sheared filter")?;
        let info = frame.info();
        let planes = info.shadow_planes();
        let shadow = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let field = frame.device(&self.gpu, BufferId::LightFieldPixels)?;
        let bands = [&wider, &wider, &wide, &wide, &rows, &rows];
        self.step_times = [Duration::ZERO; 6];
        for (chained, l) in p.lights.iter().enumerate() {
            let Some(plane) = info.shadow_plane(l.light) else {
                bail!(
                    "the sheared filter reads the shadows and light field of sphere light {}, \
                     but the frame's shadow output holds sphere light(s) {:?}: render it with \
                     the filter asking for that light",
                    l.light,
                    info.shadow_lights
                );
            };
            let plane = plane as u32;
            let [prepare, k1a, k1b, _, k2b, last] = &l.kernels;
            for k in [prepare, k1b, k2b] {
                k.set_arg("shadow_pixels", shadow)?;
            }
            for k in [prepare, k1a, k1b, k2b] {
                k.set_arg("light_field", field)?;
                k.set_arg("plane", plane)?;
                k.set_arg("planes", planes)?;
            }
            if lens {
                last.set_arg("lens_field", frame.device(&self.gpu, BufferId::LensFieldPixels)?)?;
                last.set_arg(
                    "lens_shadow",
                    frame.device(&self.gpu, BufferId::LensShadowPixels)?,
                )?;
                last.set_arg("shadow_pixels", shadow)?;
            } else {
                last.set_arg("pixels", shadow)?;
                last.set_arg("fv", frame.device(&self.gpu, BufferId::FilterVectors)?)?;
                last.set_arg("terms", frame.device(&self.gpu, BufferId::ShadowTerms)?)?;
            }
            last.set_arg("plane", plane)?;
            last.set_arg("planes", planes)?;
            last.set_arg("chained", (chained > 0) as u32)?;
            for (n, k) in l.kernels.iter().enumerate() {
                // SAFETY: every buffer is owned by self or the frame, both alive until the
                // event completes (enqueue_rows waits), and sized for width x height pixels
                // (times the frame's planes for the per-light ones, indexed below planes).
                let event =
                    unsafe { enqueue_rows(k, self.width, h, bands[n].clone(), STEPS[n])? };
                self.step_times[n] += event_duration(&event)?;
            }
        }
        Ok(())
    }

    /// The last run's intermediate buffers, of its last light (None without a light).
    pub fn intermediates(&self) -> Result<Option<Intermediates>> {
        let Some(p) = &self.passes else {
            return Ok(None);
        };
        let read = |b: &Buffer<f32>| -> Result<Vec<f32>> {
            let mut v = vec![0f32; b.len()];
            b.read(&mut v).enq()?;
            Ok(v)
        };
        let mut guide = vec![Float4::default(); p.guide.len()];
        p.guide.read(&mut guide).enq()?;
        Ok(Some(Intermediates {
            guide: guide.into_iter().map(|g| g.0).collect(),
            p1a: read(&p.p1a)?,
            g1b: read(&p.g1b)?,
            q2a: read(&p.q2a)?,
            visibility: read(&p.visibility)?,
        }))
    }
}

impl Passes {
    fn new(
        gpu: &Gpu,
        s: &ShearedSettings,
        lights: &[(u32, [f32; 4])],
        scene_centre: [f32; 3],
        w: u32,
        h: u32,
        lens: bool,
    ) -> Result<Passes> {
        let n = w as usize * h as usize;
        let bins = s.bins;
        gpu.check_alloc(
            (n * p_floats(bins) * 4) as u64,
            "sheared filter's step-1a (p per bin and row)",
        )?;
        gpu.check_total(
            n as u64 * s.shadow_bytes_per_pixel(lights.len() as u32),
            "the sheared filter's buffers",
        )?;
        let program = gpu.program("filters/sheared.cl", &[], "")?;
        let aaf = gpu.program("filters/aaf_shadows.cl", &[], "")?;
        let combine = if lens {
            Some(gpu.program("filters/sheared_lens_shadows.cl", &[], "")?)
        } else {
            None
        };
        let combined = if lens {
            Some(gpu.zeroed::<u8>(
                n * std::mem::size_of::<crate::layout::LightFieldPixel>(),
                "sheared lens field with the shadows put back",
            )?)
        } else {
            None
        };
        let guide = gpu.zeroed::<Float4>(n, "sheared guide")?;
        let p1a = gpu.zeroed::<f32>(n * p_floats(bins), "sheared step 1a")?;
        let g1b = gpu.zeroed::<f32>(n * g_floats(bins), "sheared step 1b")?;
        let q2a = gpu.zeroed::<f32>(n * g_floats(bins), "sheared step 2a")?;
        let visibility = gpu.zeroed::<f32>(n, "sheared visibility")?;
        let image = gpu.zeroed::<Float4>(n, "sheared image")?;
        let size = [w as usize, h as usize];
        let what = "creating a sheared filter kernel";
        let lights = lights
            .iter()
            .map(|&(light, sphere)| -> Result<LightPasses> {
                let params = gpu.upload(&[s.params(sphere, scene_centre, w, h)])?;
                let compose_params =
                    gpu.upload(&[AafShadowSettings::default().params(sphere, w, h, 0)])?;
                let step = |name, shadow| reads(gpu, &program, name, size, &params, shadow);
                let prepare = step("sheared_prepare", true)
                    .arg(&guide)
                    .build()
                    .context(what)?;
                let k1a = step("sheared_1a", false)
                    .arg(&guide)
                    .arg(&p1a)
                    .build()
                    .context(what)?;
                let k1b = step("sheared_1b", true)
                    .arg(&guide)
                    .arg(&p1a)
                    .arg(&g1b)
                    .build()
                    .context(what)?;
                let k2a = gpu
                    .kernel(&program, "sheared_2a", size)
                    .arg_named("p", &params)
                    .arg(&guide)
                    .arg(&g1b)
                    .arg(&q2a)
                    .build()
                    .context(what)?;
                let k2b = step("sheared_2b", true)
                    .arg(&guide)
                    .arg(&q2a)
                    .arg(&visibility)
                    .build()
                    .context(what)?;
                let last = match (&combine, &combined) {
                    (Some(program), Some(out)) => combine_kernel(
                        gpu,
                        program,
                        size,
                        &params,
                        &guide,
                        &visibility,
                        out,
                    )?,
                    _ => compose_kernel(
                        gpu,
                        &aaf,
                        "aaf_compose_sheared",
                        size,
                        &compose_params,
                        [&guide, &image],
                        &visibility,
                    )?,
                };
                Ok(LightPasses {
                    light,
                    kernels: [prepare, k1a, k1b, k2a, k2b, last],
                    _params: params,
                    _compose_params: compose_params,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Passes {
            lights,
            guide,
            p1a,
            g1b,
            q2a,
            visibility,
            image,
            combined,
        })
    }
}

/// kernels/filters/sheared_lens_shadows.cl `sheared_lens_combine` into `out`, its frame
/// buffers, plane and chaining set per run.
fn combine_kernel(
    gpu: &Gpu,
    program: &ocl::Program,
    size: [usize; 2],
    params: &Buffer<ShearedParams>,
    guide: &Buffer<Float4>,
    visibility: &Buffer<f32>,
    out: &Buffer<u8>,
) -> Result<Kernel> {
    let none = None::<&Buffer<u8>>;
    gpu.kernel(program, "sheared_lens_combine", size)
        .arg_named("p", params)
        .arg_named("lens_field", none)
        .arg_named("lens_shadow", none)
        .arg_named("shadow_pixels", none)
        .arg_named("plane", 0u32)
        .arg_named("planes", 1u32)
        .arg_named("chained", 0u32)
        .arg(guide)
        .arg(visibility)
        .arg(out)
        .build()
        .context("creating the sheared lens-shadows combine kernel")
}

/// A builder of step `name` (prepare, 1a, 1b or 2b) with the arguments these share, in
/// their order: the light's parameters, the shadow output (`shadow`: the steps that read it)
/// and the light field (set per run) and their plane (set per run).
fn reads<'a>(
    gpu: &Gpu,
    program: &'a ocl::Program,
    name: &str,
    size: [usize; 2],
    params: &'a Buffer<ShearedParams>,
    shadow: bool,
) -> ocl::builders::KernelBuilder<'a> {
    let none = None::<&Buffer<u8>>;
    let mut b = gpu.kernel(program, name, size);
    b.arg_named("p", params);
    if shadow {
        b.arg_named("shadow_pixels", none);
    }
    b.arg_named("light_field", none)
        .arg_named("plane", 0u32)
        .arg_named("planes", 1u32);
    b
}

impl PreparedFilter for ShearedKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    fn reach(&self) -> Option<u32> {
        Some(2 * self.max_radius)
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}
