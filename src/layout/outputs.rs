//! Every per-pixel (and per-sample) output of the megakernel, declared once.
//!
//! An [`Output`] is what a filter asks for ("the feature variances"); it owns device buffers
//! ([`BufferDecl`], laid out as one shared struct per pixel or per sample) or lanes of another
//! output's buffer, is compiled in by one `-D` switch, may need other outputs, and names its AOV
//! channels. From this table come:
//! - the megakernel's output parameters and their order (`RENDER_OUTPUT_PARAMS` in the
//!   generated kernels/render/outputs.cl) and the host's binding of them, by name;
//! - the `-D OUTPUT_*` switches and the checks that they were all given;
//! - buffer allocation and its memory check (src/render);
//! - the AOV channels, written and read back (src/stats/aov.rs): a file without an optional
//!   output still loads when the chosen filter does not need it;
//! - the layout test's device sizes, and the generic defines of the test kernels;
//! - how renders of disjoint sample ranges or tiles merge into one ([`Merge`], applied by
//!   src/stats/merge/ with an exhaustive match, and written into partial files by
//!   src/stats/partial/).
//!
//! Adding an output: a row in [`OUTPUTS`] (and its buffer in [`BUFFERS`], with its merge rule),
//! the kernel code that writes it (kernels/render/film.cl), and the filter that reads it.

use std::mem::{offset_of, size_of};

use super::{
    DepthShift, FilterVector, Float4, IndirectPixel, LensShadowPixel, LightFieldPixel,
    SampleVector, ShadowPixel, ShadowTerms, WelfordState, WelfordSums,
};

/// A group of per-pixel outputs switched on together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Output {
    /// The direct and indirect light means of the FilterVector (eq. 6.1): always on.
    Colour,
    /// The first-hit feature means of the FilterVector: depth, normal, albedo, albedo2.
    Features,
    /// Welford's running S_n of every feature (the variance GBuffer, eq. 6.2) and the mean
    /// first-bounce direction.
    Variance,
    /// The mean world position of the first hit (over the samples that hit a surface).
    Position,
    /// Every sample's Random Parameter Filtering vector (thesis §5.1.1, Table 5.1).
    Samples,
    /// AAF soft shadows of one sphere light (Wang 2013 ch. 3): the part of F the filtered term
    /// replaces, and the sparse + adaptive light samples of each pixel's centre receiver.
    Shadows,
    /// The mean light (direct + indirect) of the pixel's odd-numbered samples alone: with F
    /// it splits the pixel's samples into two independent half buffers (even and odd, as in
    /// NFOR, Bitterli et al. 2016), whose difference estimates the variance of F's light.
    Halves,
    /// Sheared filtering (Yan et al. 2015 §3.1): l² samples per pixel on a jittered grid (the
    /// 4-D light field): with the shadow output each shadow light's visibility and its axes
    /// on the screen (one per light plane); without it (a thin lens) the radiance through the
    /// lens, slopes and hit.
    LightField,
    /// AAF indirect light (Wang 2013 ch. 4): the sparse + adaptive indirect samples of each
    /// pixel's centre receiver (diffuse, or a metal's glossy lobe), demodulated, with z_min
    /// and z_max.
    Indirect,
    /// Sheared soft shadows and depth of field together (Yan et al. 2015, appendix eqs.
    /// 16-17): beside the shadow fields of the light-field output, the lens field with each
    /// lens sample's light less the filtered lights' direct term on the pixel centre's
    /// receiver, that sample's albedo, and the lights' unoccluded terms.
    LensShadows,
    /// The light of lights seen directly (emitters hit by the camera ray), the part of the
    /// FilterVector's direct light that is no surface's reflection: its mean over the pixel's
    /// samples and the share of samples whose camera ray hit an emitter. A filter that models
    /// reflected light (bmfr's fit) takes it out of its target and treats it apart.
    Emission,
}

/// A device buffer of the megakernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum BufferId {
    FilterVectors,
    DepthShifts,
    WelfordSums,
    WelfordState,
    Positions,
    SampleVectors,
    ShadowTerms,
    ShadowPixels,
    OddHalves,
    LightFieldPixels,
    IndirectPixels,
    LensFieldPixels,
    LensShadowPixels,
    FirstEmission,
    OddEmission,
}

/// How many elements a buffer holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Per {
    Pixel,
    /// `sample_capacity` elements per pixel, pixel-major (index = pixel · capacity + sample).
    Sample,
    /// One element per pixel for each light plane of the shadow output (the sphere lights a
    /// filter asks for: the render's `ShadowSampling::lights`), pixel-major (index =
    /// pixel · planes + plane): a row of pixels stays contiguous, so splitting and merging by
    /// rows or by elements works as for [`Per::Pixel`]. Without the shadow output (0 planes)
    /// one element per pixel: the light field is per light with it (sheared shadows, one
    /// light field per filtered light) and per pixel without it (depth of field, GI).
    Light,
}

/// Most light planes of the shadow output (`SHADOW_PLANES` is a build define of the
/// megakernel: each plane is a private float4 of every path sample's state).
pub const MAX_SHADOW_PLANES: u32 = 8;

/// How the buffers of renders of disjoint sample ranges (or tiles) of one image combine into
/// the buffer of a single render of all those samples (`noisefree merge`, src/stats/merge/).
/// Every buffer declares one, so an output cannot be added without saying how it merges, and
/// the merge matches on it exhaustively.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Merge {
    /// Every lane a running mean over the pixel's samples (eq. 6.5): the count-weighted mean of
    /// the parts' means. FilterVector's depth lane is the exception when the depth shifts are
    /// gathered: it is recomputed as K + mean(x − K) from the merged [`Merge::DepthShift`].
    Means,
    /// [`DepthShift`]: K is the depth of the pixel's first sample, so the merged K is that of
    /// the part holding sample 0; the other parts' means of x − K_part are moved to it.
    DepthShift,
    /// Welford's S_n of every lane (eq. 6.6), each paired with its mean in [`WELFORD_MEANS`]:
    /// combined by the parallel update of Chan, Golub & LeVeque (1979),
    /// S = S_a + S_b + δ² n_a n_b / (n_a + n_b), δ = mean_b − mean_a.
    WelfordSums,
    /// [`WelfordState`]: the mean first-bounce direction (a running mean) and the Kahan
    /// compensation of each S_n, which is rewritten from the merged S_n (the part of the
    /// double-precision sum that its float does not hold).
    WelfordState,
    /// xyz: means over a subset of the pixel's samples (those whose camera ray hit a surface;
    /// the odd-numbered ones); w: how many there are (a count).
    HitMeans,
    /// One element per sample: each part's samples go to their sample numbers.
    PerSample,
    /// The same in every part: computed before the path samples from the pixel alone (AAF's
    /// shadow passes, whose light samples are a hash of the pixel, not of the sample range),
    /// so the merge keeps the first part's and checks that the others agree.
    Identical,
}

#[derive(Debug)]
pub struct BufferDecl {
    pub id: BufferId,
    /// The kernel parameter and the name in messages.
    pub name: &'static str,
    /// The shared struct of one element (src/layout/mod.rs).
    pub element: &'static str,
    pub element_bytes: usize,
    pub per: Per,
    /// How partial renders of this buffer merge.
    pub merge: Merge,
    pub doc: &'static str,
}

/// How an AOV channel relates to the buffer lane it comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelScale {
    AsIs,
    /// The lane holds Welford's S_n; the channel holds the variance S_n / (n − 1).
    Variance,
}

#[derive(Debug)]
pub struct ChannelDecl {
    /// `layer.channel`, as standard EXR tools group them.
    pub name: &'static str,
    pub buffer: BufferId,
    /// Float lane within one element.
    pub lane: usize,
    pub scale: ChannelScale,
}

#[derive(Debug)]
pub struct OutputDecl {
    pub output: Output,
    /// Name in messages, `--explain` and the AOV header.
    pub name: &'static str,
    /// The `-D` switch that compiles it into the megakernel; None: always compiled in.
    pub switch: Option<&'static str>,
    pub requires: &'static [Output],
    /// Buffers this output owns (allocated only when it is on).
    pub buffers: &'static [BufferId],
    pub channels: &'static [ChannelDecl],
    pub doc: &'static str,
}

const fn lane(byte_offset: usize) -> usize {
    byte_offset / 4
}

const fn ch(name: &'static str, buffer: BufferId, lane: usize) -> ChannelDecl {
    ChannelDecl {
        name,
        buffer,
        lane,
        scale: ChannelScale::AsIs,
    }
}

