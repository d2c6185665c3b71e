//! Plain Rust references of the kernels in kernels/render/subtractive.cl, operation for
//! operation in the same order, so the kernel-vs-reference tests can hold them to rounding.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3;

use super::{DirLight, GBuffer};

fn v3(a: &[f32; 4]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

fn rgba(c: Vec3) -> [f32; 4] {
    [c.x, c.y, c.z, 0.0]
}

/// f·(n·ω)·E for the diffuse BRDF f = albedo/π, summed over the lights `pick` accepts
/// (given the light's index), those facing the surface only.
fn sum_lights(
    albedo: Vec3,
    n: Vec3,
    lights: &[DirLight],
    mut pick: impl FnMut(usize) -> bool,
) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for (l, light) in lights.iter().enumerate() {
        let cos = n.dot(light.dir);
        if cos > 0.0 && pick(l) {
            sum += light.irradiance * cos;
        }
    }
    albedo * FRAC_1_PI * sum
}

/// Step 3 (`sub_unshadowed`): C, the unshadowed direct light of `lights`; the sky where the
/// camera ray escapes.
pub fn unshadowed(g: &GBuffer, lights: &[DirLight]) -> Vec<[f32; 4]> {
    (0..g.position.len())
        .map(|k| {
            if g.position[k][3] == 0.0 {
                return g.albedo[k];
            }
            rgba(sum_lights(
                v3(&g.albedo[k]),
                v3(&g.normal[k]),
                lights,
                |_| true,
            ))
        })
        .collect()
}

/// Step 2(c-d) (`sub_shadow`): per sample, the light of the lights whose visibility bit
/// equals `visible`: blocked (false) is the shadow buffer S; visible (true) at every pixel
/// is the additive form, which shows the sky where the ray escapes.
pub fn shadow(
    g: &GBuffer,
    pixels: &[u32],
    lights: &[DirLight],
    bits: &[u32],
    visible: bool,
) -> Vec<[f32; 4]> {
    let words = super::vis_words(lights.len());
    pixels
        .iter()
        .enumerate()
        .map(|(k, &px)| {
            let px = px as usize;
            if g.position[px][3] == 0.0 {
                return if visible { g.albedo[px] } else { [0.0; 4] };
            }
            let row = &bits[k * words..(k + 1) * words];
            let pick = |l: usize| ((row[l / 32] >> (l % 32)) & 1 == 1) == visible;
            rgba(sum_lights(
                v3(&g.albedo[px]),
                v3(&g.normal[px]),
                lights,
                pick,
            ))
        })
        .collect()
}

/// Steps 4-5 (`sub_compose`): S′ at every pixel by joint-bilateral upsampling of S (bilinear
/// weights of the 2×2 nearest samples × G(‖S′_p − S_p‖) × max(S′_n·S_n, 0), §2.2; σ of G =
/// `sigma` × block × the pixel's world footprint), the nearest sample when every weight is 0
/// (§2.4), then max(C − S′, 0).
#[allow(clippy::too_many_arguments)]
pub fn compose(
    g: &GBuffer,
    c: &[[f32; 4]],
    s_low: &[[f32; 4]],
    pixels: &[u32],
    lw: u32,
    lh: u32,
    block: u32,
    sigma: f32,
) -> Vec<[f32; 4]> {
    let w = g.width;
    (0..g.position.len())
        .map(|k| {
            let pos = g.position[k];
            if pos[3] == 0.0 {
                return c[k];
            }
            let (x, y) = (k as u32 % w, k as u32 / w);
            let p = v3(&pos);
            let n = v3(&g.normal[k]);
            let sig = sigma * block as f32 * g.normal[k][3];
            let inv2s2 = 1.0 / (2.0 * sig * sig);
            // Sample (i, j) sits at pixel i·block + block/2: continuous low-res coordinates.
            let half = (block / 2) as f32;
            let fx = (x as f32 - half) / block as f32;
            let fy = (y as f32 - half) / block as f32;
            let (x0, y0) = (fx.floor(), fy.floor());
            let (ax, ay) = (fx - x0, fy - y0);
            let mut sum = Vec3::ZERO;
            let mut wsum = 0.0f32;
            for dj in 0..2 {
                for di in 0..2 {
                    let wb = (if di == 0 { 1.0 - ax } else { ax })
                        * (if dj == 0 { 1.0 - ay } else { ay });
                    let i = (x0 as i32 + di).clamp(0, lw as i32 - 1) as usize;
                    let j = (y0 as i32 + dj).clamp(0, lh as i32 - 1) as usize;
                    let q = pixels[j * lw as usize + i] as usize;
                    if g.position[q][3] == 0.0 {
                        continue;
                    }
                    let d = v3(&g.position[q]) - p;
                    let wg = (-d.dot(d) * inv2s2).exp();
                    let wn = n.dot(v3(&g.normal[q])).max(0.0);
                    let wt = wb * wg * wn;
                    sum += wt * v3(&s_low[j * lw as usize + i]);
                    wsum += wt;
                }
            }
            let s = if wsum > 0.0 {
                sum / wsum
            } else {
                let i = (x / block).min(lw - 1) as usize;
                let j = (y / block).min(lh - 1) as usize;
                v3(&s_low[j * lw as usize + i])
            };
            rgba((v3(&c[k]) - s).max(Vec3::ZERO))
        })
        .collect()
}

/// Step 3 with the prefiltered map (`sub_prefiltered`): C = albedo/π · E(n), E bilinear in the
/// lat-long map of normals (u wraps, v clamps); the sky where the camera ray escapes.
pub fn prefiltered(g: &GBuffer, map: &[[f32; 4]]) -> Vec<[f32; 4]> {
    use super::{MAP_H, MAP_W};
    (0..g.position.len())
        .map(|k| {
            if g.position[k][3] == 0.0 {
                return g.albedo[k];
            }
            let n = v3(&g.normal[k]);
            let u = 0.5 + n.x.atan2(-n.z) * (0.5 * FRAC_1_PI);
            let v = 0.5 + n.y.clamp(-1.0, 1.0).asin() * FRAC_1_PI;
            let fx = u * MAP_W as f32 - 0.5;
            let fy = (v * MAP_H as f32 - 0.5).clamp(0.0, (MAP_H - 1) as f32);
            let (x0, y0) = (fx.floor(), fy.floor());
            let (ax, ay) = (fx - x0, fy - y0);
            let at = |i: i32, j: i32| {
                let i = i.rem_euclid(MAP_W as i32) as u32;
                let j = j.clamp(0, MAP_H as i32 - 1) as u32;
                v3(&map[(j * MAP_W + i) as usize])
            };
            let (i, j) = (x0 as i32, y0 as i32);
            let e = (at(i, j) * (1.0 - ax) + at(i + 1, j) * ax) * (1.0 - ay)
                + (at(i, j + 1) * (1.0 - ax) + at(i + 1, j + 1) * ax) * ay;
            rgba(v3(&g.albedo[k]) * FRAC_1_PI * e)
        })
        .collect()
}
