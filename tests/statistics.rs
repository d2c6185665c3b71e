//! Per-pixel statistics (thesis §6.1-6.2.2): the Welford update in float32 against float64,
//! the direct/indirect split, texture2 through mirrors and glass, the variance buffers'
//! behaviour (Fig. 6.4), and the AOV file round trip.

mod common;

use common::*;
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::layout::{Float4, SampleVector};
use noisefree::render::cpu::pathtrace::{ReferenceOptions, ShadowTarget, trace_path};
use noisefree::render::cpu::rng::{DIM_LENS_U, DIM_LENS_V, DIM_PIXEL_X, DIM_PIXEL_Y};
use noisefree::render::cpu::rng::{rng_sample_key, rng_uniform};
use noisefree::render::cpu::sampling::camera_ray;
use noisefree::render::{Renderer, SceneArrays};
use noisefree::stats::{RenderRecord, feature_variance_sums, variances_from_sums};

#[test]
fn welford_in_float32_matches_float64_two_pass() {
    let mut rng = TestRng(17);
    let n = 100_000;
    let depth_like = rng.normals(n, 1.0e4, 0.1);
    let colour_like = rng.normals(n, 0.5, 0.3);
    let constant = vec![0.73f32; n];
    let streams = vec![depth_like.clone(), colour_like.clone(), constant];
    // Progressive: launches of 1000 samples, as the renderer carries state across launches.
    let (f, s) = device_welford(&streams, 1000);
    let var = variances_from_sums(&s, n as u32);

    let (m, v) = two_pass(&depth_like);
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    // Float32 against float64, relative. Measured: 4.2e-8 for the depth mean, 5.2e-8 for its
    // variance, 2.0e-8 for each colour-like variance lane below: within one float32 rounding
    // (1.2e-7 relative at most). Bound: two ulps, 2.5e-7 (4.8x the largest of these).
    assert!(
        rel(f[0].depth as f64, m) < 2.5e-7,
        "depth mean {} vs {m}",
        f[0].depth
    );
    assert!(
        rel(var[0].depth as f64, v) < 2.5e-7,
        "depth-like variance {} vs {v} (rel {:.2e})",
        var[0].depth,
        rel(var[0].depth as f64, v)
    );
    // The same stream through the unshifted lanes (normal) shows why the shift is needed.
    // Measured: 1.12e-3, four orders of magnitude worse than the shifted lane. Bound at half
    // that: how much is lost depends on the device's rounding (e.g. contracted multiply-adds).
    let unshifted = rel(var[0].normal[0] as f64, v);
    assert!(
        unshifted > 5e-4,
        "expected the unshifted float32 recursion to lose accuracy here ({unshifted:.2e})"
    );

    let (m, v) = two_pass(&colour_like);
    for (got, what) in [
        (var[1].albedo[0], "albedo"),
        (var[1].normal[1], "normal"),
        (var[1].direction[2], "direction"),
        (var[1].albedo2[0], "albedo2"),
    ] {
        assert!(
            rel(got as f64, v) < 2.5e-7,
            "colour-like {what} variance {got} vs {v}"
        );
    }
    // The plain running mean (eq. 6.5) of 100,000 values accumulates rounding. Measured:
    // 3.4e-6; bound 1.5x.
    assert!(
        rel(f[1].albedo[0] as f64, m) < 5e-6,
        "colour-like mean {} vs {m}",
        f[1].albedo[0]
    );

    let g = &s[2];
    for x in feature_variance_sums(g) {
        assert_eq!(x, 0.0, "a constant stream has exactly zero S_n");
    }
    for g in &s {
        assert!(
            feature_variance_sums(g).iter().all(|&x| x >= 0.0),
            "negative variance: {g:?}"
        );
    }
}

#[test]
fn welford_single_launch_and_one_sample_per_launch_agree() {
    let mut rng = TestRng(5);
    let streams = vec![rng.normals(300, 3.0, 0.5)];
    let (_, a) = device_welford(&streams, 300);
    let (_, b) = device_welford(&streams, 1);
    assert_eq!(
        a[0], b[0],
        "the statistics must not depend on launch batching"
    );
}

