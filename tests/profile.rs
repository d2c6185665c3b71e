//! `noisefree filter --profile` (src/gpu/profile.rs): every kernel a filter launches is in
//! the per-kernel split, so the split adds up to the filter's own kernel time exactly. A
//! filter that launched a kernel around the recording (its own command instead of
//! `gpu::enqueue`) would be missing from the split and fail here.
//!
//! Its own test binary: the recording is process-wide, and the tests of one binary run in
//! parallel threads.

mod common;

use common::*;
use noisefree::filters::{FilterRequest, Registry};
use noisefree::gpu::profile;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::{Renderer, SceneArrays, SceneInfo};

#[test]
fn the_kernel_split_adds_up_to_every_device_filters_kernel_time() {
    let registry = Registry::builtin();
    let mut profiled = std::collections::BTreeSet::new();
    // Between them these scenes run every device filter: the Cornell box (ddf, à-trous, bmfr,
    // path density), sphere-light shadows (aaf-shadows, stylized, sheared, subtractive), GI
    // (room_gi: aaf-indirect, sheared GI) and depth of field (toasters_dof, outside_dof).
    for name in [
        "cornell_glossy",
        "two_lights_shadows",
        "room_gi",
        "toasters_dof",
        "outside_dof",
    ] {
        let scene = bundled_scene(name);
        let o = options(&scene, 24, 20, 1);
        let arrays = SceneArrays::build(&scene, &o.frame).unwrap();
        let info = SceneInfo::new(&scene, &arrays);
        let request = FilterRequest {
            scene: scene.filter.settings.clone(),
            ..Default::default()
        };
        for c in registry.configure_all(&request, &info).unwrap() {
            // Each filter on a render that gathers what it needs, as `render --filter` does.
            let mut o = o.clone();
            o.outputs = OutputSet::of(&[Output::Features]).union(c.needs());
            c.adjust_render(&mut o);
            o.sample_capacity = 4;
            let mut r = Renderer::with_arrays(gpu(), &scene, arrays.clone(), &o).unwrap();
            r.render_samples(4).unwrap();
            let frame = r.frame();
            let mut prepared = c.prepare(frame.info(), &gpu()).unwrap();
            profile::start();
            let run = prepared.run(&frame).unwrap();
            let kernels = profile::finish().unwrap();
            let Some(kernel_time) = run.kernel_time else {
                // A host filter (RPF) launches nothing.
                assert!(kernels.is_empty(), "{name} {}: {kernels:?}", c.name());
                continue;
            };
            let split: std::time::Duration = kernels.iter().map(|k| k.time).sum();
            if kernels.is_empty() {
                // A filter with nothing to do on this scene (shadow filters without a sphere
                // light) passes the image through.
                assert_eq!(
                    kernel_time,
                    std::time::Duration::ZERO,
                    "{name} {}",
                    c.name()
                );
                continue;
            }
            assert_eq!(
                split,
                kernel_time,
                "{name} {}: the split {kernels:?} against the filter's kernel time",
                c.name()
            );
            profiled.insert(c.name().to_string());
            if c.name() == "stylized-shadows" {
                // The same frame again: only the compose runs (the thesis's fast edits), so a
                // repeated run would time a fraction of the filter; after `forget` the whole
                // filter runs again, as `filter --repeat` and the benchmarks time it.
                let launched = |prepared: &mut Box<dyn noisefree::filters::PreparedFilter>| {
                    profile::start();
                    prepared.run(&frame).unwrap();
                    let k = profile::finish().unwrap();
                    k.iter().map(|k| k.kernel.clone()).collect::<Vec<_>>()
                };
                let again = launched(&mut prepared);
                assert!(
                    !again.iter().any(|k| k == "st_distance"),
                    "{name}: {again:?}"
                );
                prepared.forget();
                let fresh = launched(&mut prepared);
                let all: Vec<String> = kernels.iter().map(|k| k.kernel.clone()).collect();
                assert_eq!(fresh, all, "{name}");
                assert!(
                    fresh.iter().any(|k| k == "st_distance"),
                    "{name}: {fresh:?}"
                );
            }
        }
    }
    // Nothing recorded outside a recording.
    assert!(profile::finish().unwrap().is_empty());
    eprintln!("profiled: {profiled:?}");
    for filter in [
        "ddf",
        "atrous",
        "bmfr",
        "path-density",
        "aaf-shadows",
        "aaf-indirect",
        "stylized-shadows",
        "sheared",
    ] {
        assert!(profiled.contains(filter), "{filter} was not profiled");
    }
}

/// scripts/filter-ab.sh reads `filter --profile`'s table (a kernel's name first, its
/// milliseconds third) and the filter's median line: run with this binary as both builds on a
/// small AOV file, it must find the filter's and a kernel's times and the same bytes.
#[test]
fn filter_ab_script_reads_the_profile_table() {
    let dir = tempdir("filter-ab");
    let aovs = dir.join("a.aov.exr");
    let status = noisefree()
        .args([
            "render",
            "scenes/cornell_glossy.toml",
            "--spp",
            "4",
            "--width",
            "32",
        ])
        .args(["--height", "24", "--aovs", aovs.to_str().unwrap()])
        .arg("--out")
        .arg(dir.join("a.png"))
        .status()
        .unwrap();
    assert!(status.success());
    let bin = env!("CARGO_BIN_EXE_noisefree");
    let out = std::process::Command::new("bash")
        .arg("scripts/filter-ab.sh")
        .args([bin, bin, aovs.to_str().unwrap()])
        .env("FILTER", "atrous")
        .env("KERNELS", "atrous_pass_packed")
        .env("ROUNDS", "1")
        .env("REPEAT", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 3, "{stdout}");
    assert!(lines[0].contains("old atrous_pass_packed"), "{stdout}");
    // | file | old ms | new ms | ratio | old kernel | new kernel | ratio | same bytes |
    let cells: Vec<&str> = lines[2].split('|').map(str::trim).collect();
    assert_eq!(cells[1], "a.aov.exr", "{stdout}");
    for i in [2, 3, 5, 6] {
        let ms: f64 = cells[i]
            .parse()
            .unwrap_or_else(|_| panic!("cell {i}: {stdout}"));
        assert!(ms > 0.0, "cell {i}: {stdout}");
    }
    assert_eq!(cells[8], "yes", "{stdout}");
    let _ = std::fs::remove_dir_all(&dir);
}