const fn var(name: &'static str, lane: usize) -> ChannelDecl {
    ChannelDecl {
        name,
        buffer: BufferId::WelfordSums,
        lane,
        scale: ChannelScale::Variance,
    }
}

use BufferId::*;

const F_DIRECT: usize = lane(offset_of!(FilterVector, direct));
const F_INDIRECT: usize = lane(offset_of!(FilterVector, indirect));
const F_DEPTH: usize = lane(offset_of!(FilterVector, depth));
const F_NORMAL: usize = lane(offset_of!(FilterVector, normal));
const F_ALBEDO: usize = lane(offset_of!(FilterVector, albedo));
const F_ALBEDO2: usize = lane(offset_of!(FilterVector, albedo2));
const S_DEPTH: usize = lane(offset_of!(WelfordSums, depth));
const S_NORMAL: usize = lane(offset_of!(WelfordSums, normal));
const S_ALBEDO: usize = lane(offset_of!(WelfordSums, albedo));
const S_DIRECTION: usize = lane(offset_of!(WelfordSums, direction));
const S_ALBEDO2: usize = lane(offset_of!(WelfordSums, albedo2));
const W_DIRECTION: usize = lane(offset_of!(WelfordState, direction_mean));
const T_DIRECT: usize = lane(offset_of!(ShadowTerms, direct));
const T_UNSHADOWED: usize = lane(offset_of!(ShadowTerms, unshadowed));
const P_VISIBLE: usize = lane(offset_of!(ShadowPixel, visible));
const P_WEIGHT: usize = lane(offset_of!(ShadowPixel, weight));
const P_SAMPLES: usize = lane(offset_of!(ShadowPixel, samples));
const P_OCCLUDED: usize = lane(offset_of!(ShadowPixel, occluded));
const P_DISTANCE: usize = lane(offset_of!(ShadowPixel, light_distance));
const P_SLOPE_MAX: usize = lane(offset_of!(ShadowPixel, slope_max));
const P_SLOPE_MIN: usize = lane(offset_of!(ShadowPixel, slope_min));
const P_SLOPE_SOURCE: usize = lane(offset_of!(ShadowPixel, slope_source));
const P_PIXEL_SIZE: usize = lane(offset_of!(ShadowPixel, pixel_size));
const P_TARGET: usize = lane(offset_of!(ShadowPixel, target));
const P_OBJECT: usize = lane(offset_of!(ShadowPixel, object));
const P_CENTRE_VISIBLE: usize = lane(offset_of!(ShadowPixel, centre_visible));
const P_OCCLUDER: usize = lane(offset_of!(ShadowPixel, occluder_distance));
const P_POSITION: usize = lane(offset_of!(ShadowPixel, position));
const P_NORMAL: usize = lane(offset_of!(ShadowPixel, normal));
const P_UNSHADOWED: usize = lane(offset_of!(ShadowPixel, unshadowed));
const I_IRRADIANCE: usize = lane(offset_of!(IndirectPixel, irradiance));
const I_SAMPLES: usize = lane(offset_of!(IndirectPixel, samples));
const I_ALBEDO: usize = lane(offset_of!(IndirectPixel, albedo));
const I_WEIGHT: usize = lane(offset_of!(IndirectPixel, weight));
const I_POSITION: usize = lane(offset_of!(IndirectPixel, position));
const I_Z_MIN: usize = lane(offset_of!(IndirectPixel, z_min));
const I_NORMAL: usize = lane(offset_of!(IndirectPixel, normal));
const I_Z_MAX: usize = lane(offset_of!(IndirectPixel, z_max));
const I_PIXEL_SIZE: usize = lane(offset_of!(IndirectPixel, pixel_size));
const I_TARGET: usize = lane(offset_of!(IndirectPixel, target));
const I_OBJECT: usize = lane(offset_of!(IndirectPixel, object));
const I_REFLECTORS: usize = lane(offset_of!(IndirectPixel, reflectors));
const I_BANDLIMIT: usize = lane(offset_of!(IndirectPixel, bandlimit));
const I_LOBE: usize = lane(offset_of!(IndirectPixel, lobe));
const L_SAMPLES: usize = lane(offset_of!(LightFieldPixel, samples));
const L_JITTER: usize = lane(offset_of!(LightFieldPixel, jitter));
const L_DIR1: usize = lane(offset_of!(LightFieldPixel, dir1));
const L_DIR2: usize = lane(offset_of!(LightFieldPixel, dir2));
const L_SCALE: usize = lane(offset_of!(LightFieldPixel, scale));
const L_COUNT: usize = lane(offset_of!(LightFieldPixel, count));
const L_SLOPES: usize = lane(offset_of!(LightFieldPixel, slopes));
const L_EXTRA_SAMPLES: usize = lane(offset_of!(LightFieldPixel, extra_samples));
const L_GREEN: usize = lane(offset_of!(LightFieldPixel, green));
const L_BLUE: usize = lane(offset_of!(LightFieldPixel, blue));
const L_POSITION: usize = lane(offset_of!(LightFieldPixel, position));
const L_NORMAL: usize = lane(offset_of!(LightFieldPixel, normal));
const L_EXTRA: usize = lane(offset_of!(LightFieldPixel, extra));
const K_ALBEDO: usize = lane(offset_of!(LensShadowPixel, albedo));
const K_GREEN: usize = lane(offset_of!(LensShadowPixel, albedo_green));
const K_BLUE: usize = lane(offset_of!(LensShadowPixel, albedo_blue));
const K_EXTRA: usize = lane(offset_of!(LensShadowPixel, albedo_extra));
const K_UNSHADOWED: usize = lane(offset_of!(LensShadowPixel, unshadowed));
const D_MEAN: usize = lane(offset_of!(DepthShift, mean));

/// The mean each lane of [`WelfordSums`] is the S_n of: (S_n lane, buffer of the mean, lane of
/// the mean). kernels/render/film.cl pairs them the same way (`welford` takes both); merging
/// S_n needs the means (Chan et al.), so a lane without its mean here could not be merged.
pub const WELFORD_MEANS: &[(usize, BufferId, usize)] = &[
    (S_DEPTH, DepthShifts, D_MEAN),
    (S_NORMAL, FilterVectors, F_NORMAL),
    (S_NORMAL + 1, FilterVectors, F_NORMAL + 1),
    (S_NORMAL + 2, FilterVectors, F_NORMAL + 2),
    (S_ALBEDO, FilterVectors, F_ALBEDO),
    (S_ALBEDO + 1, FilterVectors, F_ALBEDO + 1),
    (S_ALBEDO + 2, FilterVectors, F_ALBEDO + 2),
    (S_DIRECTION, WelfordState, W_DIRECTION),
    (S_DIRECTION + 1, WelfordState, W_DIRECTION + 1),
    (S_DIRECTION + 2, WelfordState, W_DIRECTION + 2),
    (S_ALBEDO2, FilterVectors, F_ALBEDO2),
    (S_ALBEDO2 + 1, FilterVectors, F_ALBEDO2 + 1),
    (S_ALBEDO2 + 2, FilterVectors, F_ALBEDO2 + 2),
];

