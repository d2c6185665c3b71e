//! The regression filter on the device: one `bmfr_fit` launch per block grid (a work-group per
//! block), then one `bmfr_apply` launch over the pixels (kernels/filters/bmfr.cl).

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use ocl::enums::{KernelWorkGroupInfo, KernelWorkGroupInfoResult};
use ocl::{Buffer, Kernel};

use super::nlm::{
    MAX_NLM_PATCH, MAX_NLM_RADIUS, NLM_EPSILON, NLM_PACKED_LINES, NLM_PACKED_PAD,
    NLM_PACKED_ROWS, NLM_TILE, RELATIVE_EPSILON,
};
use super::emission::{
    EMISSION_EPSILON, EMISSION_LINES, EMISSION_PACKED_ROWS, EMISSION_PACKED_STEP, EMISSION_PATCH,
    EMISSION_TILE,
};
use super::guided;
use super::outliers::{NEIGHBOURS, OUTLIER_RADIUS};
use super::prefilter::{MAX_ALBEDO_RADIUS, PREFILTER_EPSILON, PREFILTER_K, prefilter_packed_lines};
use super::{
    ALBEDO_EPSILON, BmfrSettings, INFO_FLOATS, MAX_GUIDED_RADIUS, PIVOT_MIN, TARGETS, WORK_GROUP,
    blocks_per_grid, grid_blocks, grid_offset,
};
use crate::filters::{FilterRun, PreparedFilter};
use crate::gpu::{Gpu, enqueue, event_duration, read_rgb};
use crate::layout::{FilterVector, Float2, Float4};
use crate::layout::outputs::{BufferId, OutputSet};
use crate::render::Frame;

/// Floats either side of each plane of the packed fit's rows (kernels/filters/bmfr_fit_packed.cl
/// BMFR_PAD).
const PACKED_PAD: usize = 16;

/// Unused floats after each column of the packed fit's block matrix (kernels/filters/bmfr.cl
/// BMFR_LD): with B = 32 a column is 4 KiB, and without them the same rows of all the block's
/// columns share one set of the first-level cache. One cache line.
const COLUMN_PAD: u32 = 16;

/// Which of the frame's arguments (set per frame) a selection kernel takes.
#[derive(Clone, Copy)]
struct FrameArgs {
    positions: bool,
    odd_halves: bool,
    spp: bool,
}

/// The albedo prefilter's launches and the copy of F they write, which the other kernels then
/// read (prefilter.rs).
struct Prefilter {
    /// Takes the frame's buffers: `bmfr_albedo_prefilter`, or with the packed kernel
    /// `bmfr_prefilter_lines`, which writes its input lines.
    inputs: Kernel,
    /// `bmfr_albedo_prefilter_packed` and its input lines (`packed_nlm`).
    packed: Option<(Kernel, Buffer<f32>)>,
    copy: Buffer<u8>,
    /// The positions the other kernels then read: with `prefilter_geometry` their xyz
    /// averaged, else a copy.
    positions: Buffer<u8>,
}

/// With `emission` (emission.rs): `bmfr_reflected`, which writes the copies of F and the odd
/// half that the other kernels then read, `bmfr_emission_prep`, which writes E's lines, and
/// `bmfr_emission_nlm` (or `bmfr_emission_nlm_packed`), which adds the filtered emission to the
/// image last.
struct Emission {
    reflected: Kernel,
    prep: Kernel,
    nlm: Kernel,
    fv: Buffer<u8>,
    odd: Buffer<u8>,
    /// E's lines (bmfr_emission.cl), which `prep` writes and `nlm` reads.
    _lines: Buffer<f32>,
}

/// Bytes of local memory that the work-group kernel `bmfr_emission_nlm`
/// (kernels/filters/bmfr_emission.cl) declares: the prep (float2) over the tile and its
/// radius + patch apron; the offset's terms over the tile and its patch border, and their
/// patch-row sums over the tile's columns (floats); with the mean-difference test the same two
/// again for the taps' differences and for their variances; and the group's lit flag (an int).
/// The device reports the same (tests/bmfr.rs asks it), so a GPU without the test keeps the
/// occupancy of the kernel before the test existed.
pub fn emission_local_bytes(radius: u32, mean_test: bool) -> u64 {
    let tile = EMISSION_TILE as u64;
    let side = tile + 2 * EMISSION_PATCH as u64;
    let input = tile + 2 * (radius as u64 + EMISSION_PATCH as u64);
    let per_sum = side * side * 4 + side * tile * 4;
    let sums = if mean_test { 3 } else { 1 };
    input * input * 8 + sums * per_sum + 4
}

impl BmfrKernel {
    /// The local memory the device reports for the emission's work-group kernel: None without
    /// `emission` or with the packed kernel (which declares none).
    pub fn emission_kernel_local_bytes(&self) -> Result<Option<u64>> {
        let Some(e) = &self.emission else { return Ok(None) };
        if e.nlm.name()? != "bmfr_emission_nlm" {
            return Ok(None);
        }
        match e.nlm.wg_info(self.gpu.device, KernelWorkGroupInfo::LocalMemSize)? {
            KernelWorkGroupInfoResult::LocalMemSize(bytes) => Ok(Some(bytes)),
            other => bail!("the device answered {other:?} for a kernel's local memory size"),
        }
    }
}

