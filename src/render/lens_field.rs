//! The lens-field pass of sheared depth of field (Yan et al. 2015 §3.1, §3.2 "DoF"; issue 16):
//! l × l radiance samples per pixel on a jittered grid over the thin lens's square [−A, A]²,
//! their slopes s = W (F/z − 1) / S, the lens-centre hit, and 36 more samples where the slopes
//! straddle the focal plane, kept per pixel in [`crate::layout::LightFieldPixel`] (the output
//! [`crate::layout::outputs::Output::LightField`] without the shadow output). The kernel is
//! kernels/render/lens_field.cl, built from the megakernel's program (it traces whole paths);
//! src/render/cpu/lens_field.rs is its Rust reference. With
//! [`super::ShadowSampling::light_field_gi`] the same pass runs kernels/render/gi_field.cl
//! instead: the sheared filter's GI field over the v-plane (src/render/gi_field.rs).

use std::time::Duration;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel, Program};

use super::shadows::light_field::MAX_SIDE;
use crate::gpu::{Gpu, enqueue, event_duration};
use crate::layout::outputs::{FieldKind, Output, OutputSet};

/// Samples the fallback adds where s_min · s_max < 0 (Yan et al. §3.1: "a fixed 36 more").
pub const EXTRA_SAMPLES: u32 = 36;

/// Checks the grid side and that the whole image is rendered (the pass writes pixel-indexed
/// lanes and the filter gathers across tile borders).
pub fn check(side: u32, whole_image: bool) -> Result<()> {
    if side == 0 || side > MAX_SIDE {
        bail!(
            "the lens field's grid side l must be 1..={MAX_SIDE} (Yan et al.: l <= 4), got {side}"
        );
    }
    if !whole_image {
        bail!(
            "the light-field output (the sheared filter's depth of field) needs the whole \
             image, not a tile: the filter gathers across tile borders; render sample ranges \
             (--samples A..B) instead of tiles"
        );
    }
    Ok(())
}

/// What the lens pass of sheared shadows with depth of field (the lens-shadows output) reads
/// and writes besides the scene.
pub(super) struct LensShadows<'a> {
    pub shadow_pixels: &'a Buffer<u8>,
    /// The filtered lights, a bit each (a shadow plane per set bit).
    pub lights: u32,
    pub lens_field: &'a Buffer<u8>,
    pub lens_shadow: &'a Buffer<u8>,
}

/// The lens-field pass of one renderer.
pub(super) struct LensPass {
    kernel: Kernel,
    rays: Buffer<u32>,
}

impl LensPass {
    /// The pass over the renderer's scene buffers into `field`, or with `shadows` (the shadow
    /// output's pixels, the filtered lights' bit mask, and the lens-shadows output's two
    /// buffers) the lens field of sheared shadows with depth of field into those buffers.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        gpu: &Gpu,
        program: &Program,
        size: [usize; 2],
        sampling: super::ShadowSampling,
        scene: &super::DeviceScene,
        debug_counters: &Buffer<u32>,
        field: &Buffer<u8>,
        shadows: Option<LensShadows<'_>>,
    ) -> Result<LensPass> {
        let (side, gi) = (sampling.light_field, sampling.light_field_gi);
        check(side, true)?;
        let rays = gpu.zeroed::<u32>(size[0] * size[1], "lens-field ray count")?;
        let mut b = Kernel::builder();
        let name = match (&shadows, gi) {
            (Some(_), _) => "lens_shadow_field_sample",
            (None, true) => "gi_field_sample",
            (None, false) => "lens_field_sample",
        };
        b.program(program)
            .name(name)
            .queue(gpu.queue.clone())
            .global_work_size(size);
        scene.bind(&mut b, debug_counters);
        match &shadows {
            Some(s) => {
                b.arg_named("shadow_pixels", s.shadow_pixels)
                    .arg_named("shadow_lights", s.lights)
                    .arg_named("lens_field", s.lens_field)
                    .arg_named("lens_shadow", s.lens_shadow);
            }
            None => {
                b.arg_named("light_field", field);
            }
        }
        b.arg_named("lens_rays", &rays).arg_named("side", side);
        let kernel = b.build().context("creating the lens-field kernel")?;
        Ok(LensPass { kernel, rays })
    }

    /// Runs the pass; its rays and kernel time.
    pub(super) fn run(&self) -> Result<(u64, Duration)> {
        // SAFETY: every buffer argument is owned by the renderer or by self and sized for the
        // image; enqueue waits for the event.
        let event = unsafe { enqueue(&self.kernel, "the lens-field pass")? };
        let time = event_duration(&event)?;
        let mut counts = vec![0u32; self.rays.len()];
        self.rays.read(&mut counts).enq()?;
        Ok((counts.iter().map(|&c| c as u64).sum(), time))
    }
}

impl super::RenderOptions {
    /// The light field a renderer built with these options gathers, by the renderer's own
    /// rule (src/render/mod.rs `with_arrays` and `build_kernels`): the shadow fields with the
    /// shadow output, else the GI field when `shadows.light_field_gi` asks for it, else the
    /// lens field; None without the light-field output.
    pub fn light_field(&self) -> Option<FieldKind> {
        let outputs = self.outputs.closed();
        if !outputs.contains(Output::LightField) {
            None
        } else if outputs.contains(Output::Shadows) {
            Some(FieldKind::Shadows)
        } else if self.shadows.light_field_gi {
            Some(FieldKind::Gi)
        } else {
            Some(FieldKind::Lens)
        }
    }

    /// The outputs the renderer gathers (closed under their requirements), recording the
    /// light field [`Self::light_field`] says it gathers, whatever `outputs` claimed: what a
    /// film, its frames and their files say they hold. [`super::SplitRenderer::new`] builds
    /// its renderers with it.
    pub fn recorded_outputs(&self) -> OutputSet {
        let outputs = self.outputs.closed();
        match self.light_field() {
            Some(kind) => outputs.with_field(kind),
            None => outputs,
        }
    }
}
