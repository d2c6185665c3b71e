//! Sheared soft shadows and depth of field together (Yan et al. 2015, appendix eqs. 16-17;
//! src/filters/sheared/lens_shadows.rs, kernels/filters/sheared_lens_shadows.cl,
//! kernels/render/lens_field.cl `lens_shadow_field_sample`): the lens pass takes exactly the
//! receiver's direct term out of each lens sample (the same paths as the depth-of-field
//! field's, byte for byte elsewhere) and matches its Rust mirror; the device filter matches
//! its Rust reference; on the toasters scene it lowers the error against a reference below
//! depth of field alone's; online == offline through the AOV file; and the refusals.

mod common;

use common::sheared::cli_online_equals_offline;
use common::*;
use noisefree::filters::sheared::lens_shadows;
use noisefree::filters::sheared::{Effect, Sheared, ShearedSettings};
use noisefree::filters::{Auto, Configured};
use noisefree::layout::outputs::BufferId;
use noisefree::layout::{LensShadowPixel, LightFieldPixel, ShadowPixel};
use noisefree::render::cpu::pathtrace::{ReferenceOptions, ShadowTarget};
use noisefree::render::{Frame, SceneArrays};

fn settings(effect: Effect, side: u32) -> ShearedSettings {
    ShearedSettings {
        side,
        effect: Auto::Set(effect),
        light: Auto::Set(if effect == Effect::Dof { -1 } else { 0 }),
        ..Default::default()
    }
}

/// The toasters scene at w × h, `spp` path samples, gathered for the sheared filter with
/// `effect`: the frame and the configured filter.
fn gathered(effect: Effect, side: u32, w: u32, h: u32, spp: u32) -> (Frame, Configured) {
    let scene = bundled_scene("toasters_dof");
    let mut o = options(&scene, w, h, 7);
    let c =
        Configured::typed::<Sheared>(settings(effect, side), &scene_info(&scene, w, h)).unwrap();
    o.outputs = c.needs();
    c.adjust_render(&mut o);
    (render_frame(&scene, &o, spp), c)
}

#[test]
fn the_lens_pass_takes_out_the_receivers_direct_term_and_matches_its_rust_mirror() {
    let (w, h, side) = (40u32, 32u32, 2u32);
    let (both, _) = gathered(Effect::DofShadows, side, w, h, 1);
    let (alone, _) = gathered(Effect::Dof, side, w, h, 1);
    let rest: &[LightFieldPixel] = both.host_slice(BufferId::LensFieldPixels).unwrap();
    let extra: &[LensShadowPixel] = both.host_slice(BufferId::LensShadowPixels).unwrap();
    let full: &[LightFieldPixel] = alone.host_slice(BufferId::LightFieldPixels).unwrap();
    let n = (side * side) as usize;
    let (mut on, mut taken) = (0usize, 0usize);
    for ((r, f), e) in rest.iter().zip(full).zip(extra) {
        // The same lens samples: the geometry lanes are the same bytes.
        assert_eq!(
            (
                r.jitter,
                r.slopes,
                r.count,
                r.position,
                r.normal,
                r.extra_samples
            ),
            (
                f.jitter,
                f.slopes,
                f.count,
                f.position,
                f.normal,
                f.extra_samples
            )
        );
        for k in 0..n {
            let albedo = [e.albedo[k], e.albedo_green[k], e.albedo_blue[k]];
            let pairs = [
                (r.samples[k], f.samples[k]),
                (r.green[k], f.green[k]),
                (r.blue[k], f.blue[k]),
            ];
            if albedo == [0.0; 3] {
                // Not on the receiver: the whole light, bit for bit.
                for (a, b) in pairs {
                    assert_eq!(a.to_bits(), b.to_bits());
                }
            } else {
                on += 1;
                // On it: the light less a direct term, which is >= 0.
                for (a, b) in pairs {
                    assert!(a <= b + 1e-6 * b.abs().max(1.0), "{a} > {b}");
                    taken += (a < b) as usize;
                }
            }
        }
        let u = e.unshadowed[0].0;
        assert!(u[3] <= n as f32 && u.iter().all(|v| v.is_finite() && *v >= 0.0));
    }
    eprintln!(
        "lens samples on the receiver: {on} of {}; channels with a term taken out: {taken}",
        rest.len() * n
    );
    assert!(on > rest.len() * n / 4 && taken > on, "{on} {taken}");

    // The Rust mirror of the pass (one light: ShadowTarget of each pixel's receiver).
    let scene = bundled_scene("toasters_dof");
    let o = options(&scene, w, h, 7);
    let arrays = SceneArrays::build(&scene, &o.frame).unwrap();
    let shadow: &[ShadowPixel] = both.host_slice(BufferId::ShadowPixels).unwrap();
    let target = |pixel: u32| {
        let px = &shadow[pixel as usize];
        ShadowTarget {
            light: 0,
            object: if px.weight > 0.0 { px.object } else { f32::NAN },
        }
    };
    let ro = ReferenceOptions {
        russian_roulette: true,
        next_event_estimation: true,
    };
    let (host_rest, host_extra, _) =
        noisefree::render::cpu::lens_field::lens_shadow_field(&arrays, ro, side, target);
    let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1.0);
    let (mut worst, mut receivers_differ) = (0f32, 0usize);
    for ((d, hr), (e, he)) in rest
        .iter()
        .zip(&host_rest)
        .zip(extra.iter().zip(&host_extra))
    {
        for k in 0..n {
            for (a, b) in [
                (d.samples[k], hr.samples[k]),
                (d.green[k], hr.green[k]),
                (d.blue[k], hr.blue[k]),
            ] {
                worst = worst.max(rel(a, b));
            }
            receivers_differ += ((e.albedo[k] == 0.0) != (he.albedo[k] == 0.0)) as usize;
            worst = worst.max(rel(e.albedo[k], he.albedo[k]));
        }
        for c in 0..4 {
            worst = worst.max(rel(e.unshadowed[0].0[c], he.unshadowed[0].0[c]));
        }
    }
    eprintln!("lens-shadows pass vs its Rust mirror: max relative difference {worst:e}");
    // Float rounding only (the same float operations in the same order; measured below).
    assert!(worst < 1e-3, "{worst}");
    assert_eq!(receivers_differ, 0);
}