/// Direct and indirect light are one image split in two: their sum equals the unsplit total
/// of every path (accumulated separately by the Rust reference with the same random numbers).
#[test]
fn direct_plus_indirect_is_the_beauty_image() {
    let extra = r#"
[[material]]
name = "mirror"
type = "specular"
color = [0.9, 0.9, 0.9]

[[sphere]]
center = [-0.4, 0.4, -0.2]
radius = 0.4
material = "mirror"

[[sphere]]
center = [0.4, 0.3, 0.3]
radius = 0.3
material = "white"
"#;
    let scene = scene_from_toml(&cornell("max_depth = 3", extra));
    let (w, h, spp) = (24u32, 24u32, 8u32);
    let mut opts = options(&scene, w, h, 21);
    opts.outputs = OutputSet::of(&[Output::Features, Output::Variance]);
    let film = render_film(&scene, &opts, spp, spp);
    let arrays = SceneArrays::build(&scene, &opts.frame).unwrap();
    let ro = ReferenceOptions {
        russian_roulette: true,
        next_event_estimation: true,
    };
    let mut agree = 0;
    let mut with_both = 0;
    for (i, f) in film.iter().enumerate() {
        let (x, y) = (i as u32 % w, i as u32 / w);
        let mut total = [0f64; 3];
        let mut rays = 0;
        for s in 0..spp {
            let ps = trace_path(
                &arrays,
                ro,
                x,
                y,
                rng_sample_key(21, i as u32, s),
                &mut rays,
                ShadowTarget::NONE,
            );
            for (t, v) in total.iter_mut().zip(ps.total.to_array()) {
                *t += v as f64 / spp as f64;
            }
        }
        if f.direct.iter().sum::<f32>() > 0.0 && f.indirect.iter().sum::<f32>() > 0.0 {
            with_both += 1;
        }
        let ok = (0..3).all(|c| {
            let split = (f.direct[c] + f.indirect[c]) as f64;
            (split - total[c]).abs() <= 1e-5 * total[c].abs().max(1e-3)
        });
        agree += ok as usize;
    }
    eprintln!(
        "{agree} of {} pixels agree, {with_both} have direct and indirect light",
        film.len()
    );
    // Measured: 448 of 576 pixels have both; bound 400 (0.9x).
    assert!(
        with_both >= 400,
        "most pixels should have both direct and indirect light: {with_both} of {}",
        film.len()
    );
    // Paths that round a comparison differently on the device may branch apart; that is rare.
    // Measured: 574 of 576 pixels agree to 1e-5 (the other two by 1.3e-5 and 1.8e-4); bound:
    // at most 4 disagree (2x the measured count).
    assert!(
        agree + 4 >= film.len(),
        "direct + indirect matched the total in only {agree} of {} pixels",
        film.len()
    );
}