/// Every output buffer, in the order of the megakernel's parameters.
pub const BUFFERS: &[BufferDecl] = &[
    BufferDecl {
        id: FilterVectors,
        name: "filter_vectors",
        element: "FilterVector",
        element_bytes: size_of::<FilterVector>(),
        per: Per::Pixel,
        merge: Merge::Means,
        doc: "FilterVector F per pixel (eq. 6.1, one float16, §6.2.1)",
    },
    BufferDecl {
        id: DepthShifts,
        name: "depth_shifts",
        element: "DepthShift",
        element_bytes: size_of::<DepthShift>(),
        per: Per::Pixel,
        merge: Merge::DepthShift,
        doc: "depth mean on shifted data per pixel (F.depth = shift + mean)",
    },
    BufferDecl {
        id: WelfordSums,
        name: "welford_sums",
        element: "WelfordSums",
        element_bytes: size_of::<WelfordSums>(),
        per: Per::Pixel,
        merge: Merge::WelfordSums,
        doc: "Welford S_n of every feature per pixel (the variance GBuffer, eq. 6.2)",
    },
    BufferDecl {
        id: WelfordState,
        name: "welford_state",
        element: "WelfordState",
        element_bytes: size_of::<WelfordState>(),
        per: Per::Pixel,
        merge: Merge::WelfordState,
        doc: "Welford state per pixel (mean direction, depth shift, Kahan compensation)",
    },
    BufferDecl {
        id: Positions,
        name: "positions",
        element: "float4",
        element_bytes: size_of::<Float4>(),
        per: Per::Pixel,
        merge: Merge::HitMeans,
        doc: "mean first-hit world position per pixel (xyz) and the samples that hit (w)",
    },
    BufferDecl {
        id: SampleVectors,
        name: "sample_vectors",
        element: "SampleVector",
        element_bytes: size_of::<SampleVector>(),
        per: Per::Sample,
        merge: Merge::PerSample,
        doc: "RPF sample vectors (26 floats per sample, thesis §5.1.1)",
    },
    BufferDecl {
        id: ShadowTerms,
        name: "shadow_terms",
        element: "ShadowTerms",
        element_bytes: size_of::<ShadowTerms>(),
        per: Per::Light,
        merge: Merge::Means,
        doc: "shadows: the direct light the filtered term replaces, per pixel and light",
    },
    BufferDecl {
        id: ShadowPixels,
        name: "shadow_pixels",
        element: "ShadowPixel",
        element_bytes: size_of::<ShadowPixel>(),
        per: Per::Light,
        merge: Merge::Identical,
        doc: "shadows: visibility sums, slopes and the pixel centre's hit, per pixel and light",
    },
    BufferDecl {
        id: OddHalves,
        name: "odd_halves",
        element: "float4",
        element_bytes: size_of::<Float4>(),
        per: Per::Pixel,
        merge: Merge::HitMeans,
        doc: "mean light of the odd-numbered samples per pixel (rgb) and how many (w)",
    },
    BufferDecl {
        id: LightFieldPixels,
        name: "light_field",
        element: "LightFieldPixel",
        element_bytes: size_of::<LightFieldPixel>(),
        per: Per::Light,
        merge: Merge::Identical,
        doc: "sheared filtering: l x l light (shadows, per pixel and light) or lens (depth of \
              field) samples, jitter, axes on screen, slopes",
    },
    BufferDecl {
        id: IndirectPixels,
        name: "indirect_pixels",
        element: "IndirectPixel",
        element_bytes: size_of::<IndirectPixel>(),
        per: Per::Pixel,
        merge: Merge::Identical,
        doc: "AAF indirect: demodulated indirect sums, z_min, z_max and the centre's hit, per pixel",
    },
    BufferDecl {
        id: LensFieldPixels,
        name: "lens_field",
        element: "LightFieldPixel",
        element_bytes: size_of::<LightFieldPixel>(),
        per: Per::Pixel,
        merge: Merge::Identical,
        doc: "sheared shadows with depth of field: the lens field, each sample's light less the \
              filtered lights' direct term on the receiver",
    },
    BufferDecl {
        id: LensShadowPixels,
        name: "lens_shadow",
        element: "LensShadowPixel",
        element_bytes: size_of::<LensShadowPixel>(),
        per: Per::Pixel,
        merge: Merge::Identical,
        doc: "sheared shadows with depth of field: each lens sample's albedo and each light's \
              unoccluded term",
    },
    BufferDecl {
        id: FirstEmission,
        name: "first_emission",
        element: "float4",
        element_bytes: size_of::<Float4>(),
        per: Per::Pixel,
        merge: Merge::Means,
        doc: "mean light of emitters seen directly per pixel (rgb) and the share of samples \
              whose camera ray hit an emitter (w)",
    },
    BufferDecl {
        id: OddEmission,
        name: "odd_emission",
        element: "float4",
        element_bytes: size_of::<Float4>(),
        per: Per::Pixel,
        merge: Merge::HitMeans,
        doc: "mean light of emitters seen directly by the odd-numbered samples (rgb) and how \
              many (w)",
    },
];

