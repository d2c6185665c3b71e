//! Stylized shadows of several lights (DeCoro 2009 eq. 3.1: Σ_l ρ S_l L_l, each light with its
//! own S_l; src/filters/stylized "Several lights"): the shadow output's per-light planes
//! (src/layout/outputs.rs `Per::Light`) against one-light renders, the compose
//! F − Σ_l direct_l + Σ_l r_l·S_l on the device against the Rust reference, one light's edit
//! changing the image by exactly its own term, the AOV file and merged sample ranges holding
//! every plane. Scene: scenes/decoro/stylized_two_lights.toml (two sphere lights).

mod common;
#[path = "common/stylized.rs"]
mod stylized_common;

use std::path::PathBuf;

use common::aaf::shadow_renderer;
use common::merge::{assert_outputs_within_bound, filtered_difference};
use common::*;
use noisefree::filters::stylized::{
    Controls, StylizedKernel, StylizedSettings, light_plane, reference_lights,
};
use noisefree::filters::{Auto, Configured};
use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::layout::{ShadowPixel, ShadowTerms};
use noisefree::render::{Frame, HostBuffer, LightPlanes, Renderer, ShadowSampling, Tile};
use noisefree::scene::Scene;
use noisefree::stats::merge::Plan;
use noisefree::stats::partial::{self, Piece, PieceInfo};
use stylized_common::*;

const W: u32 = 64;
const H: u32 = 48;

fn scene() -> Scene {
    noisefree::scene::load_scene(&repo_path("scenes/decoro/stylized_two_lights.toml"))
        .unwrap_or_else(|e| panic!("{e}"))
}

fn sampling(lights: &[u32]) -> ShadowSampling {
    ShadowSampling {
        lights: LightPlanes::of(lights),
        ..StylizedSettings::default().sampling()
    }
}

fn frame(lights: &[u32]) -> Frame {
    shadow_renderer(&scene(), W, H, 4, 7, sampling(lights)).frame()
}

/// Both lights stylized (light = auto, specialised to the scene's two sphere lights).
fn both() -> StylizedSettings {
    StylizedSettings {
        light_count: 2,
        contour_samples: 64,
        blur_samples: 32,
        ..Default::default()
    }
}

fn bits(img: &RgbImage) -> Vec<u32> {
    img.pixels.iter().flatten().map(|v| v.to_bits()).collect()
}

fn floats<T: ocl::OclPrm>(v: &[T]) -> Vec<u32> {
    HostBuffer::from_slice(v)
        .floats()
        .iter()
        .map(|f| f.to_bits())
        .collect()
}

#[test]
fn each_plane_holds_the_bytes_of_a_one_light_render() {
    // The passes of a plane depend on the pixel and its light alone, and the megakernel folds
    // each light's term into its own plane with the same random numbers: plane l of a render
    // of both lights is, byte for byte, the shadow output of a render of light l alone, and
    // F does not depend on the planes.
    let two = frame(&[0, 1]);
    assert_eq!(two.info().shadow_lights, vec![0, 1]);
    let fv = bits_of(&two);
    let mut receivers = [0usize; 2];
    for l in [0u32, 1] {
        let one = frame(&[l]);
        assert_eq!(one.info().shadow_lights, vec![l]);
        assert_eq!(bits_of(&one), fv, "F with planes {{{l}}} and {{0, 1}}");
        let p2: Vec<ShadowPixel> = light_plane(&two, BufferId::ShadowPixels, l).unwrap();
        let t2: Vec<ShadowTerms> = light_plane(&two, BufferId::ShadowTerms, l).unwrap();
        let p1: &[ShadowPixel] = one.host_slice(BufferId::ShadowPixels).unwrap();
        let t1: &[ShadowTerms] = one.host_slice(BufferId::ShadowTerms).unwrap();
        assert_eq!(floats(&p2), floats(p1), "shadow pixels of light {l}");
        assert_eq!(floats(&t2), floats(t1), "shadow terms of light {l}");
        receivers[l as usize] = p1.iter().filter(|p| p.weight > 0.0).count();
        let shadowed = p1
            .iter()
            .filter(|p| p.weight > 0.0 && p.centre_visible == 0.0)
            .count();
        eprintln!(
            "light {l}: {} receivers, {shadowed} in its hard shadow",
            receivers[l as usize]
        );
        assert!(
            shadowed > 50,
            "light {l} casts a shadow in view: {shadowed}"
        );
        assert!(t1.iter().any(|t| t.direct[0] > 0.0));
    }
    // The two planes differ (different lights), so the test could fail.
    let a: Vec<ShadowPixel> = light_plane(&two, BufferId::ShadowPixels, 0).unwrap();
    let b: Vec<ShadowPixel> = light_plane(&two, BufferId::ShadowPixels, 1).unwrap();
    assert_ne!(floats(&a), floats(&b));
}