/// texture2 is the albedo of the first diffuse surface after the first bounce: the wall seen
/// in a mirror, or through glass (Fig. 6.3).
#[test]
fn texture2_sees_through_mirrors_and_glass() {
    let base = |object: &str| {
        format!(
            r#"
[render]
max_depth = 4

[camera]
origin = [0, 0, 3]
target = [0, 0, 0]
fov = 10

[[material]]
name = "red"
type = "diffuse"
color = [0.8, 0.1, 0.1]

[[material]]
name = "green"
type = "diffuse"
color = [0.1, 0.8, 0.1]

[[material]]
name = "mirror"
type = "specular"
color = [0.9, 0.9, 0.9]

[[material]]
name = "glass"
type = "glass"
refract_color = [0.95, 0.95, 0.95]

[[light]]
type = "infinite"
color = [0.2, 0.2, 0.2]

# Red wall behind the camera, green wall behind the object.
[[mesh]]
generator = "quad"
material = "red"
scale = 20
rotate = [-90, 0, 0]
translate = [0, 0, 6]

[[mesh]]
generator = "quad"
material = "green"
scale = 20
rotate = [90, 0, 0]
translate = [0, 0, -3]

{object}
"#
        )
    };
    let mirror = base(
        "[[mesh]]\ngenerator = \"quad\"\nmaterial = \"mirror\"\nscale = 4\nrotate = [90, 0, 0]\n",
    );
    let glass = base("[[mesh]]\ngenerator = \"box\"\nmaterial = \"glass\"\nscale = [4, 4, 0.5]\n");
    // Through glass, a fraction of paths is reflected back to the red wall: a slab reflects
    // 2R / (1 + R) in total with R = 0.04 at normal incidence (n = 1.5), the rest reaches green.
    let r = 0.04f32;
    let slab = 2.0 * r / (1.0 + r);
    let mix = |a: [f32; 3], b: [f32; 3], t: f32| [0, 1, 2].map(|c| a[c] * (1.0 - t) + b[c] * t);
    let (red, green) = ([0.8, 0.1, 0.1], [0.1, 0.8, 0.1]);
    for (text, want_albedo, want_albedo2, what) in [
        (mirror, [0.9, 0.9, 0.9], red, "mirror"),
        (glass, [0.95, 0.95, 0.95], mix(green, red, slab), "glass"),
    ] {
        let scene = scene_from_toml(&text);
        let mut opts = options(&scene, 8, 8, 2);
        opts.outputs = OutputSet::of(&[Output::Features]);
        let film = render_film(&scene, &opts, 64, 64);
        let mut mean2 = [0f32; 3];
        for f in &film {
            // Every sample's first hit has the same albedo, and the running mean of equal
            // values is exact (measured: equal).
            assert_eq!(f.albedo, want_albedo, "{what}: albedo");
            for (m, v) in mean2.iter_mut().zip(f.albedo2) {
                *m += v / film.len() as f32;
            }
            // Each sample saw red, green or (escaping sideways) nothing: a mix with blue <= 0.1
            // and red + green = 9 blue. Measured: blue at most 0.1 exactly, |r + g - 9b| at most
            // 1.8e-7 (rounding of the running means); bounds 0.1 + 1e-7 and 4e-7 (2.2x).
            assert!(
                f.albedo2[2] <= 0.1 + 1e-7
                    && (f.albedo2[0] + f.albedo2[1] - 9.0 * f.albedo2[2]).abs() < 4e-7,
                "{what}: {:?}",
                f.albedo2
            );
        }
        eprintln!("{what}: mean albedo2 {mean2:?}, expected {want_albedo2:?}");
        // Mirror: every sample sees the red wall; measured 4.6e-7 off (this test's float32 sum
        // of the 64 pixel means), bound 1e-6. Glass: 4096 samples, the standard error of the
        // reflected fraction is 0.0042, 0.0029 in red and green; measured 0.0016 off (0.55
        // standard errors), bound 0.01 (measured + 3 standard errors).
        let tolerance = if what == "mirror" { 1e-6 } else { 0.01 };
        for c in 0..3 {
            assert!(
                (mean2[c] - want_albedo2[c]).abs() < tolerance,
                "{what}: mean albedo2 {mean2:?}, expected {want_albedo2:?}"
            );
        }
    }
}

/// The frame of `spp` samples of the scene `text` with features and variances, seed 8.
fn render_variances(text: &str, w: u32, h: u32, spp: u32) -> noisefree::render::Frame {
    let scene = scene_from_toml(text);
    let mut opts = options(&scene, w, h, 8);
    opts.outputs = OutputSet::of(&[Output::Features, Output::Variance]);
    render_frame(&scene, &opts, spp)
}

fn render_buffers(text: &str, w: u32, h: u32, spp: u32) -> Buffers {
    Buffers::of_frame(&render_variances(text, w, h, spp))
}

