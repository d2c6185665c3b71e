//! Subtractive shadows (src/render/subtractive, kernels/render/subtractive.cl; DeCoro 2009
//! ch. 4): the tests of the digest's §2.7 (shared/notes/seed-decoro.md): kernels against the
//! Rust reference, subtractive == additive when S is at full resolution from the same lights,
//! no occluders ⇒ output == C, all blocked, C − S′ ≥ 0 and no NaN when every upsampling
//! weight is 0, the error for a scene without an environment, and §2.7.5 (subtractive beats
//! additive at equal |E| against a many-light reference).

mod common;

use common::*;
use glam::Vec3;
use noisefree::render::subtractive::device::SubtractiveKernels;
use noisefree::render::subtractive::{self as sub, DirLight, GBuffer, Settings, reference};
use noisefree::render::{FrameSettings, SceneArrays};
use noisefree::scene::Scene;
use std::path::Path;

fn arrays(scene: &Scene, w: u32, h: u32) -> SceneArrays {
    let mut f = FrameSettings::from_scene(scene);
    f.width = w;
    f.height = h;
    SceneArrays::build(scene, &f).unwrap()
}

fn kernels() -> SubtractiveKernels {
    SubtractiveKernels::new(gpu()).unwrap()
}

/// Largest |a − b| / max(|b|, floor) over every channel.
fn worst(a: &[[f32; 4]], b: &[[f32; 4]], floor: f32) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs() / y[c].abs().max(floor)))
        .fold(0.0, f32::max)
}

fn rms(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    let n = a.len() as u32;
    noisefree::metrics::mse_rgb(&sub::to_rgb(n, 1, a), &sub::to_rgb(n, 1, b))
        .unwrap()
        .sqrt()
}

fn all_finite_nonnegative(img: &[[f32; 4]]) {
    for p in img {
        for c in &p[..3] {
            assert!(c.is_finite() && *c >= 0.0, "{p:?}");
        }
    }
}

#[test]
fn kernels_match_the_reference_on_outside() {
    let s = arrays(&bundled_scene("outside"), 96, 64);
    let g = sub::gbuffer(&s);
    let k = kernels();
    let dg = k.upload(&g).unwrap();
    let e = sub::environment_lights(&s, 40, 1);
    assert_eq!(e.len(), 40);
    let c_set = sub::environment_lights(&s, 256, 2);
    let c_dev = k.unshadowed(&dg, &c_set).unwrap().image;
    let c_ref = reference::unshadowed(&g, &c_set);
    let map = sub::irradiance_map(&c_set);
    let m_dev = k.prefiltered(&dg, &map).unwrap().image;
    let m_ref = reference::prefiltered(&g, &map);
    let wm = worst(&m_dev, &m_ref, 1e-3);
    // The prefiltered map against the direct sum it tabulates: interpolation error only.
    let lookup = worst(&m_ref, &c_ref, 1e-2);
    eprintln!("prefiltered kernel vs reference {wm:e}; map lookup vs direct sum {lookup:e}");
    // Measured on PoCL: kernel vs reference 3.4e-7 (atan2/asin of the device vs libm, a few
    // ulps of u, v), bound 1e-6; the 64×32 map's bilinear lookup against the direct sum over
    // the same 256 lights 4.5e-3 at worst (relative, floor 1e-2), bound 1e-2.
    assert!(wm < 1e-6, "prefiltered: {wm}");
    assert!(lookup < 1e-2, "map vs sum: {lookup}");
    let (lw, lh, pixels) = sub::low_res(g.width, g.height, 4);
    assert_eq!((lw, lh, pixels.len()), (24, 16, 384));
    let bits = sub::shadow_visibility(&s, &g, &pixels, &e);
    let s_dev = k.shadow(&dg, &pixels, &e, &bits, false).unwrap().image;
    let s_ref = reference::shadow(&g, &pixels, &e, &bits, false);
    let all: Vec<u32> = (0..g.width * g.height).collect();
    let all_bits = sub::shadow_visibility(&s, &g, &all, &e);
    let a_dev = k.shadow(&dg, &all, &e, &all_bits, true).unwrap().image;
    let a_ref = reference::shadow(&g, &all, &e, &all_bits, true);
    let o_dev = k
        .compose(&dg, &c_ref, &s_ref, &pixels, lw, lh, 4, 1.0)
        .unwrap()
        .image;
    let o_ref = reference::compose(&g, &c_ref, &s_ref, &pixels, lw, lh, 4, 1.0);
    // Some samples are shadowed: S is exercised, not only zeros.
    let shadowed = s_ref.iter().filter(|p| p[1] > 0.0).count();
    eprintln!("shadowed low-res samples: {shadowed} of {}", s_ref.len());
    assert!(shadowed > 20, "{shadowed}");
    let floor = 1e-3;
    let w = [
        worst(&c_dev, &c_ref, floor),
        worst(&s_dev, &s_ref, floor),
        worst(&a_dev, &a_ref, floor),
        worst(&o_dev, &o_ref, floor),
    ];
    eprintln!(
        "C {:e}, S {:e}, additive {:e}, C − S′ {:e}",
        w[0], w[1], w[2], w[3]
    );
    // Measured on PoCL (96×64): C 2.9e-7, S 1.9e-7, additive 3.0e-7 (sums over up to 256
    // lights in the same order: FMA contraction and rounding only), compose 1.4e-5 (exp of
    // the device vs libm, amplified where C − S′ nearly cancels). Bounds ~3-4× those.
    for (v, what) in w[..3].iter().zip(["C", "S", "additive"]) {
        assert!(*v < 1e-6, "{what}: {v}");
    }
    assert!(w[3] < 5e-5, "compose: {}", w[3]);
    all_finite_nonnegative(&o_dev);
}

