//! The AAF soft-shadow filter on the device (kernels/filters/aaf_shadows.cl): per filtered
//! light, prepare, the pass along rows, the pass along columns and compose (each light's
//! compose on the image of the lights before it).

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel};

use super::AafShadowSettings;
use crate::filters::aaf_pass::DevicePasses;
use crate::gpu::read_rgb_rows;
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::{BufferId, Output, OutputSet};
use crate::layout::{AafShadowParams, Float4};
use crate::render::Frame;

/// One filtered light's kernels: its parameters (centre, radius, σ) in `prepare` and
/// `compose`, which read its plane of the shadow output.
struct LightPasses {
    /// The scene's sphere light (its plane is looked up in each frame).
    light: u32,
    prepare: Kernel,
    compose: Kernel,
    _params: Buffer<AafShadowParams>,
}

/// The filter's kernels and buffers for one image size: the 1-D passes and their buffers,
/// shared by the lights, which run one after another.
struct Passes {
    lights: Vec<LightPasses>,
    passes: DevicePasses,
    image: Buffer<Float4>,
}

/// The AAF soft-shadow filter, built for an image size and its lights (none: the image passes
/// through untouched).
pub struct AafShadowKernel {
    gpu: Arc<Gpu>,
    passes: Option<Passes>,
    width: u32,
    height: u32,
    /// Half width of eq. 3.7's 1-D passes, pixels: the rows a band's pixels read beyond it.
    radius: u32,
}

impl AafShadowKernel {
    /// `lights`: the filtered sphere lights (number, centre and radius), in increasing order;
    /// empty: none.
    pub fn new(
        gpu: Arc<Gpu>,
        settings: &AafShadowSettings,
        lights: &[(u32, [f32; 4])],
        width: u32,
        height: u32,
    ) -> Result<AafShadowKernel> {
        settings.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let passes = if lights.is_empty() {
            None
        } else {
            Some(Passes::new(&gpu, settings, lights, width, height)?)
        };
        Ok(AafShadowKernel {
            gpu,
            passes,
            width,
            height,
            radius: settings.radius,
        })
    }

    /// Filters `frame` (width × height, with the shadow output unless there is no light) and
    /// reads the image back; the kernel time sums the launches (four per light).
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..self.height)
    }

    /// Filters the pixels of `rows` only (one band of a frame split across devices): each
    /// light's prepare pass and pass along rows run on the band widened by `radius` rows,
    /// which the pass along columns reads, so the band's pixels get the bytes that filtering
    /// the whole frame gives them. The image's other rows are black.
    pub fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        let h = self.height;
        let rows = rows.start.min(h)..rows.end.min(h);
        frame.check_size(self.width, self.height, "the aaf-shadows filter")?;
        let Some(p) = &mut self.passes else {
            let mut image = frame.beauty()?;
            let w = self.width as usize;
            for (y, row) in image.pixels.chunks_mut(w).enumerate() {
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
        frame.require(
            OutputSet::of(&[Output::Colour, Output::Shadows]),
            "the aaf-shadows filter",
        )?;
        let info = frame.info();
        let planes = info.shadow_planes();
        let pixels = frame.device(&self.gpu, BufferId::ShadowPixels)?;
        let fv = frame.device(&self.gpu, BufferId::FilterVectors)?;
        let terms = frame.device(&self.gpu, BufferId::ShadowTerms)?;
        let mut kernel_time = Duration::ZERO;
        for (k, l) in p.lights.iter().enumerate() {
            let Some(plane) = info.shadow_plane(l.light) else {
                bail!(
                    "the aaf-shadows filter reads the shadows of sphere light {}, but the \
                     frame's shadow output holds sphere light(s) {:?}: render it with the \
                     filter asking for that light",
                    l.light,
                    info.shadow_lights
                );
            };
            let plane = plane as u32;
            l.prepare.set_arg("pixels", pixels)?;
            l.prepare.set_arg("plane", plane)?;
            l.prepare.set_arg("planes", planes)?;
            l.compose.set_arg("pixels", pixels)?;
            l.compose.set_arg("fv", fv)?;
            l.compose.set_arg("terms", terms)?;
            l.compose.set_arg("plane", plane)?;
            l.compose.set_arg("planes", planes)?;
            l.compose.set_arg("chained", (k > 0) as u32)?;
            kernel_time +=
                p.passes
                    .run_band(&l.prepare, &l.compose, self.radius, rows.clone())?;
        }
        Ok(FilterRun {
            image: read_rgb_rows(&p.image, self.width, self.height, rows)?,
            wall_time: start.elapsed(),
            kernel_time: Some(kernel_time),
        })
    }
}

impl Passes {
    fn new(
        gpu: &Gpu,
        s: &AafShadowSettings,
        lights: &[(u32, [f32; 4])],
        width: u32,
        height: u32,
    ) -> Result<Passes> {
        let program = gpu.program("filters/aaf_shadows.cl", &[], "")?;
        let n = width as usize * height as usize;
        let passes = DevicePasses::new(gpu, &s.pass_params(width, height))?;
        let image = gpu.zeroed::<Float4>(n, "AAF image")?;
        let size = [width as usize, height as usize];
        let none = None::<&Buffer<u8>>;
        let lights = lights
            .iter()
            .map(|&(light, sphere)| -> Result<LightPasses> {
                let params = gpu.upload(&[s.params(sphere, width, height, 0)])?;
                let prepare = gpu
                    .kernel(&program, "aaf_prepare", size)
                    .arg_named("p", &params)
                    .arg_named("pixels", none)
                    .arg_named("plane", 0u32)
                    .arg_named("planes", 1u32)
                    .arg(&passes.guide)
                    .arg(&passes.values[0])
                    .build()
                    .context("creating the AAF prepare kernel")?;
                let compose = compose_kernel(
                    gpu,
                    &program,
                    "aaf_compose",
                    size,
                    &params,
                    [&passes.guide, &image],
                    &passes.values[0],
                )?;
                Ok(LightPasses {
                    light,
                    prepare,
                    compose,
                    _params: params,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Passes {
            lights,
            passes,
            image,
        })
    }
}

/// A compose kernel of kernels/filters/aaf_shadows.cl (`aaf_compose`, or the sheared
/// filter's `aaf_compose_sheared`) for one light (`params`), on `program` over a w × h grid:
/// the frame's buffers, the plane and `chained` are set per run; `guide_image` the guide read
/// and the image written, `visibility` the filtered visibility.
pub(crate) fn compose_kernel<V: ocl::OclPrm>(
    gpu: &Gpu,
    program: &ocl::Program,
    name: &str,
    size: [usize; 2],
    params: &Buffer<AafShadowParams>,
    [guide, image]: [&Buffer<Float4>; 2],
    visibility: &Buffer<V>,
) -> Result<Kernel> {
    let none = None::<&Buffer<u8>>;
    gpu.kernel(program, name, size)
        .arg_named("p", params)
        .arg_named("fv", none)
        .arg_named("terms", none)
        .arg_named("pixels", none)
        .arg_named("plane", 0u32)
        .arg_named("planes", 1u32)
        .arg_named("chained", 0u32)
        .arg(guide)
        .arg(visibility)
        .arg(image)
        .build()
        .with_context(|| format!("creating the {name} kernel"))
}

impl PreparedFilter for AafShadowKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }

    fn reach(&self) -> Option<u32> {
        Some(self.radius)
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}
