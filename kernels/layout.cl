// GENERATED from src/layout/mod.rs by `NOISEFREE_BLESS=1 cargo test --test layout`.
// Do not edit: change src/layout/mod.rs instead. tests/layout.rs checks that this file
// is current and that the device lays every struct out exactly as Rust does.
#ifndef NOISEFREE_LAYOUT_CL
#define NOISEFREE_LAYOUT_CL

#define MATERIAL_DIFFUSE 0u // Lambertian, Alg. 5
#define MATERIAL_SPECULAR 1u // perfect mirror, eq. 4.7
#define MATERIAL_GLASS 2u // Schlick Fresnel + Snell, eqs. 4.8-4.10
#define MATERIAL_METAL 3u // normalised Phong lobe around the mirror direction
#define MATERIAL_EMITTER 4u // a light surface: emits, reflects nothing
#define LIGHT_SPHERE 0u
#define LIGHT_TRIANGLE 1u
#define LEAF_COUNT_SHIFT 28u // BvhNode.leaf = first | count << LEAF_COUNT_SHIFT
#define LEAF_FIRST_MASK 0xfffffffu
#define BVH_WIDTH 8u // children of a WideBvhNode at most
#define SKY_DEPTH 1e9f // depth of a camera ray that escapes (§6.3.4)

// Everything a launch of the megakernel reads once: camera, environment, counts (§4.2.2).
typedef struct __attribute__((aligned(16))) {
    float4 camera_origin; // Camera position (xyz).
    float4 camera_forward; // Unit view direction, target - origin.
    float4 camera_right; // Unit right vector of the image plane.
    float4 camera_up; // Unit up vector of the image plane.
    float4 env_radiance; // Environment radiance multiplier (colour * gain), rgb.
    float4 env_uv; // Environment texture transform: uv scale (xy), uv shift (zw).
    uint image_width;
    uint image_height;
    float tan_half_fov; // tan(vertical fov / 2).
    float lens_radius; // Thin-lens radius, 0 for a pinhole (Fig. 4.8).
    float focal_distance; // Distance from the lens to the plane in focus.
    uint node_count;
    uint sphere_count;
    uint light_count;
    int env_texture; // Texture index of the environment light, -1 for a constant colour.
    uint rr_depth; // Path depth from which Russian roulette runs (eq. 2.9).
    uint max_vertices; // Hard cap on path vertices, a guard against runaway paths (see kernels/render/pathtrace.cl).
    uint seed;
    float sample_clamp; // Largest colour component a single path sample may carry; 0: no clamp (default).  Clamping trades a bias for fewer fireflies.
    float scene_size; // Size of the scene (largest extent of its bounds): the unit of the absolute part of  the secondary-ray origin offset (kernels/geometry.cl), so it works at any scale.
    uint pad1;
    uint pad2;
} SceneParams;

// A flattened BVH node (§4.2.2 "BVH construction", Fig. 4.6). Depth-first order, left child
// directly after its parent; `skip` is the node to visit when the ray misses this subtree.
typedef struct __attribute__((aligned(4))) {
    float bounds_min[3];
    uint skip; // Index of the next node after this node's subtree (the thesis's skip index).
    float bounds_max[3];
    uint leaf; // 0 for an inner node; for a leaf: first triangle | (triangle count << 28).
} BvhNode;

// An eight-wide BVH node (issue 14; not in the thesis, whose Alg. 4 walks [`BvhNode`]s):
// the boxes of up to eight children as a structure of arrays, so that one slab test
// (Alg. 2) in float8 lanes tests them all. Collapsed from the binary tree
// (src/bvh/wide.rs), over the same triangles in the same leaf order.
typedef struct __attribute__((aligned(64))) {
    float min_x[8]; // The children's boxes, one lane per child: the padded boxes of the binary nodes.
    float min_y[8];
    float min_z[8];
    float max_x[8];
    float max_y[8];
    float max_z[8];
    uint child[8]; // An inner child's node index, or for a leaf its TrianglePack's index | triangle  count << 28: a word whose top four bits are zero is an inner node.
    uint child_count; // Children in use, from lane 0; the other lanes are never entered.
    uint pad[7];
} WideBvhNode;