/// Every output. The AOV file lists the channels in this order.
// `BASE + 0` beside `BASE + 1`, ... keeps each channel's float offset readable as a column.
#[allow(clippy::identity_op)]
pub const OUTPUTS: &[OutputDecl] = &[
    OutputDecl {
        output: Output::Colour,
        name: "colour",
        switch: None,
        requires: &[],
        buffers: &[FilterVectors],
        channels: &[
            ch("direct.R", FilterVectors, F_DIRECT),
            ch("direct.G", FilterVectors, F_DIRECT + 1),
            ch("direct.B", FilterVectors, F_DIRECT + 2),
            ch("indirect.R", FilterVectors, F_INDIRECT),
            ch("indirect.G", FilterVectors, F_INDIRECT + 1),
            ch("indirect.B", FilterVectors, F_INDIRECT + 2),
        ],
        doc: "mean direct and indirect light (eq. 6.1)",
    },
    OutputDecl {
        output: Output::Features,
        name: "features",
        switch: Some("OUTPUT_FEATURES"),
        requires: &[Output::Colour],
        buffers: &[DepthShifts],
        channels: &[
            ch("depth.Z", FilterVectors, F_DEPTH),
            ch("normal.X", FilterVectors, F_NORMAL),
            ch("normal.Y", FilterVectors, F_NORMAL + 1),
            ch("normal.Z", FilterVectors, F_NORMAL + 2),
            ch("albedo.R", FilterVectors, F_ALBEDO),
            ch("albedo.G", FilterVectors, F_ALBEDO + 1),
            ch("albedo.B", FilterVectors, F_ALBEDO + 2),
            ch("albedo2.R", FilterVectors, F_ALBEDO2),
            ch("albedo2.G", FilterVectors, F_ALBEDO2 + 1),
            ch("albedo2.B", FilterVectors, F_ALBEDO2 + 2),
        ],
        doc: "mean first-hit depth, normal, albedo and albedo2 (eq. 6.1)",
    },
    OutputDecl {
        output: Output::Variance,
        name: "variance",
        switch: Some("OUTPUT_VARIANCE"),
        requires: &[Output::Features],
        buffers: &[WelfordSums, WelfordState],
        channels: &[
            ch("direction.X", WelfordState, W_DIRECTION),
            ch("direction.Y", WelfordState, W_DIRECTION + 1),
            ch("direction.Z", WelfordState, W_DIRECTION + 2),
            var("var.depth", S_DEPTH),
            var("var.normal.X", S_NORMAL),
            var("var.normal.Y", S_NORMAL + 1),
            var("var.normal.Z", S_NORMAL + 2),
            var("var.albedo.R", S_ALBEDO),
            var("var.albedo.G", S_ALBEDO + 1),
            var("var.albedo.B", S_ALBEDO + 2),
            var("var.direction.X", S_DIRECTION),
            var("var.direction.Y", S_DIRECTION + 1),
            var("var.direction.Z", S_DIRECTION + 2),
            var("var.albedo2.R", S_ALBEDO2),
            var("var.albedo2.G", S_ALBEDO2 + 1),
            var("var.albedo2.B", S_ALBEDO2 + 2),
        ],
        doc: "feature variances (eq. 6.2) and the mean first-bounce direction",
    },
    OutputDecl {
        output: Output::Position,
        name: "position",
        switch: Some("OUTPUT_POSITION"),
        requires: &[Output::Colour],
        buffers: &[Positions],
        channels: &[
            ch("position.X", Positions, 0),
            ch("position.Y", Positions, 1),
            ch("position.Z", Positions, 2),
            ch("position.hits", Positions, 3),
        ],
        doc: "mean first-hit world position (over the samples that hit a surface)",
    },
    OutputDecl {
        output: Output::Samples,
        name: "samples",
        switch: Some("OUTPUT_SAMPLES"),
        requires: &[Output::Features],
        buffers: &[SampleVectors],
        channels: &[],
        doc: "every sample's RPF vector (thesis §5.1.1); kept in a samples file, not the AOVs",
    },
    OutputDecl {
        output: Output::Shadows,
        name: "shadows",
        switch: Some("OUTPUT_SHADOWS"),
        requires: &[Output::Colour],
        buffers: &[ShadowTerms, ShadowPixels],
        channels: &[
            ch("shadow.direct.R", ShadowTerms, T_DIRECT),
            ch("shadow.direct.G", ShadowTerms, T_DIRECT + 1),
            ch("shadow.direct.B", ShadowTerms, T_DIRECT + 2),
            ch("shadow.r.R", ShadowTerms, T_UNSHADOWED),
            ch("shadow.r.G", ShadowTerms, T_UNSHADOWED + 1),
            ch("shadow.r.B", ShadowTerms, T_UNSHADOWED + 2),
            ch("shadow.visible", ShadowPixels, P_VISIBLE),
            ch("shadow.weight", ShadowPixels, P_WEIGHT),
            ch("shadow.samples", ShadowPixels, P_SAMPLES),
            ch("shadow.occluded", ShadowPixels, P_OCCLUDED),
            ch("shadow.light_distance", ShadowPixels, P_DISTANCE),
            ch("shadow.slope_max", ShadowPixels, P_SLOPE_MAX),
            ch("shadow.slope_min", ShadowPixels, P_SLOPE_MIN),
            ch("shadow.slope_source", ShadowPixels, P_SLOPE_SOURCE),
            ch("shadow.pixel_size", ShadowPixels, P_PIXEL_SIZE),
            ch("shadow.target", ShadowPixels, P_TARGET),
            ch("shadow.object", ShadowPixels, P_OBJECT),
            ch("shadow.centre_visible", ShadowPixels, P_CENTRE_VISIBLE),
            ch("shadow.occluder_distance", ShadowPixels, P_OCCLUDER),
            ch("shadow.position.X", ShadowPixels, P_POSITION),
            ch("shadow.position.Y", ShadowPixels, P_POSITION + 1),
            ch("shadow.position.Z", ShadowPixels, P_POSITION + 2),
            ch("shadow.normal.X", ShadowPixels, P_NORMAL),
            ch("shadow.normal.Y", ShadowPixels, P_NORMAL + 1),
            ch("shadow.normal.Z", ShadowPixels, P_NORMAL + 2),
            ch("shadow.unshadowed.R", ShadowPixels, P_UNSHADOWED),
            ch("shadow.unshadowed.G", ShadowPixels, P_UNSHADOWED + 1),
            ch("shadow.unshadowed.B", ShadowPixels, P_UNSHADOWED + 2),
        ],
        // One plane per light: the channels are named `shadow.l<light>.<rest>` for the scene's
        // sphere light of each plane ([`channel_name`]).
        doc: "soft shadows of sphere lights: unshadowed term, visibility sums, slopes, the \
              centre's binary visibility (one plane per light)",
    },
    OutputDecl {
        output: Output::Halves,
        name: "halves",
        switch: Some("OUTPUT_HALVES"),
        requires: &[Output::Colour],
        buffers: &[OddHalves],
        channels: &[
            ch("odd.R", OddHalves, 0),
            ch("odd.G", OddHalves, 1),
            ch("odd.B", OddHalves, 2),
            ch("odd.samples", OddHalves, 3),
        ],
        doc: "mean light of the odd-numbered samples (with F: the two half buffers)",
    },
    OutputDecl {
        output: Output::LightField,
        name: "light-field",
        switch: Some("OUTPUT_LIGHT_FIELD"),
        // Soft shadows ask for the shadow output beside it (src/filters/sheared); depth of
        // field needs the colour alone.
        requires: &[Output::Colour],
        buffers: &[LightFieldPixels],
        channels: &[
            ch("lightfield.f00", LightFieldPixels, L_SAMPLES),
            ch("lightfield.f01", LightFieldPixels, L_SAMPLES + 1),
            ch("lightfield.f02", LightFieldPixels, L_SAMPLES + 2),
            ch("lightfield.f03", LightFieldPixels, L_SAMPLES + 3),
            ch("lightfield.f04", LightFieldPixels, L_SAMPLES + 4),
            ch("lightfield.f05", LightFieldPixels, L_SAMPLES + 5),
            ch("lightfield.f06", LightFieldPixels, L_SAMPLES + 6),
            ch("lightfield.f07", LightFieldPixels, L_SAMPLES + 7),
            ch("lightfield.f08", LightFieldPixels, L_SAMPLES + 8),
            ch("lightfield.f09", LightFieldPixels, L_SAMPLES + 9),
            ch("lightfield.f10", LightFieldPixels, L_SAMPLES + 10),
            ch("lightfield.f11", LightFieldPixels, L_SAMPLES + 11),
            ch("lightfield.f12", LightFieldPixels, L_SAMPLES + 12),
            ch("lightfield.f13", LightFieldPixels, L_SAMPLES + 13),
            ch("lightfield.f14", LightFieldPixels, L_SAMPLES + 14),
            ch("lightfield.f15", LightFieldPixels, L_SAMPLES + 15),
            ch("lightfield.jitter.U", LightFieldPixels, L_JITTER),
            ch("lightfield.jitter.V", LightFieldPixels, L_JITTER + 1),
            ch("lightfield.dir1.X", LightFieldPixels, L_DIR1),
            ch("lightfield.dir1.Y", LightFieldPixels, L_DIR1 + 1),
            ch("lightfield.dir2.X", LightFieldPixels, L_DIR2),
            ch("lightfield.dir2.Y", LightFieldPixels, L_DIR2 + 1),
            ch("lightfield.scale.X", LightFieldPixels, L_SCALE),
            ch("lightfield.scale.Y", LightFieldPixels, L_SCALE + 1),
            ch("lightfield.count", LightFieldPixels, L_COUNT),
            ch("lightfield.slope.min", LightFieldPixels, L_SLOPES),
            ch("lightfield.slope.max", LightFieldPixels, L_SLOPES + 1),
            ch("lightfield.extra", LightFieldPixels, L_EXTRA_SAMPLES),
            ch("lightfield.g00", LightFieldPixels, L_GREEN),
            ch("lightfield.g01", LightFieldPixels, L_GREEN + 1),
            ch("lightfield.g02", LightFieldPixels, L_GREEN + 2),
            ch("lightfield.g03", LightFieldPixels, L_GREEN + 3),
            ch("lightfield.g04", LightFieldPixels, L_GREEN + 4),
            ch("lightfield.g05", LightFieldPixels, L_GREEN + 5),
            ch("lightfield.g06", LightFieldPixels, L_GREEN + 6),
            ch("lightfield.g07", LightFieldPixels, L_GREEN + 7),
            ch("lightfield.g08", LightFieldPixels, L_GREEN + 8),
            ch("lightfield.g09", LightFieldPixels, L_GREEN + 9),
            ch("lightfield.g10", LightFieldPixels, L_GREEN + 10),
            ch("lightfield.g11", LightFieldPixels, L_GREEN + 11),
            ch("lightfield.g12", LightFieldPixels, L_GREEN + 12),
            ch("lightfield.g13", LightFieldPixels, L_GREEN + 13),
            ch("lightfield.g14", LightFieldPixels, L_GREEN + 14),
            ch("lightfield.g15", LightFieldPixels, L_GREEN + 15),
            ch("lightfield.b00", LightFieldPixels, L_BLUE),
            ch("lightfield.b01", LightFieldPixels, L_BLUE + 1),
            ch("lightfield.b02", LightFieldPixels, L_BLUE + 2),
            ch("lightfield.b03", LightFieldPixels, L_BLUE + 3),
            ch("lightfield.b04", LightFieldPixels, L_BLUE + 4),
            ch("lightfield.b05", LightFieldPixels, L_BLUE + 5),
            ch("lightfield.b06", LightFieldPixels, L_BLUE + 6),
            ch("lightfield.b07", LightFieldPixels, L_BLUE + 7),
            ch("lightfield.b08", LightFieldPixels, L_BLUE + 8),
            ch("lightfield.b09", LightFieldPixels, L_BLUE + 9),
            ch("lightfield.b10", LightFieldPixels, L_BLUE + 10),
            ch("lightfield.b11", LightFieldPixels, L_BLUE + 11),
            ch("lightfield.b12", LightFieldPixels, L_BLUE + 12),
            ch("lightfield.b13", LightFieldPixels, L_BLUE + 13),
            ch("lightfield.b14", LightFieldPixels, L_BLUE + 14),
            ch("lightfield.b15", LightFieldPixels, L_BLUE + 15),
            ch("lightfield.position.X", LightFieldPixels, L_POSITION),
            ch("lightfield.position.Y", LightFieldPixels, L_POSITION + 1),
            ch("lightfield.position.Z", LightFieldPixels, L_POSITION + 2),
            ch("lightfield.normal.X", LightFieldPixels, L_NORMAL),
            ch("lightfield.normal.Y", LightFieldPixels, L_NORMAL + 1),
            ch("lightfield.normal.Z", LightFieldPixels, L_NORMAL + 2),
            ch("lightfield.extra.R", LightFieldPixels, L_EXTRA),
            ch("lightfield.extra.G", LightFieldPixels, L_EXTRA + 1),
            ch("lightfield.extra.B", LightFieldPixels, L_EXTRA + 2),
            ch("lightfield.extra.W", LightFieldPixels, L_EXTRA + 3),
        ],
        doc: "sheared filtering: the 4-D light field (l x l samples per pixel) of each shadow \
              light or, with a thin lens, of the lens",
    },
    OutputDecl {
        output: Output::Indirect,
        name: "indirect",
        switch: Some("OUTPUT_INDIRECT"),
        requires: &[Output::Colour],
        buffers: &[IndirectPixels],
        channels: &[
            ch("indirect.irradiance.R", IndirectPixels, I_IRRADIANCE),
            ch("indirect.irradiance.G", IndirectPixels, I_IRRADIANCE + 1),
            ch("indirect.irradiance.B", IndirectPixels, I_IRRADIANCE + 2),
            ch("indirect.samples", IndirectPixels, I_SAMPLES),
            ch("indirect.albedo.R", IndirectPixels, I_ALBEDO),
            ch("indirect.albedo.G", IndirectPixels, I_ALBEDO + 1),
            ch("indirect.albedo.B", IndirectPixels, I_ALBEDO + 2),
            ch("indirect.weight", IndirectPixels, I_WEIGHT),
            ch("indirect.position.X", IndirectPixels, I_POSITION),
            ch("indirect.position.Y", IndirectPixels, I_POSITION + 1),
            ch("indirect.position.Z", IndirectPixels, I_POSITION + 2),
            ch("indirect.z_min", IndirectPixels, I_Z_MIN),
            ch("indirect.normal.X", IndirectPixels, I_NORMAL),
            ch("indirect.normal.Y", IndirectPixels, I_NORMAL + 1),
            ch("indirect.normal.Z", IndirectPixels, I_NORMAL + 2),
            ch("indirect.z_max", IndirectPixels, I_Z_MAX),
            ch("indirect.pixel_size", IndirectPixels, I_PIXEL_SIZE),
            ch("indirect.target", IndirectPixels, I_TARGET),
            ch("indirect.object", IndirectPixels, I_OBJECT),
            ch("indirect.reflectors", IndirectPixels, I_REFLECTORS),
            ch("indirect.bandlimit", IndirectPixels, I_BANDLIMIT),
            ch("indirect.lobe", IndirectPixels, I_LOBE),
        ],
        doc: "indirect light of diffuse and glossy receivers: demodulated indirect samples of \
              the centre's receiver, z_min, z_max, pixel size, bandlimit, lobe (AAF ch. 4)",
    },
    OutputDecl {
        output: Output::LensShadows,
        name: "lens-shadows",
        switch: Some("OUTPUT_LENS_SHADOWS"),
        // The shadow passes give each pixel centre's receiver and its shadow fields (in the
        // light-field output); the lens pass reads the receiver.
        requires: &[Output::Colour, Output::Shadows, Output::LightField],
        buffers: &[LensFieldPixels, LensShadowPixels],
        channels: &[
            ch("lens.f00", LensFieldPixels, L_SAMPLES + 0),
            ch("lens.f01", LensFieldPixels, L_SAMPLES + 1),
            ch("lens.f02", LensFieldPixels, L_SAMPLES + 2),
            ch("lens.f03", LensFieldPixels, L_SAMPLES + 3),
            ch("lens.f04", LensFieldPixels, L_SAMPLES + 4),
            ch("lens.f05", LensFieldPixels, L_SAMPLES + 5),
            ch("lens.f06", LensFieldPixels, L_SAMPLES + 6),
            ch("lens.f07", LensFieldPixels, L_SAMPLES + 7),
            ch("lens.f08", LensFieldPixels, L_SAMPLES + 8),
            ch("lens.f09", LensFieldPixels, L_SAMPLES + 9),
            ch("lens.f10", LensFieldPixels, L_SAMPLES + 10),
            ch("lens.f11", LensFieldPixels, L_SAMPLES + 11),
            ch("lens.f12", LensFieldPixels, L_SAMPLES + 12),
            ch("lens.f13", LensFieldPixels, L_SAMPLES + 13),
            ch("lens.f14", LensFieldPixels, L_SAMPLES + 14),
            ch("lens.f15", LensFieldPixels, L_SAMPLES + 15),
            ch("lens.g00", LensFieldPixels, L_GREEN + 0),
            ch("lens.g01", LensFieldPixels, L_GREEN + 1),
            ch("lens.g02", LensFieldPixels, L_GREEN + 2),
            ch("lens.g03", LensFieldPixels, L_GREEN + 3),
            ch("lens.g04", LensFieldPixels, L_GREEN + 4),
            ch("lens.g05", LensFieldPixels, L_GREEN + 5),
            ch("lens.g06", LensFieldPixels, L_GREEN + 6),
            ch("lens.g07", LensFieldPixels, L_GREEN + 7),
            ch("lens.g08", LensFieldPixels, L_GREEN + 8),
            ch("lens.g09", LensFieldPixels, L_GREEN + 9),
            ch("lens.g10", LensFieldPixels, L_GREEN + 10),
            ch("lens.g11", LensFieldPixels, L_GREEN + 11),
            ch("lens.g12", LensFieldPixels, L_GREEN + 12),
            ch("lens.g13", LensFieldPixels, L_GREEN + 13),
            ch("lens.g14", LensFieldPixels, L_GREEN + 14),
            ch("lens.g15", LensFieldPixels, L_GREEN + 15),
            ch("lens.b00", LensFieldPixels, L_BLUE + 0),
            ch("lens.b01", LensFieldPixels, L_BLUE + 1),
            ch("lens.b02", LensFieldPixels, L_BLUE + 2),
            ch("lens.b03", LensFieldPixels, L_BLUE + 3),
            ch("lens.b04", LensFieldPixels, L_BLUE + 4),
            ch("lens.b05", LensFieldPixels, L_BLUE + 5),
            ch("lens.b06", LensFieldPixels, L_BLUE + 6),
            ch("lens.b07", LensFieldPixels, L_BLUE + 7),
            ch("lens.b08", LensFieldPixels, L_BLUE + 8),
            ch("lens.b09", LensFieldPixels, L_BLUE + 9),
            ch("lens.b10", LensFieldPixels, L_BLUE + 10),
            ch("lens.b11", LensFieldPixels, L_BLUE + 11),
            ch("lens.b12", LensFieldPixels, L_BLUE + 12),
            ch("lens.b13", LensFieldPixels, L_BLUE + 13),
            ch("lens.b14", LensFieldPixels, L_BLUE + 14),
            ch("lens.b15", LensFieldPixels, L_BLUE + 15),
            ch("lens.jitter.U", LensFieldPixels, L_JITTER),
            ch("lens.jitter.V", LensFieldPixels, L_JITTER + 1),
            ch("lens.dir1.X", LensFieldPixels, L_DIR1),
            ch("lens.dir1.Y", LensFieldPixels, L_DIR1 + 1),
            ch("lens.dir2.X", LensFieldPixels, L_DIR2),
            ch("lens.dir2.Y", LensFieldPixels, L_DIR2 + 1),
            ch("lens.scale.X", LensFieldPixels, L_SCALE),
            ch("lens.scale.Y", LensFieldPixels, L_SCALE + 1),
            ch("lens.count", LensFieldPixels, L_COUNT),
            ch("lens.slope.min", LensFieldPixels, L_SLOPES),
            ch("lens.slope.max", LensFieldPixels, L_SLOPES + 1),
            ch("lens.extra", LensFieldPixels, L_EXTRA_SAMPLES),
            ch("lens.position.X", LensFieldPixels, L_POSITION),
            ch("lens.position.Y", LensFieldPixels, L_POSITION + 1),
            ch("lens.position.Z", LensFieldPixels, L_POSITION + 2),
            ch("lens.normal.X", LensFieldPixels, L_NORMAL),
            ch("lens.normal.Y", LensFieldPixels, L_NORMAL + 1),
            ch("lens.normal.Z", LensFieldPixels, L_NORMAL + 2),
            ch("lens.extra.R", LensFieldPixels, L_EXTRA),
            ch("lens.extra.G", LensFieldPixels, L_EXTRA + 1),
            ch("lens.extra.B", LensFieldPixels, L_EXTRA + 2),
            ch("lens.extra.W", LensFieldPixels, L_EXTRA + 3),
            ch("lensshadow.albedo.r00", LensShadowPixels, K_ALBEDO + 0),
            ch("lensshadow.albedo.r01", LensShadowPixels, K_ALBEDO + 1),
            ch("lensshadow.albedo.r02", LensShadowPixels, K_ALBEDO + 2),
            ch("lensshadow.albedo.r03", LensShadowPixels, K_ALBEDO + 3),
            ch("lensshadow.albedo.r04", LensShadowPixels, K_ALBEDO + 4),
            ch("lensshadow.albedo.r05", LensShadowPixels, K_ALBEDO + 5),
            ch("lensshadow.albedo.r06", LensShadowPixels, K_ALBEDO + 6),
            ch("lensshadow.albedo.r07", LensShadowPixels, K_ALBEDO + 7),
            ch("lensshadow.albedo.r08", LensShadowPixels, K_ALBEDO + 8),
            ch("lensshadow.albedo.r09", LensShadowPixels, K_ALBEDO + 9),
            ch("lensshadow.albedo.r10", LensShadowPixels, K_ALBEDO + 10),
            ch("lensshadow.albedo.r11", LensShadowPixels, K_ALBEDO + 11),
            ch("lensshadow.albedo.r12", LensShadowPixels, K_ALBEDO + 12),
            ch("lensshadow.albedo.r13", LensShadowPixels, K_ALBEDO + 13),
            ch("lensshadow.albedo.r14", LensShadowPixels, K_ALBEDO + 14),
            ch("lensshadow.albedo.r15", LensShadowPixels, K_ALBEDO + 15),
            ch("lensshadow.albedo.g00", LensShadowPixels, K_GREEN + 0),
            ch("lensshadow.albedo.g01", LensShadowPixels, K_GREEN + 1),
            ch("lensshadow.albedo.g02", LensShadowPixels, K_GREEN + 2),
            ch("lensshadow.albedo.g03", LensShadowPixels, K_GREEN + 3),
            ch("lensshadow.albedo.g04", LensShadowPixels, K_GREEN + 4),
            ch("lensshadow.albedo.g05", LensShadowPixels, K_GREEN + 5),
            ch("lensshadow.albedo.g06", LensShadowPixels, K_GREEN + 6),
            ch("lensshadow.albedo.g07", LensShadowPixels, K_GREEN + 7),
            ch("lensshadow.albedo.g08", LensShadowPixels, K_GREEN + 8),
            ch("lensshadow.albedo.g09", LensShadowPixels, K_GREEN + 9),
            ch("lensshadow.albedo.g10", LensShadowPixels, K_GREEN + 10),
            ch("lensshadow.albedo.g11", LensShadowPixels, K_GREEN + 11),
            ch("lensshadow.albedo.g12", LensShadowPixels, K_GREEN + 12),
            ch("lensshadow.albedo.g13", LensShadowPixels, K_GREEN + 13),
            ch("lensshadow.albedo.g14", LensShadowPixels, K_GREEN + 14),
            ch("lensshadow.albedo.g15", LensShadowPixels, K_GREEN + 15),
            ch("lensshadow.albedo.b00", LensShadowPixels, K_BLUE + 0),
            ch("lensshadow.albedo.b01", LensShadowPixels, K_BLUE + 1),
            ch("lensshadow.albedo.b02", LensShadowPixels, K_BLUE + 2),
            ch("lensshadow.albedo.b03", LensShadowPixels, K_BLUE + 3),
            ch("lensshadow.albedo.b04", LensShadowPixels, K_BLUE + 4),
            ch("lensshadow.albedo.b05", LensShadowPixels, K_BLUE + 5),
            ch("lensshadow.albedo.b06", LensShadowPixels, K_BLUE + 6),
            ch("lensshadow.albedo.b07", LensShadowPixels, K_BLUE + 7),
            ch("lensshadow.albedo.b08", LensShadowPixels, K_BLUE + 8),
            ch("lensshadow.albedo.b09", LensShadowPixels, K_BLUE + 9),
            ch("lensshadow.albedo.b10", LensShadowPixels, K_BLUE + 10),
            ch("lensshadow.albedo.b11", LensShadowPixels, K_BLUE + 11),
            ch("lensshadow.albedo.b12", LensShadowPixels, K_BLUE + 12),
            ch("lensshadow.albedo.b13", LensShadowPixels, K_BLUE + 13),
            ch("lensshadow.albedo.b14", LensShadowPixels, K_BLUE + 14),
            ch("lensshadow.albedo.b15", LensShadowPixels, K_BLUE + 15),
            ch("lensshadow.albedo.extra.R", LensShadowPixels, K_EXTRA + 0),
            ch("lensshadow.albedo.extra.G", LensShadowPixels, K_EXTRA + 1),
            ch("lensshadow.albedo.extra.B", LensShadowPixels, K_EXTRA + 2),
            ch(
                "lensshadow.unshadowed0.R",
                LensShadowPixels,
                K_UNSHADOWED + 0,
            ),
            ch(
                "lensshadow.unshadowed0.G",
                LensShadowPixels,
                K_UNSHADOWED + 1,
            ),
            ch(
                "lensshadow.unshadowed0.B",
                LensShadowPixels,
                K_UNSHADOWED + 2,
            ),
            ch(
                "lensshadow.unshadowed0.W",
                LensShadowPixels,
                K_UNSHADOWED + 3,
            ),
            ch(
                "lensshadow.unshadowed1.R",
                LensShadowPixels,
                K_UNSHADOWED + 4,
            ),
            ch(
                "lensshadow.unshadowed1.G",
                LensShadowPixels,
                K_UNSHADOWED + 5,
            ),
            ch(
                "lensshadow.unshadowed1.B",
                LensShadowPixels,
                K_UNSHADOWED + 6,
            ),
            ch(
                "lensshadow.unshadowed1.W",
                LensShadowPixels,
                K_UNSHADOWED + 7,
            ),
            ch(
                "lensshadow.unshadowed2.R",
                LensShadowPixels,
                K_UNSHADOWED + 8,
            ),
            ch(
                "lensshadow.unshadowed2.G",
                LensShadowPixels,
                K_UNSHADOWED + 9,
            ),
            ch(
                "lensshadow.unshadowed2.B",
                LensShadowPixels,
                K_UNSHADOWED + 10,
            ),
            ch(
                "lensshadow.unshadowed2.W",
                LensShadowPixels,
                K_UNSHADOWED + 11,
            ),
            ch(
                "lensshadow.unshadowed3.R",
                LensShadowPixels,
                K_UNSHADOWED + 12,
            ),
            ch(
                "lensshadow.unshadowed3.G",
                LensShadowPixels,
                K_UNSHADOWED + 13,
            ),
            ch(
                "lensshadow.unshadowed3.B",
                LensShadowPixels,
                K_UNSHADOWED + 14,
            ),
            ch(
                "lensshadow.unshadowed3.W",
                LensShadowPixels,
                K_UNSHADOWED + 15,
            ),
            ch(
                "lensshadow.unshadowed4.R",
                LensShadowPixels,
                K_UNSHADOWED + 16,
            ),
            ch(
                "lensshadow.unshadowed4.G",
                LensShadowPixels,
                K_UNSHADOWED + 17,
            ),
            ch(
                "lensshadow.unshadowed4.B",
                LensShadowPixels,
                K_UNSHADOWED + 18,
            ),
            ch(
                "lensshadow.unshadowed4.W",
                LensShadowPixels,
                K_UNSHADOWED + 19,
            ),
            ch(
                "lensshadow.unshadowed5.R",
                LensShadowPixels,
                K_UNSHADOWED + 20,
            ),
            ch(
                "lensshadow.unshadowed5.G",
                LensShadowPixels,
                K_UNSHADOWED + 21,
            ),
            ch(
                "lensshadow.unshadowed5.B",
                LensShadowPixels,
                K_UNSHADOWED + 22,
            ),
            ch(
                "lensshadow.unshadowed5.W",
                LensShadowPixels,
                K_UNSHADOWED + 23,
            ),
            ch(
                "lensshadow.unshadowed6.R",
                LensShadowPixels,
                K_UNSHADOWED + 24,
            ),
            ch(
                "lensshadow.unshadowed6.G",
                LensShadowPixels,
                K_UNSHADOWED + 25,
            ),
            ch(
                "lensshadow.unshadowed6.B",
                LensShadowPixels,
                K_UNSHADOWED + 26,
            ),
            ch(
                "lensshadow.unshadowed6.W",
                LensShadowPixels,
                K_UNSHADOWED + 27,
            ),
            ch(
                "lensshadow.unshadowed7.R",
                LensShadowPixels,
                K_UNSHADOWED + 28,
            ),
            ch(
                "lensshadow.unshadowed7.G",
                LensShadowPixels,
                K_UNSHADOWED + 29,
            ),
            ch(
                "lensshadow.unshadowed7.B",
                LensShadowPixels,
                K_UNSHADOWED + 30,
            ),
            ch(
                "lensshadow.unshadowed7.W",
                LensShadowPixels,
                K_UNSHADOWED + 31,
            ),
        ],
        doc: "sheared soft shadows with depth of field (Yan et al.'s appendix): the lens field \
              less the filtered lights' direct term, each lens sample's albedo, the lights' \
              unoccluded terms",
    },
    OutputDecl {
        output: Output::Emission,
        name: "emission",
        switch: Some("OUTPUT_EMISSION"),
        requires: &[Output::Colour],
        buffers: &[FirstEmission, OddEmission],
        channels: &[
            ch("emitted.R", FirstEmission, 0),
            ch("emitted.G", FirstEmission, 1),
            ch("emitted.B", FirstEmission, 2),
            ch("emitted.share", FirstEmission, 3),
            ch("emitted_odd.R", OddEmission, 0),
            ch("emitted_odd.G", OddEmission, 1),
            ch("emitted_odd.B", OddEmission, 2),
            ch("emitted_odd.samples", OddEmission, 3),
        ],
        doc: "mean light of emitters seen directly (part of F's direct light), the share of \
              samples whose camera ray hit an emitter, and the mean of the odd-numbered samples \
              alone (the emission's half buffers, as the halves output's)",
    },
];

