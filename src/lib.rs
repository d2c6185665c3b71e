//! noisefree: a physically based OpenCL path tracer with per-pixel feature statistics and
//! real-time denoising filters, after M. van de Vlasakker, *Physically Accurate Noise Free
//! Real-time Rendering*, MSc thesis, Utrecht University, 2013.
//!
//! Modules follow the data: [`scene`] → [`bvh`] → [`render`] (device buffers and the
//! megakernel in `kernels/`) → [`stats`] (per-pixel statistics) → [`filters`] → [`output`],
//! [`metrics`], [`bench`] → [`cli`]. [`layout`] is the one definition of every struct shared
//! with the kernels; [`reference`] holds plain Rust versions of the kernels for tests.

// Comparisons such as `!(x > 0.0)` are deliberate: they are also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod arrays;
pub mod bench;
pub mod bvh;
pub mod cli;
pub mod filters;
pub mod geometry;
pub mod gpu;
pub mod imaging;
pub mod kernels;
pub mod layout;
pub mod memory;
pub mod metrics;
pub mod render;
pub mod scene;
pub mod stats;
pub mod view;
