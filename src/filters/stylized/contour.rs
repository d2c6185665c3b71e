//! Step 1 (DeCoro 2009 §3.3.3 "Distance Transform", digest §1.3 step 2): the shadow contour C
//! as a list of points, the plain Rust reference of `st_contour` in
//! kernels/filters/stylized.cl, and the compaction both use.
//!
//! The thesis reads V back to the CPU, detects edges there and sends "a list of coordinates of
//! pixels in C" to the GPU; what counts as contour is not defined (digest §1.2 item 5). Here:
//! - a **contour point** lies between a pixel and its right or lower neighbour whose binary
//!   visibilities differ: the midpoint of their world positions, so that no pixel centre is a
//!   contour point and D ≠ 0 at every pixel (digest §1.3 step 2: "edge-midpoint samples keep
//!   D ≠ 0 at pixel centres"); with them the hard step of eq. 3.3 at i = 0 reproduces V;
//! - both pixels are in the matte (their centre ray hit a diffuse surface), their normals are
//!   within the 45° rule (§3.3.2 "Normal Discontinuities"), and each lies on the other's
//!   surface: the offset between them along their mean normal is at most `gap` pixel
//!   footprints. A pair across a silhouette (a lit object in front of a shadowed floor) is no
//!   boundary of any shadow, and its midpoint floats in the air; two pixels of one plane are
//!   0 apart along its normal at any viewing angle, two of a curved surface nearly so;
//! - its normal is the mean of the two, its occluder distance that of the shadowed pixel
//!   (d(x) of §3.3.2 for the quadratic controls, spread by the distance step).
//!
//! The kernel writes two slots per pixel (right, lower); the host compacts the used ones in
//! pixel order ([`compact`]), as the thesis's CPU pass did. Pixel order, not an atomic
//! counter, so the list (and every random choice from it) is the same on any device.

use glam::Vec3;

use crate::layout::{Float4, ShadowPixel};

/// A matte pixel: the shadow pass wrote a unit normal (zeros where the centre ray found no
/// diffuse surface). kernels/filters/stylized.cl `st_in_matte`.
pub fn in_matte(p: &ShadowPixel) -> bool {
    let n = Vec3::from(p.normal);
    n.dot(n) > 0.5
}

/// `st_contour`: two slots per pixel (right, then lower neighbour), each two float4s:
/// (midpoint, occluder distance) and (normal, 1), zeros when there is no contour point.
pub fn slots(pixels: &[ShadowPixel], width: u32, height: u32, normal_cos: f32, gap: f32) -> Vec<Float4> {
    let mut out = vec![Float4::default(); pixels.len() * 4];
    for y in 0..height {
        for x in 0..width {
            let i = (y * width + x) as usize;
            let a = &pixels[i];
            for dir in 0..2u32 {
                let (nx, ny) = (x + (dir == 0) as u32, y + (dir == 1) as u32);
                if nx >= width || ny >= height {
                    continue;
                }
                let b = &pixels[(ny * width + nx) as usize];
                if !in_matte(a) || !in_matte(b) || a.centre_visible == b.centre_visible {
                    continue;
                }
                let (na, nb) = (Vec3::from(a.normal), Vec3::from(b.normal));
                if na.dot(nb) < normal_cos {
                    continue;
                }
                let (pa, pb) = (Vec3::from(a.position), Vec3::from(b.position));
                let delta = pb - pa;
                let n = na + nb;
                let n = n / n.dot(n).sqrt();
                let foot = a.pixel_size.max(b.pixel_size);
                if n.dot(delta).abs() > gap * foot {
                    continue;
                }
                let occluder = if a.centre_visible == 0.0 {
                    a.occluder_distance
                } else {
                    b.occluder_distance
                };
                let mid = (pa + pb) * 0.5;
                let slot = (i * 2 + dir as usize) * 2;
                out[slot] = Float4([mid.x, mid.y, mid.z, occluder]);
                out[slot + 1] = Float4([n.x, n.y, n.z, 1.0]);
            }
        }
    }
    out
}

/// The used slots in pixel order: the contour list, two float4s per point.
pub fn compact(slots: &[Float4]) -> Vec<Float4> {
    slots
        .chunks_exact(2)
        .filter(|s| s[1].0[3] == 1.0)
        .flatten()
        .copied()
        .collect()
}

/// Points per group of `st_distance`'s lanes (kernels/filters/stylized.cl `ST_LANES`).
pub const LANES: usize = 16;

/// The list as seven planes (x, y, z, occluder distance, normal x, y, z), each padded with
/// zeros by at least two [`LANES`] to a whole number of them, and that padded length: what
/// `st_distance`'s lanes read, sixteen at a time with one vector load per plane when they use
/// every point (no more points than samples), and a window of up to 64 points from the
/// first drawn entry when they draw (whose loads reach up to 31 points past the list's last
/// point: the padding). A draw that spreads wider gathers from the list itself (scalar loads
/// from planes measured slower there).
pub fn planes(list: &[Float4]) -> (Vec<f32>, usize) {
    let count = list.len() / 2;
    let stride = (count + 2 * LANES).div_ceil(LANES) * LANES;
    let mut out = vec![0.0; stride * 7];
    for (k, point) in list.chunks_exact(2).enumerate() {
        for lane in 0..4 {
            out[lane * stride + k] = point[0].0[lane];
        }
        for lane in 0..3 {
            out[(4 + lane) * stride + k] = point[1].0[lane];
        }
    }
    (out, stride)
}