// The triangles of one leaf of the wide BVH as a structure of arrays (issue 14): up to
// four triangles, one per float4 lane, so that one Möller-Trumbore test (Alg. 3) in four
// lanes tests them all. The edges are stored as the kernels' scalar test computes them
// (v1 - v0, v2 - v0: the same floats), so each lane's t, u and v are that test's bits.
typedef struct __attribute__((aligned(16))) {
    float v0_x[4];
    float v0_y[4];
    float v0_z[4];
    float e1_x[4];
    float e1_y[4];
    float e1_z[4];
    float e2_x[4];
    float e2_y[4];
    float e2_z[4];
    uint first; // The leaf's first triangle (leaf order): lane i is triangle first + i.
    uint count; // Lanes in use, from lane 0.
    uint pad[2];
} TrianglePack;

// Triangle vertices for intersection (Alg. 3), in leaf order.
typedef struct __attribute__((aligned(16))) {
    float4 v0;
    float4 v1;
    float4 v2;
} TriangleGeom;

// Per-triangle shading data, read only for the nearest hit.
typedef struct __attribute__((aligned(16))) {
    float4 n0;
    float4 n1;
    float4 n2;
    float2 uv0;
    float2 uv1;
    float2 uv2;
    uint material;
    int light; // Index into the light list when the triangle is emissive, else -1.
    uint object; // The object (mesh part) the triangle belongs to (src/scene Triangle::object).
    uint pad0;
    uint pad1;
    uint pad2;
} TriangleShading;

// An analytic sphere (kept in its own list, tested after the BVH).
typedef struct __attribute__((aligned(16))) {
    float center[3];
    float radius;
    uint material;
    int light; // Index into the light list for sphere lights, else -1.
    uint pad0;
    uint pad1;
} Sphere;

// A material (§4.2.2 "Material", §4.3.3).
typedef struct __attribute__((aligned(16))) {
    float4 color; // diffuse/specular/metal colour; glass: reflection colour.
    float4 color2; // glass: refraction colour.
    float4 emission; // Emitted radiance (rgb); non-zero makes the surface a light.
    uint kind; // MATERIAL_DIFFUSE, MATERIAL_SPECULAR, MATERIAL_GLASS, MATERIAL_METAL or MATERIAL_EMITTER.
    int texture; // Texture index multiplying `color` (diffuse), -1 for none.
    float exponent; // Phong exponent of the metal lobe.
    float ior_outside;
    float ior_inside;
    uint pad0;
    uint pad1;
    uint pad2;
} Material;

// Where a texture's texels start in the shared texel buffer, and its uv transform.
typedef struct __attribute__((aligned(8))) {
    uint offset;
    uint width;
    uint height;
    uint format; // TEXTURE_LINEAR or TEXTURE_SRGB8 (src/arrays/texels.rs).
    float2 uv_scale;
    float2 uv_shift;
} TextureInfo;

// A light for next-event estimation: a sphere light or one emissive triangle. It carries
// its own geometry so that sampling needs no second lookup.
typedef struct __attribute__((aligned(16))) {
    uint kind; // LIGHT_SPHERE or LIGHT_TRIANGLE.
    uint primitive; // Sphere index or triangle index (leaf order) of the light's surface.
    float pmf; // Probability of choosing this light for a connection.
    float area; // Surface area (triangles).
    float4 emission; // Emitted radiance (rgb).
    float4 p0; // Sphere: centre (xyz) and radius (w). Triangle: first vertex.
    float4 p1;
    float4 p2;
} Light;

// The FilterVector F of eq. 6.1: the per-pixel means, exactly 64 bytes (one float16, §6.2.1).
typedef struct __attribute__((aligned(64))) {
    float direct[3]; // Mean direct light: emission seen directly plus light reaching the first surface  straight from a light.
    float indirect[3]; // Mean indirect light: everything else.
    float depth; // Mean distance along the camera ray to the first hit; SKY_DEPTH when it escapes.
    float normal[3]; // Mean shading normal at the first hit, facing the camera; 0 for sky.
    float albedo[3]; // Mean albedo ("texture") at the first hit; 0 for sky.
    float albedo2[3]; // Mean albedo of the first diffuse surface after the first bounce ("texture2"); 0 if none.
} FilterVector;
// Float lanes of FilterVector (offset / 4).
#define FILTER_VECTOR_DIRECT 0
#define FILTER_VECTOR_INDIRECT 3
#define FILTER_VECTOR_DEPTH 6
#define FILTER_VECTOR_NORMAL 7
#define FILTER_VECTOR_ALBEDO 10
#define FILTER_VECTOR_ALBEDO2 13
#define FILTER_VECTOR_FLOATS 16

