//! The à-trous filter's two kernels, scalar (kernels/filters/atrous.cl, one pixel per
//! work-item) and packed (kernels/filters/atrous_packed.cl, 16 pixels of a row per work-item on
//! float16 lanes), against the plain Rust reference: rendered buffers, widths that are no
//! multiple of 16, groups of sky, taps spaced wider than the image, bands of rows.

mod common;

#[path = "common/atrous.rs"]
mod atrous_common;

use atrous_common::*;
use common::*;
use noisefree::filters::Auto;
use noisefree::filters::atrous::{AtrousKernel, AtrousSettings, MAX_ITERATIONS, Variant};
use noisefree::layout::SKY_DEPTH;

const VARIANTS: [Variant; 2] = [Variant::Scalar, Variant::Packed];

fn with(s: &AtrousSettings, variant: Variant) -> AtrousSettings {
    AtrousSettings {
        variant,
        ..s.clone()
    }
}

/// Checks `s` for both variants on `b`; returns the largest difference of each to the
/// reference (scalar, packed).
fn both(
    b: &Buffers,
    cam: &noisefree::scene::CameraBasis,
    s: &AtrousSettings,
    what: &str,
) -> [f32; 2] {
    VARIANTS.map(|v| check_against_reference(b, cam, &with(s, v), &format!("{what} {v:?}")))
}

fn max2(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [a[0].max(b[0]), a[1].max(b[1])]
}

#[test]
fn both_kernels_match_the_rust_reference_on_rendered_buffers() {
    // 70 x 45: no multiple of any work-group size, nor of the 16 lanes.
    let (b, cam) = render(&cornell_with_spheres(), 70, 45, 8, 1);
    let (d, dcam) = render(&bundled_scene("cornell_diffuse"), 61, 37, 4, 2);
    let mut worst = [0f32; 2];
    for demodulate in [true, false] {
        for iterations in [0, 1, 5, 7] {
            let s = AtrousSettings {
                iterations,
                demodulate,
                ..Default::default()
            };
            worst = max2(worst, both(&b, &cam, &s, "cornell with spheres"));
            worst = max2(worst, both(&d, &dcam, &s, "cornell diffuse"));
        }
        let s = AtrousSettings {
            sigma_color: Auto::Set(0.1),
            sigma_normal: Auto::Set(0.05),
            sigma_position: Auto::Set(0.5),
            demodulate,
            ..Default::default()
        };
        worst = max2(
            worst,
            both(&b, &cam, &s, "cornell with spheres, small sigmas"),
        );
    }
    eprintln!("rendered: scalar {:e}, packed {:e}", worst[0], worst[1]);
}

#[test]
fn both_kernels_match_the_rust_reference_on_synthetic_buffers_of_many_sizes() {
    // Random buffers have 10 % sky pixels. Widths below, at and past one group of 16 lanes,
    // and ones that leave a partial group (70, 45, 33, 20, 9, 1).
    let sizes = [
        (1, 1),
        (1, 13),
        (13, 1),
        (2, 3),
        (5, 5),
        (9, 11),
        (16, 4),
        (17, 9),
        (20, 6),
        (33, 65),
        (45, 8),
        (70, 9),
        (100, 7),
    ];
    let mut worst = [0f32; 2];
    for (k, (w, h)) in sizes.into_iter().enumerate() {
        let b = random_buffers(w, h, 11 + k as u64);
        for demodulate in [true, false] {
            for iterations in [1, 5] {
                let s = AtrousSettings {
                    iterations,
                    demodulate,
                    ..Default::default()
                };
                let what = format!("{w}x{h}");
                worst = max2(worst, both(&b, &test_camera(), &s, &what));
            }
        }
    }
    eprintln!("synthetic: scalar {:e}, packed {:e}", worst[0], worst[1]);
}

#[test]
fn sky_groups_and_taps_wider_than_the_image() {
    // 45 x 12: columns 16-31 (the packed kernel's second group of lanes) are sky in rows
    // 0-5, so those work-items skip every tap; elsewhere sky in a pattern that leaves partial
    // groups; the last group has 13 lanes.
    let b = synthetic(45, 12, |x, y| {
        let sky = ((16..32).contains(&x) && y < 6) || (x * 5 + y * 3) % 13 == 0;
        if sky {
            fv([x as f32 * 0.1, 0.5, 2.0], SKY_DEPTH, [0.0; 3], [0.0; 3])
        } else {
            let n = if (x + y) % 3 == 0 {
                [0.0, 0.0, 1.0]
            } else {
                [0.6, 0.0, 0.8]
            };
            let light = [((x * 7 + y * 3) % 5) as f32 * 0.2; 3];
            fv(light, 2.0 + (y % 4) as f32, n, [0.4, 0.6, 0.8])
        }
    });
    // Up to MAX_ITERATIONS passes: taps 2^14 pixels apart, every one but the centre outside
    // the image (the packed kernel skips them whole, its padding is 16 floats).
    let mut worst = [0f32; 2];
    for iterations in [3, 5, 8, MAX_ITERATIONS] {
        for demodulate in [true, false] {
            let s = AtrousSettings {
                iterations,
                demodulate,
                ..Default::default()
            };
            worst = max2(worst, both(&b, &test_camera(), &s, "sky groups"));
        }
    }
    eprintln!("sky groups: scalar {:e}, packed {:e}", worst[0], worst[1]);
    // Sky keeps its input bit for bit in both.
    for v in VARIANTS {
        let out = device(&b, &test_camera(), &with(&AtrousSettings::default(), v));
        for (i, f) in b.filter_vectors.iter().enumerate() {
            if f.depth >= SKY_DEPTH {
                assert_eq!(out.pixels[i], b.beauty().pixels[i], "{v:?}: sky changed");
            }
        }
    }
}

#[test]
fn auto_runs_the_packed_kernel_on_a_cpu_and_the_scalar_one_elsewhere() {
    assert_eq!(Variant::Auto.for_device("CPU"), Variant::Packed);
    assert_eq!(Variant::Auto.for_device("GPU"), Variant::Scalar);
    assert_eq!(Variant::Scalar.for_device("CPU"), Variant::Scalar);
    let gpu = gpu();
    let b = random_buffers(37, 21, 5);
    let cam = test_camera();
    let auto = AtrousKernel::new(gpu.clone(), &AtrousSettings::default(), &cam, 37, 21).unwrap();
    let want = Variant::Auto.for_device(&gpu.summary.kind);
    assert_eq!(auto.variant(), want);
    assert_eq!(
        device(&b, &cam, &AtrousSettings::default()).pixels,
        device(&b, &cam, &with(&AtrousSettings::default(), want)).pixels
    );
}

#[test]
fn a_band_of_rows_gets_the_whole_frames_bytes() {
    // filter_rows widens every pass by what the later passes read; each band's pixels must
    // be those of the whole frame, for both kernels.
    let (b, cam) = render(&cornell_with_spheres(), 53, 90, 4, 6);
    let frame = b.frame();
    for v in VARIANTS {
        let s = with(&AtrousSettings::default(), v);
        let mut f = AtrousKernel::new(gpu(), &s, &cam, 53, 90).unwrap();
        let whole = f.filter(&frame).unwrap().image;
        for rows in [0..7, 7..70, 70..90] {
            let band = f.filter_rows(&frame, rows.clone()).unwrap().image;
            let at = |y: u32| (y * 53) as usize..((y + 1) * 53) as usize;
            for y in rows {
                assert_eq!(band.pixels[at(y)], whole.pixels[at(y)], "{v:?} row {y}");
            }
        }
    }
}