#[test]
fn subtractive_equals_additive_when_s_is_full_resolution_from_the_same_lights() {
    // §2.7.1: C from E itself, S at 1/1 with no blur ⇒ C − S = Σ V f E (float tolerance).
    let s = arrays(&bundled_scene("outside"), 96, 64);
    let g = sub::gbuffer(&s);
    let k = kernels();
    let dg = k.upload(&g).unwrap();
    let settings = Settings {
        lights: 48,
        block: 1,
        unshadowed_lights: None,
        ..Settings::default()
    };
    let e = sub::environment_lights(&s, settings.lights, settings.seed);
    let c = sub::unshadowed(&s, &dg, &k, &settings, &e).unwrap();
    let out = sub::subtractive(&s, &g, &dg, &k, &c.image, &settings).unwrap();
    let add = sub::additive(&s, &g, &dg, &k, settings.lights, settings.seed).unwrap();
    assert_eq!(out.rays, add.rays);
    let max_abs = out
        .image
        .iter()
        .zip(&add.image)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0f32, f32::max);
    let mean: f64 = add.image.iter().map(|p| p[1] as f64).sum::<f64>() / add.image.len() as f64;
    eprintln!("max |subtractive − additive| = {max_abs:e} (mean green {mean:.3})");
    // Measured on PoCL: 1.2e-7 (one ulp near 1): C − S cancels the blocked lights' sum,
    // leaving the rounding of a sum of 48 terms of size ~0.3. Bound 4 ulps.
    assert!(max_abs < 5e-7, "{max_abs}");
}