// The thesis's variance WelfordSums GB (eq. 6.2), held as Welford's running sums of squared
// deviations S_n (eq. 6.6): the variance S_n / (n - 1) is formed only where a filter reads
// it. 13 floats padded to one float16 (§6.3.1).
typedef struct __attribute__((aligned(64))) {
    float depth;
    float normal[3];
    float albedo[3];
    float direction[3]; // Direction leaving the first hit (its mean lives in WelfordState, not in F).
    float albedo2[3];
    float pad[3];
} WelfordSums;
// Float lanes of WelfordSums (offset / 4).
#define WELFORD_SUMS_DEPTH 0
#define WELFORD_SUMS_NORMAL 1
#define WELFORD_SUMS_ALBEDO 4
#define WELFORD_SUMS_DIRECTION 7
#define WELFORD_SUMS_ALBEDO2 10
#define WELFORD_SUMS_FLOATS 16

// The rest of Welford's running state (eq. 6.6), neither a FilterVector mean nor an S_n:
// the mean first-bounce direction and the Kahan compensation of every S_n (see
// kernels/render/film.cl on float32).
typedef struct __attribute__((aligned(16))) {
    float direction_mean[3];
    float pad;
    float s_compensation[16]; // Kahan compensation of each WelfordSums lane's S_n (13 used).
} WelfordState;
// Float lanes of WelfordState (offset / 4).
#define WELFORD_STATE_DIRECTION_MEAN 0
#define WELFORD_STATE_S_COMPENSATION 4
#define WELFORD_STATE_FLOATS 20

// The depth mean on shifted data (see kernels/render/film.cl): F.depth = shift + mean.
typedef struct __attribute__((aligned(8))) {
    float shift; // The pixel's first depth sample K.
    float mean; // Running mean of x - K (eq. 6.5).
} DepthShift;
// Float lanes of DepthShift (offset / 4).
#define DEPTH_SHIFT_SHIFT 0
#define DEPTH_SHIFT_MEAN 1
#define DEPTH_SHIFT_FLOATS 2

// Parameters of the data-driven filter for one run (thesis Tables 6.2, 6.3).
typedef struct __attribute__((aligned(16))) {
    uint width;
    uint height;
    int half_width; // (kw - 1) / 2 (Alg. 8 line 2).
    int step; // 1, or 2 with holes (§6.3.3).
    float sigma2_dc; // Eq. 6.8: 1 / (2 sigma_dc^2).
    float sigma2_ic; // Eq. 6.9: 1 / (2 sigma_ic^2).
    float variance_factor; // Multiplies GB to give variances: 1 / (n - 1) for Welford sums, 1 for variances.
    float depth_scale; // Multiplies depths before they are compared (depth in hundredths of the scene size).
    float sigma2_f[5]; // 1 / (2 sigma_f,i^2) for depth, normal, texture, direction, texture2 (eq. 6.10).
    uint pad2[3];
    float variance_scale[5]; // The variance scales s_f,i, same order.
    uint pad3[3];
} DdfParams;