/// Fig. 6.4: normal and texture variance are high at geometric edges, and much higher where
/// depth of field blurs the image.
#[test]
fn variances_rise_at_edges_and_out_of_focus() {
    let scene = |lens: &str| {
        format!(
            r#"
[camera]
origin = [0, 0, 4]
target = [0, 0, 0]
fov = 30
{lens}

[[material]]
name = "a"
type = "diffuse"
color = [0.9, 0.6, 0.2]

[[material]]
name = "b"
type = "diffuse"
color = [0.2, 0.3, 0.8]

[[light]]
type = "infinite"
color = [1, 1, 1]

[[sphere]]
center = [0, 0, 1.5]
radius = 0.5
material = "a"

[[mesh]]
generator = "quad"
material = "b"
scale = 10
rotate = [90, 0, 0]
translate = [0, 0, -2]
"#
        )
    };
    let (w, h) = (48u32, 48u32);
    let sharp = render_buffers(&scene(""), w, h, 32);
    // Focused on the wall 6 units away: the sphere 2.5 units away is blurred.
    let blurred = render_buffers(&scene("lens_radius = 0.15\nfocal_distance = 6.0"), w, h, 32);
    let var_sum = |b: &Buffers, i: usize| {
        let v = feature_variance_sums(&b.variances.as_ref().unwrap()[i]);
        v[1] + v[2] // normal + texture
    };
    // Classify pixels of the sharp image: interior (all neighbours have the same material) or
    // edge (the sphere's silhouette).
    let on_sphere = |b: &Buffers, i: usize| b.filter_vectors[i].depth < 4.0;
    let mut edge = Vec::new();
    let mut interior = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = (y * w + x) as usize;
            let n = [i - 1, i + 1, i - w as usize, i + w as usize];
            let same = n
                .iter()
                .all(|&j| on_sphere(&sharp, j) == on_sphere(&sharp, i));
            let var = var_sum(&sharp, i);
            if same {
                interior.push(var)
            } else {
                edge.push(var)
            }
        }
    }
    let mean = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
    // Measured: 204 edge and 1912 interior pixels (the same for every seed); bounds 0.9x.
    assert!(
        edge.len() >= 180 && interior.len() >= 1700,
        "{} edge and {} interior pixels",
        edge.len(),
        interior.len()
    );
    // The three ratios below were measured at seeds 1-8 (seed 8 is the one used): edge /
    // interior 605-644 (625 at seed 8, sd 13); depth of field / pinhole 5.47-5.80 (5.54, sd
    // 0.12), and for depth 6.22-6.64 (6.35, sd 0.14). Bounds: the seed-8 value less about
    // five standard deviations of the spread across seeds.
    eprintln!("edge / interior {:.1}", mean(&edge) / mean(&interior));
    assert!(
        mean(&edge) > 560.0 * mean(&interior),
        "edge {} vs interior {}",
        mean(&edge),
        mean(&interior)
    );
    let total = |b: &Buffers| {
        (0..(w * h) as usize)
            .map(|i| var_sum(b, i) as f64)
            .sum::<f64>()
    };
    eprintln!("DOF / pinhole {:.2}", total(&blurred) / total(&sharp));
    assert!(
        total(&blurred) > 5.0 * total(&sharp),
        "DOF {} vs pinhole {}",
        total(&blurred),
        total(&sharp)
    );
    // Depth variance too (Fig. 6.5): the blurred silhouette mixes sphere and wall depths.
    let depth_total = |b: &Buffers| {
        b.variances
            .as_ref()
            .unwrap()
            .iter()
            .map(|g| g.depth as f64)
            .sum::<f64>()
    };
    eprintln!(
        "DOF / pinhole, depth {:.2}",
        depth_total(&blurred) / depth_total(&sharp)
    );
    assert!(
        depth_total(&blurred) > 5.7 * depth_total(&sharp),
        "depth: DOF {} vs pinhole {}",
        depth_total(&blurred),
        depth_total(&sharp)
    );
}