impl Output {
    pub fn decl(self) -> &'static OutputDecl {
        OUTPUTS
            .iter()
            .find(|o| o.output == self)
            .expect("every output is in OUTPUTS")
    }

    pub fn name(self) -> &'static str {
        self.decl().name
    }

    fn bit(self) -> u32 {
        1 << (self as u32)
    }
}

impl BufferId {
    pub fn decl(self) -> &'static BufferDecl {
        BUFFERS
            .iter()
            .find(|b| b.id == self)
            .expect("every buffer is in BUFFERS")
    }

    /// The output that owns this buffer.
    pub fn owner(self) -> Output {
        OUTPUTS
            .iter()
            .find(|o| o.buffers.contains(&self))
            .expect("every buffer has an owner")
            .output
    }
}

/// What the light-field output holds (Yan et al. 2015 §3.1: one output, three integrands).
/// The renderer decides it, not the filter that reads it: with the shadow output beside it,
/// one shadow field per sphere light plane (src/render/shadows/light_field.rs); without it,
/// the GI field over the v-plane when its sampling asks for it
/// (`ShadowSampling::light_field_gi`, src/render/gi_field.rs), else the lens field
/// (src/render/lens_field.rs). An [`OutputSet`] records it, so that a frame, an AOV file and
/// a film say which field they hold and a filter that reads another one is refused (or the
/// viewer gathers again) instead of filtering the wrong samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FieldKind {
    /// Visibility of each filtered sphere light (sheared soft shadows).
    Shadows,
    /// Radiance through the thin lens (sheared depth of field).
    Lens,
    /// Indirect radiance over the v-plane (sheared diffuse indirect light).
    Gi,
}