// One path sample as Random Parameter Filtering stores it (thesis §5.1.1, Table 5.1):
// 26 floats. Written by the megakernel only when RPF is requested.
typedef struct __attribute__((aligned(4))) {
    float position[2]; // Screen position: pixel coordinates plus the random point inside the pixel.
    float random[6]; // Random parameters: lens u, v; time t (always 0); first-bounce direction x, y, z.
    float world1[3]; // World position of the first hit (camera origin + SKY_DEPTH x direction for sky).
    float normal1[3]; // Shading normal of the first hit (0 for sky).
    float world2[3]; // World position of the second hit (0 when the path ends before).
    float normal2[3]; // Shading normal of the second hit (0 when the path ends before).
    float texture1[3]; // Albedo ("texture") of the first hit.
    float color[3]; // The sample's colour (direct + indirect).
} SampleVector;
// Float lanes of SampleVector (offset / 4).
#define SAMPLE_VECTOR_POSITION 0
#define SAMPLE_VECTOR_RANDOM 2
#define SAMPLE_VECTOR_WORLD1 8
#define SAMPLE_VECTOR_NORMAL1 11
#define SAMPLE_VECTOR_WORLD2 14
#define SAMPLE_VECTOR_NORMAL2 17
#define SAMPLE_VECTOR_TEXTURE1 20
#define SAMPLE_VECTOR_COLOR 23
#define SAMPLE_VECTOR_FLOATS 26

// Parameters of one pass of the edge-avoiding a-trous filter (Dammertz et al. 2010).
typedef struct __attribute__((aligned(16))) {
    float4 camera_origin; // Camera, to turn depth into world position.
    float4 camera_forward;
    float4 camera_right;
    float4 camera_up;
    uint width;
    uint height;
    int step; // Tap spacing of this pass, 2^iteration.
    uint iteration;
    float sigma_color;
    float sigma_normal;
    float sigma_position;
    float tan_half_fov;
} AtrousParams;

// AAF soft shadows (Wang 2013 ch. 3), what the megakernel gathers per pixel for the one
// sphere light whose shadows are filtered: a running mean over the path samples, like F.
typedef struct __attribute__((aligned(16))) {
    float direct[3]; // The light the path samples whose first hit is the pixel centre's receiver brought  to it straight from that light (its next-event estimate, or its emission found by  the first bounce): the part of F that the filtered term replaces.
    float pad0;
    float unshadowed[3]; // The same samples' unoccluded term: albedo × the light's unoccluded term at their  first hit (kernels/render/shadows.cl `shadow_unshadowed`), 0 for a sample off the  receiver: eq. 3.1's r(x) averaged over the pixel as `direct` is, so that the  sheared filter's r · v stands where `direct` stood (texture and edge included).
    float pad1;
} ShadowTerms;
// Float lanes of ShadowTerms (offset / 4).
#define SHADOW_TERMS_DIRECT 0
#define SHADOW_TERMS_UNSHADOWED 4
#define SHADOW_TERMS_FLOATS 8

// AAF soft shadows: the primary hit through the pixel centre (and the lens centre) and its
// light samples (kernels/render/shadows.cl), from the sparse and the adaptive pass.
typedef struct __attribute__((aligned(16))) {
    float visible; // Σ f·l over the light samples: l = cos θ at the receiver, f = 1 when unoccluded.
    float weight; // Σ l (eq. 3.2's normaliser); 0 when the pixel is no receiver.
    float samples; // Light samples traced (sparse + adaptive).
    float occluded; // Samples whose shadow ray met an occluder.
    float light_distance; // d1: receiver-to-light-centre distance.
    float slope_max; // s1 = max(d1/d2 − 1) over the occluded samples (eq. 3.5).
    float slope_min; // s2 = min(d1/d2 − 1) over the occluded samples.
    float slope_source; // 0: no slopes; 1: from the pixel's own occluded samples; 2: filled from neighbours.
    float pixel_size; // d: the world size of one pixel at the hit (eq. 3.4).
    float target; // n(x) of eq. 3.5 clamped to [sparse, max] (before rounding to whole strata).
    float object; // The object hit: mesh part for triangles, −1 − index for spheres.
    float centre_visible; // V of the one shadow ray from the centre's hit to the light's centre: 1 visible, 0  occluded or the centre below the surface (the binary matte of the stylized-shadows  filter, DeCoro 2009 §3.3 step 1).
    float position[3]; // World position of the hit.
    float occluder_distance; // d(x): distance from the hit to the nearest occluder on that ray; 0 when visible or  below the surface (DeCoro §3.3.2 "approximate distance to occluder").
    float normal[3]; // Shading normal at the hit, facing the camera.
    float pad2;
    float unshadowed[3]; // Σ r(x_k) over the light samples' points x_k on the receiver: r of eq. 3.1, the  light's unshadowed direct term from its centre with the albedo (albedo · L sin²α  cos θ_c); divided by `samples` it is r over the pixel, anti-aliased as the samples  spread over it.
    float pad3;
} ShadowPixel;
// Float lanes of ShadowPixel (offset / 4).
#define SHADOW_PIXEL_VISIBLE 0
#define SHADOW_PIXEL_WEIGHT 1
#define SHADOW_PIXEL_SAMPLES 2
#define SHADOW_PIXEL_OCCLUDED 3
#define SHADOW_PIXEL_LIGHT_DISTANCE 4
#define SHADOW_PIXEL_SLOPE_MAX 5
#define SHADOW_PIXEL_SLOPE_MIN 6
#define SHADOW_PIXEL_SLOPE_SOURCE 7
#define SHADOW_PIXEL_PIXEL_SIZE 8
#define SHADOW_PIXEL_TARGET 9
#define SHADOW_PIXEL_OBJECT 10
#define SHADOW_PIXEL_CENTRE_VISIBLE 11
#define SHADOW_PIXEL_POSITION 12
#define SHADOW_PIXEL_OCCLUDER_DISTANCE 15
#define SHADOW_PIXEL_NORMAL 16
#define SHADOW_PIXEL_UNSHADOWED 20
#define SHADOW_PIXEL_FLOATS 24