#[test]
fn no_occluders_give_c_exactly_and_all_blocked_gives_black() {
    // An environment over a plane: nothing blocks any light facing the ground (§2.7.2).
    let scene = scene_from_toml(
        r#"
[render]
width = 32
height = 32
[camera]
origin = [0, 1, 3]
target = [0, 0, 0]
fov = 60
[[texture]]
name = "sky"
file = "textures/sky.exr"
[[material]]
name = "grey"
type = "diffuse"
color = [0.5, 0.5, 0.5]
[[light]]
type = "infinite"
texture = "sky"
[[mesh]]
generator = "quad"
material = "grey"
scale = 10
"#,
    );
    let s = arrays(&scene, 32, 32);
    let g = sub::gbuffer(&s);
    let k = kernels();
    let dg = k.upload(&g).unwrap();
    let settings = Settings {
        lights: 24,
        block: 8,
        ..Settings::default()
    };
    let e = sub::environment_lights(&s, settings.lights, settings.seed);
    let c = sub::unshadowed(&s, &dg, &k, &settings, &e).unwrap().image;
    let out = sub::subtractive(&s, &g, &dg, &k, &c, &settings).unwrap();
    assert!(g.position.iter().filter(|p| p[3] == 1.0).count() > 300);
    assert_eq!(out.image, c, "S = 0 ⇒ output == C bit-exactly");
    // Every light blocked (bits all 0) with C from E at 1/1: C − S = 0 up to rounding, and the
    // clamp keeps it ≥ 0.
    let all: Vec<u32> = (0..32 * 32).collect();
    let none = vec![0u32; all.len() * sub::vis_words(e.len())];
    let c_e = k.unshadowed(&dg, &e).unwrap().image;
    let s_all = k.shadow(&dg, &all, &e, &none, false).unwrap().image;
    let black = k
        .compose(&dg, &c_e, &s_all, &all, 32, 32, 1, 1.0)
        .unwrap()
        .image;
    all_finite_nonnegative(&black);
    let (mut worst_hit, mut c_max) = (0.0f32, 0.0f32);
    for (i, p) in black.iter().enumerate() {
        if g.position[i][3] == 1.0 {
            worst_hit = worst_hit.max(p[0].max(p[1]).max(p[2]));
            c_max = c_max.max(c_e[i][1]);
        }
    }
    eprintln!("all blocked: largest residue {worst_hit:e} (C up to {c_max})");
    // Measured on PoCL: exactly 0 (C and S sum the same lights in the same order); bound one
    // ulp of C for a driver that contracts the two sums differently.
    assert!(worst_hit <= 1.2e-7 * c_max, "{worst_hit}");
}

fn tiny_gbuffer(normal_flip: bool) -> GBuffer {
    // 8×8 pixels on a plane z = 0 facing +z; with `normal_flip`, the low-res samples' pixels
    // (block 4: pixels (2,2), (6,2), (2,6), (6,6)) face −z, so every n·n weight is 0.
    let (w, h) = (8u32, 8u32);
    let mut g = GBuffer {
        width: w,
        height: h,
        position: vec![],
        normal: vec![],
        albedo: vec![],
    };
    for y in 0..h {
        for x in 0..w {
            let sample = x % 4 == 2 && y % 4 == 2;
            let nz = if normal_flip && sample { -1.0 } else { 1.0 };
            g.position.push([x as f32, y as f32, 0.0, 1.0]);
            g.normal.push([0.0, 0.0, nz, 0.1]);
            g.albedo.push([0.5, 0.5, 0.5, 0.0]);
        }
    }
    g
}

#[test]
fn all_zero_upsampling_weights_fall_back_to_the_nearest_sample() {
    let k = kernels();
    let light = [DirLight {
        dir: Vec3::Z,
        irradiance: Vec3::splat(2.0),
    }];
    let (lw, lh, pixels) = sub::low_res(8, 8, 4);
    let s_low = vec![
        [0.1, 0.2, 0.3, 0.0],
        [0.4, 0.5, 0.6, 0.0],
        [0.7, 0.8, 0.9, 0.0],
        [2.0, 2.0, 2.0, 0.0],
    ];
    for (flip, sigma) in [(true, 1.0f32), (false, 1e-20)] {
        // Flipped normals: n·n = 0; σ = 1e-20: G underflows to 0 at any distance > 0 (the
        // sample's own pixel keeps weight 1: that is the nearest sample anyway).
        let g = tiny_gbuffer(flip);
        let dg = k.upload(&g).unwrap();
        let c = reference::unshadowed(&g, &light);
        let dev = k
            .compose(&dg, &c, &s_low, &pixels, lw, lh, 4, sigma)
            .unwrap()
            .image;
        let cpu = reference::compose(&g, &c, &s_low, &pixels, lw, lh, 4, sigma);
        assert_eq!(dev, cpu);
        all_finite_nonnegative(&dev);
        for y in 0..8usize {
            for x in 0..8usize {
                let near = s_low[(y / 4) * 2 + x / 4];
                let want: Vec<f32> = (0..3)
                    .map(|i| (c[y * 8 + x][i] - near[i]).max(0.0))
                    .collect();
                assert_eq!(
                    &dev[y * 8 + x][..3],
                    &want[..],
                    "pixel ({x}, {y}) flip {flip}"
                );
            }
        }
        // The last sample blocks more than C holds: clamped at exactly 0 (§2.4).
        assert_eq!(dev[7 * 8 + 7][..3], [0.0; 3]);
    }
}