impl FieldKind {
    pub const ALL: [FieldKind; 3] = [FieldKind::Shadows, FieldKind::Lens, FieldKind::Gi];

    /// The name AOV and partial files record (`light_field = "gi"`).
    pub fn name(self) -> &'static str {
        match self {
            FieldKind::Shadows => "shadows",
            FieldKind::Lens => "lens",
            FieldKind::Gi => "gi",
        }
    }

    pub fn parse(name: &str) -> Option<FieldKind> {
        FieldKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// What the field is, for messages.
    pub fn describe(self) -> &'static str {
        match self {
            FieldKind::Shadows => {
                "its sphere lights' shadow fields (the shadow output was gathered)"
            }
            FieldKind::Lens => "the lens field (depth of field)",
            FieldKind::Gi => "the v-plane field (diffuse indirect light)",
        }
    }

    /// The bits of [`OutputSet`] that record a kind the shadow output does not imply.
    fn bits(self) -> u32 {
        match self {
            FieldKind::Shadows => 0,
            FieldKind::Lens => 1 << FIELD_SHIFT,
            FieldKind::Gi => 2 << FIELD_SHIFT,
        }
    }
}

/// Where [`OutputSet`] keeps the recorded [`FieldKind`] (above every output's bit).
const FIELD_SHIFT: u32 = 24;
const FIELD_MASK: u32 = 3 << FIELD_SHIFT;

