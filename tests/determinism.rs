//! Random numbers come from a hash of (seed, pixel, sample, bounce, dimension): the same seed
//! gives the same bytes whatever the work-group size or the number of samples per launch, and
//! the device draws exactly the numbers of the Rust reference.

mod common;

use common::*;
use noisefree::layout::Float4;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::SceneArrays;
use noisefree::render::cpu::rng::{rng_sample_key, rng_uniform};
use noisefree::render::cpu::sampling::camera_ray;

fn test_scene() -> noisefree::scene::Scene {
    scene_from_toml(&cornell(
        "max_depth = 2",
        r#"
[[material]]
name = "glass"
type = "glass"

[[sphere]]
center = [0.3, 0.4, 0.0]
radius = 0.4
material = "glass"
"#,
    ))
}

#[test]
fn same_seed_same_bytes_any_work_group_size_and_batching() {
    let scene = test_scene();
    let mut base = options(&scene, 37, 23, 9); // sizes that are no multiple of any group
    base.outputs = OutputSet::of(&[Output::Features]);
    let reference = film_bytes(&render_film(&scene, &base, 12, 12));
    for (local, batch) in [
        (None, 1),
        (Some([1, 1]), 5),
        (Some([8, 8]), 12),
        (Some([16, 4]), 3),
        (Some([64, 1]), 7),
    ] {
        let mut o = base.clone();
        o.local_size = local;
        let bytes = film_bytes(&render_film(&scene, &o, 12, batch));
        assert!(
            bytes == reference,
            "work-group {local:?}, {batch} samples per launch changed the image"
        );
    }
    let mut other = base.clone();
    other.frame.seed = 10;
    assert!(
        film_bytes(&render_film(&scene, &other, 12, 12)) != reference,
        "a different seed must change the image"
    );
}

#[test]
fn device_random_numbers_equal_the_reference_bit_for_bit() {
    let gpu = gpu();
    let program = gpu
        .program("test/probes.cl", &generic_defines(), "")
        .unwrap();
    let mut rng = TestRng(3);
    let counters: Vec<[u32; 4]> = (0..50_000)
        .map(|i| {
            [
                rng.next_u32() % 4_000_000,
                rng.next_u32() % 100_000,
                rng.next_u32() % 300,
                i % 11,
            ]
        })
        .collect();
    let seed = 0xdead_beef;
    let buf = ocl::Buffer::<ocl::prm::Uint4>::builder()
        .queue(gpu.queue.clone())
        .len(counters.len())
        .copy_host_slice(
            &counters
                .iter()
                .map(|c| ocl::prm::Uint4::new(c[0], c[1], c[2], c[3]))
                .collect::<Vec<_>>(),
        )
        .build()
        .unwrap();
    let out = gpu.zeroed::<f32>(counters.len(), "rng out").unwrap();
    let k = ocl::Kernel::builder()
        .program(&program)
        .name("probe_rng")
        .queue(gpu.queue.clone())
        .global_work_size(counters.len())
        .arg(&buf)
        .arg(seed)
        .arg(&out)
        .arg(counters.len() as u32)
        .build()
        .unwrap();
    unsafe { k.enq().unwrap() };
    let mut got = vec![0f32; counters.len()];
    out.read(&mut got).enq().unwrap();
    for (c, g) in counters.iter().zip(&got) {
        let want = rng_uniform(rng_sample_key(seed, c[0], c[1]), c[2], c[3]);
        assert_eq!(g.to_bits(), want.to_bits(), "counter {c:?}");
    }
}

#[test]
fn camera_rays_match_the_reference() {
    for lens in ["", "lens_radius = 0.05\nfocal_distance = 3.0"] {
        let text = cornell("max_depth = 2", "").replace("fov = 40", &format!("fov = 40\n{lens}"));
        let scene = scene_from_toml(&text);
        let opts = options(&scene, 20, 10, 4);
        let arrays = SceneArrays::build(&scene, &opts.frame).unwrap();
        let gpu = gpu();
        let mut defines = generic_defines();
        if lens.is_empty() {
            defines.retain(|d| d.0 != "HAS_DOF");
            defines.push(("HAS_DOF".into(), "0".into()));
        }
        let program = gpu.program("test/probes.cl", &defines, "").unwrap();
        let params = gpu.upload(std::slice::from_ref(&arrays.params)).unwrap();
        let n = 200;
        let o = gpu.zeroed::<Float4>(n, "o").unwrap();
        let d = gpu.zeroed::<Float4>(n, "d").unwrap();
        let k = ocl::Kernel::builder()
            .program(&program)
            .name("probe_camera")
            .queue(gpu.queue.clone())
            .global_work_size([20, 10])
            .arg(&params)
            .arg(5u32)
            .arg(&o)
            .arg(&d)
            .build()
            .unwrap();
        unsafe { k.enq().unwrap() };
        let (mut go, mut gd) = (vec![Float4::default(); n], vec![Float4::default(); n]);
        o.read(&mut go).enq().unwrap();
        d.read(&mut gd).enq().unwrap();
        for y in 0..10u32 {
            for x in 0..20u32 {
                let i = (y * 20 + x) as usize;
                let (ro, rd) = camera_ray(&arrays.params, x, y, rng_sample_key(4, i as u32, 5));
                // Measured: at most 6.0e-8 for the directions (half a float32 ulp at 1) and
                // 3.7e-9 for the origins; bound 1.2e-7, one ulp at 1 (2x the directions').
                assert!(
                    (go[i].xyz() - ro).length() < 1.2e-7 && (gd[i].xyz() - rd).length() < 1.2e-7,
                    "pixel ({x},{y}) lens {lens:?}: device {:?} {:?} vs reference {ro} {rd}",
                    go[i],
                    gd[i]
                );
            }
        }
    }
}

