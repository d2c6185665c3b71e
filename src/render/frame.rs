//! What a filter reads: the outputs of one render ([`Frame`]), wherever they are. The live
//! renderer builds a frame over its device buffers ([`crate::render::Renderer::frame`]); the AOV
//! and samples readers (src/stats) build one over host copies read from a file. Filters take
//! either the same way: [`Frame::device`] uploads host data on first use, [`Frame::host`] reads
//! device data back on first use, so filtering at the end of a render and filtering its AOV
//! file run the same code on the same bytes.
//!
//! A frame also carries [`SceneInfo`], what filters may know about the scene (its effects,
//! camera, size, setting), which the AOV header records so that offline filtering specialises
//! exactly as the render did.

use std::cell::OnceCell;
use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Context as _, Result, anyhow, bail};
use ocl::{Buffer, OclPrm};
use serde::{Deserialize, Serialize};

use crate::arrays::SceneArrays;
use crate::gpu::Gpu;
use crate::imaging::RgbImage;
use crate::layout::outputs::{BufferId, Output, OutputSet, Per};
use crate::layout::{FilterVector, Float16, IndirectPixel, LightFieldPixel, ShadowPixel};
use crate::scene::{CameraBasis, Scene, Setting};

/// What filters may know about the scene a frame was rendered from. Recorded in AOV and
/// samples files (as TOML), so that a filter specialises offline exactly as it did online.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneInfo {
    /// The scene file.
    pub path: String,
    /// The effects the scene calls for: the `HAS_*` switches of its specialised megakernel
    /// (src/render/features.rs), whatever kernel actually rendered it.
    pub effects: BTreeMap<String, bool>,
    pub camera: CameraBasis,
    /// Largest extent of the scene's bounds, in scene units.
    pub scene_size: f32,
    /// Indoor or outdoor (RPF's σ²₈, thesis §5.1.4).
    pub setting: Setting,
    pub seed: u32,
    /// The emissive spheres, in the order of the scene's light list (which puts them first):
    /// centre and radius. AAF soft shadows filter one of them. Files written before this
    /// field existed read as none.
    #[serde(default)]
    pub sphere_lights: Vec<[f32; 4]>,
    /// The centre of the scene's bounds: sheared shadows sample a light in the frame
    /// perpendicular to (this -> the light's centre). Files written before: the origin.
    #[serde(default)]
    pub scene_centre: [f32; 3],
    /// Whether paths go on past their first surface (max_depth above 1, or Russian roulette):
    /// false means a direct-light-only image, with no indirect light to filter. Files written
    /// before this field existed read as true.
    #[serde(default = "yes")]
    pub indirect: bool,
}

fn yes() -> bool {
    true
}

impl SceneInfo {
    pub fn new(scene: &Scene, arrays: &SceneArrays) -> SceneInfo {
        let effects = super::FeatureSet::for_scene(scene, OutputSet::colour())
            .features
            .iter()
            .filter(|f| f.define.starts_with("HAS_"))
            .map(|f| (f.define.to_string(), f.on))
            .collect();
        SceneInfo {
            path: scene.path.display().to_string(),
            effects,
            camera: arrays.camera(),
            scene_size: arrays.params.scene_size,
            indirect: arrays.params.rr_depth > 1 || scene.render.russian_roulette,
            setting: scene.render.setting,
            seed: arrays.params.seed,
            sphere_lights: arrays
                .lights
                .iter()
                .filter(|l| l.kind == crate::layout::LIGHT_SPHERE)
                .map(|l| l.p0.0)
                .collect(),
            scene_centre: {
                let (lo, hi) = crate::arrays::scene_bounds(scene);
                ((lo + hi) * 0.5).to_array()
            },
        }
    }