/// A set of outputs, and what its light-field output holds ([`OutputSet::light_field`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct OutputSet(u32);

impl OutputSet {
    /// Colour only: what every render writes.
    pub fn colour() -> OutputSet {
        OutputSet::of(&[Output::Colour])
    }

    /// Exactly these outputs (what a filter reads, what a file holds).
    pub fn of(outputs: &[Output]) -> OutputSet {
        outputs.iter().fold(OutputSet::default(), |s, &o| s.with(o))
    }

    /// This set and `o`.
    pub fn with(self, o: Output) -> OutputSet {
        OutputSet(self.0 | o.bit())
    }

    /// This set with everything its outputs need to be computed, colour always: what the
    /// megakernel must be built with (the sample vectors reuse the features, the variances
    /// update the feature means).
    pub fn closed(self) -> OutputSet {
        let mut s = self.with(Output::Colour);
        loop {
            let next = s
                .iter()
                .flat_map(|o| o.decl().requires.iter().copied())
                .fold(s, |acc, r| acc.with(r));
            if next == s {
                return s;
            }
            s = next;
        }
    }

    /// Both sets; the light field's recorded kind is this set's, else `other`'s.
    pub fn union(self, other: OutputSet) -> OutputSet {
        let kind = if self.0 & FIELD_MASK != 0 {
            self.0
        } else {
            other.0
        } & FIELD_MASK;
        OutputSet((self.0 | other.0) & !FIELD_MASK | kind)
    }

    pub fn contains(self, o: Output) -> bool {
        self.0 & o.bit() != 0
    }

    /// This set with the light-field output holding `kind` (with [`FieldKind::Shadows`], the
    /// shadow output too: the renderer puts shadow fields there exactly when it gathers it).
    pub fn with_field(self, kind: FieldKind) -> OutputSet {
        let s = OutputSet(self.0 & !FIELD_MASK | kind.bits()).with(Output::LightField);
        match kind {
            FieldKind::Shadows => s.with(Output::Shadows),
            _ => s,
        }
    }

    /// What the light-field output holds: None without it, or when the set does not record it
    /// (AOV and partial files written before the kind was recorded; sets built without
    /// [`OutputSet::with_field`]). With the shadow output it is always the shadow fields.
    pub fn light_field(self) -> Option<FieldKind> {
        if !self.contains(Output::LightField) {
            return None;
        }
        if self.contains(Output::Shadows) {
            return Some(FieldKind::Shadows);
        }
        FieldKind::ALL
            .into_iter()
            .find(|k| *k != FieldKind::Shadows && self.0 & FIELD_MASK == k.bits())
    }

    /// This set with its light field recorded as holding the field named `name`
    /// ([`FieldKind::name`], as AOV and partial files record it); None when the name is
    /// unknown or does not fit the set (no light-field output; the shadow fields without the
    /// shadow output, or another field with it).
    pub fn with_field_named(self, name: &str) -> Option<OutputSet> {
        let kind = FieldKind::parse(name)?;
        let fits = self.contains(Output::LightField)
            && (kind == FieldKind::Shadows) == self.contains(Output::Shadows);
        fits.then(|| self.with_field(kind))
    }

    /// Every output of `other` is in this set, and where both say what their light field
    /// holds, it is the same field (one that does not say, from a file written before it was
    /// recorded, is taken as it is, as `Frame::require` takes it).
    pub fn covers(self, other: OutputSet) -> bool {
        let outputs = other.0 & !FIELD_MASK;
        let field = match (self.light_field(), other.light_field()) {
            (Some(have), Some(want)) => have == want,
            _ => true,
        };
        self.0 & outputs == outputs && field
    }

    /// The outputs in table order.
    pub fn iter(self) -> impl Iterator<Item = Output> {
        OUTPUTS
            .iter()
            .map(|o| o.output)
            .filter(move |&o| self.contains(o))
    }