/// With `outliers` (outliers.rs): `bmfr_outlier_levels`, then `bmfr_outliers`, which writes the
/// copies of F and the odd half that the other kernels then read.
struct Outliers {
    levels: Kernel,
    replace: Kernel,
    fv: Buffer<u8>,
    odd: Buffer<u8>,
    _levels: Buffer<f32>,
}

/// Floats per line of the packed kernels' inputs (kernels/filters/bmfr_nlm_packed.cl): the
/// padding left of the image, its width rounded up to the lanes, twice the padding right.
fn line_stride(width: u32) -> u32 {
    NLM_PACKED_PAD + width.next_multiple_of(PACK) + 2 * NLM_PACKED_PAD
}

/// Lanes of the packed kernels (bmfr_nlm_packed.cl BMFR_NLM_PACK; the pixels whose windows one
/// work-item of the packed selection sums, bmfr_select_packed.cl BMFR_SELECT_PACK).
const PACK: u32 = 16;

/// Pixels filtered per work-item of the packed non-local means with patches of half width
/// `patch`: its lanes less the left and right neighbours (bmfr_nlm_packed.cl BMFR_NLM_STEP).
const fn nlm_step(patch: u32) -> u32 {
    PACK - 2 * patch
}

// The packed kernels' reads reach the search window's radius past the lanes, into the padding:
// left, the radius (the guided filter's: its window's) and (non-local means) the neighbour
// lanes; right, from the last work-item's first pixel (at most width - 1) its lanes and the
// radius.
const _: () = assert!(
    MAX_NLM_RADIUS + MAX_NLM_PATCH <= NLM_PACKED_PAD
        && MAX_ALBEDO_RADIUS < NLM_PACKED_PAD
        && nlm_step(1) + MAX_NLM_RADIUS <= 2 * NLM_PACKED_PAD
        && PACK - 1 + MAX_ALBEDO_RADIUS <= 2 * NLM_PACKED_PAD
        && MAX_GUIDED_RADIUS <= NLM_PACKED_PAD
        && PACK - 1 + MAX_GUIDED_RADIUS <= 2 * NLM_PACKED_PAD
);

/// The regression filter, built once for an image size.
pub struct BmfrKernel {
    gpu: Arc<Gpu>,
    /// With the packed fit: `bmfr_rows` and the planes it writes for every grid's fit.
    rows: Option<(Kernel, Buffer<f32>)>,
    fits: Vec<Kernel>,
    apply: Kernel,
    /// With `select`: `bmfr_residuals`, then `bmfr_select` (select.rs); with `nlm` too,
    /// `bmfr_nlm_prep`, `bmfr_nlm_inputs`, `bmfr_nlm`, `bmfr_residuals_nlm` and
    /// `bmfr_select_nlm` (nlm.rs). In launch order, each with the frame arguments it takes.
    select: Vec<(Kernel, FrameArgs)>,
    /// With `albedo_prefilter` (prefilter.rs).
    prefilter: Option<Prefilter>,
    emission: Option<Emission>,
    outliers: Option<Outliers>,
    needs: OutputSet,
    _weights: Buffer<f32>,
    _info: Buffer<f32>,
    _matrices: Buffer<f32>,
    out: Buffer<Float4>,
    width: u32,
    height: u32,
}