#[test]
fn aov_exr_round_trips() {
    let text = cornell("max_depth = 2", "");
    let frame = render_variances(&text, 20, 12, 4);
    let b = Buffers::of_frame(&frame);
    let dir = tempdir("aov");
    let path = dir.join("aovs.exr");
    let mut record = RenderRecord {
        scene: Some(frame.info().scene.clone()),
        ..Default::default()
    };
    record.extra.insert("scene".to_string(), "test".to_string());
    noisefree::stats::aov::write_aov_exr(&path, &frame, &record).unwrap();
    let (back, record_back) = noisefree::stats::aov::read_aov_exr(&path).unwrap();
    assert_eq!(
        back.outputs(),
        frame.outputs(),
        "the file holds every output the render gathered"
    );
    assert_eq!(
        Buffers::of_frame(&back),
        b,
        "every buffer, the spp and the scene information must survive the file"
    );
    assert_eq!(record_back, record);
    let pngs = noisefree::stats::aov::write_aov_pngs(&dir.join("png"), &frame, 0.0).unwrap();
    assert_eq!(pngs.len(), 12);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Random Parameter Filtering's sample vectors (§5.1.1): one per sample, drawn with the
/// camera's own random numbers, consistent with the per-pixel means, and only allocated when
/// asked for.
#[test]
fn sample_vectors_agree_with_the_pixel_means() {
    let text = cornell(
        "max_depth = 3",
        "[[sphere]]\ncenter = [0, 0.5, 0]\nradius = 0.5\nmaterial = \"red\"\n",
    )
    .replace(
        "fov = 40",
        "fov = 40\nlens_radius = 0.05\nfocal_distance = 3.0",
    );
    let scene = scene_from_toml(&text);
    let (w, h, spp, seed) = (12u32, 10u32, 6u32, 4u32);
    let mut opts = options(&scene, w, h, seed);
    opts.outputs = OutputSet::of(&[Output::Samples]);
    opts.sample_capacity = spp;
    let mut r = Renderer::new(gpu(), &scene, &opts).unwrap();
    assert!(
        r.outputs().contains(Output::Features),
        "the samples output needs the features"
    );
    r.render_samples(2).unwrap();
    r.render_samples(4).unwrap(); // progressive launches fill the same buffer
    let frame = r.frame();
    assert_eq!(frame.info().sample_capacity, spp);
    assert_eq!(frame.info().samples_stored(), spp);
    let film = frame.filter_vectors().unwrap();
    let samples: &[SampleVector] = frame.host_slice(BufferId::SampleVectors).unwrap();
    assert_eq!(samples.len(), (w * h * spp) as usize);
    let params = &r.arrays.params;
    let mut worst_depth = 0f32;
    for (pixel, f) in film.iter().enumerate() {
        let px = &samples[pixel * spp as usize..(pixel + 1) * spp as usize];
        let (x, y) = (pixel as u32 % w, pixel as u32 / w);
        let mut mean_color = [0f32; 3];
        let mut mean_depth = 0f64;
        for (k, s) in px.iter().enumerate() {
            // The screen position and the lens numbers are the camera's, bit for bit.
            let key = rng_sample_key(seed, pixel as u32, k as u32);
            assert_eq!(
                s.position.map(f32::to_bits),
                [
                    x as f32 + rng_uniform(key, 0, DIM_PIXEL_X),
                    y as f32 + rng_uniform(key, 0, DIM_PIXEL_Y)
                ]
                .map(f32::to_bits),
                "pixel {pixel} sample {k}: screen position"
            );
            assert_eq!(
                s.random[..3]
                    .iter()
                    .map(|v| v.to_bits())
                    .collect::<Vec<_>>(),
                [
                    rng_uniform(key, 0, DIM_LENS_U),
                    rng_uniform(key, 0, DIM_LENS_V),
                    0.0
                ]
                .map(f32::to_bits),
                "pixel {pixel} sample {k}: lens u, v and time"
            );
            for (m, v) in mean_color.iter_mut().zip(s.color) {
                *m += v / spp as f32;
            }
            // The first hit lies at the sample's depth from its point on the lens (every camera
            // ray hits the box: no sample's depth is the sky's).
            let (lens_point, _) = camera_ray(params, x, y, key);
            mean_depth += (glam::Vec3::from(s.world1) - lens_point).length() as f64 / spp as f64;
            assert!(s.texture1.iter().all(|c| (0.0..=1.0).contains(c)));
        }
        for c in 0..3 {
            let want = f.direct[c] + f.indirect[c];
            assert!(
                (mean_color[c] - want).abs() <= 1e-4 * want.max(1.0),
                "pixel {pixel}: colour mean {mean_color:?} vs F"
            );
        }
        let rel = ((mean_depth - f.depth as f64) / f.depth as f64).abs() as f32;
        worst_depth = worst_depth.max(rel);
    }
    eprintln!("largest relative difference of the world1 distance and F.depth: {worst_depth:e}");
    // Measured: 1.1e-7 (about one float32 rounding); bound 3e-7 (2.8x).
    assert!(
        worst_depth < 3e-7,
        "world1 distances do not average to the depth: {worst_depth:e}"
    );
    // Without RPF no sample vector buffer exists and the kernel has no code for it.
    let plain = Renderer::new(gpu(), &scene, &options(&scene, w, h, seed)).unwrap();
    assert!(!plain.outputs().contains(Output::Samples));
    assert!(!plain.features.is_on("OUTPUT_SAMPLES"));
    assert!(plain.frame().host(BufferId::SampleVectors).is_err());
}

/// The emission output holds the light of emitters the camera ray hit, the part of F's direct
/// light that no surface reflected (src/layout/outputs.rs `Output::Emission`), and the share of
/// samples that hit one: the Rust reference's means with the same random numbers. The lamp
/// seen in the mirror sphere is reflected light (direct, but not emitted).
#[test]
fn emission_output_is_the_light_of_emitters_seen_directly() {
    let scene = cornell_with_spheres();
    let (w, h, spp) = (32u32, 32u32, 8u32);
    let mut opts = options(&scene, w, h, 21);
    opts.outputs = OutputSet::of(&[Output::Features, Output::Emission]);
    let frame = render_frame(&scene, &opts, spp);
    let fv = frame.filter_vectors().unwrap();
    let emission: &[Float4] = frame.host_slice(BufferId::FirstEmission).unwrap();
    let odd: &[Float4] = frame.host_slice(BufferId::OddEmission).unwrap();
    let arrays = SceneArrays::build(&scene, &opts.frame).unwrap();
    let ro = ReferenceOptions {
        russian_roulette: true,
        next_event_estimation: true,
    };
    let (mut agree, mut partly, mut whole, mut reflected) = (0, 0, 0, 0);
    for (i, (e, f)) in emission.iter().zip(fv).enumerate() {
        let (x, y) = (i as u32 % w, i as u32 / w);
        let (mut emitted, mut share, mut rays) = ([0f64; 3], 0f64, 0);
        let mut emitted_odd = [0f64; 3];
        for s in 0..spp {
            let key = rng_sample_key(21, i as u32, s);
            let ps = trace_path(&arrays, ro, x, y, key, &mut rays, ShadowTarget::NONE);
            for c in 0..3 {
                emitted[c] += ps.emitted[c] as f64 / spp as f64;
                emitted_odd[c] += (s % 2) as f64 * ps.emitted[c] as f64 / (spp / 2) as f64;
            }
            share += ps.on_emitter as u32 as f64 / spp as f64;
        }
        let close = |a: f32, b: f64| (a as f64 - b).abs() <= 1e-5 * b.abs().max(1e-3);
        let halves = (0..3).all(|c| close(odd[i].0[c], emitted_odd[c])) && odd[i].0[3] == 4.0;
        agree +=
            ((0..3).all(|c| close(e.0[c], emitted[c])) && close(e.0[3], share) && halves) as usize;
        partly += (share > 0.0 && share < 1.0) as usize;
        whole += (share == 1.0) as usize;
        // Direct light beyond the emitted, on a pixel that sees no emitter: the lamp in the
        // mirror, or light reaching the first surface from the lamp.
        reflected += (share == 0.0 && f.direct[0] > 0.0) as usize;
        for c in 0..3 {
            assert!(
                e.0[c] <= f.direct[c] * (1.0 + 1e-6),
                "pixel {i}: emitted {} above the direct light {}",
                e.0[c],
                f.direct[c]
            );
        }
    }
    eprintln!(
        "{agree} of {} agree; lamp pixels: {whole} whole, {partly} partly; {reflected} with reflected direct light only",
        emission.len()
    );
    // Measured: all 1024 agree; 2 left for a path that rounds a comparison differently on
    // another device (as in direct_plus_indirect_is_the_beauty_image).
    assert!(
        agree + 2 >= emission.len(),
        "only {agree} of {} pixels agree",
        emission.len()
    );
    assert!(
        whole >= 1 && partly >= 1,
        "the lamp is in view: {whole} whole, {partly} partly"
    );
}