fn bits_of(frame: &Frame) -> Vec<u32> {
    floats(frame.filter_vectors().unwrap())
}

#[test]
fn identity_controls_give_f_minus_every_direct_plus_r_v() {
    let s = both();
    let frame = frame(&[0, 1]);
    let (image, _) = device(&frame, &s);
    let fv = frame.filter_vectors().unwrap();
    let planes: Vec<(Vec<ShadowPixel>, Vec<ShadowTerms>)> = [0u32, 1]
        .iter()
        .map(|&l| {
            (
                light_plane(&frame, BufferId::ShadowPixels, l).unwrap(),
                light_plane(&frame, BufferId::ShadowTerms, l).unwrap(),
            )
        })
        .collect();
    let (mut changed, mut worst_err) = (0, 0f32);
    for k in 0..fv.len() {
        let mut want: [f32; 3] = std::array::from_fn(|c| fv[k].direct[c] + fv[k].indirect[c]);
        let beauty = want;
        for (p, t) in &planes {
            let (p, t) = (&p[k], &t[k]);
            if p.weight > 0.0 {
                for (c, w) in want.iter_mut().enumerate() {
                    *w = *w - t.direct[c] + p.unshadowed[c] / p.samples * p.centre_visible;
                }
            }
        }
        for (got, w) in image.pixels[k].iter().zip(&want) {
            worst_err = worst_err.max((got - w).abs() / w.abs().max(1.0));
        }
        changed += (want != beauty) as usize;
    }
    eprintln!(
        "{changed} of {} pixels changed by the two lights' hard shadows; worst error \
         {worst_err:e}",
        fv.len()
    );
    assert!(changed > fv.len() / 4);
    // The kernel composes in this order, a light at a time: measured 0 on PoCL (the same
    // floats); 1e-6 of the value for another driver's rounding.
    assert!(worst_err <= 1e-6, "{worst_err:e}");
}

fn styled_for(l: u32) -> Controls {
    let mut c = styled().controls();
    if l == 1 {
        c.inflation = [-0.05, 0.02, 0.0];
        c.softness = [0.2, 0.0, 0.0];
        c.abstraction = [4.0, 0.0, 0.0];
    }
    c
}

#[test]
fn kernels_match_the_reference_with_two_lights_styled_apart() {
    let s = both();
    let frame = frame(&[0, 1]);
    let controls = [styled_for(0), styled_for(1)];
    let cpu = reference_lights(&frame, &s, &controls).unwrap();
    let mut k = StylizedKernel::new(gpu(), &s, &[0, 1], W, H).unwrap();
    for (l, c) in controls.iter().enumerate() {
        k.set_light_controls(l, c).unwrap();
    }
    let image = k.filter(&frame).unwrap().image;
    for (l, stages) in cpu.iter().enumerate() {
        let dev = k.light_stages(l).unwrap();
        assert_eq!(
            dev.contour_points as usize,
            stages.contour.len() / 2,
            "light {l}"
        );
        let wd = worst(&dev.distance, &stages.distance, 1e-3);
        let wb = worst(&dev.blurred, &stages.blurred, 1e-3);
        let wm = worst(&dev.matte, &stages.matte, 1e-3);
        eprintln!("light {l}: D {wd:e}, G*D {wb:e}, S {wm:e}");
        // Measured on PoCL: bit-identical, as the one-light test; 1e-6 for another driver.
        assert!(wd < 1e-6 && wb < 1e-6 && wm < 1e-6, "light {l}");
    }
    let wi = max_rel_diff(&image, &cpu[1].image);
    eprintln!("image {wi:e}");
    assert!(wi < 1e-6, "{wi}");
    // The lights' mattes differ: each light has its own contour.
    assert_ne!(cpu[0].matte, cpu[1].matte);
}