// Sheared filtering (Yan et al. 2015 §3.1, issue 16): the 4-D light field of one pixel,
// l × l samples on a jittered grid. Soft shadows: the visibility of the pixel centre's
// receiver towards points of the filtered sphere light's square [−R, R]² in one global
// frame (kernels/render/light_field.cl), and the screen directions of the light's two axes
// (Fig. 5a). Depth of field: the radiance through points of the lens square [−A, A]²
// (kernels/render/lens_field.cl), the slopes, the lens-centre hit and the fallback's 36
// extra samples; the shadow pass leaves those lanes 0.
typedef struct __attribute__((aligned(16))) {
    float samples[16]; // Shadows: visibility f ∈ {0, 1} of grid point (a, b) at lane b·l + a (a along the  light's first axis y1, b along y2). Depth of field: the red radiance through lens  point (a, b) (a along the camera's right, b along its down). Lanes from l² on are 0.
    float jitter[2]; // The pixel's jitter j ∈ [0, 1)²: point (a, b) is at y = R (2 (a + j) / l − 1).
    float dir1[2]; // Unit screen direction (pixels) in which the receiver's x1 grows with x2 fixed  (depth of field: the row, (1, 0)).
    float dir2[2]; // The same for x2 with x1 fixed (depth of field: the column, (0, 1)).
    float scale[2]; // World x1 per pixel along dir1, world x2 per pixel along dir2 (0: not defined;  depth of field: 1, x is in pixels).
    float count; // l² for a receiver (depth of field: every pixel), 0 for none.
    float slopes[2]; // Depth of field: s_min and s_max of s = W (F/z − 1) / S over the l² samples (pixels  per metre of lens; Yan et al. §3.2), z the depth of each sample's first hit.
    float extra_samples; // Depth of field: 36 where s_min · s_max < 0 (the fallback's extra samples), else 0.
    float green[16]; // Depth of field: the green radiance of lens point (a, b), lanes as `samples`.
    float blue[16]; // Depth of field: the blue radiance, lanes as `samples`.
    float position[3]; // Depth of field: the first hit of the ray through the pixel centre and the lens  centre (0 where it leaves the scene).
    float pad0;
    float normal[3]; // Depth of field: that hit's shading normal, facing the camera (0: no hit).
    float pad1;
    float extra[4]; // Depth of field: Σ w(u) L(u) (rgb) and Σ w(u) (w) over the 36 extra samples, w the  Gaussian aperture of σ = A/2.
} LightFieldPixel;
// Float lanes of LightFieldPixel (offset / 4).
#define LIGHT_FIELD_PIXEL_SAMPLES 0
#define LIGHT_FIELD_PIXEL_JITTER 16
#define LIGHT_FIELD_PIXEL_DIR1 18
#define LIGHT_FIELD_PIXEL_DIR2 20
#define LIGHT_FIELD_PIXEL_SCALE 22
#define LIGHT_FIELD_PIXEL_COUNT 24
#define LIGHT_FIELD_PIXEL_SLOPES 25
#define LIGHT_FIELD_PIXEL_EXTRA_SAMPLES 27
#define LIGHT_FIELD_PIXEL_GREEN 28
#define LIGHT_FIELD_PIXEL_BLUE 44
#define LIGHT_FIELD_PIXEL_POSITION 60
#define LIGHT_FIELD_PIXEL_NORMAL 64
#define LIGHT_FIELD_PIXEL_EXTRA 68
#define LIGHT_FIELD_PIXEL_FLOATS 72