/// Every program is built with `-cl-fp32-correctly-rounded-divide-sqrt` where the device
/// offers it (src/gpu/mod.rs `program_with_options`), so a division or square root gives one
/// float for the same operands in every inlining context and on every such device: the
/// megakernel, the wavefront steps and both BVH walks must agree to the byte. Checked here
/// against Rust's IEEE `/` and `sqrt` on 2^20 pairs of normal floats (exponents -30..=30, so no
/// result is denormal, which OpenCL lets a device flush), and the option is in the build.
#[test]
fn division_and_sqrt_are_correctly_rounded_where_the_device_offers_it() {
    let gpu = gpu();
    let program = gpu
        .program("test/probes.cl", &generic_defines(), "")
        .unwrap();
    let offers = gpu.summary.correctly_rounded_divide_sqrt;
    let built = gpu.builds().iter().any(|b| {
        b.main == "test/probes.cl" && b.options.contains("-cl-fp32-correctly-rounded-divide-sqrt")
    });
    assert_eq!(
        built, offers,
        "the option is given exactly where the device offers it"
    );
    // The renderer's counter-based hash of the index: mantissa bits, and an exponent in
    // -30..=30 (quotients and roots then stay within 2^±61, far from denormals).
    let normal = |k: u32| -> f32 {
        let h = noisefree::render::cpu::rng::hash_u32(k);
        let exp = -30 + (noisefree::render::cpu::rng::hash_u32(h) % 61) as i32;
        f32::from_bits((((exp + 127) as u32) << 23) | (h & 0x007f_ffff))
    };
    let n = 1usize << 20;
    let pairs: Vec<[f32; 2]> = (0..n as u32)
        .map(|i| [normal(2 * i), normal(2 * i + 1)])
        .collect();
    let flat: Vec<f32> = pairs.iter().flatten().copied().collect();
    let ab = gpu.upload(&flat).unwrap();
    let out = gpu.zeroed::<f32>(2 * n, "quotients and roots").unwrap();
    let k = ocl::Kernel::builder()
        .program(&program)
        .name("probe_divide_sqrt")
        .queue(gpu.queue.clone())
        .global_work_size(n)
        .arg(&ab)
        .arg(&out)
        .arg(n as u32)
        .build()
        .unwrap();
    unsafe { k.enq().unwrap() };
    let mut got = vec![0f32; 2 * n];
    out.read(&mut got).enq().unwrap();
    let wrong = pairs
        .iter()
        .zip(got.chunks_exact(2))
        .filter(|([a, b], qr)| {
            (a / b).to_bits() != qr[0].to_bits() || a.sqrt().to_bits() != qr[1].to_bits()
        })
        .count();
    eprintln!("{wrong} of {n} quotients or roots differ from IEEE 754's (option given: {offers})");
    if offers {
        assert_eq!(
            wrong, 0,
            "the device rounds / or sqrt otherwise despite the option"
        );
    }
}

/// The samplers use one sincos per direction (issue 14: it halves their argument reductions)
/// where the thesis's Algorithm 5 has sin and cos. The images stay those of sin and cos because
/// on this device sincos returns exactly their bits for every angle the samplers can pass:
/// 2 pi k 2^-24 for all 2^24 values k of rng_uniform, checked exhaustively.
#[test]
fn sincos_equals_sin_and_cos_for_every_sampled_angle() {
    let gpu = gpu();
    let program = gpu
        .program("test/probes.cl", &generic_defines(), "")
        .unwrap();
    let mismatches = gpu.zeroed::<u32>(1, "mismatches").unwrap();
    let k = ocl::Kernel::builder()
        .program(&program)
        .name("probe_sincos")
        .queue(gpu.queue.clone())
        .global_work_size(1usize << 24)
        .arg(&mismatches)
        .build()
        .unwrap();
    unsafe { k.enq().unwrap() };
    let mut out = [0u32];
    mismatches.read(&mut out[..]).enq().unwrap();
    assert_eq!(out[0], 0, "angles where sincos differs from sin and cos");
}