    /// The buffers of the outputs in this set, in parameter order.
    pub fn buffers(self) -> impl Iterator<Item = &'static BufferDecl> {
        BUFFERS.iter().filter(move |b| self.contains(b.id.owner()))
    }

    pub fn names(self) -> Vec<&'static str> {
        self.iter().map(Output::name).collect()
    }

    /// Bytes the buffers of this set take for a w × h image holding `sample_capacity` samples
    /// per pixel in its per-sample buffers and `planes` light planes in the shadow output.
    pub fn bytes(self, width: u32, height: u32, sample_capacity: u32, planes: u32) -> u64 {
        self.buffers()
            .map(|b| b.bytes(width, height, sample_capacity, planes))
            .sum()
    }
}

impl BufferDecl {
    /// Elements of this buffer for a w × h image.
    pub fn elements(&self, width: u32, height: u32, sample_capacity: u32, planes: u32) -> u64 {
        let pixels = width as u64 * height as u64;
        match self.per {
            Per::Pixel => pixels,
            Per::Sample => pixels * sample_capacity as u64,
            Per::Light => pixels * planes.max(1) as u64,
        }
    }

    pub fn bytes(&self, width: u32, height: u32, sample_capacity: u32, planes: u32) -> u64 {
        self.elements(width, height, sample_capacity, planes) * self.element_bytes as u64
    }

    /// Elements per pixel: 1, `sample_capacity` or `planes` (at least 1; what a row of
    /// pixels holds per pixel).
    pub fn per_pixel(&self, sample_capacity: u32, planes: u32) -> usize {
        self.elements(1, 1, sample_capacity, planes) as usize
    }

    /// The AOV channels that come from this buffer.
    pub fn channels(&self) -> impl Iterator<Item = &'static ChannelDecl> {
        let id = self.id;
        OUTPUTS
            .iter()
            .flat_map(|o| o.channels.iter())
            .filter(move |c| c.buffer == id)
    }
}

/// The AOV name of channel `c` for the light plane holding the scene's sphere light `light`
/// (None: a buffer with one element per pixel): `shadow.direct.R` of light 1 is
/// `shadow.l1.direct.R`.
pub fn channel_name(c: &ChannelDecl, light: Option<u32>) -> String {
    match light {
        None => c.name.to_string(),
        Some(l) => match c.name.split_once('.') {
            Some((layer, rest)) => format!("{layer}.l{l}.{rest}"),
            None => format!("l{l}.{}", c.name),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requirements_close_and_colour_is_everywhere() {
        let s = OutputSet::of(&[Output::Variance]);
        assert!(!s.contains(Output::Features));
        let s = s.closed();
        assert!(s.contains(Output::Features) && s.contains(Output::Colour));
        assert!(
            OutputSet::of(&[Output::Samples])
                .closed()
                .contains(Output::Features)
        );
        for o in OUTPUTS {
            assert!(
                OutputSet::of(&[o.output]).closed().contains(Output::Colour),
                "{}",
                o.name
            );
        }
    }

    #[test]
    fn a_set_records_what_its_light_field_holds() {
        use FieldKind::*;
        let plain = OutputSet::of(&[Output::Colour, Output::LightField]);
        assert_eq!(plain.light_field(), None, "not recorded");
        assert_eq!(OutputSet::colour().light_field(), None);
        let lens = OutputSet::colour().with_field(Lens);
        let gi = lens.with_field(Gi);
        assert_eq!(
            (lens.light_field(), gi.light_field()),
            (Some(Lens), Some(Gi))
        );
        assert_eq!(lens.names(), gi.names());
        // With the shadow output the field is the shadows', whatever was recorded.
        let shadows = gi.with(Output::Shadows);
        assert_eq!(shadows.light_field(), Some(Shadows));
        assert_eq!(
            OutputSet::colour().with_field(Shadows),
            shadows.with_field(Shadows)
        );
        // Closing, uniting and covering keep the kind; another recorded kind does not cover.
        assert_eq!(gi.closed().light_field(), Some(Gi));
        let features = OutputSet::of(&[Output::Features]);
        assert_eq!(features.union(gi).light_field(), Some(Gi));
        assert_eq!(gi.union(lens).light_field(), Some(Gi));
        assert!(gi.union(features).covers(gi) && !gi.covers(lens) && !lens.covers(gi));
        assert!(!shadows.covers(lens) && !gi.covers(shadows));
        assert!(
            plain.covers(gi) && gi.covers(plain),
            "unrecorded: taken as it is"
        );
        // As files name them.
        for k in FieldKind::ALL {
            assert_eq!(FieldKind::parse(k.name()), Some(k));
        }
        assert_eq!(plain.with_field_named("gi"), Some(gi));
        assert_eq!(
            shadows.with_field_named("shadows"),
            Some(shadows.with_field(Shadows))
        );
        assert_eq!(plain.with_field_named("shadows"), None);
        assert_eq!(shadows.with_field_named("lens"), None);
        assert_eq!(OutputSet::colour().with_field_named("lens"), None);
        assert_eq!(plain.with_field_named("glow"), None);
    }

    #[test]
    fn table_is_consistent() {
        // Every buffer has exactly one owner; every channel lane lies inside its element;
        // channel names are unique; switches are unique.
        for b in BUFFERS {
            let owners = OUTPUTS.iter().filter(|o| o.buffers.contains(&b.id)).count();
            assert_eq!(owners, 1, "{}", b.name);
            assert_eq!(b.element_bytes % 4, 0, "{}: elements are floats", b.name);
        }
        let mut names = std::collections::BTreeSet::new();
        for o in OUTPUTS {
            for c in o.channels {
                assert!(c.lane < c.buffer.decl().element_bytes / 4, "{}", c.name);
                assert!(names.insert(c.name), "duplicate channel {}", c.name);
            }
        }
        let switches: std::collections::BTreeSet<_> =
            OUTPUTS.iter().filter_map(|o| o.switch).collect();
        assert_eq!(
            switches.len(),
            OUTPUTS.iter().filter(|o| o.switch.is_some()).count()
        );
    }

    #[test]
    fn every_welford_sum_has_its_mean_and_merge_rules_fit_their_buffers() {
        // Each S_n lane of WelfordSums but the padding appears once, with a mean that lies in
        // an element and belongs to an output the variances require (so it is there to merge).
        let pad = lane(offset_of!(WelfordSums, pad));
        let mut seen: Vec<usize> = WELFORD_MEANS.iter().map(|w| w.0).collect();
        seen.sort();
        assert_eq!(seen, (0..pad).collect::<Vec<_>>());
        let variance = OutputSet::of(&[Output::Variance]).closed();
        for &(_, buffer, mean) in WELFORD_MEANS {
            assert!(mean < buffer.decl().element_bytes / 4);
            assert!(variance.contains(buffer.owner()), "{}", buffer.decl().name);
        }
        for b in BUFFERS {
            assert_eq!(
                b.merge == Merge::PerSample,
                b.per == Per::Sample,
                "{}: per-sample buffers and only they merge by sample number",
                b.name
            );
        }
        for b in BUFFERS.iter().filter(|b| b.merge == Merge::HitMeans) {
            assert_eq!(b.element_bytes, 16, "{}: HitMeans is xyz + w", b.name);
        }
    }

    #[test]
    fn bytes_per_pixel_and_per_sample() {
        let s = OutputSet::of(&[Output::Variance]).closed();
        assert_eq!(s.bytes(2, 3, 0, 0), 6 * (64 + 8 + 64 + 80));
        let r = OutputSet::of(&[Output::Samples]).closed();
        assert_eq!(r.bytes(2, 3, 4, 0), 6 * (64 + 8) + 6 * 4 * 104);
        let t = OutputSet::of(&[Output::Shadows]).closed();
        let plane = (size_of::<ShadowTerms>() + size_of::<ShadowPixel>()) as u64;
        assert_eq!(t.bytes(2, 3, 0, 2), 6 * 64 + 6 * 2 * plane);
        // The light field: one per light plane with the shadow output, one per pixel without.
        let f = BufferId::LightFieldPixels.decl();
        assert_eq!(
            f.bytes(2, 3, 0, 2),
            6 * 2 * size_of::<LightFieldPixel>() as u64
        );
        assert_eq!(f.bytes(2, 3, 0, 0), f.bytes(2, 3, 0, 1));
        let c = &Output::Shadows.decl().channels[0];
        assert_eq!(channel_name(c, Some(3)), "shadow.l3.direct.R");
        assert_eq!(channel_name(c, None), "shadow.direct.R");
    }
}