// Sheared soft shadows and depth of field together (Yan et al. 2015, appendix eqs.
// 16-17; issue 16): beside the lens field (a [`LightFieldPixel`] per pixel whose radiance
// lanes hold each lens sample's light without the filtered sphere lights' direct term on
// the pixel centre's receiver, kernels/render/lens_field.cl `lens_shadow_field_sample`),
// what the filter needs to put that term back after filtering the shadows: eq. 16's
// texture k(x, u) of every lens sample and eq. 17's F̄ per light.
typedef struct __attribute__((aligned(16))) {
    float albedo[16]; // Red albedo k(x, u) of lens point (a, b)'s first hit where that hit took the  filtered lights' direct term out (a diffuse hit on the pixel centre's receiver),  else 0; lanes as [`LightFieldPixel::samples`].
    float albedo_green[16]; // The green albedo, lanes as `albedo`.
    float albedo_blue[16]; // The blue albedo, lanes as `albedo`.
    float albedo_extra[4]; // Σ w(u) k(u) (rgb) over the fallback's 36 extra samples (their Σ w is the lens  field's extra.w); w: 0.
    float4 unshadowed[8]; // Per shadow plane: eq. 17's F̄ without its visibility, the mean over the lens samples  on the receiver of the plane's light's unoccluded term (rgb; eq. 3.1's r / albedo,  kernels/render/shadows.cl `shadow_unshadowed`), and (w) how many samples that is.
} LensShadowPixel;
// Float lanes of LensShadowPixel (offset / 4).
#define LENS_SHADOW_PIXEL_ALBEDO 0
#define LENS_SHADOW_PIXEL_ALBEDO_GREEN 16
#define LENS_SHADOW_PIXEL_ALBEDO_BLUE 32
#define LENS_SHADOW_PIXEL_ALBEDO_EXTRA 48
#define LENS_SHADOW_PIXEL_UNSHADOWED 52
#define LENS_SHADOW_PIXEL_FLOATS 84

// AAF indirect light (Wang 2013 ch. 4; kernels/render/indirect.cl): the primary hit
// through the pixel centre (and the lens centre) and the indirect samples of the sparse
// and the adaptive pass, for one of two lobes: a diffuse receiver's cosine-weighted
// hemisphere or a metal receiver's Phong lobe (the seed's separate glossy buffer).
typedef struct __attribute__((aligned(16))) {
    float irradiance[3]; // Σ L_i over the indirect samples, L_i the radiance arriving along the sampled  direction. Diffuse: cosine-weighted samples, so albedo · Σ L_i / `weight` is the  indirect light a Lambertian receiver sends to the camera (Σ L_i / n is the  demodulated irradiance / π). Glossy: samples of the Phong lobe (f cos / pdf is the  metal's colour), so colour · Σ L_i / `weight` is the metal's indirect light.
    float samples; // Indirect samples traced (sparse + adaptive), 0 for no receiver.
    float albedo[3]; // Σ albedo(x_k) over the samples' points x_k on the receiver (a metal's colour).
    float weight; // Samples whose point lay on the centre's receiver (the normaliser of both sums).
    float position[3]; // World position of the centre's hit.
    float z_min; // z_min: the nearest first-bounce hit over the sparse samples (eqs. 4.4, 4.6); 0 when  no sample hit a surface.
    float normal[3]; // Shading normal at the centre's hit, facing the camera.
    float z_max; // z_max: the farthest first-bounce hit (eq. 4.6 uses it but the seed never defines  it: the maximum reflector distance).
    float pixel_size; // d: the world size of one pixel at the hit (eq. 4.4; A_p = d²).
    float target; // n(x) of eq. 4.6 clamped to [sparse, max] (before rounding to whole strata).
    float object; // The object hit: mesh part for triangles, −1 − index for spheres.
    float reflectors; // Sparse samples whose first bounce hit a surface (the z's are defined when > 0).
    float bandlimit; // Ω_h^max of the receiver's lobe (eq. 4.5): 2.8 diffuse, 3.6 + 0.084 m for a metal  of Phong exponent m; 0 for no receiver. Eqs. 4.4 and 4.6 use it.
    float lobe; // The lobe: 0 diffuse, 1 glossy (a metal receiver).
    float pad[2];
} IndirectPixel;
// Float lanes of IndirectPixel (offset / 4).
#define INDIRECT_PIXEL_IRRADIANCE 0
#define INDIRECT_PIXEL_SAMPLES 3
#define INDIRECT_PIXEL_ALBEDO 4
#define INDIRECT_PIXEL_WEIGHT 7
#define INDIRECT_PIXEL_POSITION 8
#define INDIRECT_PIXEL_Z_MIN 11
#define INDIRECT_PIXEL_NORMAL 12
#define INDIRECT_PIXEL_Z_MAX 15
#define INDIRECT_PIXEL_PIXEL_SIZE 16
#define INDIRECT_PIXEL_TARGET 17
#define INDIRECT_PIXEL_OBJECT 18
#define INDIRECT_PIXEL_REFLECTORS 19
#define INDIRECT_PIXEL_BANDLIMIT 20
#define INDIRECT_PIXEL_LOBE 21
#define INDIRECT_PIXEL_FLOATS 24

