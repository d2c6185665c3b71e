//! Plain Rust references of the kernels: the same algorithms, the same order of operations,
//! over the same arrays (src/render/arrays.rs). Tests run a kernel and its reference on the
//! same inputs and compare; the host also uses them where it needs a ray query itself
//! (autofocus).
//!
//! | kernel file            | reference            |
//! |------------------------|----------------------|
//! | kernels/rng.cl         | [`rng`]              |
//! | kernels/geometry.cl    | [`geometry`]         |
//! | kernels/scene.cl       | [`trace`]            |
//! | kernels/sampling.cl    | [`sampling`]         |
//! | kernels/camera.cl      | [`sampling::camera_ray`] |
//! | kernels/materials.cl, lights.cl, film.cl, pathtrace.cl | [`pathtrace`] |

pub mod geometry;
pub mod pathtrace;
pub mod rng;
pub mod sampling;
pub mod trace;