#[test]
fn an_edit_of_light_1_changes_the_image_by_its_own_term_alone() {
    let s = both();
    let frame = frame(&[0, 1]);
    let mut k = StylizedKernel::new(gpu(), &s, &[0, 1], W, H).unwrap();
    let before = k.filter(&frame).unwrap().image;
    let m0 = k.light_stages(0).unwrap().matte;
    let m1 = k.light_stages(1).unwrap().matte;
    k.set_light_controls(1, &styled_for(1)).unwrap();
    let after = k.filter(&frame).unwrap().image;
    let m0b = k.light_stages(0).unwrap().matte;
    let m1b = k.light_stages(1).unwrap().matte;
    assert_eq!(m0, m0b, "light 0's matte is left alone");
    assert_ne!(m1, m1b);
    let p1: Vec<ShadowPixel> = light_plane(&frame, BufferId::ShadowPixels, 1).unwrap();
    let (mut moved, mut worst_err) = (0, 0f32);
    for k in 0..p1.len() {
        let p = &p1[k];
        for c in 0..3 {
            let want = if p.weight > 0.0 {
                p.unshadowed[c] / p.samples * (m1b[k] - m1[k])
            } else {
                0.0
            };
            let got = after.pixels[k][c] - before.pixels[k][c];
            // The compose adds light 1's term last, so the difference is r_1·(S_1′ − S_1) up
            // to the rounding of the sums (measured 1.4e-8 on PoCL, relative to max(|v|, 1);
            // bound 2.4e-7, two float steps at 1).
            let err = (got - want).abs()
                / before.pixels[k][c]
                    .abs()
                    .max(after.pixels[k][c].abs())
                    .max(1.0);
            worst_err = worst_err.max(err);
            moved += (want != 0.0) as usize;
        }
    }
    eprintln!("{moved} channel values moved by light 1's edit; worst error {worst_err:e}");
    assert!(worst_err <= 2.4e-7, "{worst_err:e}");
    assert!(moved > 100);
}

#[test]
fn one_light_stylized_reads_its_plane_and_gives_the_one_light_bytes() {
    // Light 1 alone: on a frame of both planes it reads plane 1 and leaves light 0's shadow as
    // rendered; the bytes are those of the filter on a render of light 1 alone.
    let s = StylizedSettings {
        light: Auto::Set(1),
        ..styled()
    };
    assert_eq!(s.stylized_lights(), vec![1]);
    assert_eq!(s.sampling().lights, LightPlanes::one(1));
    let (two, one) = (frame(&[0, 1]), frame(&[1]));
    let (a, _) = device(&two, &s);
    let (b, _) = device(&one, &s);
    assert_eq!(bits(&a), bits(&b));
    assert_ne!(bits(&a), bits(&two.beauty().unwrap()));
    // A light the frame has no plane for is an error naming both.
    let e = StylizedKernel::new(gpu(), &s, &[1], W, H)
        .unwrap()
        .filter(&frame(&[0]))
        .map(|_| ())
        .expect_err("no plane for light 1");
    let e = format!("{e:#}");
    assert!(e.contains("sphere light 1") && e.contains("[0]"), "{e}");
}

#[test]
fn auto_stylizes_every_sphere_light_and_the_cap_is_an_error() {
    let scene = scene();
    let mut o = noisefree::render::RenderOptions::for_scene(&scene);
    o.frame.width = W;
    o.frame.height = H;
    let arrays = noisefree::render::SceneArrays::build(&scene, &o.frame).unwrap();
    let info = noisefree::render::SceneInfo::new(&scene, &arrays);
    let c = Configured::typed::<noisefree::filters::stylized::StylizedShadows>(
        StylizedSettings::default(),
        &info,
    )
    .unwrap();
    let mut opts = o.clone();
    c.adjust_render(&mut opts);
    assert_eq!(opts.shadows.lights, LightPlanes::of(&[0, 1]));
    assert!(c.needs().contains(Output::Shadows));
    // More planes than the cap: the renderer refuses with the cap and what to do.
    o.outputs = OutputSet::of(&[Output::Shadows]);
    o.shadows = ShadowSampling {
        lights: LightPlanes(0x1ff),
        ..sampling(&[0])
    };
    let e = format!(
        "{:#}",
        Renderer::new(gpu(), &scene, &o).err().expect("9 planes")
    );
    assert!(e.contains("1 to 8") && e.contains("fewer lights"), "{e}");
    let e = StylizedSettings {
        light_count: 9,
        ..Default::default()
    }
    .validate()
    .expect_err("lights = 9");
    assert!(format!("{e:#}").contains("at most 8"), "{e:#}");
}