impl BmfrKernel {
    pub fn new(gpu: Arc<Gpu>, s: &BmfrSettings, width: u32, height: u32) -> Result<BmfrKernel> {
        s.validate()?;
        if width == 0 || height == 0 {
            bail!("the image must be at least 1x1 pixels, got {width}x{height}");
        }
        let b = s.block_size;
        let wg = WORK_GROUP.min(b * b);
        let max = gpu.summary.max_work_group_size;
        if max > 0 && wg as usize > max {
            bail!(
                "the bmfr filter needs work-groups of {wg}, {} allows {max}",
                gpu.summary.name
            );
        }
        // The non-local means, the albedo prefilter, the emission's filter and the selection
        // packed on CPU devices (nlm.rs `packed_nlm`): 16 pixels of a row per work-item.
        let packed_nlm = s.packed_nlm.or(gpu.summary.kind == "CPU");
        let k = s.features();
        // bmfr_fit's local memory: the block's matrix (unless in global memory) and each
        // work-item's partial dot products.
        // Its columns are BMFR_LD = B² + pad floats apart (bmfr.cl): COLUMN_PAD for the
        // packed fit, none for the work-group fit.
        let matrix_bytes_with = |pad: u32| (b * b + pad) as usize * (k + TARGETS) * 4;
        let partial_bytes = wg as usize * (k + TARGETS) * 4;
        let have = gpu.summary.local_mem_bytes;
        let fits = |bytes: usize| have == 0 || bytes as u64 <= have;
        // The packed fit (one work-item per block) always holds the matrix in local memory:
        // auto only where it fits; else the work-group fit with the matrix in global memory.
        let packed = s.packed_fit.or(gpu.summary.kind == "CPU" && fits(matrix_bytes_with(COLUMN_PAD)));
        let column_pad = if packed { COLUMN_PAD } else { 0 };
        let matrix_bytes = matrix_bytes_with(column_pad);
        let local_matrix = s.local_matrix.or(packed || fits(matrix_bytes + partial_bytes));
        if packed && !local_matrix {
            bail!(
                "the bmfr packed_fit keeps the matrix in local memory: set local_matrix auto or \
                 on, or packed_fit off"
            );
        }
        let local_bytes = match (packed, local_matrix) {
            (true, _) => matrix_bytes,
            (false, true) => matrix_bytes + partial_bytes,
            (false, false) => partial_bytes,
        };
        if !fits(local_bytes) {
            bail!(
                "the bmfr filter with block_size {b} needs {local_bytes} bytes of local memory \
                 (packed_fit {packed}, local_matrix {local_matrix}), {} has {have}; set \
                 packed_fit and local_matrix auto (the matrix in global memory) or use a \
                 smaller block_size",
                gpu.summary.name
            );
        }
        let flag = |v: bool| (v as u32).to_string();
        let defines: Vec<(String, String)> = [
            ("BMFR_BLOCK", b.to_string()),
            ("BMFR_WG", wg.to_string()),
            ("BMFR_GRIDS", s.grids.to_string()),
            ("BMFR_DEPTH", flag(s.depth)),
            ("BMFR_TEXTURE", flag(s.texture)),
            ("BMFR_TEXTURE2", flag(s.texture2)),
            ("BMFR_NOISE", format!("{:e}f", s.noise as f32)),
            ("BMFR_ALBEDO_EPSILON", format!("{ALBEDO_EPSILON:e}f")),
            ("BMFR_PIVOT_MIN", format!("{PIVOT_MIN:e}f")),
            ("BMFR_SELECT_RADIUS", s.select_radius.to_string()),
            ("BMFR_SELECT_SCALE", format!("{:e}f", s.select_scale as f32)),
            ("BMFR_SELECT_FLOOR", format!("{:e}f", s.select_floor())),
            ("BMFR_PREFILTER_K", format!("{PREFILTER_K:e}f")),
            ("BMFR_PREFILTER_EPSILON", format!("{PREFILTER_EPSILON:e}f")),
            ("BMFR_PREFILTER_GEOMETRY", flag(s.prefilter_geometry)),
            ("BMFR_GEOMETRY_K", format!("{:e}f", s.geometry_k as f32)),
            (
                "BMFR_PREFILTER_LINES",
                prefilter_packed_lines(s.prefilter_geometry).to_string(),
            ),
            ("BMFR_NLM_RADIUS", s.nlm_radius.to_string()),
            ("BMFR_NLM_ESTIMATE_RADIUS", s.estimate_radius().to_string()),
            ("BMFR_NLM_PATCH", s.nlm_patch.to_string()),
            ("BMFR_NLM_K", format!("{:e}f", s.nlm_k() as f32)),
            ("BMFR_NLM_EPSILON", format!("{NLM_EPSILON:e}f")),
            ("BMFR_SELECT_RELATIVE", flag(s.select_relative)),
            // The packed selection reads the residuals as four planes (bmfr_residuals_nlm).
            ("BMFR_RESIDUAL_PLANES", flag(packed_nlm)),
            ("BMFR_OPEN_MARGIN", flag(s.open_margin())),
            ("BMFR_OUTLIER_RATIO", format!("{:e}f", s.outlier_ratio as f32)),
            ("BMFR_OUTLIER_RADIUS", OUTLIER_RADIUS.to_string()),
            ("BMFR_OUTLIER_NEIGHBOURS", format!("{NEIGHBOURS:e}f")),
            ("BMFR_RELATIVE_EPSILON", format!("{RELATIVE_EPSILON:e}f")),
            ("BMFR_NLM_TILE", NLM_TILE.to_string()),
            ("BMFR_NLM_ROWS", NLM_PACKED_ROWS.to_string()),
            ("BMFR_EMISSION_RADIUS", s.emission_radius.to_string()),
            ("BMFR_EMISSION_PATCH", EMISSION_PATCH.to_string()),
            ("BMFR_EMISSION_TILE", EMISSION_TILE.to_string()),
            ("BMFR_EMISSION_LINES", EMISSION_LINES.to_string()),
            ("BMFR_EMISSION_ROWS", EMISSION_PACKED_ROWS.to_string()),
            ("BMFR_EMISSION_K", format!("{:e}f", s.emission_k as f32)),
            ("BMFR_EMISSION_EPSILON", format!("{EMISSION_EPSILON:e}f")),
            ("BMFR_EMISSION_SELF", format!("{:e}f", s.emission_self_weight() as f32)),
            ("BMFR_EMISSION_MEAN", format!("{:e}f", s.emission_mean_test() as f32)),
            ("BMFR_EMISSION_MEAN_ON", flag(s.emission_mean_test() > 0.0)),
            ("BMFR_SPLIT_EMISSION", flag(s.splits_emission())),
            ("BMFR_GLOBAL_MATRIX", flag(!packed && !local_matrix)),
            ("BMFR_COLUMN_PAD", column_pad.to_string()),
            ("BMFR_GUIDED", flag(s.uses_nlm() && s.guided)),
            ("BMFR_GUIDED_RADIUS", s.guided_radius.to_string()),
            ("BMFR_GUIDED_RIDGE", format!("{:e}f", s.guided_ridge as f32)),
            ("BMFR_GUIDED_SCALE", format!("{:e}f", s.guided_scale() as f32)),
        ]
        .into_iter()
        .map(|(n, v)| (n.to_string(), v))
        .collect();
        let program = gpu.program("filters/bmfr.cl", &defines, "")?;
        let stride = blocks_per_grid(width, height, b);
        let slots = (stride * s.grids) as usize;
        let weights = gpu.zeroed::<f32>(slots * TARGETS * k, "bmfr weights")?;
        let info = gpu.zeroed::<f32>(slots * INFO_FLOATS, "bmfr block information")?;
        let out = gpu.zeroed::<Float4>(width as usize * height as usize, "bmfr image")?;
        // The work-group fit's matrices in global memory: one per block of a grid, reused by
        // the next grid's launch (in order on the queue).
        let matrices = gpu.zeroed::<f32>(
            if packed || local_matrix {
                1
            } else {
                stride as usize * matrix_bytes / 4
            },
            "bmfr fit matrices",
        )?;
        // One work-item per block on CPU devices (same bytes; bmfr_fit_packed.cl), over the
        // pixels' rows of the fit written once by `bmfr_rows` for every grid.
        let rows = if packed {
            let pixels = width as usize * height as usize;
            let planes = gpu.zeroed::<f32>(
                (k + TARGETS) * (pixels + 2 * PACKED_PAD),
                "bmfr rows of the fit",
            )?;
            let kernel = Kernel::builder()
                .program(&program)
                .name("bmfr_rows")
                .queue(gpu.queue.clone())
                .global_work_size([width as usize, height as usize])
                .arg_named("fv", None::<&Buffer<u8>>)
                .arg_named("positions", None::<&Buffer<u8>>)
                .arg(width)
                .arg(height)
                .arg_named("spp", 0f32)
                .arg(&planes)
                .build()
                .context("creating the bmfr rows kernel")?;
            Some((kernel, planes))
        } else {
            None
        };
        let fits = (0..s.grids)
            .map(|g| {
                let (across, down) = grid_blocks(width, height, b, grid_offset(g, s.grids, b));
                let mut kb = Kernel::builder();
                kb.program(&program).queue(gpu.queue.clone());
                if let Some((_, planes)) = &rows {
                    kb.name("bmfr_fit_packed")
                        .global_work_size([(across * down) as usize])
                        .local_work_size([1])
                        .arg(planes);
                } else {
                    kb.name("bmfr_fit")
                        .global_work_size([(across * down * wg) as usize])
                        .local_work_size([wg as usize])
                        .arg_named("fv", None::<&Buffer<u8>>)
                        .arg_named("positions", None::<&Buffer<u8>>);
                }
                kb.arg(width).arg(height).arg(g).arg(stride);
                if rows.is_none() {
                    kb.arg_named("spp", 0f32);
                }
                kb.arg(&weights).arg(&info);
                if rows.is_none() {
                    kb.arg(&matrices);
                }
                kb.build().context("creating the bmfr fit kernel")
            })
            .collect::<Result<Vec<_>>>()?;
        // With the packed fit, the packed application too (bmfr_apply_packed.cl: 16 pixels
        // of a row per work-item, the same bytes).
        let mut apply = Kernel::builder();
        if packed {
            apply
                .name("bmfr_apply_packed")
                .global_work_size([width.div_ceil(PACK) as usize, height as usize])
                .local_work_size([1, 1]);
        } else {
            apply
                .name("bmfr_apply")
                .global_work_size([width as usize, height as usize]);
        }
        let apply = apply
            .program(&program)
            .queue(gpu.queue.clone())
            .arg_named("fv", None::<&Buffer<u8>>)
            .arg_named("positions", None::<&Buffer<u8>>)
            .arg(width)
            .arg(height)
            .arg(stride)
            .arg_named("spp", 0f32)
            .arg(&weights)
            .arg(&info)
            .arg(&out)
            .build()
            .context("creating the bmfr apply kernel")?;
        let pixels = width as usize * height as usize;
        // A kernel over the pixels with the frame's F first, then the frame arguments `frame`
        // names (set per frame), width and height; the caller adds the fixed ones.
        let per_pixel = |name: &'static str, frame: FrameArgs| {
            let mut kb = Kernel::builder();
            kb.program(&program)
                .name(name)
                .queue(gpu.queue.clone())
                .global_work_size([width as usize, height as usize])
                .arg_named("fv", None::<&Buffer<u8>>);
            if frame.positions {
                kb.arg_named("positions", None::<&Buffer<u8>>);
            }
            if frame.odd_halves {
                kb.arg_named("odd_halves", None::<&Buffer<u8>>);
            }
            kb.arg(width).arg(height);
            if frame.spp {
                kb.arg_named("spp", 0f32);
            }
            kb
        };
        let built = |kb: ocl::builders::KernelBuilder, frame: FrameArgs| -> Result<(Kernel, FrameArgs)> {
            Ok((kb.build().context("creating a bmfr selection kernel")?, frame))
        };
        let all = FrameArgs {
            positions: true,
            odd_halves: true,
            spp: true,
        };
        let no_positions = FrameArgs {
            positions: false,
            ..all
        };
        let none = FrameArgs {
            positions: false,
            odd_halves: false,
            spp: false,
        };
        let mut select = Vec::new();
        if s.uses_nlm() {
            let raw = gpu.zeroed::<Float4>(pixels, "bmfr nlm variance samples")?;
            let nlm_out = gpu.zeroed::<Float4>(3 * pixels, "bmfr nlm outputs")?;
            let residuals = gpu.zeroed::<Float4>(pixels, "bmfr selection residuals")?;
            let mut kb = per_pixel("bmfr_nlm_prep", all);
            kb.arg(&raw);
            select.push(built(kb, all)?);
            // Packed on CPU devices (nlm.rs `packed_nlm`): the inputs as lines of floats,
            // padded either side and zeroed once (kernels/filters/bmfr_nlm_packed.cl).
            let stride = line_stride(width);
            // The packed kernels' input lines, which the packed guided filter reads too.
            let mut nlm_lines = None;
            if packed_nlm {
                let lines = gpu.zeroed::<f32>(
                    (NLM_PACKED_LINES * stride) as usize * height as usize,
                    "bmfr nlm input lines",
                )?;
                let mut kb = per_pixel("bmfr_nlm_inputs_lines", no_positions);
                kb.arg(&raw).arg(stride).arg(&lines);
                select.push(built(kb, no_positions)?);
                let mut kb = per_pixel("bmfr_nlm_packed", no_positions);
                kb.global_work_size([
                    width.div_ceil(nlm_step(s.nlm_patch)) as usize,
                    height.div_ceil(NLM_PACKED_ROWS) as usize,
                ])
                .local_work_size([1, 1])
                .arg(&lines)
                .arg(stride)
                .arg(&nlm_out);
                select.push(built(kb, no_positions)?);
                nlm_lines = Some(lines);
            } else {
                // bmfr_nlm's local memory: the tile's four inputs and each tap's distance, over
                // the tile and its patch border (float4s).
                let side = (NLM_TILE + 2 * s.nlm_patch) as u64;
                let nlm_bytes = side * side * 5 * 16;
                let have = gpu.summary.local_mem_bytes;
                if have > 0 && nlm_bytes > have {
                    bail!(
                        "the bmfr non-local means with nlm_patch {} needs {nlm_bytes} bytes of \
                         local memory, {} has {have}; use a smaller nlm_patch",
                        s.nlm_patch,
                        gpu.summary.name
                    );
                }
                let nlm_in = gpu.zeroed::<Float4>(4 * pixels, "bmfr nlm inputs")?;
                let mut kb = per_pixel("bmfr_nlm_inputs", no_positions);
                kb.arg(&raw).arg(&nlm_in);
                select.push(built(kb, no_positions)?);
                let mut kb = per_pixel("bmfr_nlm", no_positions);
                let tile = NLM_TILE as usize;
                kb.global_work_size([
                    (width as usize).next_multiple_of(tile),
                    (height as usize).next_multiple_of(tile),
                ])
                .local_work_size([tile, tile])
                .arg(&nlm_in)
                .arg(&nlm_out);
                select.push(built(kb, no_positions)?);
            }
            // The classes from bmfr_nlm_prep's `raw` (w), as the non-local means used them.
            let mut kb = per_pixel("bmfr_residuals_nlm", no_positions);
            kb.arg(&raw).arg(&out).arg(&nlm_out).arg(&residuals);
            select.push(built(kb, no_positions)?);
            // A packed kernel's launch: one work-item per PACK pixels of a row.
            let row_packed = |name, frame| {
                let mut kb = per_pixel(name, frame);
                kb.global_work_size([width.div_ceil(PACK) as usize, height as usize])
                    .local_work_size([1, 1]);
                kb
            };
            // The guided filter's four passes (guided.rs), before the selection overwrites
            // the fit that its error terms are relative to.
            let guided_out = if s.guided {
                let guided_out = gpu.zeroed::<Float4>(pixels, "bmfr guided filter")?;
                if let Some(lines) = &nlm_lines {
                    // 16 pixels per work-item on the packed kernels' lines
                    // (kernels/filters/bmfr_guided_packed.cl), the same bytes.
                    let planes = |n: usize, what| {
                        gpu.zeroed::<f32>(n * stride as usize * height as usize, what)
                    };
                    let guides = planes(guided::GUIDES, "bmfr guided guide lines")?;
                    // The moments' planes later hold the models' row sums (MODEL ≤ MOMENTS).
                    let moments = planes(guided::MOMENTS, "bmfr guided moments")?;
                    let models = planes(guided::MODEL, "bmfr guided models")?;
                    let positions_only = FrameArgs {
                        odd_halves: false,
                        spp: false,
                        ..all
                    };
                    let mut kb = per_pixel("bmfr_guided_guide_lines", positions_only);
                    kb.arg(stride).arg(&guides);
                    select.push(built(kb, positions_only)?);
                    let mut kb = row_packed("bmfr_guided_rows_packed", none);
                    kb.arg(stride).arg(lines).arg(&guides).arg(&moments);
                    select.push(built(kb, none)?);
                    let mut kb = row_packed("bmfr_guided_solve_packed", none);
                    kb.arg(stride).arg(&moments).arg(&models);
                    select.push(built(kb, none)?);
                    let mut kb = row_packed("bmfr_guided_average_rows_packed", none);
                    kb.arg(stride).arg(&models).arg(&moments);
                    select.push(built(kb, none)?);
                    let frame = FrameArgs {
                        positions: false,
                        ..all
                    };
                    let mut kb = row_packed("bmfr_guided_eval_packed", frame);
                    kb.arg(stride)
                        .arg(&raw)
                        .arg(&guides)
                        .arg(&moments)
                        .arg(&out)
                        .arg(&nlm_out)
                        .arg(&guided_out);
                    select.push(built(kb, frame)?);
                } else {
                    let planes = |n, what| gpu.zeroed::<f32>(n * pixels, what);
                    // The moments' planes later hold the models' row sums (MODEL ≤ MOMENTS).
                    let moments = planes(guided::MOMENTS, "bmfr guided moments")?;
                    let models = planes(guided::MODEL, "bmfr guided models")?;
                    let mut kb = per_pixel("bmfr_guided_rows", all);
                    kb.arg(&raw).arg(&moments);
                    select.push(built(kb, all)?);
                    let mut kb = per_pixel("bmfr_guided_solve", none);
                    kb.arg(&moments).arg(&models);
                    select.push(built(kb, none)?);
                    let mut kb = per_pixel("bmfr_guided_average_rows", none);
                    kb.arg(&models).arg(&moments);
                    select.push(built(kb, none)?);
                    let mut kb = per_pixel("bmfr_guided_eval", all);
                    kb.arg(&raw).arg(&moments).arg(&out).arg(&nlm_out).arg(&guided_out);
                    select.push(built(kb, all)?);
                }
                Some(guided_out)
            } else {
                None
            };
            // Packed on CPU devices too (kernels/filters/bmfr_select_packed.cl): 16 pixels'
            // windows per work-item, the same bytes.
            let mut kb = if packed_nlm {
                row_packed("bmfr_select_nlm_packed", none)
            } else {
                per_pixel("bmfr_select_nlm", none)
            };
            kb.arg(&residuals).arg(&nlm_out).arg(&out);
            match &guided_out {
                // The packed selection joins the guided filter itself (bmfr_guided_join).
                Some(guided_out) if packed_nlm => {
                    kb.arg(guided_out);
                    select.push(built(kb, none)?);
                }
                Some(guided_out) => {
                    select.push(built(kb, none)?);
                    let mut kb = per_pixel("bmfr_guided_blend", none);
                    kb.arg(&residuals).arg(guided_out).arg(&out);
                    select.push(built(kb, none)?);
                }
                None => select.push(built(kb, none)?),
            }
        } else if s.select {
            let residuals = gpu.zeroed::<Float2>(pixels, "bmfr selection residuals")?;
            let mut kb = per_pixel("bmfr_residuals", all);
            kb.arg(&out).arg(&residuals);
            select.push(built(kb, all)?);
            let mut kb = per_pixel("bmfr_select", none);
            kb.arg(&residuals).arg(&out);
            select.push(built(kb, none)?);
        }
        let prefilter = if s.prefilters_albedo() {
            let copy = gpu.zeroed::<u8>(
                pixels * std::mem::size_of::<FilterVector>(),
                "bmfr prefiltered F",
            )?;
            let positions = gpu.zeroed::<u8>(
                pixels * std::mem::size_of::<Float4>(),
                "bmfr prefiltered positions",
            )?;
            // On CPU devices the packed kernel (bmfr_prefilter_packed.cl) over its inputs as
            // lines; elsewhere one work-item per pixel.
            let stride = line_stride(width);
            let lines = if packed_nlm {
                Some(gpu.zeroed::<f32>(
                    (prefilter_packed_lines(s.prefilter_geometry) * stride) as usize
                        * height as usize,
                    "bmfr albedo prefilter lines",
                )?)
            } else {
                None
            };
            let mut kb = Kernel::builder();
            kb.program(&program)
                .queue(gpu.queue.clone())
                .global_work_size([width as usize, height as usize])
                .arg_named("fv", None::<&Buffer<u8>>)
                .arg_named("sums", None::<&Buffer<u8>>)
                .arg_named("positions", None::<&Buffer<u8>>)
                .arg(width)
                .arg(height)
                .arg_named("spp", 0f32)
                .arg_named("factor", 0f32);
            if let Some(lines) = &lines {
                kb.name("bmfr_prefilter_lines").arg(stride).arg(lines);
            } else {
                kb.name("bmfr_albedo_prefilter")
                    .arg(s.albedo_radius)
                    .arg(&copy)
                    .arg(&positions);
            }
            let inputs = kb
                .build()
                .context("creating the bmfr albedo prefilter kernel")?;
            let packed = match lines {
                Some(lines) => {
                    let kernel = Kernel::builder()
                        .program(&program)
                        .name("bmfr_albedo_prefilter_packed")
                        .queue(gpu.queue.clone())
                        .global_work_size([width.div_ceil(PACK) as usize, height as usize])
                        .local_work_size([1, 1])
                        .arg_named("fv", None::<&Buffer<u8>>)
                        .arg_named("positions", None::<&Buffer<u8>>)
                        .arg(width)
                        .arg(height)
                        .arg(&lines)
                        .arg(stride)
                        .arg(s.albedo_radius)
                        .arg(&copy)
                        .arg(&positions)
                        .build()
                        .context("creating the packed bmfr albedo prefilter kernel")?;
                    Some((kernel, lines))
                }
                None => None,
            };
            Some(Prefilter {
                inputs,
                packed,
                copy,
                positions,
            })
        } else {
            None
        };
        let emission = if s.splits_emission() {
            let fv = gpu.zeroed::<u8>(
                pixels * std::mem::size_of::<FilterVector>(),
                "bmfr reflected F",
            )?;
            let odd = gpu.zeroed::<u8>(
                pixels * std::mem::size_of::<Float4>(),
                "bmfr reflected odd half",
            )?;
            // E's lines (bmfr_emission.cl), padded either side and zeroed once.
            let stride = line_stride(width);
            let lines = gpu.zeroed::<f32>(
                (EMISSION_LINES * stride) as usize * height as usize,
                "bmfr emission lines",
            )?;
            let frame_kernel = |name: &'static str| {
                let mut kb = Kernel::builder();
                kb.program(&program)
                    .name(name)
                    .queue(gpu.queue.clone())
                    .global_work_size([width as usize, height as usize]);
                kb
            };
            let mut kb = frame_kernel("bmfr_reflected");
            kb.arg_named("fv", None::<&Buffer<u8>>)
                .arg_named("odd_halves", None::<&Buffer<u8>>)
                .arg_named("emission", None::<&Buffer<u8>>)
                .arg_named("odd_emission", None::<&Buffer<u8>>)
                .arg(width)
                .arg(height)
                .arg(&fv)
                .arg(&odd);
            let reflected = kb.build().context("creating the bmfr reflected-light kernel")?;
            let mut kb = frame_kernel("bmfr_emission_prep");
            kb.arg_named("emission", None::<&Buffer<u8>>)
                .arg_named("odd_emission", None::<&Buffer<u8>>)
                .arg(width)
                .arg(height)
                .arg_named("spp", 0f32)
                .arg(stride)
                .arg(&lines);
            let prep = kb.build().context("creating the bmfr emission kernel")?;
            // Packed on CPU devices (`packed_nlm`, bmfr_emission_nlm_packed), else work-groups
            // of a tile.
            let mut kb = Kernel::builder();
            kb.program(&program).queue(gpu.queue.clone());
            if packed_nlm {
                kb.name("bmfr_emission_nlm_packed")
                    .global_work_size([
                        width.div_ceil(EMISSION_PACKED_STEP) as usize,
                        height.div_ceil(EMISSION_PACKED_ROWS) as usize,
                    ])
                    .local_work_size([1, 1]);
            } else {
                let need = emission_local_bytes(s.emission_radius, s.emission_mean_test() > 0.0);
                let have = gpu.summary.local_mem_bytes;
                if have > 0 && need > have {
                    bail!(
                        "the bmfr emission's non-local means with emission_radius {} needs \
                         {need} bytes of local memory, {} has {have}; use a smaller \
                         emission_radius",
                        s.emission_radius,
                        gpu.summary.name
                    );
                }
                let tile = EMISSION_TILE as usize;
                kb.name("bmfr_emission_nlm")
                    .global_work_size([
                        (width as usize).next_multiple_of(tile),
                        (height as usize).next_multiple_of(tile),
                    ])
                    .local_work_size([tile, tile]);
            }
            kb.arg(&lines).arg(stride).arg(width).arg(height).arg(&out);
            let nlm = kb.build().context("creating the bmfr emission kernel")?;
            Some(Emission {
                reflected,
                prep,
                nlm,
                fv,
                odd,
                _lines: lines,
            })
        } else {
            None
        };
        let outliers = if s.outliers {
            let fv = gpu.zeroed::<u8>(
                pixels * std::mem::size_of::<FilterVector>(),
                "bmfr F without outliers",
            )?;
            let odd = gpu.zeroed::<u8>(
                pixels * std::mem::size_of::<Float4>(),
                "bmfr odd half without outliers",
            )?;
            let levels_buffer = gpu.zeroed::<f32>(pixels, "bmfr outlier levels")?;
            let mut kb = per_pixel("bmfr_outlier_levels", all);
            kb.arg(&levels_buffer);
            let levels = kb.build().context("creating the bmfr outlier kernel")?;
            let mut kb = per_pixel("bmfr_outliers", no_positions);
            kb.arg(&levels_buffer).arg(&fv).arg(&odd);
            let replace = kb.build().context("creating the bmfr outlier kernel")?;
            Some(Outliers {
                levels,
                replace,
                fv,
                odd,
                _levels: levels_buffer,
            })
        } else {
            None
        };
        Ok(BmfrKernel {
            gpu,
            rows,
            fits,
            apply,
            select,
            prefilter,
            emission,
            outliers,
            needs: s.needs(),
            _weights: weights,
            _info: info,
            _matrices: matrices,
            out,
            width,
            height,
        })
    }

    /// Filters `frame` (which must be width × height) and reads the image back. The kernel
    /// time is the sum over the fits and the blend, from their profiling events.
    pub fn filter(&mut self, frame: &Frame) -> Result<FilterRun> {
        let start = Instant::now();
        frame.check_size(self.width, self.height, "the bmfr filter")?;
        frame.require(self.needs, "the bmfr filter")?;
        let mut fv = frame.device(&self.gpu, BufferId::FilterVectors)?;
        let mut pos = frame.device(&self.gpu, BufferId::Positions)?;
        let spp = frame.info().spp as f32;
        let mut events = Vec::with_capacity(self.fits.len() + 4);
        // The odd half the selection reads: the frame's, or with `emission` its reflected copy.
        let mut odd = None;
        if let Some(em) = &self.emission {
            let e = frame.device(&self.gpu, BufferId::FirstEmission)?;
            let e_odd = frame.device(&self.gpu, BufferId::OddEmission)?;
            em.reflected.set_arg("fv", fv)?;
            em.reflected
                .set_arg("odd_halves", frame.device(&self.gpu, BufferId::OddHalves)?)?;
            em.reflected.set_arg("emission", e)?;
            em.reflected.set_arg("odd_emission", e_odd)?;
            em.prep.set_arg("emission", e)?;
            em.prep.set_arg("odd_emission", e_odd)?;
            em.prep.set_arg("spp", spp)?;
            // SAFETY: the buffers are sized for the image; the in-order queue runs every
            // other kernel on the copies after these, and we wait for every event below.
            events.push(unsafe { enqueue(&em.reflected, "the bmfr reflected light")? });
            events.push(unsafe { enqueue(&em.prep, "the bmfr emission")? });
            fv = &em.fv;
            odd = Some(&em.odd);
        }
        if let Some(o) = &self.outliers {
            let odd_in = match odd {
                Some(odd) => odd,
                None => frame.device(&self.gpu, BufferId::OddHalves)?,
            };
            o.levels.set_arg("fv", fv)?;
            o.levels.set_arg("positions", pos)?;
            o.levels.set_arg("odd_halves", odd_in)?;
            o.levels.set_arg("spp", spp)?;
            o.replace.set_arg("fv", fv)?;
            o.replace.set_arg("odd_halves", odd_in)?;
            o.replace.set_arg("spp", spp)?;
            // SAFETY: the buffers are sized for the image; the in-order queue runs the
            // replacement after the levels and every other kernel on the copies after both;
            // we wait for every event below.
            events.push(unsafe { enqueue(&o.levels, "the bmfr outlier levels")? });
            events.push(unsafe { enqueue(&o.replace, "the bmfr outliers")? });
            fv = &o.fv;
            odd = Some(&o.odd);
        }
        if let Some(p) = &self.prefilter {
            p.inputs.set_arg("fv", fv)?;
            p.inputs
                .set_arg("sums", frame.device(&self.gpu, BufferId::WelfordSums)?)?;
            p.inputs.set_arg("positions", pos)?;
            p.inputs.set_arg("spp", spp)?;
            p.inputs.set_arg("factor", frame.variance_factor())?;
            // SAFETY: the buffers are sized for the image; the in-order queue runs the packed
            // kernel after its lines, and the fits on the copy after both; we wait for every
            // event below.
            events.push(unsafe { enqueue(&p.inputs, "the bmfr albedo prefilter")? });
            if let Some((kernel, _)) = &p.packed {
                kernel.set_arg("fv", fv)?;
                kernel.set_arg("positions", pos)?;
                events.push(unsafe { enqueue(kernel, "the packed bmfr albedo prefilter")? });
            }
            fv = &p.copy;
            pos = &p.positions;
        }
        if let Some((kernel, _)) = &self.rows {
            kernel.set_arg("fv", fv)?;
            kernel.set_arg("positions", pos)?;
            kernel.set_arg("spp", spp)?;
            // SAFETY: the planes are sized for the image; the in-order queue runs the fits
            // after this launch, and we wait for every event below.
            events.push(unsafe { enqueue(kernel, "the bmfr rows")? });
        }
        let fits = self.fits.iter().filter(|_| self.rows.is_none());
        for k in fits.chain(std::iter::once(&self.apply)) {
            k.set_arg("fv", fv)?;
            k.set_arg("positions", pos)?;
            k.set_arg("spp", spp)?;
        }
        for (k, args) in &self.select {
            k.set_arg("fv", fv)?;
            if args.positions {
                k.set_arg("positions", pos)?;
            }
            if args.odd_halves {
                let odd = match odd {
                    Some(odd) => odd,
                    None => frame.device(&self.gpu, BufferId::OddHalves)?,
                };
                k.set_arg("odd_halves", odd)?;
            }
            if args.spp {
                k.set_arg("spp", spp)?;
            }
        }
        let selection = self.select.iter().map(|(k, _)| k);
        for k in self.fits.iter().chain(std::iter::once(&self.apply)).chain(selection) {
            // SAFETY: every buffer outlives its launch (we wait for all of them below) and is
            // sized for the image and the grids the kernels were built for; the in-order queue
            // runs the blend after the fits, and the selection's steps after the blend in turn.
            events.push(unsafe { enqueue(k, "a bmfr filter kernel")? });
        }
        if let Some(em) = &self.emission {
            // SAFETY: as above; the in-order queue adds the emission after the selection.
            events.push(unsafe { enqueue(&em.nlm, "the bmfr emission")? });
        }
        let mut kernel_time = Duration::ZERO;
        for e in &events {
            kernel_time += event_duration(e)?;
        }
        Ok(FilterRun {
            image: read_rgb(&self.out, self.width, self.height)?,
            wall_time: start.elapsed(),
            kernel_time: Some(kernel_time),
        })
    }
}

impl PreparedFilter for BmfrKernel {
    fn run(&mut self, frame: &Frame) -> Result<FilterRun> {
        self.filter(frame)
    }
}