    /// A scene nothing is known about (synthetic test frames): no effects, size unknown (0),
    /// a camera at the origin looking down −z.
    pub fn unknown() -> SceneInfo {
        SceneInfo {
            path: String::new(),
            effects: BTreeMap::new(),
            camera: CameraBasis {
                origin: glam::Vec3::ZERO,
                forward: glam::Vec3::NEG_Z,
                right: glam::Vec3::X,
                up: glam::Vec3::Y,
                tan_half_fov: 1.0,
                lens_radius: 0.0,
                focal_distance: 1.0,
            },
            scene_size: 0.0,
            indirect: true,
            setting: Setting::Indoor,
            seed: 0,
            sphere_lights: Vec::new(),
            scene_centre: [0.0; 3],
        }
    }

    /// Whether the scene has an effect (`"HAS_ENV"`, `"HAS_GLASS"`, ...); unknown: no.
    pub fn has(&self, effect: &str) -> bool {
        self.effects.get(effect).copied().unwrap_or(false)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("SceneInfo serialises")
    }

    pub fn from_toml(text: &str) -> Result<SceneInfo> {
        toml::from_str(text).map_err(|e| anyhow!("scene information: {}", e.message()))
    }
}

/// The size of a frame and what it holds.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameInfo {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel behind the means.
    pub spp: u32,
    /// Samples per pixel the per-sample buffers hold (0 without them).
    pub sample_capacity: u32,
    /// The scene's sphere light of each plane of the shadow output, in plane order (empty
    /// without it; src/layout/outputs.rs `Per::Light`).
    pub shadow_lights: Vec<u32>,
    pub scene: SceneInfo,
}

impl FrameInfo {
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Samples per pixel stored in the per-sample buffers.
    pub fn samples_stored(&self) -> u32 {
        self.spp.min(self.sample_capacity)
    }

    /// Light planes of the shadow output.
    pub fn shadow_planes(&self) -> u32 {
        self.shadow_lights.len() as u32
    }

    /// The plane of the shadow output holding sphere light `light`, if any.
    pub fn shadow_plane(&self, light: u32) -> Option<usize> {
        self.shadow_lights.iter().position(|&l| l == light)
    }
}

/// What the Welford-sums buffer holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarianceForm {
    /// Welford's S_n, as the renderer leaves it: the variance is S_n / (n − 1).
    Sums,
    /// Variances, as an AOV file stores them.
    Variances,
}

/// The factor that turns Welford's S_n after `n` samples into variances: 1 / (n − 1); with one
/// sample there is no variance estimate and it is 0.
pub fn variance_factor(n: u32) -> f32 {
    if n > 1 { 1.0 / (n - 1) as f32 } else { 0.0 }
}

/// The bytes of one output buffer on the host, 64-byte aligned so that they can be viewed as
/// any shared layout struct.
#[derive(Clone, Debug, PartialEq)]
pub struct HostBuffer {
    blocks: Vec<Float16>,
    bytes: usize,
}

impl HostBuffer {
    pub fn zeroed(bytes: usize) -> HostBuffer {
        HostBuffer {
            blocks: vec![Float16::default(); bytes.div_ceil(64)],
            bytes,
        }
    }

    pub fn from_slice<T: OclPrm>(values: &[T]) -> HostBuffer {
        let mut b = HostBuffer::zeroed(std::mem::size_of_val(values));
        b.as_mut_slice::<T>().copy_from_slice(values);
        b
    }

    pub fn len_bytes(&self) -> usize {
        self.bytes
    }

    pub fn as_bytes(&self) -> &[u8] {
        // SAFETY: `blocks` holds at least `bytes` initialised bytes (plain f32 data).
        unsafe { std::slice::from_raw_parts(self.blocks.as_ptr() as *const u8, self.bytes) }
    }