#[test]
fn a_scene_without_an_environment_is_refused_clearly() {
    let err = sub::check_scene(&bundled_scene("cornell_diffuse"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("environment") && err.contains("infinite"),
        "{err}"
    );
    sub::check_scene(&bundled_scene("outside")).unwrap();
    let bad = Settings {
        block: 0,
        ..Settings::default()
    };
    assert!(bad.validate().unwrap_err().to_string().contains("block"));
}

#[test]
fn subtractive_beats_additive_at_equal_lights_against_many_lights() {
    // §2.7.5 / §2.5: against an additive 2048-light reference, subtractive (C from 1024
    // unshadowed lights, S at 1/16) has less error than additive at the same |E|.
    let s = arrays(&bundled_scene("outside"), 96, 64);
    let g = sub::gbuffer(&s);
    let k = kernels();
    let dg = k.upload(&g).unwrap();
    let reference = sub::additive(&s, &g, &dg, &k, 2048, 7).unwrap().image;
    let settings = Settings::default();
    let e = sub::environment_lights(&s, settings.lights, settings.seed);
    let c = sub::unshadowed(&s, &dg, &k, &settings, &e).unwrap().image;
    // Measured on PoCL (96×64): 8 lights .0264 vs .0521 (ratio .51), 32 lights .0198 vs .0242
    // (.82); bounds on the ratio a little above those.
    for (lights, ratio) in [(8u32, 0.55), (32, 0.86)] {
        let st = Settings {
            lights,
            ..settings.clone()
        };
        let sub_rms = rms(
            &sub::subtractive(&s, &g, &dg, &k, &c, &st).unwrap().image,
            &reference,
        );
        let add_rms = rms(
            &sub::additive(&s, &g, &dg, &k, lights, 1).unwrap().image,
            &reference,
        );
        eprintln!("{lights} lights: subtractive {sub_rms:.4}, additive {add_rms:.4}");
        assert!(
            sub_rms < ratio * add_rms,
            "{lights}: {sub_rms} vs {add_rms}"
        );
    }
}

#[test]
fn the_cli_writes_a_preview_and_refuses_scenes_without_an_environment() {
    let dir = tempdir("subtractive_cli");
    let png = dir.join("outside.png");
    let out = noisefree()
        .args(["render", "scenes/outside.toml", "--preview", "subtractive"])
        .args(["--width", "48", "--height", "32", "--preview-lights", "8"])
        .args([
            "--shadow-block",
            "8",
            "--unshadowed-lights",
            "64",
            "--quiet",
            "--out",
        ])
        .arg(&png)
        .current_dir(repo_path(""))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(png.exists() && png.with_extension("exr").exists());
    let scene = bundled_scene_path("cornell_diffuse");
    let scene = scene.to_str().unwrap();
    let out = dir.join("cornell.png");
    let out = out.to_str().unwrap();
    fails(
        &["render", scene, "--preview", "subtractive", "--out", out],
        &[
            "cornell_diffuse.toml",
            "needs a scene lit by an environment",
        ],
    );
    assert!(!Path::new(out).exists(), "nothing written on an error");
    fails(
        &[
            "render",
            "scenes/outside.toml",
            "--preview",
            "subtractive",
            "--shadow-block",
            "0",
            "--out",
            out,
        ],
        &["shadow block must be 1..=64"],
    );
    fails(
        &[
            "render",
            "scenes/outside.toml",
            "--preview",
            "sheared",
            "--out",
            out,
        ],
        &["no such preview", "subtractive"],
    );
}

#[test]
fn environment_lights_integrate_a_constant_sky_to_pi() {
    // Step 1: a constant sky of radiance 1 gives irradiance π at any normal (∫ cos dω over the
    // hemisphere). The lights carry equal luminance; their sum over a hemisphere estimates it.
    let scene = scene_from_toml(
        r#"
[render]
width = 4
height = 4
[camera]
origin = [0, 1, 3]
target = [0, 0, 0]
[[material]]
name = "grey"
type = "diffuse"
color = [0.5, 0.5, 0.5]
[[light]]
type = "infinite"
color = [1, 1, 1]
[[mesh]]
generator = "quad"
material = "grey"
"#,
    );
    let s = arrays(&scene, 4, 4);
    let lights = sub::environment_lights(&s, 4096, 3);
    let total: f32 = lights.iter().map(|l| l.irradiance.y).sum();
    let mut worst = (total - 4.0 * std::f32::consts::PI).abs() / (4.0 * std::f32::consts::PI);
    for n in [
        Vec3::Y,
        -Vec3::Y,
        Vec3::X,
        Vec3::new(1.0, 1.0, -1.0).normalize(),
    ] {
        let e: f32 = lights
            .iter()
            .map(|l| l.irradiance.y * n.dot(l.dir).max(0.0))
            .sum();
        let err = (e - std::f32::consts::PI).abs() / std::f32::consts::PI;
        eprintln!("n {n:?}: irradiance {e} (π {})", std::f32::consts::PI);
        worst = worst.max(err);
    }
    eprintln!("worst relative error {worst:e}");
    // Measured: 1.2e-3 at worst (the 4 normals and the total 4π; 4096 stratified lights on
    // the 256×128 grid); bound 2e-3.
    assert!(worst < 2e-3, "{worst}");
}

/// Two planes facing +z, the left half at z = 0 and the right half at z = −`gap` (8×8,
/// block 4: samples at x = 2 on the left, x = 6 on the right), pixel footprint 0.1.
fn step_gbuffer(gap: f32) -> GBuffer {
    let mut g = tiny_gbuffer(false);
    for (k, p) in g.position.iter_mut().enumerate() {
        if k % 8 >= 4 {
            p[2] = -gap;
        }
    }
    g
}

#[test]
fn upsampling_keeps_a_constant_and_does_not_bleed_across_a_depth_edge() {
    // §2.7.3. C = 1 everywhere (a constant, not a lighting term, so C − S′ shows S′).
    let k = kernels();
    let (lw, lh, pixels) = sub::low_res(8, 8, 4);
    let c = vec![[1.0, 1.0, 1.0, 0.0]; 64];
    // A constant S stays constant across the plane, at every pixel.
    let g = tiny_gbuffer(false);
    let dg = k.upload(&g).unwrap();
    let s_const = vec![[0.25, 0.5, 0.75, 0.0]; 4];
    let out = k
        .compose(&dg, &c, &s_const, &pixels, lw, lh, 4, 1.0)
        .unwrap()
        .image;
    // Σ w·s / Σ w rounds: measured at most 6e-8 off; bound 2 ulps of 0.75.
    for p in &out {
        for (v, want) in p[..3].iter().zip([0.75, 0.5, 0.25]) {
            assert!((v - want).abs() <= 1.2e-7, "{p:?}");
        }
    }
    // Left samples shadowed (S = 1), right ones lit (S = 0): with the right plane 100 units
    // behind, G of a left sample at a right pixel underflows and no shadow bleeds across.
    let g = step_gbuffer(100.0);
    let dg = k.upload(&g).unwrap();
    let s_left = vec![
        [1.0, 1.0, 1.0, 0.0],
        [0.0; 4],
        [1.0, 1.0, 1.0, 0.0],
        [0.0; 4],
    ];
    let out = k
        .compose(&dg, &c, &s_left, &pixels, lw, lh, 4, 1.0)
        .unwrap()
        .image;
    assert_eq!(
        out,
        reference::compose(&g, &c, &s_left, &pixels, lw, lh, 4, 1.0)
    );
    for y in 0..8 {
        for x in 0..8 {
            let want = if x < 4 { 0.0 } else { 1.0 };
            assert_eq!(out[y * 8 + x][1], want, "({x}, {y})");
        }
    }
    // The same step on one plane (gap 0) does blend: pixels between the samples get a mix.
    let g = step_gbuffer(0.0);
    let dg = k.upload(&g).unwrap();
    let out = k
        .compose(&dg, &c, &s_left, &pixels, lw, lh, 4, 1.0)
        .unwrap()
        .image;
    let mid = out[2 * 8 + 4][1];
    eprintln!("one plane, between the samples: {mid}");
    assert!(mid > 0.0 && mid < 1.0, "{mid}");
}
