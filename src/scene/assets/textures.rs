//! The bundled texture images, made by code: 8-bit sRGB images (checkerboard, bricks, wood
//! grain, marble, floor tiles), all seamlessly tileable, and an equirectangular sky for the
//! infinite light (half-float OpenEXR: blue gradient, sun disk, soft clouds, darker ground).
//!
//! `write_all` writes them to a folder (`cargo run --release --bin make_assets --
//! scenes/textures`); the files in scenes/textures/ are its output and tests/assets.rs checks
//! that they still decode to exactly what these functions make. All arithmetic is done in
//! f64 and only then rounded to 8 or 16 bits, so the result does not depend on the last bit
//! of a platform's sin or exp.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use exr::prelude::f16;

/// An 8-bit sRGB RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb8 {
    /// File name (PNG) in the texture folder.
    pub file: &'static str,
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 3]>,
}

/// A linear half-float RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbHalf {
    /// File name (OpenEXR) in the texture folder.
    pub file: &'static str,
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f16; 3]>,
}

/// The file name of the sky.
pub const SKY_FILE: &str = "sky.exr";

/// All 8-bit textures.
pub fn ldr_textures() -> Vec<Rgb8> {
    vec![checker(), bricks(), wood(), marble(), tiles()]
}

/// Writes every texture into `dir` (created if missing); returns the paths written.
pub fn write_all(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut written = Vec::new();
    for t in ldr_textures() {
        let path = dir.join(t.file);
        let bytes: Vec<u8> = t.pixels.iter().flatten().copied().collect();
        image::save_buffer(
            &path,
            &bytes,
            t.width,
            t.height,
            image::ExtendedColorType::Rgb8,
        )
        .with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    let sky = sky();
    let path = dir.join(sky.file);
    write_exr(&path, &sky)?;
    written.push(path);
    Ok(written)
}

fn write_exr(path: &Path, img: &RgbHalf) -> anyhow::Result<()> {
    use exr::prelude::*;
    let w = img.width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = img.pixels[y * w + x];
        (p[0], p[1], p[2])
    });
    Image::from_encoded_channels((w, img.height as usize), Encoding::SMALL_LOSSLESS, channels)
        .write()
        .to_file(path)
        .with_context(|| format!("cannot write {}", path.display()))
}

// ---------------------------------------------------------------------------------------
// Noise: periodic value noise on an integer lattice (so textures tile), summed in octaves.

fn hash(x: i64, y: i64, salt: u64) -> u64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ salt.wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    h = h.wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^ (h >> 32)
}

/// Uniform in [0, 1) from a lattice point.
fn lattice(x: i64, y: i64, salt: u64) -> f64 {
    (hash(x, y, salt) >> 11) as f64 / (1u64 << 53) as f64
}

/// Value noise in [0, 1) with period `px` x `py` lattice cells.
fn value_noise(x: f64, y: f64, px: i64, py: i64, salt: u64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let (tx, ty) = (x - fx, y - fy);
    let s = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (sx, sy) = (s(tx), s(ty));
    let at = |dx: i64, dy: i64| lattice((ix + dx).rem_euclid(px), (iy + dy).rem_euclid(py), salt);
    let a = at(0, 0) + (at(1, 0) - at(0, 0)) * sx;
    let b = at(0, 1) + (at(1, 1) - at(0, 1)) * sx;
    a + (b - a) * sy
}

/// Fractal sum of `octaves` of periodic value noise, in [0, 1). `(u, v)` in [0,1)^2 spans one
/// period; the lowest octave has `cells` lattice cells across.
fn fbm(u: f64, v: f64, cells: i64, octaves: u32, salt: u64) -> f64 {
    let (mut sum, mut amp, mut norm) = (0.0, 1.0, 0.0);
    let mut c = cells;
    for o in 0..octaves {
        sum += amp * value_noise(u * c as f64, v * c as f64, c, c, salt + o as u64);
        norm += amp;
        amp *= 0.5;
        c *= 2;
    }
    sum / norm
}

fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// An image from `f(u, v)` giving sRGB values in [0, 1], (u, v) at pixel centres, v down.
fn render8(file: &'static str, size: u32, f: impl Fn(f64, f64) -> [f64; 3]) -> Rgb8 {
    let mut pixels = Vec::with_capacity((size * size) as usize);
    for y in 0..size {
        for x in 0..size {
            let u = (x as f64 + 0.5) / size as f64;
            let v = (y as f64 + 0.5) / size as f64;
            let c = f(u, v);
            pixels.push(c.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8));
        }
    }
    Rgb8 {
        file,
        width: size,
        height: size,
        pixels,
    }
}