#[test]
fn the_aov_file_and_merged_sample_ranges_hold_every_plane() {
    let s = both();
    let two = frame(&[0, 1]);
    let dir = tempdir("stylized-lights");
    // AOV: channels shadow.l0.* and shadow.l1.*; the file's frame filters to the same bytes.
    let record = record_of(&two);
    let file = aov_round_trip(&two, &dir);
    assert_eq!(file.info().shadow_lights, vec![0, 1]);
    let (online, _) = device(&two, &s);
    let (offline, _) = device(&file, &s);
    assert_eq!(bits(&online), bits(&offline));

    // Two sample ranges merged: the planes' terms are means like F, their pixels identical.
    let scene = scene();
    let render = |range: std::ops::Range<u32>| {
        let mut o = options(&scene, W, H, 7);
        o.outputs = OutputSet::of(&[Output::Shadows]);
        o.shadows = sampling(&[0, 1]);
        o.first_sample = range.start;
        let mut r = Renderer::new(gpu(), &scene, &o).unwrap_or_else(|e| panic!("{e:#}"));
        r.render_samples(range.end - range.start).unwrap();
        let info = PieceInfo {
            tile: Tile::whole(W, H),
            samples: range,
            rays: r.rays_total,
            seconds: 0.0,
            device: "test".into(),
        };
        (r.frame(), info)
    };
    let (one, _) = render(0..8);
    let id = noisefree::stats::partial::RenderIdentity {
        scene: "test".into(),
        scene_hash: 0,
        kernel_hash: noisefree::render::kernel_hash(),
        width: W,
        height: H,
        seed: 7,
        spp: 8,
        outputs: one.outputs(),
        shadow_lights: vec![0, 1],
        record,
    };
    let paths: Vec<PathBuf> = [0..3, 3..8]
        .into_iter()
        .map(|range| {
            let (frame, info) = render(range.clone());
            let path = dir.join(format!("{}.nfp", range.start));
            let piece = Piece::of_frame(&frame, info).unwrap();
            partial::write(&path, &id, std::slice::from_ref(&piece)).unwrap();
            path
        })
        .collect();
    let merged = Plan::new(&paths).unwrap().merge(|_| {}).unwrap().frame;
    assert_eq!(merged.info().shadow_lights, vec![0, 1]);
    assert_outputs_within_bound(&one, &merged);
    let (a, b) = (
        one.host(BufferId::ShadowPixels).unwrap().floats(),
        merged.host(BufferId::ShadowPixels).unwrap().floats(),
    );
    assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
    let (i1, _) = device(&one, &s);
    let (i2, _) = device(&merged, &s);
    let (d, compared) = filtered_difference(&one, &i1, &i2);
    eprintln!("two-light stylized image: merged within {d:.2e} of one render ({compared} px)");
    // Measured 1.49e-5 (PoCL): the merged means round differently in the last bit, and the
    // compose subtracts two lights' terms from F, so the cancellation is twice aaf-shadows'
    // (tests/partial.rs bounds its one light at 1e-5); bound 3e-5.
    assert!(d <= 3e-5, "{d:e}");
}

