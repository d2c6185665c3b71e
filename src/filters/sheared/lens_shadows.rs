//! Sheared soft shadows and depth of field together (Yan et al. 2015, appendix, eqs. 16-17;
//! digest /work/shared/notes/seeds-aaf-sheared.md §3.4; issue 16), `effect = "dof-shadows"`:
//!
//! L_dir(x) = ∫_u (∫_y f V dy) k(x, u) du (16) ≈ ∫_u (∫_y F̄(x, y) dy) k(x, u) du (17).
//!
//! The appendix keeps the storage 4-D by averaging F = f·V over the pixel's lens samples, and
//! filters twice: the light with the four steps, then the resulting (x, u) field over the lens
//! with the four steps again. Here:
//! - **The render** (kernels/render/lens_field.cl `lens_shadow_field_sample`, after the shadow
//!   passes): the shadow passes of the shadows effect (AAF's sparse pass, each light's l × l
//!   field, the slope fill), all for the receiver seen through the pixel centre and the lens
//!   centre; then l × l lens samples, each a whole path traced as the path samples are. A lens
//!   sample whose first hit is a diffuse point of the receiver's object leaves the filtered
//!   lights' direct term out of its light (rest(x, u)) and records its albedo k(x, u); per light
//!   the unoccluded term of those hits, averaged: F̄'s f part.
//! - **F̄'s visibility** is the shadow filter's v(x) for the receiver through the lens centre
//!   (the shadow field's samples are that receiver's, which the slopes, the screen axes and
//!   rejection describe): the average over u that eq. 17 asks for is taken at u = 0. Both are
//!   exact on the focal plane; away from it the lens filter blurs over the difference, which
//!   the appendix counts on ("the outer integral (lens filter) dominates").
//! - **Combine** (kernels/filters/sheared_lens_shadows.cl, [`combine`] here): each lens sample
//!   gets rest + k · Σ_lights F̄ · v back, the fallback's 36 extra samples likewise.
//! - **Then** the depth-of-field filter ([`DofKernel`], kernels/filters/sheared_dof.cl) over the
//!   combined field. Indirect light rides in rest and is filtered over the lens with the rest
//!   (the appendix filters it in a third, separate pass, which our GI effect cannot do through a
//!   lens: its receivers are pinhole hits; see mod.rs).
//!
//! A lens sample whose first hit is elsewhere (another object, glossy, the sky) keeps its
//! direct light as path traced; a pixel whose centre has no receiver for a light keeps that
//! light's term as path traced in every sample.

use std::ops::Range;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Result, bail};

use super::reference::{Guide, KIND, NONE};
use super::{DofKernel, ShearedKernel, ShearedSettings};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::Gpu;
use crate::layout::outputs::BufferId;
use crate::layout::{LensShadowPixel, LightFieldPixel, ShadowPixel};
use crate::render::{Frame, FrameInfo};

/// `sheared_lens_combine` for one light plane: onto `out` (the lens field as rendered when
/// `chained` is false, else what the lights before left), each sample's k · F̄ · v. `shadow`:
/// the plane's shadow pixels; `guide`, `visibility`: the shadow filter's for that light.
#[allow(clippy::too_many_arguments)]
pub fn combine(
    side: u32,
    lens_field: &[LightFieldPixel],
    lens_shadow: &[LensShadowPixel],
    shadow: &[ShadowPixel],
    plane: usize,
    guide: &[Guide],
    visibility: &[f32],
    chained: bool,
    out: &mut Vec<LightFieldPixel>,
) {
    if !chained {
        *out = lens_field.to_vec();
    }
    for (i, o) in out.iter_mut().enumerate() {
        let ls = &lens_shadow[i];
        let u = ls.unshadowed[plane].0;
        if !(u[3] > 0.0) {
            continue;
        }
        let v = if guide[i][KIND] == NONE {
            let px = &shadow[i];
            if px.weight > 0.0 {
                px.visible / px.weight
            } else {
                0.0
            }
        } else {
            visibility[i]
        };
        let d = [u[0] * v, u[1] * v, u[2] * v];
        for k in 0..(side * side) as usize {
            o.samples[k] += ls.albedo[k] * d[0];
            o.green[k] += ls.albedo_green[k] * d[1];
            o.blue[k] += ls.albedo_blue[k] * d[2];
        }
        for ((e, a), dc) in o.extra.iter_mut().zip(&ls.albedo_extra).zip(d) {
            *e += a * dc;
        }
    }
}

