//! The one source of truth for everything the host shares with the OpenCL kernels.
//!
//! - Every shared struct is declared once, here, with the [`device_structs!`] macro. The macro
//!   emits the `#[repr(C)]` Rust struct and, at run time, the OpenCL C declaration that mirrors
//!   it, with a `#define` for the float lane of every field of the per-pixel structs
//!   ([`cl`]).
//! - Every per-pixel (and per-sample) output of the renderer is declared once, in the table of
//!   [`outputs`]: its buffers, element layout, feature switch and AOV channels. Kernel
//!   arguments, `-D` switches, allocation, AOV files and the layout test all come from it.
//!
//! `kernels/layout.cl` and `kernels/render/outputs.cl` are the generated texts, committed so a
//! reader of the kernels sees them; `tests/layout.rs` checks that the committed files equal the
//! generated ones and asks the device for `sizeof` and every field offset, comparing them with
//! Rust's.

//!
//! OpenCL vector types are 16-byte (`float4`), 8-byte (`float2`) or 64-byte (`float16`) aligned,
//! so they are mirrored by the aligned wrappers [`Float2`], [`Float4`] and [`Float16`]. `float3`
//! is never used in a shared struct: it is 16 bytes in OpenCL and 12 in Rust.

pub mod cl;
pub mod outputs;

use std::fmt::Write as _;

/// OpenCL `float2`: 8 bytes, 8-byte aligned.
#[repr(C, align(8))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Float2(pub [f32; 2]);

/// OpenCL `float4`: 16 bytes, 16-byte aligned.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Float4(pub [f32; 4]);

/// OpenCL `float16`: 64 bytes, 64-byte aligned (one cache line on the thesis's GPU, §6.2.1).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Float16(pub [f32; 16]);

// SAFETY: plain f32 arrays with the alignment OpenCL gives its vector types.
unsafe impl ocl::OclPrm for Float2 {}
unsafe impl ocl::OclPrm for Float4 {}
unsafe impl ocl::OclPrm for Float16 {}

impl Float4 {
    pub fn new(x: f32, y: f32, z: f32, w: f32) -> Self {
        Float4([x, y, z, w])
    }
    pub fn from_vec3(v: glam::Vec3, w: f32) -> Self {
        Float4([v.x, v.y, v.z, w])
    }
    pub fn xyz(&self) -> glam::Vec3 {
        glam::Vec3::new(self.0[0], self.0[1], self.0[2])
    }
}

impl Float2 {
    pub fn from_vec2(v: glam::Vec2) -> Self {
        Float2([v.x, v.y])
    }
}

/// How a Rust field type is spelled in OpenCL C.
pub trait ClType {
    /// The declaration of a field `name` of this type, e.g. `float4 origin` or `float n[3]`.
    fn cl_field(name: &str) -> String;
}

macro_rules! scalar_cl_type {
    ($($t:ty => $cl:literal),* $(,)?) => {$(
        impl ClType for $t {
            fn cl_field(name: &str) -> String { format!("{} {}", $cl, name) }
        }
        impl<const N: usize> ClType for [$t; N] {
            fn cl_field(name: &str) -> String { format!("{} {}[{}]", $cl, name, N) }
        }
    )*};
}
scalar_cl_type!(f32 => "float", u32 => "uint", i32 => "int", Float2 => "float2", Float4 => "float4");

impl ClType for Float16 {
    fn cl_field(name: &str) -> String {
        format!("float16 {name}")
    }
}

/// Field name, byte offset and byte size, as Rust lays them out.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldLayout {
    pub name: &'static str,
    pub offset: usize,
    pub size: usize,
}

/// A struct shared with the kernels.
pub trait DeviceStruct: Sized {
    const NAME: &'static str;
    /// The OpenCL C `typedef struct` that mirrors this struct.
    fn cl_declaration() -> String;
    /// Rust's field offsets and sizes, in declaration order.
    fn fields() -> Vec<FieldLayout>;
    fn size() -> usize {
        std::mem::size_of::<Self>()
    }
    fn align() -> usize {
        std::mem::align_of::<Self>()
    }
}

fn field_size<T, F>(_: fn(&T) -> &F) -> usize {
    std::mem::size_of::<F>()
}