#[test]
fn per_light_tables_override_the_controls_of_their_light() {
    // As a scene file writes them: the filter's controls for every light, light 1's own
    // softness and abstraction.
    let table: toml::Table = toml::from_str(
        "inflation = [0.05, 0.0, 0.0]\nlight_count = 2\ncontour_samples = 64\n\
         blur_samples = 32\n[lights.1]\nsoftness = [0.3, 0.0, 0.0]\n\
         abstraction = [3.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let s: StylizedSettings = noisefree::filters::settings::from_table(&table).unwrap();
    s.validate().unwrap();
    let shared = s.controls();
    let own = s.controls_of(1);
    assert_eq!(s.controls_of(0), shared);
    assert_eq!(own.inflation, shared.inflation);
    assert_eq!(own.softness, [0.3, 0.0, 0.0]);
    assert_eq!(own.abstraction, [3.0, 0.0, 0.0]);
    let frame = frame(&[0, 1]);
    let cpu = reference_lights(&frame, &s, &[shared, own]).unwrap();
    let mut k = StylizedKernel::new(gpu(), &s, &s.stylized_lights(), W, H).unwrap();
    let image = k.filter(&frame).unwrap().image;
    assert_eq!(bits(&image), bits(&cpu[1].image), "device and reference");
    // Light 0 has the shared controls: its matte is that of the settings without the table.
    let plain = StylizedSettings {
        lights: Default::default(),
        ..s.clone()
    };
    let mut k0 = StylizedKernel::new(gpu(), &plain, &[0, 1], W, H).unwrap();
    let other = k0.filter(&frame).unwrap().image;
    assert_eq!(
        k.light_stages(0).unwrap().matte,
        k0.light_stages(0).unwrap().matte
    );
    assert_ne!(
        k.light_stages(1).unwrap().matte,
        k0.light_stages(1).unwrap().matte
    );
    assert_ne!(bits(&image), bits(&other));

    // stylize = false leaves a light's shadow as rendered: light 1 alone is stylized.
    let table: toml::Table = toml::from_str("[lights.0]\nstylize = false\n").unwrap();
    let mut s: StylizedSettings = noisefree::filters::settings::from_table(&table).unwrap();
    s.light_count = 2;
    assert_eq!(s.stylized_lights(), vec![1]);
    assert_eq!(s.sampling().lights, LightPlanes::one(1));
    // A table named by anything but a light number is refused, naming it.
    let table: toml::Table = toml::from_str("[lights.key]\nsoftness = [1.0, 0.0, 0.0]\n").unwrap();
    let s: StylizedSettings = noisefree::filters::settings::from_table(&table).unwrap();
    let e = format!("{:#}", s.validate().expect_err("lights.key"));
    assert!(e.contains("lights.key") && e.contains("number"), "{e}");
    let table: toml::Table = toml::from_str("[lights.1]\nsoftnes = [1.0, 0.0, 0.0]\n").unwrap();
    let e = noisefree::filters::settings::from_table::<StylizedSettings>(&table)
        .expect_err("unknown key");
    assert!(format!("{e:#}").contains("softnes"), "{e:#}");
    // On the command line: an inline table.
    let v = noisefree::filters::settings::parse_flag_value(
        "{1 = {softness = [0.4, 0, 0]}}",
        &toml::Value::Table(Default::default()),
    );
    let mut t = toml::Table::new();
    t.insert("lights".into(), v);
    let s: StylizedSettings = noisefree::filters::settings::from_table(&t).unwrap();
    assert_eq!(s.controls_of(1).softness, [0.4, 0.0, 0.0]);
}

#[test]
fn aaf_shadows_reads_the_plane_of_its_light() {
    // A frame of both planes (a render for the stylized filter, or its AOV file) filtered by
    // aaf-shadows for light 1: the bytes of the render of light 1 alone. F and plane 1 are
    // the same bytes in both (each_plane_holds_the_bytes_of_a_one_light_render); the sparse
    // sampling of aaf differs from the stylized filter's, so both frames use aaf's.
    let aaf = noisefree::filters::aaf_shadows::AafShadowSettings {
        light: Auto::Set(1),
        ..Default::default()
    };
    let planes = |lights: &[u32]| ShadowSampling {
        lights: LightPlanes::of(lights),
        ..aaf.sampling()
    };
    let two = shadow_renderer(&scene(), W, H, 4, 7, planes(&[0, 1])).frame();
    let one = shadow_renderer(&scene(), W, H, 4, 7, planes(&[1])).frame();
    let a = common::aaf::aaf_filtered(&two, &aaf);
    let b = common::aaf::aaf_filtered(&one, &aaf);
    assert_eq!(bits(&a), bits(&b));
    assert_ne!(bits(&a), bits(&one.beauty().unwrap()));
}

#[test]
fn sheared_reads_the_planes_of_its_light() {
    use noisefree::filters::sheared::{Sheared, ShearedSettings};
    // Every plane has its light's light field (kernels/render/light_field.cl, in that light's
    // frame): sheared filtering of light 0 or of light 1 on a render of planes {0, 1} gives
    // the bytes of a render of that light alone.
    let scene = scene();
    let render = |lights: &[u32], s: &ShearedSettings| {
        let mut o = options(&scene, W, H, 5);
        o.outputs = OutputSet::of(&[Output::Shadows, Output::LightField]);
        o.shadows = ShadowSampling {
            lights: LightPlanes::of(lights),
            ..s.sampling()
        };
        let mut r = Renderer::new(gpu(), &scene, &o).unwrap_or_else(|e| panic!("{e:#}"));
        r.render_samples(2).unwrap();
        r.frame()
    };
    let filter = |frame: &Frame, s: &ShearedSettings| filtered::<Sheared>(frame, s);
    let two = render(&[0, 1], &ShearedSettings::default());
    for l in [0, 1] {
        let s = ShearedSettings {
            light: Auto::Set(l),
            ..Default::default()
        };
        let a = filter(&two, &s);
        let b = filter(&render(&[l as u32], &s), &s);
        assert_eq!(bits(&a), bits(&b), "light {l}");
        assert_ne!(bits(&a), bits(&two.beauty().unwrap()), "light {l}");
    }
}

#[test]
fn every_plane_matches_the_rust_reference_of_its_light() {
    // The Rust reference (src/render/cpu/shadows.rs) computes one light's passes and terms;
    // the renderer's plane l must match it for light l as the one-light output does
    // (tests/aaf_sampling.rs, whose bounds these are).
    use noisefree::render::SceneArrays;
    use noisefree::render::cpu::pathtrace::ReferenceOptions;
    use noisefree::render::cpu::shadows::{passes, render_shadow_terms};
    let scene = scene();
    let spp = 3;
    let two = shadow_renderer(&scene, W, H, spp, 7, sampling(&[0, 1])).frame();
    let arrays = SceneArrays::build(&scene, &options(&scene, W, H, 7).frame).unwrap();
    let ro = ReferenceOptions {
        russian_roulette: scene.render.russian_roulette,
        next_event_estimation: scene.render.next_event_estimation,
    };
    for l in [0u32, 1] {
        let device: Vec<ShadowPixel> = light_plane(&two, BufferId::ShadowPixels, l).unwrap();
        let terms: Vec<ShadowTerms> = light_plane(&two, BufferId::ShadowTerms, l).unwrap();
        let (cpu, _) = passes(&arrays, &sampling(&[l]));
        let lanes = |p: &ShadowPixel| {
            HostBuffer::from_slice(std::slice::from_ref(p))
                .floats()
                .to_vec()
        };
        let close = device
            .iter()
            .zip(&cpu)
            .filter(|(d, c)| {
                lanes(d)
                    .iter()
                    .zip(lanes(c))
                    .all(|(a, b)| (a - b).abs() <= 1e-5 * a.abs().max(b.abs()).max(1.0))
            })
            .count();
        let mut reference = vec![[0f32; 8]; terms.len()];
        render_shadow_terms(&arrays, ro, l, &device, &mut reference, 0, spp);
        let far = terms
            .iter()
            .zip(&reference)
            .filter(|(t, r)| {
                t.direct
                    .iter()
                    .zip(&r[..3])
                    .chain(t.unshadowed.iter().zip(&r[4..7]))
                    .any(|(a, b)| (a - b).abs() > 1e-5 * a.abs().max(b.abs()).max(1.0))
            })
            .count();
        eprintln!(
            "light {l}: {close} of {} shadow pixels agree, {far} terms apart",
            device.len()
        );
        // Measured here: every pixel within 1e-5 and no term apart, for both lights; the
        // bounds of tests/aaf_sampling.rs (99% of the pixels: a grazing shadow ray can be
        // decided differently by two libraries' sin/cos; terms at most 1% apart).
        assert!(close * 100 >= device.len() * 99, "light {l}: {close}");
        assert!(far * 100 <= terms.len(), "light {l}: {far} pixels apart");
    }
}