    pub fn as_bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: as above; any byte pattern is a valid f32.
        unsafe { std::slice::from_raw_parts_mut(self.blocks.as_mut_ptr() as *mut u8, self.bytes) }
    }

    fn check<T>(&self) {
        let size = std::mem::size_of::<T>();
        assert!(
            size > 0 && self.bytes.is_multiple_of(size) && std::mem::align_of::<T>() <= 64,
            "a host buffer of {} bytes viewed as {} ({size} bytes)",
            self.bytes,
            std::any::type_name::<T>()
        );
    }

    /// The buffer as shared layout structs (`T` is one of src/layout's plain-old-data types).
    pub fn as_slice<T: OclPrm>(&self) -> &[T] {
        self.check::<T>();
        let n = self.bytes / std::mem::size_of::<T>();
        // SAFETY: 64-byte aligned storage, T is plain old data (OclPrm) of at most that
        // alignment, and n elements fit in `bytes`.
        unsafe { std::slice::from_raw_parts(self.blocks.as_ptr() as *const T, n) }
    }

    pub fn as_mut_slice<T: OclPrm>(&mut self) -> &mut [T] {
        self.check::<T>();
        let n = self.bytes / std::mem::size_of::<T>();
        // SAFETY: as in as_slice.
        unsafe { std::slice::from_raw_parts_mut(self.blocks.as_mut_ptr() as *mut T, n) }
    }

    /// The buffer as floats (every output element is made of f32 lanes).
    pub fn floats(&self) -> &[f32] {
        self.as_slice::<f32>()
    }

    pub fn floats_mut(&mut self) -> &mut [f32] {
        self.as_mut_slice::<f32>()
    }
}

struct Slot {
    id: BufferId,
    bytes: usize,
    device: OnceCell<Buffer<u8>>,
    host: OnceCell<HostBuffer>,
}

/// The outputs of one render: device buffers, host copies, or both, each made on first use.
/// A frame is a snapshot: take a new one after rendering more samples.
pub struct Frame {
    info: FrameInfo,
    outputs: OutputSet,
    variances: VarianceForm,
    slots: Vec<Slot>,
    /// The device that holds the device buffers a live frame was made from.
    gpu: Option<Arc<Gpu>>,
}

impl std::fmt::Debug for Frame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Frame")
            .field("info", &self.info)
            .field("outputs", &self.outputs.names())
            .field("variances", &self.variances)
            .finish_non_exhaustive()
    }
}

impl Frame {
    /// A frame over device buffers (the live renderer's). `buffers` holds every buffer of
    /// `outputs`, each sized for `info`.
    pub fn on_device(
        info: FrameInfo,
        outputs: OutputSet,
        gpu: Arc<Gpu>,
        buffers: Vec<(BufferId, Buffer<u8>)>,
    ) -> Frame {
        let slots = buffers
            .into_iter()
            .map(|(id, b)| {
                let device = OnceCell::new();
                let bytes = b.len();
                let _ = device.set(b);
                Slot {
                    id,
                    bytes,
                    device,
                    host: OnceCell::new(),
                }
            })
            .collect();
        Frame {
            info,
            outputs,
            variances: VarianceForm::Sums,
            slots,
            gpu: Some(gpu),
        }
    }

    /// A frame over host data (a file's, or a test's). Every buffer of `outputs` must be given,
    /// each with the size `info` calls for.
    pub fn on_host(
        info: FrameInfo,
        outputs: OutputSet,
        variances: VarianceForm,
        buffers: Vec<(BufferId, HostBuffer)>,
    ) -> Result<Frame> {
        for b in outputs.buffers() {
            let want = b.bytes(
                info.width,
                info.height,
                info.sample_capacity,
                info.shadow_planes(),
            ) as usize;
            match buffers.iter().find(|(id, _)| *id == b.id) {
                None => bail!("the {} buffer of the frame is missing", b.name),
                Some((_, h)) if h.len_bytes() != want => bail!(
                    "the {} buffer holds {} bytes, a {}x{} frame needs {want}",
                    b.name,
                    h.len_bytes(),
                    info.width,
                    info.height
                ),
                Some(_) => {}
            }
        }
        let slots = buffers
            .into_iter()
            .filter(|(id, _)| outputs.contains(id.owner()))
            .map(|(id, h)| {
                let host = OnceCell::new();
                let bytes = h.len_bytes();
                let _ = host.set(h);
                Slot {
                    id,
                    bytes,
                    device: OnceCell::new(),
                    host,
                }
            })
            .collect();
        Ok(Frame {
            info,
            outputs,
            variances,
            slots,
            gpu: None,
        })
    }