/// Declares structs shared with OpenCL. Each becomes a `#[repr(C)]` Rust struct with `OclPrm`
/// and [`DeviceStruct`] implemented; alignment above the natural one is carried into OpenCL
/// with `__attribute__((aligned(N)))`.
macro_rules! device_structs {
    ($(
        $(#[doc = $doc:literal])*
        #[align($align:literal)]
        pub struct $name:ident { $( $(#[doc = $fdoc:literal])* pub $field:ident : $ty:ty ),* $(,)? }
    )*) => {$(
        $(#[doc = $doc])*
        #[repr(C, align($align))]
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        pub struct $name { $( $(#[doc = $fdoc])* pub $field: $ty ),* }

        // SAFETY: plain-old-data made of f32/u32/i32 and their aligned arrays, no padding
        // that the device could read as uninitialised (Default zeroes every field).
        unsafe impl ocl::OclPrm for $name {}

        impl DeviceStruct for $name {
            const NAME: &'static str = stringify!($name);
            fn cl_declaration() -> String {
                let mut s = String::new();
                let docs: &[&str] = &[$($doc),*];
                for line in docs {
                    let _ = writeln!(s, "//{}", line);
                }
                let _ = writeln!(s, "typedef struct __attribute__((aligned({}))) {{", $align);
                $(
                    let _ = writeln!(s, "    {};{}", <$ty as ClType>::cl_field(stringify!($field)),
                        { let d: &[&str] = &[$($fdoc),*]; if d.is_empty() { String::new() } else { format!(" //{}", d.join(" ")) } });
                )*
                let _ = writeln!(s, "}} {};", stringify!($name));
                s
            }
            fn fields() -> Vec<FieldLayout> {
                vec![$( FieldLayout {
                    name: stringify!($field),
                    offset: std::mem::offset_of!($name, $field),
                    size: field_size(|s: &$name| &s.$field),
                } ),*]
            }
        }
    )*};
}

device_structs! {
    /// Everything a launch of the megakernel reads once: camera, environment, counts (§4.2.2).
    #[align(16)]
    pub struct SceneParams {
        /// Camera position (xyz).
        pub camera_origin: Float4,
        /// Unit view direction, target - origin.
        pub camera_forward: Float4,
        /// Unit right vector of the image plane.
        pub camera_right: Float4,
        /// Unit up vector of the image plane.
        pub camera_up: Float4,
        /// Environment radiance multiplier (colour * gain), rgb.
        pub env_radiance: Float4,
        /// Environment texture transform: uv scale (xy), uv shift (zw).
        pub env_uv: Float4,
        pub image_width: u32,
        pub image_height: u32,
        /// tan(vertical fov / 2).
        pub tan_half_fov: f32,
        /// Thin-lens radius, 0 for a pinhole (Fig. 4.8).
        pub lens_radius: f32,
        /// Distance from the lens to the plane in focus.
        pub focal_distance: f32,
        pub node_count: u32,
        pub sphere_count: u32,
        pub light_count: u32,
        /// Texture index of the environment light, -1 for a constant colour.
        pub env_texture: i32,
        /// Path depth from which Russian roulette runs (eq. 2.9).
        pub rr_depth: u32,
        /// Hard cap on path vertices, a guard against runaway paths (see kernels/render/pathtrace.cl).
        pub max_vertices: u32,
        pub seed: u32,
        /// Largest colour component a single path sample may carry; 0: no clamp (default).
        /// Clamping trades a bias for fewer fireflies.
        pub sample_clamp: f32,
        /// Size of the scene (largest extent of its bounds): the unit of the absolute part of
        /// the secondary-ray origin offset (kernels/geometry.cl), so it works at any scale.
        pub scene_size: f32,
        pub pad1: u32,
        pub pad2: u32,
    }

    /// A flattened BVH node (§4.2.2 "BVH construction", Fig. 4.6). Depth-first order, left child
    /// directly after its parent; `skip` is the node to visit when the ray misses this subtree.
    #[align(4)]
    pub struct BvhNode {
        pub bounds_min: [f32; 3],
        /// Index of the next node after this node's subtree (the thesis's skip index).
        pub skip: u32,
        pub bounds_max: [f32; 3],
        /// 0 for an inner node; for a leaf: first triangle | (triangle count << 28).
        pub leaf: u32,
    }

    /// An eight-wide BVH node (issue 14; not in the thesis, whose Alg. 4 walks [`BvhNode`]s):
    /// the boxes of up to eight children as a structure of arrays, so that one slab test
    /// (Alg. 2) in float8 lanes tests them all. Collapsed from the binary tree
    /// (src/bvh/wide.rs), over the same triangles in the same leaf order.
    #[align(64)]
    pub struct WideBvhNode {
        /// The children's boxes, one lane per child: the padded boxes of the binary nodes.
        pub min_x: [f32; 8],
        pub min_y: [f32; 8],
        pub min_z: [f32; 8],
        pub max_x: [f32; 8],
        pub max_y: [f32; 8],
        pub max_z: [f32; 8],
        /// An inner child's node index, or for a leaf its TrianglePack's index | triangle
        /// count << 28: a word whose top four bits are zero is an inner node.
        pub child: [u32; 8],
        /// Children in use, from lane 0; the other lanes are never entered.
        pub child_count: u32,
        pub pad: [u32; 7],
    }

    /// The triangles of one leaf of the wide BVH as a structure of arrays (issue 14): up to
    /// four triangles, one per float4 lane, so that one Möller-Trumbore test (Alg. 3) in four
    /// lanes tests them all. The edges are stored as the kernels' scalar test computes them
    /// (v1 - v0, v2 - v0: the same floats), so each lane's t, u and v are that test's bits.
    #[align(16)]
    pub struct TrianglePack {
        pub v0_x: [f32; 4],
        pub v0_y: [f32; 4],
        pub v0_z: [f32; 4],
        pub e1_x: [f32; 4],
        pub e1_y: [f32; 4],
        pub e1_z: [f32; 4],
        pub e2_x: [f32; 4],
        pub e2_y: [f32; 4],
        pub e2_z: [f32; 4],
        /// The leaf's first triangle (leaf order): lane i is triangle first + i.
        pub first: u32,
        /// Lanes in use, from lane 0.
        pub count: u32,
        pub pad: [u32; 2],
    }

    /// Triangle vertices for intersection (Alg. 3), in leaf order.
    #[align(16)]
    pub struct TriangleGeom {
        pub v0: Float4,
        pub v1: Float4,
        pub v2: Float4,
    }

    /// Per-triangle shading data, read only for the nearest hit.
    #[align(16)]
    pub struct TriangleShading {
        pub n0: Float4,
        pub n1: Float4,
        pub n2: Float4,
        pub uv0: Float2,
        pub uv1: Float2,
        pub uv2: Float2,
        pub material: u32,
        /// Index into the light list when the triangle is emissive, else -1.
        pub light: i32,
        /// The object (mesh part) the triangle belongs to (src/scene Triangle::object).
        pub object: u32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }

    /// An analytic sphere (kept in its own list, tested after the BVH).
    #[align(16)]
    pub struct Sphere {
        pub center: [f32; 3],
        pub radius: f32,
        pub material: u32,
        /// Index into the light list for sphere lights, else -1.
        pub light: i32,
        pub pad0: u32,
        pub pad1: u32,
    }

    /// A material (§4.2.2 "Material", §4.3.3).
    #[align(16)]
    pub struct Material {
        /// diffuse/specular/metal colour; glass: reflection colour.
        pub color: Float4,
        /// glass: refraction colour.
        pub color2: Float4,
        /// Emitted radiance (rgb); non-zero makes the surface a light.
        pub emission: Float4,
        /// MATERIAL_DIFFUSE, MATERIAL_SPECULAR, MATERIAL_GLASS, MATERIAL_METAL or MATERIAL_EMITTER.
        pub kind: u32,
        /// Texture index multiplying `color` (diffuse), -1 for none.
        pub texture: i32,
        /// Phong exponent of the metal lobe.
        pub exponent: f32,
        pub ior_outside: f32,
        pub ior_inside: f32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }

    /// Where a texture's texels start in the shared texel buffer, and its uv transform.
    #[align(8)]
    pub struct TextureInfo {
        pub offset: u32,
        pub width: u32,
        pub height: u32,
        /// TEXTURE_LINEAR or TEXTURE_SRGB8 (src/arrays/texels.rs).
        pub format: u32,
        pub uv_scale: Float2,
        pub uv_shift: Float2,
    }

    /// A light for next-event estimation: a sphere light or one emissive triangle. It carries
    /// its own geometry so that sampling needs no second lookup.
    #[align(16)]
    pub struct Light {
        /// LIGHT_SPHERE or LIGHT_TRIANGLE.
        pub kind: u32,
        /// Sphere index or triangle index (leaf order) of the light's surface.
        pub primitive: u32,
        /// Probability of choosing this light for a connection.
        pub pmf: f32,
        /// Surface area (triangles).
        pub area: f32,
        /// Emitted radiance (rgb).
        pub emission: Float4,
        /// Sphere: centre (xyz) and radius (w). Triangle: first vertex.
        pub p0: Float4,
        pub p1: Float4,
        pub p2: Float4,
    }

    /// The FilterVector F of eq. 6.1: the per-pixel means, exactly 64 bytes (one float16, §6.2.1).
    #[align(64)]
    pub struct FilterVector {
        /// Mean direct light: emission seen directly plus light reaching the first surface
        /// straight from a light.
        pub direct: [f32; 3],
        /// Mean indirect light: everything else.
        pub indirect: [f32; 3],
        /// Mean distance along the camera ray to the first hit; SKY_DEPTH when it escapes.
        pub depth: f32,
        /// Mean shading normal at the first hit, facing the camera; 0 for sky.
        pub normal: [f32; 3],
        /// Mean albedo ("texture") at the first hit; 0 for sky.
        pub albedo: [f32; 3],
        /// Mean albedo of the first diffuse surface after the first bounce ("texture2"); 0 if none.
        pub albedo2: [f32; 3],
    }

    /// The thesis's variance WelfordSums GB (eq. 6.2), held as Welford's running sums of squared
    /// deviations S_n (eq. 6.6): the variance S_n / (n - 1) is formed only where a filter reads
    /// it. 13 floats padded to one float16 (§6.3.1).
    #[align(64)]
    pub struct WelfordSums {
        pub depth: f32,
        pub normal: [f32; 3],
        pub albedo: [f32; 3],
        /// Direction leaving the first hit (its mean lives in WelfordState, not in F).
        pub direction: [f32; 3],
        pub albedo2: [f32; 3],
        pub pad: [f32; 3],
    }

    /// The rest of Welford's running state (eq. 6.6), neither a FilterVector mean nor an S_n:
    /// the mean first-bounce direction and the Kahan compensation of every S_n (see
    /// kernels/render/film.cl on float32).
    #[align(16)]
    pub struct WelfordState {
        pub direction_mean: [f32; 3],
        pub pad: f32,
        /// Kahan compensation of each WelfordSums lane's S_n (13 used).
        pub s_compensation: [f32; 16],
    }

    /// The depth mean on shifted data (see kernels/render/film.cl): F.depth = shift + mean.
    #[align(8)]
    pub struct DepthShift {
        /// The pixel's first depth sample K.
        pub shift: f32,
        /// Running mean of x - K (eq. 6.5).
        pub mean: f32,
    }

    /// Parameters of the data-driven filter for one run (thesis Tables 6.2, 6.3).
    #[align(16)]
    pub struct DdfParams {
        pub width: u32,
        pub height: u32,
        /// (kw - 1) / 2 (Alg. 8 line 2).
        pub half_width: i32,
        /// 1, or 2 with holes (§6.3.3).
        pub step: i32,
        /// Eq. 6.8: 1 / (2 sigma_dc^2).
        pub sigma2_dc: f32,
        /// Eq. 6.9: 1 / (2 sigma_ic^2).
        pub sigma2_ic: f32,
        /// Multiplies GB to give variances: 1 / (n - 1) for Welford sums, 1 for variances.
        pub variance_factor: f32,
        /// Multiplies depths before they are compared (depth in hundredths of the scene size).
        pub depth_scale: f32,
        /// 1 / (2 sigma_f,i^2) for depth, normal, texture, direction, texture2 (eq. 6.10).
        pub sigma2_f: [f32; 5],
        pub pad2: [u32; 3],
        /// The variance scales s_f,i, same order.
        pub variance_scale: [f32; 5],
        pub pad3: [u32; 3],
    }

    /// One path sample as Random Parameter Filtering stores it (thesis §5.1.1, Table 5.1):
    /// 26 floats. Written by the megakernel only when RPF is requested.
    #[align(4)]
    pub struct SampleVector {
        /// Screen position: pixel coordinates plus the random point inside the pixel.
        pub position: [f32; 2],
        /// Random parameters: lens u, v; time t (always 0); first-bounce direction x, y, z.
        pub random: [f32; 6],
        /// World position of the first hit (camera origin + SKY_DEPTH x direction for sky).
        pub world1: [f32; 3],
        /// Shading normal of the first hit (0 for sky).
        pub normal1: [f32; 3],
        /// World position of the second hit (0 when the path ends before).
        pub world2: [f32; 3],
        /// Shading normal of the second hit (0 when the path ends before).
        pub normal2: [f32; 3],
        /// Albedo ("texture") of the first hit.
        pub texture1: [f32; 3],
        /// The sample's colour (direct + indirect).
        pub color: [f32; 3],
    }

    /// AAF soft shadows (Wang 2013 ch. 3), what the megakernel gathers per pixel for the one
    /// sphere light whose shadows are filtered: a running mean over the path samples, like F.
    #[align(16)]
    pub struct ShadowTerms {
        /// The light the path samples whose first hit is the pixel centre's receiver brought
        /// to it straight from that light (its next-event estimate, or its emission found by
        /// the first bounce): the part of F that the filtered term replaces.
        pub direct: [f32; 3],
        pub pad0: f32,
        /// The same samples' unoccluded term: albedo × the light's unoccluded term at their
        /// first hit (kernels/render/shadows.cl `shadow_unshadowed`), 0 for a sample off the
        /// receiver: eq. 3.1's r(x) averaged over the pixel as `direct` is, so that the
        /// sheared filter's r · v stands where `direct` stood (texture and edge included).
        pub unshadowed: [f32; 3],
        pub pad1: f32,
    }

    /// AAF soft shadows: the primary hit through the pixel centre (and the lens centre) and its
    /// light samples (kernels/render/shadows.cl), from the sparse and the adaptive pass.
    #[align(16)]
    pub struct ShadowPixel {
        /// Σ f·l over the light samples: l = cos θ at the receiver, f = 1 when unoccluded.
        pub visible: f32,
        /// Σ l (eq. 3.2's normaliser); 0 when the pixel is no receiver.
        pub weight: f32,
        /// Light samples traced (sparse + adaptive).
        pub samples: f32,
        /// Samples whose shadow ray met an occluder.
        pub occluded: f32,
        /// d1: receiver-to-light-centre distance.
        pub light_distance: f32,
        /// s1 = max(d1/d2 − 1) over the occluded samples (eq. 3.5).
        pub slope_max: f32,
        /// s2 = min(d1/d2 − 1) over the occluded samples.
        pub slope_min: f32,
        /// 0: no slopes; 1: from the pixel's own occluded samples; 2: filled from neighbours.
        pub slope_source: f32,
        /// d: the world size of one pixel at the hit (eq. 3.4).
        pub pixel_size: f32,
        /// n(x) of eq. 3.5 clamped to [sparse, max] (before rounding to whole strata).
        pub target: f32,
        /// The object hit: mesh part for triangles, −1 − index for spheres.
        pub object: f32,
        /// V of the one shadow ray from the centre's hit to the light's centre: 1 visible, 0
        /// occluded or the centre below the surface (the binary matte of the stylized-shadows
        /// filter, DeCoro 2009 §3.3 step 1).
        pub centre_visible: f32,
        /// World position of the hit.
        pub position: [f32; 3],
        /// d(x): distance from the hit to the nearest occluder on that ray; 0 when visible or
        /// below the surface (DeCoro §3.3.2 "approximate distance to occluder").
        pub occluder_distance: f32,
        /// Shading normal at the hit, facing the camera.
        pub normal: [f32; 3],
        pub pad2: f32,
        /// Σ r(x_k) over the light samples' points x_k on the receiver: r of eq. 3.1, the
        /// light's unshadowed direct term from its centre with the albedo (albedo · L sin²α
        /// cos θ_c); divided by `samples` it is r over the pixel, anti-aliased as the samples
        /// spread over it.
        pub unshadowed: [f32; 3],
        pub pad3: f32,
    }

    /// AAF indirect light (Wang 2013 ch. 4; kernels/render/indirect.cl): the primary hit
    /// through the pixel centre (and the lens centre) and the indirect samples of the sparse
    /// and the adaptive pass, for one of two lobes: a diffuse receiver's cosine-weighted
    /// hemisphere or a metal receiver's Phong lobe (the seed's separate glossy buffer).
    #[align(16)]
    pub struct IndirectPixel {
        /// Σ L_i over the indirect samples, L_i the radiance arriving along the sampled
        /// direction. Diffuse: cosine-weighted samples, so albedo · Σ L_i / `weight` is the
        /// indirect light a Lambertian receiver sends to the camera (Σ L_i / n is the
        /// demodulated irradiance / π). Glossy: samples of the Phong lobe (f cos / pdf is the
        /// metal's colour), so colour · Σ L_i / `weight` is the metal's indirect light.
        pub irradiance: [f32; 3],
        /// Indirect samples traced (sparse + adaptive), 0 for no receiver.
        pub samples: f32,
        /// Σ albedo(x_k) over the samples' points x_k on the receiver (a metal's colour).
        pub albedo: [f32; 3],
        /// Samples whose point lay on the centre's receiver (the normaliser of both sums).
        pub weight: f32,
        /// World position of the centre's hit.
        pub position: [f32; 3],
        /// z_min: the nearest first-bounce hit over the sparse samples (eqs. 4.4, 4.6); 0 when
        /// no sample hit a surface.
        pub z_min: f32,
        /// Shading normal at the centre's hit, facing the camera.
        pub normal: [f32; 3],
        /// z_max: the farthest first-bounce hit (eq. 4.6 uses it but the seed never defines
        /// it: the maximum reflector distance).
        pub z_max: f32,
        /// d: the world size of one pixel at the hit (eq. 4.4; A_p = d²).
        pub pixel_size: f32,
        /// n(x) of eq. 4.6 clamped to [sparse, max] (before rounding to whole strata).
        pub target: f32,
        /// The object hit: mesh part for triangles, −1 − index for spheres.
        pub object: f32,
        /// Sparse samples whose first bounce hit a surface (the z's are defined when > 0).
        pub reflectors: f32,
        /// Ω_h^max of the receiver's lobe (eq. 4.5): 2.8 diffuse, 3.6 + 0.084 m for a metal
        /// of Phong exponent m; 0 for no receiver. Eqs. 4.4 and 4.6 use it.
        pub bandlimit: f32,
        /// The lobe: 0 diffuse, 1 glossy (a metal receiver).
        pub lobe: f32,
        pub pad: [f32; 2],
    }

    /// Parameters of the AAF diffuse-indirect filter (kernels/filters/aaf_indirect.cl).
    #[align(16)]
    pub struct AafIndirectParams {
        pub width: u32,
        pub height: u32,
        /// Half width of the 1-D window, pixels.
        pub radius: i32,
        /// 0: the pass along rows (x), 1: along columns (y).
        pub axis: u32,
        /// 1: glossy (metal) receivers are filtered; 0: they keep F as rendered.
        pub glossy: u32,
        /// The floor of β in pixel footprints (eq. 4.4's d / 0.15: 1 / 0.15).
        pub footprints: f32,
        /// cos of the largest normal angle between neighbours.
        pub normal_cos: f32,
        /// Largest offset along the normal, in units of β.
        pub depth_tolerance: f32,
    }

    /// Sheared filtering (Yan et al. 2015 §3.1, issue 16): the 4-D light field of one pixel,
    /// l × l samples on a jittered grid. Soft shadows: the visibility of the pixel centre's
    /// receiver towards points of the filtered sphere light's square [−R, R]² in one global
    /// frame (kernels/render/light_field.cl), and the screen directions of the light's two axes
    /// (Fig. 5a). Depth of field: the radiance through points of the lens square [−A, A]²
    /// (kernels/render/lens_field.cl), the slopes, the lens-centre hit and the fallback's 36
    /// extra samples; the shadow pass leaves those lanes 0.
    #[align(16)]
    pub struct LightFieldPixel {
        /// Shadows: visibility f ∈ {0, 1} of grid point (a, b) at lane b·l + a (a along the
        /// light's first axis y1, b along y2). Depth of field: the red radiance through lens
        /// point (a, b) (a along the camera's right, b along its down). Lanes from l² on are 0.
        pub samples: [f32; 16],
        /// The pixel's jitter j ∈ [0, 1)²: point (a, b) is at y = R (2 (a + j) / l − 1).
        pub jitter: [f32; 2],
        /// Unit screen direction (pixels) in which the receiver's x1 grows with x2 fixed
        /// (depth of field: the row, (1, 0)).
        pub dir1: [f32; 2],
        /// The same for x2 with x1 fixed (depth of field: the column, (0, 1)).
        pub dir2: [f32; 2],
        /// World x1 per pixel along dir1, world x2 per pixel along dir2 (0: not defined;
        /// depth of field: 1, x is in pixels).
        pub scale: [f32; 2],
        /// l² for a receiver (depth of field: every pixel), 0 for none.
        pub count: f32,
        /// Depth of field: s_min and s_max of s = W (F/z − 1) / S over the l² samples (pixels
        /// per metre of lens; Yan et al. §3.2), z the depth of each sample's first hit.
        pub slopes: [f32; 2],
        /// Depth of field: 36 where s_min · s_max < 0 (the fallback's extra samples), else 0.
        pub extra_samples: f32,
        /// Depth of field: the green radiance of lens point (a, b), lanes as `samples`.
        pub green: [f32; 16],
        /// Depth of field: the blue radiance, lanes as `samples`.
        pub blue: [f32; 16],
        /// Depth of field: the first hit of the ray through the pixel centre and the lens
        /// centre (0 where it leaves the scene).
        pub position: [f32; 3],
        pub pad0: f32,
        /// Depth of field: that hit's shading normal, facing the camera (0: no hit).
        pub normal: [f32; 3],
        pub pad1: f32,
        /// Depth of field: Σ w(u) L(u) (rgb) and Σ w(u) (w) over the 36 extra samples, w the
        /// Gaussian aperture of σ = A/2.
        pub extra: [f32; 4],
    }

    /// Sheared soft shadows and depth of field together (Yan et al. 2015, appendix eqs.
    /// 16-17; issue 16): beside the lens field (a [`LightFieldPixel`] per pixel whose radiance
    /// lanes hold each lens sample's light without the filtered sphere lights' direct term on
    /// the pixel centre's receiver, kernels/render/lens_field.cl `lens_shadow_field_sample`),
    /// what the filter needs to put that term back after filtering the shadows: eq. 16's
    /// texture k(x, u) of every lens sample and eq. 17's F̄ per light.
    #[align(16)]
    pub struct LensShadowPixel {
        /// Red albedo k(x, u) of lens point (a, b)'s first hit where that hit took the
        /// filtered lights' direct term out (a diffuse hit on the pixel centre's receiver),
        /// else 0; lanes as [`LightFieldPixel::samples`].
        pub albedo: [f32; 16],
        /// The green albedo, lanes as `albedo`.
        pub albedo_green: [f32; 16],
        /// The blue albedo, lanes as `albedo`.
        pub albedo_blue: [f32; 16],
        /// Σ w(u) k(u) (rgb) over the fallback's 36 extra samples (their Σ w is the lens
        /// field's extra.w); w: 0.
        pub albedo_extra: [f32; 4],
        /// Per shadow plane: eq. 17's F̄ without its visibility, the mean over the lens samples
        /// on the receiver of the plane's light's unoccluded term (rgb; eq. 3.1's r / albedo,
        /// kernels/render/shadows.cl `shadow_unshadowed`), and (w) how many samples that is.
        pub unshadowed: [Float4; 8],
    }

    /// Parameters of the AAF soft-shadow filter passes (kernels/filters/aaf_shadows.cl).
    #[align(16)]
    pub struct AafShadowParams {
        /// The filtered sphere light: centre (xyz) and radius (w).
        pub light: Float4,
        pub width: u32,
        pub height: u32,
        /// Half width of the 1-D window, pixels.
        pub radius: i32,
        /// 0: the pass along rows (x), 1: along columns (y).
        pub axis: u32,
        /// σ of the light (R/2).
        pub sigma: f32,
        /// cos of the largest normal angle between neighbours.
        pub normal_cos: f32,
        /// Largest offset along the light direction, in units of β.
        pub depth_tolerance: f32,
        /// Largest |β − β'| / max(β, β').
        pub beta_tolerance: f32,
    }

    /// Parameters of the sheared soft-shadow filter (kernels/filters/sheared.cl; Yan et al.
    /// 2015 eqs. 3-15; src/filters/sheared).
    #[align(16)]
    pub struct ShearedParams {
        /// The filtered sphere light: centre (xyz) and radius R (w).
        pub light: Float4,
        /// The light's axes e1, e2 (xyz; src/render/shadows/light_field.rs `light_frame`).
        pub axis1: Float4,
        pub axis2: Float4,
        pub width: u32,
        pub height: u32,
        /// Grid side l (l² samples per pixel).
        pub side: u32,
        /// Bins of the free light coordinate in steps 1a/2a (odd: one bin at y = 0).
        pub bins: u32,
        /// σ_y = 2/Ω_y^max = R/2, the Gaussian light's standard deviation (eq. 4).
        pub sigma_y: f32,
        /// The bins cover [−range, range].
        pub range: f32,
        /// cos of the largest normal angle between neighbours.
        pub normal_cos: f32,
        /// Largest offset along the light direction, in units of the written pixel's σ_x.
        pub depth_tolerance: f32,
        /// Most steps of a 1-D gather on either side (16: the seed's 32 px diameter).
        pub max_radius: i32,
        /// Factor on eq. 5's η (1: the shear as settled by tests/sheared_filter.rs, 0: no shear).
        pub shear: f32,
        pub pad0: f32,
        pub pad1: f32,
    }

    /// Parameters of one pass of the edge-avoiding a-trous filter (Dammertz et al. 2010).
    #[align(16)]
    pub struct AtrousParams {
        /// Camera, to turn depth into world position.
        pub camera_origin: Float4,
        pub camera_forward: Float4,
        pub camera_right: Float4,
        pub camera_up: Float4,
        pub width: u32,
        pub height: u32,
        /// Tap spacing of this pass, 2^iteration.
        pub step: i32,
        pub iteration: u32,
        pub sigma_color: f32,
        pub sigma_normal: f32,
        pub sigma_position: f32,
        pub tan_half_fov: f32,
    }
}

pub const MATERIAL_DIFFUSE: u32 = 0;
pub const MATERIAL_SPECULAR: u32 = 1;
pub const MATERIAL_GLASS: u32 = 2;
pub const MATERIAL_METAL: u32 = 3;
pub const MATERIAL_EMITTER: u32 = 4;
impl FilterVector {
    /// The 16 floats in field order, as the kernels read F (one float16): direct, indirect,
    /// depth, normal, albedo, albedo2.
    pub fn lanes(&self) -> [f32; 16] {
        let mut x = [0f32; 16];
        x[..3].copy_from_slice(&self.direct);
        x[3..6].copy_from_slice(&self.indirect);
        x[6] = self.depth;
        x[7..10].copy_from_slice(&self.normal);
        x[10..13].copy_from_slice(&self.albedo);
        x[13..16].copy_from_slice(&self.albedo2);
        x
    }
}

pub const LIGHT_SPHERE: u32 = 0;
pub const LIGHT_TRIANGLE: u32 = 1;
pub const LEAF_COUNT_SHIFT: u32 = 28;
pub const LEAF_FIRST_MASK: u32 = (1 << LEAF_COUNT_SHIFT) - 1;
/// Children of a [`WideBvhNode`] at most: one float8 of each bound.
pub const BVH_WIDTH: u32 = 8;
/// Depth sentinel of a camera ray that escapes (§6.3.4). Finite, so that the squared
/// differences of the Welford update and of the filter weights stay finite in float32.
pub const SKY_DEPTH: f32 = 1.0e9;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_vector_and_welford_sums_are_one_float16_each() {
        assert_eq!(std::mem::size_of::<FilterVector>(), 64);
        assert_eq!(std::mem::align_of::<FilterVector>(), 64);
        assert_eq!(std::mem::size_of::<WelfordSums>(), 64);
        assert_eq!(std::mem::size_of::<WelfordState>(), 80);
    }
}
