//! The CPU mirror of the megakernel: plain Rust versions of kernels/render/*.cl with the same
//! algorithms and the same order of float operations, over the same arrays (src/arrays). Tests
//! run a kernel and its mirror on the same inputs and compare. (Ground-truth images are
//! something else: `bench::ground_truth`, many samples of the device renderer.)
//!
//! | kernel file                  | mirror                       |
//! |------------------------------|------------------------------|
//! | kernels/render/rng.cl        | [`rng`]                      |
//! | kernels/render/sampling.cl   | [`sampling`]                 |
//! | kernels/render/camera.cl     | [`sampling::camera_ray`]     |
//! | kernels/render/textures.cl, materials.cl, lights.cl, film.cl, pathtrace.cl | [`pathtrace`] |
//! | kernels/render/shadows.cl, bandlimit.cl | [`shadows`], [`crate::render::shadows::bandlimit`] |
//! | kernels/render/indirect.cl   | [`indirect`], [`crate::render::indirect::bandlimit`] |
//!
//! The ray queries of kernels/arrays/trace.cl and kernels/geometry.cl are mirrored by
//! [`crate::arrays::trace`] and [`crate::geometry`], which the host also uses (autofocus).

pub mod indirect;
pub mod lens_field;
pub mod light_field;
pub mod pathtrace;
pub mod rng;
pub mod sampling;
pub mod shadows;