// Parameters of the AAF soft-shadow filter passes (kernels/filters/aaf_shadows.cl).
typedef struct __attribute__((aligned(16))) {
    float4 light; // The filtered sphere light: centre (xyz) and radius (w).
    uint width;
    uint height;
    int radius; // Half width of the 1-D window, pixels.
    uint axis; // 0: the pass along rows (x), 1: along columns (y).
    float sigma; // σ of the light (R/2).
    float normal_cos; // cos of the largest normal angle between neighbours.
    float depth_tolerance; // Largest offset along the light direction, in units of β.
    float beta_tolerance; // Largest |β − β'| / max(β, β').
} AafShadowParams;

// Parameters of the sheared soft-shadow filter (kernels/filters/sheared.cl; Yan et al.
// 2015 eqs. 3-15; src/filters/sheared).
typedef struct __attribute__((aligned(16))) {
    float4 light; // The filtered sphere light: centre (xyz) and radius R (w).
    float4 axis1; // The light's axes e1, e2 (xyz; src/render/shadows/light_field.rs `light_frame`).
    float4 axis2;
    uint width;
    uint height;
    uint side; // Grid side l (l² samples per pixel).
    uint bins; // Bins of the free light coordinate in steps 1a/2a (odd: one bin at y = 0).
    float sigma_y; // σ_y = 2/Ω_y^max = R/2, the Gaussian light's standard deviation (eq. 4).
    float range; // The bins cover [−range, range].
    float normal_cos; // cos of the largest normal angle between neighbours.
    float depth_tolerance; // Largest offset along the light direction, in units of the written pixel's σ_x.
    int max_radius; // Most steps of a 1-D gather on either side (16: the seed's 32 px diameter).
    float shear; // Factor on eq. 5's η (1: the shear as settled by tests/sheared_filter.rs, 0: no shear).
    float pad0;
    float pad1;
} ShearedParams;

// Parameters of the AAF diffuse-indirect filter (kernels/filters/aaf_indirect.cl).
typedef struct __attribute__((aligned(16))) {
    uint width;
    uint height;
    int radius; // Half width of the 1-D window, pixels.
    uint axis; // 0: the pass along rows (x), 1: along columns (y).
    uint glossy; // 1: glossy (metal) receivers are filtered; 0: they keep F as rendered.
    float footprints; // The floor of β in pixel footprints (eq. 4.4's d / 0.15: 1 / 0.15).
    float normal_cos; // cos of the largest normal angle between neighbours.
    float depth_tolerance; // Largest offset along the normal, in units of β.
} AafIndirectParams;

#endif