#[test]
fn the_device_filter_matches_its_rust_reference_and_is_finite() {
    let (w, h) = (40u32, 32u32);
    let (frame, c) = gathered(Effect::DofShadows, 3, w, h, 1);
    let device = c
        .prepare(frame.info(), &gpu())
        .unwrap()
        .run(&frame)
        .unwrap()
        .image;
    let s = settings(Effect::DofShadows, 3);
    let reference = lens_shadows::image(&frame, &s).unwrap();
    let worst = device
        .pixels
        .iter()
        .flatten()
        .zip(reference.iter().flatten())
        .map(|(a, b)| (a - b).abs() / b.abs().max(1.0))
        .fold(0f32, f32::max);
    eprintln!("device vs reference (shadow steps, combine, lens steps): {worst:e}");
    assert!(worst < 2e-5, "{worst}");
    assert_finite(&device, "sheared dof-shadows");
}

#[test]
fn both_at_once_beats_depth_of_field_alone_on_the_toasters() {
    // Direct light only (paths end at their first surface after its light connection), so
    // that the difference is the shadows': a 1024-sample reference of the same scene.
    let (w, h) = (96u32, 80u32);
    let mut scene = bundled_scene("toasters_dof");
    scene.render.max_depth = 1;
    scene.render.russian_roulette = false;
    let reference = reference_image(&scene, w, h, 1024, 99);
    let info = scene_info(&scene, w, h);
    let error = |effect: Effect| {
        let c = Configured::typed::<Sheared>(settings(effect, 3), &info).unwrap();
        let mut o = options(&scene, w, h, 5);
        o.outputs = c.needs();
        c.adjust_render(&mut o);
        let frame = render_frame(&scene, &o, 4);
        let image = c
            .prepare(frame.info(), &gpu())
            .unwrap()
            .run(&frame)
            .unwrap()
            .image;
        mse(&image.pixels, &reference.pixels)
    };
    let (alone, both) = (error(Effect::Dof), error(Effect::DofShadows));
    eprintln!(
        "MSE against 1024 spp: depth of field alone {alone:.3e}, with the shadows {both:.3e}"
    );
    // Measured 6.865e-4 against 7.211e-4 (0.952; 6.876e-4 with light_sigma 0.5): the shadow
    // filter's bias in the penumbrae (a Gaussian light over the square of one frame,
    // mod.rs) eats most of what it takes off the in-focus noise.
    assert!(both < 0.97 * alone, "{both} vs {alone}");
}

#[test]
fn online_equals_offline_and_the_refusals_name_the_fix() {
    cli_online_equals_offline("sheared_lens_shadows_cli", "scenes/toasters_dof.toml");
    let scene = repo_path("scenes/toasters_dof.toml");
    let path = scene.to_str().unwrap();
    let base = [
        "render", path, "--width", "8", "--height", "8", "--spp", "1", "--filter", "sheared",
    ];
    let with = |more: &[&'static str]| {
        base.iter()
            .copied()
            .chain(more.iter().copied())
            .collect::<Vec<_>>()
    };
    fails(
        &with(&["--sheared-effect=dof-shadows", "--sheared-light", "-1"]),
        &["filters none", "\"dof\""],
    );
    let grids = repo_path("scenes/grids.toml");
    let g = grids.to_str().unwrap();
    fails(
        &[
            "render",
            g,
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "--filter",
            "sheared",
            "--sheared-effect=dof-shadows",
        ],
        &["thin lens", "lens_radius"],
    );
}