fn rgb(r: u8, g: u8, b: u8) -> [f64; 3] {
    [r as f64 / 255.0, g as f64 / 255.0, b as f64 / 255.0]
}

// ---------------------------------------------------------------------------------------
// The textures.

/// 8 x 8 checks, cream and slate blue, with a faint grain so the filters see texture, not
/// just two colours.
pub fn checker() -> Rgb8 {
    let (a, b) = (rgb(232, 226, 208), rgb(52, 66, 112));
    render8("checker.png", 256, |u, v| {
        let odd = ((u * 8.0).floor() as i64 + (v * 8.0).floor() as i64) % 2 == 1;
        let g = 0.94 + 0.06 * fbm(u, v, 32, 2, 11);
        let c = if odd { b } else { a };
        c.map(|c| c * g)
    })
}

/// Running-bond red bricks with light mortar: 4 courses of 2 bricks (tiles seamlessly).
pub fn bricks() -> Rgb8 {
    let mortar = rgb(196, 190, 178);
    render8("bricks.png", 256, |u, v| {
        let rows = 8.0;
        let cols = 4.0;
        let row = (v * rows).floor();
        let shift = if row as i64 % 2 == 1 { 0.5 } else { 0.0 };
        let cu = u * cols + shift;
        let col = cu.floor();
        let (fu, fv) = (cu - col, v * rows - row);
        // Mortar joints: about 3 px of 64 across, 3 px of 32 down.
        let joint = 0.045;
        let edge = (fu.min(1.0 - fu) / joint * 0.5).min(fv.min(1.0 - fv) / (2.0 * joint) * 0.5);
        let m = smoothstep(0.35, 0.6, edge);
        let id = (col as i64).rem_euclid(cols as i64) * 17 + row as i64;
        let tone = lattice(id, 3, 5);
        let base = mix(rgb(150, 58, 38), rgb(178, 92, 60), tone);
        let base = mix(base, rgb(110, 46, 34), 0.35 * lattice(id, 9, 7));
        let speck = 0.85 + 0.3 * fbm(u, v, 16, 4, 21);
        let brick = base.map(|c| c * speck);
        let mort = mortar.map(|c| c * (0.92 + 0.08 * fbm(u, v, 64, 2, 31)));
        mix(mort, brick, m)
    })
}

/// Wood planks: grain lines along u, warped by noise, with slightly different planks.
pub fn wood() -> Rgb8 {
    let (light, dark) = (rgb(206, 160, 104), rgb(128, 80, 42));
    render8("wood.png", 256, |u, v| {
        let planks = 4.0;
        let plank = (v * planks).floor();
        let warp = fbm(u, v, 4, 4, 41);
        let ring = ((v * 24.0 + 3.0 * warp + lattice(plank as i64, 0, 43) * 7.0)
            * std::f64::consts::TAU)
            .sin();
        let grain = 0.5 + 0.5 * ring;
        let fine = fbm(u, v * 8.0 - (v * 8.0).floor(), 32, 3, 47);
        let t = (0.65 * grain.powf(3.0) + 0.35 * fine).clamp(0.0, 1.0);
        let c = mix(light, dark, t);
        let tone = 0.9 + 0.15 * lattice(plank as i64, 1, 49);
        // A dark seam between planks.
        let fv = v * planks - plank;
        let seam = smoothstep(0.0, 0.02, fv.min(1.0 - fv));
        c.map(|c| c * tone * (0.55 + 0.45 * seam))
    })
}

/// White marble with grey-green veins.
pub fn marble() -> Rgb8 {
    let (white, vein) = (rgb(236, 234, 228), rgb(78, 92, 88));
    render8("marble.png", 256, |u, v| {
        let turb = fbm(u, v, 4, 6, 61);
        let s = ((u + v) * std::f64::consts::TAU * 2.0 + 9.0 * turb).sin();
        let t = (1.0 - s.abs()).powf(6.0);
        let cloud = 0.9 + 0.1 * fbm(u, v, 8, 4, 67);
        mix(white.map(|c| c * cloud), vein, 0.85 * t)
    })
}