    /// A frame of colour and features only, from FilterVectors (tests, synthetic inputs).
    pub fn from_filter_vectors(
        width: u32,
        height: u32,
        spp: u32,
        scene: SceneInfo,
        filter_vectors: &[FilterVector],
    ) -> Result<Frame> {
        Frame::on_host(
            FrameInfo {
                width,
                height,
                spp,
                sample_capacity: 0,
                shadow_lights: Vec::new(),
                scene,
            },
            OutputSet::of(&[Output::Features]),
            VarianceForm::Variances,
            vec![(
                BufferId::FilterVectors,
                HostBuffer::from_slice(filter_vectors),
            )],
        )
    }

    pub fn info(&self) -> &FrameInfo {
        &self.info
    }

    pub fn width(&self) -> u32 {
        self.info.width
    }

    pub fn height(&self) -> u32 {
        self.info.height
    }

    pub fn outputs(&self) -> OutputSet {
        self.outputs
    }

    pub fn variance_form(&self) -> VarianceForm {
        self.variances
    }

    /// Multiplies the Welford-sums buffer to give variances: 1 / (n − 1) for sums (0 with one
    /// sample: no estimate), 1 for variances.
    pub fn variance_factor(&self) -> f32 {
        match self.variances {
            VarianceForm::Variances => 1.0,
            VarianceForm::Sums => variance_factor(self.info.spp),
        }
    }

    /// Fails unless the frame is `width` × `height` (what `who` was built for).
    pub fn check_size(&self, width: u32, height: u32, who: &str) -> Result<()> {
        if self.info.width != width || self.info.height != height {
            bail!(
                "{who} was built for {width}x{height}, the frame is {}x{}",
                self.info.width,
                self.info.height
            );
        }
        Ok(())
    }

    /// Fails with a message naming what is missing when the frame lacks one of `needs`, or
    /// when its light-field output holds another field than `needs` says
    /// ([`OutputSet::light_field`]; a frame that does not record it, from a file written
    /// before it was recorded, is taken as it is).
    pub fn require(&self, needs: OutputSet, who: &str) -> Result<()> {
        let missing: Vec<&str> = needs
            .iter()
            .filter(|o| !self.outputs.contains(*o))
            .map(Output::name)
            .collect();
        if !missing.is_empty() {
            bail!(
                "{who} needs the {} output(s), which this frame does not hold (have: {})",
                missing.join(", "),
                self.outputs.names().join(", ")
            );
        }
        if let (Some(want), Some(have)) = (needs.light_field(), self.outputs.light_field())
            && want != have
        {
            bail!(
                "{who} reads {}, but this frame's light-field output holds {}: a render \
                 gathers one kind of light field, the one its filter's sampling asks for; \
                 render the scene again for {who} alone",
                want.describe(),
                have.describe()
            );
        }
        Ok(())
    }

    fn slot(&self, id: BufferId) -> Result<&Slot> {
        self.slots.iter().find(|s| s.id == id).with_context(|| {
            format!(
                "the frame holds no {} buffer (the {} output was not gathered)",
                id.decl().name,
                id.owner().name()
            )
        })
    }

    /// The buffer on `gpu`: the live renderer's own, or the host copy uploaded once.
    pub fn device(&self, gpu: &Arc<Gpu>, id: BufferId) -> Result<&Buffer<u8>> {
        let slot = self.slot(id)?;
        if let Some(b) = slot.device.get() {
            if self.gpu.as_ref().is_some_and(|g| !Arc::ptr_eq(g, gpu)) {
                bail!(
                    "the frame's {} buffer lives on another OpenCL context",
                    id.decl().name
                );
            }
            return Ok(b);
        }
        let host = self.host(id)?;
        let buffer = gpu.upload(host.as_bytes())?;
        let _ = slot.device.set(buffer);
        Ok(slot.device.get().expect("just set"))
    }