/// The whole filter in Rust: the shadows reference ([`super::reference`]) per light, the
/// combine, then the depth-of-field reference ([`super::dof::filter`]) over the combined field.
pub fn image(frame: &Frame, s: &ShearedSettings) -> Result<Vec<[f32; 3]>> {
    use super::reference::{factored, prepare};
    let info = frame.info();
    let scene = &info.scene;
    let (w, h) = (frame.width(), frame.height());
    let lens_field: &[LightFieldPixel] = frame.host_slice(BufferId::LensFieldPixels)?;
    let lens_shadow: &[LensShadowPixel] = frame.host_slice(BufferId::LensShadowPixels)?;
    let mut out = Vec::new();
    for (n, (light, sphere)) in s.lights_of(scene)?.into_iter().enumerate() {
        let own = frame.light_plane(light, "the sheared filter")?;
        let plane_frame = own.as_ref().unwrap_or(frame);
        let shadow: &[ShadowPixel] = plane_frame.host_slice(BufferId::ShadowPixels)?;
        let field: &[LightFieldPixel] = plane_frame.host_slice(BufferId::LightFieldPixels)?;
        let p = s.params(sphere, scene.scene_centre, w, h);
        let guide = prepare(&p, shadow, field);
        let visibility = factored(&p, shadow, field, &guide);
        let plane = info.shadow_plane(light).unwrap_or(0);
        combine(
            s.side,
            lens_field,
            lens_shadow,
            shadow,
            plane,
            &guide,
            &visibility,
            n > 0,
            &mut out,
        );
    }
    if out.is_empty() {
        out = lens_field.to_vec();
    }
    let p = s.dof_params(scene.camera.lens_radius, w, h);
    Ok(super::dof::filter(&p, &out, &frame.beauty()?.pixels))
}

/// The filter on the device: the shadow filter of every light into the combined lens field,
/// then the depth-of-field filter over it.
pub struct LensShadowKernel {
    shadows: ShearedKernel,
    lens: DofKernel,
}

impl LensShadowKernel {
    pub fn new(s: &ShearedSettings, frame: &FrameInfo, gpu: &Arc<Gpu>) -> Result<Self> {
        let lens = frame.scene.camera.lens_radius;
        if !(lens > 0.0) {
            bail!(
                "sheared shadows with depth of field (effect = \"dof-shadows\") need a thin \
                 lens, but the scene's camera is a pinhole (lens_radius {lens}): set \
                 lens_radius > 0 in its [camera], or effect = \"shadows\""
            );
        }
        let shadows = ShearedKernel::with_lens(
            gpu.clone(),
            s,
            &s.lights_of(&frame.scene)?,
            frame.scene.scene_centre,
            frame.width,
            frame.height,
        )?;
        let p = s.dof_params(lens, frame.width, frame.height);
        Ok(LensShadowKernel {
            shadows,
            lens: DofKernel::new(gpu.clone(), p)?,
        })
    }

    /// Kernel time of the shadow filter's launches (summed over the lights, in the order of
    /// [`super::STEPS`], the combine in place of the compose) and the depth-of-field filter's
    /// ([`super::DOF_STEPS`]).
    pub fn step_times(&self) -> ([Duration; 6], [Duration; 5]) {
        (self.shadows.step_times(), self.lens.step_times())
    }

    fn filter_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        let start = Instant::now();
        // The lens filter reads the combined field up to its reach beyond the rows.
        let h = frame.height();
        let reach = self.lens.reach();
        let wide = rows.start.saturating_sub(reach)..(rows.end + reach).min(h);
        self.shadows.run_lights(frame, wide)?;
        let field = self
            .shadows
            .combined_field()
            .expect("built with_lens, with a light");
        let mut run = self.lens.filter_field_rows(frame, field, rows)?;
        let (a, b) = self.step_times();
        run.kernel_time = Some(a.iter().chain(b.iter()).sum());
        run.wall_time = start.elapsed();
        Ok(run)
    }
}

impl PreparedFilter for LensShadowKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter_rows(frame, 0..frame.height())
    }

    fn reach(&self) -> Option<u32> {
        // The shadow steps read twice their radius beyond the rows they write (1b, 2b), and
        // they write the lens filter's reach beyond its rows.
        Some(PreparedFilter::reach(&self.shadows).unwrap_or(0) + self.lens.reach())
    }

    fn run_rows(&mut self, frame: &Frame, rows: Range<u32>) -> Result<FilterRun> {
        self.filter_rows(frame, rows)
    }
}