/// A floor of 4 x 4 square tiles in two tones with dark grout.
pub fn tiles() -> Rgb8 {
    let grout = rgb(70, 66, 60);
    render8("tiles.png", 256, |u, v| {
        let n = 4.0;
        let (cu, cv) = (u * n, v * n);
        let (iu, iv) = (cu.floor(), cv.floor());
        let (fu, fv) = (cu - iu, cv - iv);
        let edge = fu.min(1.0 - fu).min(fv.min(1.0 - fv));
        let g = smoothstep(0.012, 0.03, edge);
        let odd = (iu as i64 + iv as i64) % 2 == 1;
        let base = if odd {
            rgb(196, 184, 160)
        } else {
            rgb(150, 110, 80)
        };
        let id_u = (iu as i64).rem_euclid(4);
        let id_v = (iv as i64).rem_euclid(4);
        let tone = 0.9 + 0.12 * lattice(id_u, id_v, 71);
        let mottle = 0.9 + 0.12 * fbm(u, v, 16, 4, 73);
        let tile = base.map(|c| c * tone * mottle);
        mix(grout, tile, g)
    })
}

/// The sun's direction (unit, y up): elevation 35 degrees, behind and to the left of a
/// camera looking along -z.
pub fn sun_direction() -> [f64; 3] {
    let el = 35f64.to_radians();
    let az = (-125f64).to_radians();
    direction(az, el)
}

/// Direction for an azimuth (0 at -z, positive towards +x) and elevation, matching the
/// renderer's equirectangular lookup (u = 0.5 + atan2(x, -z) / 2pi, v = 0.5 + asin(y) / pi).
fn direction(az: f64, el: f64) -> [f64; 3] {
    [el.cos() * az.sin(), el.sin(), -el.cos() * az.cos()]
}

/// Linear radiance of the sky in direction `d` (unit).
fn sky_radiance(d: [f64; 3]) -> [f64; 3] {
    let y = d[1];
    let sun = sun_direction();
    let cos_g = (d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2]).clamp(-1.0, 1.0);
    let gamma = cos_g.acos();
    if y < 0.0 {
        // Ground: dark earth, hazier towards the horizon.
        let ground = [0.16, 0.14, 0.11];
        let haze = [0.45, 0.48, 0.5];
        let t = (-y / 0.08).min(1.0);
        return mix(haze, ground, smoothstep(0.0, 1.0, t));
    }
    let zenith = [0.12, 0.26, 0.68];
    let horizon = [0.62, 0.72, 0.88];
    let t = (1.0 - y).powf(4.0);
    let mut c = mix(zenith, horizon, t);
    // Brighter around the sun.
    let glow = 0.5 * (-gamma / 0.25).exp() + 0.12 * (-gamma / 0.8).exp();
    c = c.map(|v| v + glow);
    // Clouds on a plane above the ground, fading out towards the horizon.
    if y > 0.015 {
        let (px, pz) = (d[0] / y, d[2] / y);
        let (u, v) = (px * 0.045, pz * 0.045);
        let (u, v) = (u - u.floor(), v - v.floor());
        let n = fbm(u, v, 6, 6, 91);
        let cover = smoothstep(0.5, 0.7, n) * smoothstep(0.015, 0.2, y);
        let shade = 0.75 + 0.35 * fbm(u, v, 12, 4, 97);
        let cloud = [0.95, 0.95, 0.97].map(|v| v * shade + 0.4 * glow);
        c = mix(c, cloud, 0.9 * cover);
    }
    // The sun: a disk of 2 degrees radius with a soft rim.
    let disk = 1.0 - smoothstep(1.8f64.to_radians(), 2.2f64.to_radians(), gamma);
    let sun_radiance = [20.0, 18.5, 16.0];
    mix(c, sun_radiance, disk)
}

/// The equirectangular sky, 1024 x 512: y up, u = 0.5 looks along -z.
pub fn sky() -> RgbHalf {
    let (w, h) = (1024u32, 512u32);
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for py in 0..h {
        for px in 0..w {
            let u = (px as f64 + 0.5) / w as f64;
            let v = 1.0 - (py as f64 + 0.5) / h as f64;
            let az = (u - 0.5) * std::f64::consts::TAU;
            let el = (v - 0.5) * std::f64::consts::PI;
            let c = sky_radiance(direction(az, el));
            pixels.push(c.map(f16::from_f64));
        }
    }
    RgbHalf {
        file: SKY_FILE,
        width: w,
        height: h,
        pixels,
    }
}