    /// The buffer on the host: the file's, or the device buffer read back once.
    pub fn host(&self, id: BufferId) -> Result<&HostBuffer> {
        let slot = self.slot(id)?;
        if let Some(h) = slot.host.get() {
            return Ok(h);
        }
        let device = slot.device.get().expect("a slot holds device or host data");
        let mut h = HostBuffer::zeroed(slot.bytes);
        device
            .read(h.as_bytes_mut())
            .enq()
            .with_context(|| format!("reading the {} buffer back", id.decl().name))?;
        let _ = slot.host.set(h);
        Ok(slot.host.get().expect("just set"))
    }

    /// This frame with the shadow output of sphere light `light` alone (one plane), for the
    /// filters that read one light's plane (aaf-shadows, sheared filtering): None when the
    /// frame holds that plane alone already (use it as is), a host copy otherwise.
    pub fn light_plane(&self, light: u32, who: &str) -> Result<Option<Frame>> {
        let lights = &self.info.shadow_lights;
        if lights.as_slice() == [light] || !self.outputs.contains(Output::Shadows) {
            return Ok(None);
        }
        let Some(plane) = self.info.shadow_plane(light) else {
            bail!(
                "{who} reads the shadows of sphere light {light}, but the frame's shadow output \
                 holds sphere light(s) {lights:?}: render it with {who} asking for light {light}"
            );
        };
        let planes = lights.len();
        let mut buffers = Vec::new();
        for b in self.outputs.buffers() {
            let host = self.host(b.id)?;
            let h = if b.per == Per::Light {
                let e = b.element_bytes;
                let all = host.as_bytes();
                let mut h = HostBuffer::zeroed(all.len() / planes);
                for (k, out) in h.as_bytes_mut().chunks_exact_mut(e).enumerate() {
                    let at = (k * planes + plane) * e;
                    out.copy_from_slice(&all[at..at + e]);
                }
                h
            } else {
                host.clone()
            };
            buffers.push((b.id, h));
        }
        let info = FrameInfo {
            shadow_lights: vec![light],
            ..self.info.clone()
        };
        Frame::on_host(info, self.outputs, self.variances, buffers).map(Some)
    }

    /// The buffer on the host as its layout struct.
    pub fn host_slice<T: OclPrm>(&self, id: BufferId) -> Result<&[T]> {
        Ok(self.host(id)?.as_slice::<T>())
    }

    pub fn filter_vectors(&self) -> Result<&[FilterVector]> {
        self.host_slice(BufferId::FilterVectors)
    }

    /// The samples per pixel of the sampling passes that run before the path samples,
    /// averaged over the image (Σ / N², pixels that take none count 0), read from the
    /// outputs that hold them: the shadow output's light samples (AAF's sparse + adaptive
    /// passes), the light field's l² (shadows, depth of field with its fallback's 36 where
    /// it applies, or GI's v-plane samples), the indirect output's samples. 0 without these outputs. The path samples are
    /// [`FrameInfo::spp`]; the studies report both, as the seeds count the passes' samples.
    pub fn pass_spp(&self) -> Result<f64> {
        let pixels = (self.info.width as f64 * self.info.height as f64).max(1.0);
        let mut total = 0.0;
        if self.outputs.contains(Output::Shadows) {
            let p: &[ShadowPixel] = self.host_slice(BufferId::ShadowPixels)?;
            total += p.iter().map(|p| p.samples as f64).sum::<f64>();
        }
        if self.outputs.contains(Output::LightField) {
            let p: &[LightFieldPixel] = self.host_slice(BufferId::LightFieldPixels)?;
            // `extra_samples`: the depth-of-field fallback's 36 (0 for shadows and GI).
            total += p
                .iter()
                .map(|p| (p.count + p.extra_samples) as f64)
                .sum::<f64>();
        }
        if self.outputs.contains(Output::Indirect) {
            let p: &[IndirectPixel] = self.host_slice(BufferId::IndirectPixels)?;
            total += p.iter().map(|p| p.samples as f64).sum::<f64>();
        }
        Ok(total / pixels)
    }

    /// direct + indirect: the unfiltered image.
    pub fn beauty(&self) -> Result<RgbImage> {
        Ok(RgbImage::beauty(
            self.info.width,
            self.info.height,
            self.filter_vectors()?,
        ))
    }
}
