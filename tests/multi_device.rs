//! Several devices rendering one frame (thesis §4.2, src/render/split.rs): the film, and every
//! filter on it, is bit for bit what one device gives, whatever the split and however rows
//! move between devices. PoCL exposes two devices on one CPU with POCL_DEVICES="pthread basic"
//! (a 2-compute-unit and a 1-compute-unit device), set here before this test binary's first
//! OpenCL call.

mod common;

use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use common::*;
use noisefree::filters::{DeviceFilter, FilterRequest, Placement, Registry};
use noisefree::gpu::Gpu;
use noisefree::layout::outputs::{Output, OutputSet};
use noisefree::render::{Frame, RenderOptions, Renderer, SceneArrays, SceneInfo, SplitRenderer};
use noisefree::scene::Scene;

/// Held by each test that launches on the shared devices: one test at a time. PoCL 3.1's basic
/// device deadlocks when two threads enqueue into one of its queues at once (a command that
/// waited for another is run from inside pocl_broadcast, which holds the event's lock that
/// pocl_update_event_running takes again; later PoCL releases it first, basic.c
/// pocl_basic_notify). noisefree itself enqueues on a device from one thread at a time.
fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// PoCL's pthread and basic devices, in that order (as `--devices 1,0` opens them).
fn two_devices() -> [Arc<Gpu>; 2] {
    static GPUS: OnceLock<[Arc<Gpu>; 2]> = OnceLock::new();
    GPUS.get_or_init(|| {
        // SAFETY: set before any OpenCL call of this process; every test goes through here.
        unsafe { std::env::set_var("POCL_DEVICES", "pthread basic") };
        let list = noisefree::gpu::list_devices().expect("an OpenCL platform");
        assert!(
            list.len() >= 2,
            "POCL_DEVICES=\"pthread basic\" should expose two devices, found {list:?}"
        );
        let open = |i| Gpu::open(Some(i)).unwrap_or_else(|e| panic!("{e:#}"));
        [open(1), open(0)]
    })
    .clone()
}

fn scene() -> Scene {
    // Mirror and glass spheres (every branch of the megakernel) at a size that is no multiple
    // of any work-group.
    cornell_with_spheres()
}

fn render_options(scene: &Scene, outputs: OutputSet) -> RenderOptions {
    let mut o = options(scene, 37, 29, 5);
    o.outputs = outputs;
    o.sample_capacity = 6;
    o
}

fn assert_same(split: &Frame, single: &Frame, when: &str) {
    assert_eq!(split.info().spp, single.info().spp, "{when}");
    for ((name, a), (_, b)) in output_bytes(split).iter().zip(output_bytes(single)) {
        assert!(
            *a == b,
            "{when}: the {name} buffer differs from one device's"
        );
    }
}

#[test]
fn a_film_split_across_two_devices_is_bit_identical_to_one_devices() {
    let _serial = serial();
    let [fast, slow] = two_devices();
    let scene = scene();
    let all = OutputSet::of(&[
        Output::Features,
        Output::Variance,
        Output::Position,
        Output::Samples,
    ]);
    let options = render_options(&scene, all);
    let arrays = SceneArrays::build(&scene, &options.frame).unwrap();
    let mut single = Renderer::with_arrays(fast.clone(), &scene, arrays.clone(), &options).unwrap();
    for merge_each_frame in [true, false] {
        let mut split = SplitRenderer::new(
            &[fast.clone(), slow.clone()],
            &scene,
            arrays.clone(),
            &options,
        )
        .unwrap();
        split.set_merge_each_frame(merge_each_frame);
        single.reset().unwrap();
        let h = split.height();
        // Rows change hands in both directions between frames, and a device is left without
        // rows once; the measured re-balancing moves them too.
        let splits = [
            vec![0..h, h..h],
            vec![0..3, 3..h],
            vec![0..h - 5, h - 5..h],
            vec![0..17, 17..h],
        ];
        for (k, batch) in [1u32, 2, 3, 1].into_iter().enumerate() {
            split.set_bands(splits[k].clone()).unwrap();
            split.render_samples(batch).unwrap();
            single.render_samples(batch).unwrap();
            let when = format!(
                "merge each frame {merge_each_frame}, frame {k}, bands {:?}",
                split.bands()
            );
            assert_same(&split.frame().unwrap(), &single.frame(), &when);
        }
        assert!(split.last_frame().unwrap().devices.len() == 2);
    }
    // The test can fail: a different seed on one device changes the film.
    let mut other = options.clone();
    other.frame.seed = 6;
    let mut different = Renderer::new(slow, &scene, &other).unwrap();
    different.render_samples(single.samples_done()).unwrap();
    let differs = output_bytes(&different.frame()) != output_bytes(&single.frame());
    assert!(differs, "another seed gave the same film");
}

#[test]
fn every_filter_on_bands_gives_the_bytes_of_the_merged_film_and_of_one_device() {
    let _serial = serial();
    let [fast, slow] = two_devices();
    let scene = scene();
    let registry = Registry::builtin();
    // The data-driven filter's variants and holes, and every registered filter by default.
    let mut requests: Vec<(String, toml::Table)> = registry
        .names()
        .into_iter()
        .map(|n| (n.to_string(), toml::Table::new()))
        .collect();
    for extra in [
        "holes = true\nkw = 9",
        "variant = \"naive\"",
        "variant = \"vector\"",
        // The default is auto: packed on PoCL (a CPU), so rows is asked for by name.
        "variant = \"rows\"",
    ] {
        requests.push(("ddf".into(), toml::from_str(extra).unwrap()));
    }
    for (name, settings) in requests {
        filter_on_bands(&registry, [&fast, &slow], &scene, &name, &settings);
    }
    // AAF's shadows on a scene with a sphere light (the one above has none, so aaf-shadows
    // passed it through): a band reads the visibility of `radius` rows around it.
    let grids = bundled_scene("grids");
    filter_on_bands(
        &registry,
        [&fast, &slow],
        &grids,
        "aaf-shadows",
        &toml::Table::new(),
    );
}

/// `name` with `settings` filters the film of two devices, merged or on bands, to the bytes of
/// one device's.
fn filter_on_bands(
    registry: &Registry,
    [fast, slow]: [&Arc<Gpu>; 2],
    scene: &Scene,
    name: &str,
    settings: &toml::Table,
) {
    let base = render_options(scene, OutputSet::colour());
    let arrays = SceneArrays::build(scene, &base.frame).unwrap();
    let info = SceneInfo::new(scene, &arrays);
    let filter = registry.get(name).unwrap();
    let mut req = FilterRequest::default();
    req.flags.insert(name.to_string(), settings.clone());
    let configured = registry.configure(filter, &req, &info).unwrap();
    let mut o = base.clone();
    o.outputs = OutputSet::colour().union(configured.needs());
    // Sampled as the filter asks, as `render --filter` does (the sheared filter's GI field:
    // without it the renderer gathers the lens field, which the GI filter refuses).
    configured.adjust_render(&mut o);
    o.sample_capacity = 4;
    let mut single = SplitRenderer::single(
        Renderer::with_arrays(fast.clone(), scene, arrays.clone(), &o).unwrap(),
    );
    let mut one = DeviceFilter::prepare(&configured, &mut single, Placement::Merged).unwrap();
    single.render_samples(4).unwrap();
    let want = one.run(&single).unwrap().image;
    for placement in [Placement::Merged, Placement::Bands] {
        let mut split =
            SplitRenderer::new(&[fast.clone(), slow.clone()], scene, arrays.clone(), &o).unwrap();
        split.balancer.enabled = false;
        let mut f = DeviceFilter::prepare(&configured, &mut split, placement).unwrap();
        split.render_samples(3).unwrap();
        split.set_bands(vec![0..11, 11..split.height()]).unwrap();
        split.render_samples(1).unwrap();
        let got = f.run(&split).unwrap().image;
        let what = format!(
            "{name} {settings:?}, asked for {}, ran {}",
            placement.name(),
            f.placement().name()
        );
        assert!(
            got.pixels == want.pixels,
            "{what}: not the bytes of one device"
        );
        // The filters of every stored sample run on the merged film: RPF and the trimmed mean
        // on the host, path-density because a sample's k nearest neighbours may lie any number
        // of rows away (no bounded reach). So does bmfr, which fits whole blocks of shifted
        // grids in one launch per grid and has no launch over a band of rows (yet).
        let merged_only = configured.needs().contains(Output::Samples) || name == "bmfr";
        if placement == Placement::Bands && !merged_only {
            assert_eq!(
                f.placement(),
                Placement::Bands,
                "{what}: device filters run on bands"
            );
        }
    }
}

#[test]
fn render_with_devices_writes_the_images_of_one_device() {
    let dir = tempdir("multi-device-cli");
    let scene = bundled_scene_path("cornell_glossy");
    let run = |name: &str, extra: &[&str]| {
        let png = dir.join(format!("{name}.png"));
        let out = noisefree()
            .env("POCL_DEVICES", "pthread basic")
            .args([
                "render",
                scene.to_str().unwrap(),
                "--spp",
                "5",
                "--width",
                "40",
                "--height",
            ])
            .args([
                "33",
                "--filter",
                "ddf",
                "-q",
                "--out",
                png.to_str().unwrap(),
            ])
            .args(extra)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {err}");
        (
            std::fs::read(&png).unwrap(),
            std::fs::read(png.with_extension("exr")).unwrap(),
        )
    };
    let one = run("one", &["--device", "1"]);
    for (name, extra) in [
        ("merged", &["--devices", "1,0"][..]),
        (
            "bands",
            &["--devices", "0,1", "--filter-placement", "bands"],
        ),
        (
            "static",
            &["--devices", "1,0", "--no-rebalance", "--timings"],
        ),
    ] {
        assert!(
            run(name, extra) == one,
            "--devices ({name}) changed the image"
        );
    }
    let s = scene.to_str().unwrap();
    fails_with(
        ERROR,
        noisefree().env("POCL_DEVICES", "pthread basic").args([
            "render",
            s,
            "--devices",
            "1,1",
            "-q",
        ]),
        &["device 1 is listed twice"],
    );
    fails_with(
        ERROR,
        noisefree().env("POCL_DEVICES", "pthread basic").args([
            "render",
            s,
            "--devices",
            "0,7",
            "-q",
        ]),
        &["device 7 does not exist", "noisefree devices"],
    );
    usage_fails(
        &["render", s, "--devices", "0,1", "--device", "0"],
        &["--device"],
    );
}

#[test]
fn a_moved_camera_gives_the_film_of_a_renderer_built_for_it() {
    // The viewer moves the camera of a built film (thesis §4.2.2: the Film is reset and the new
    // camera sent to every device); that film must be the one `render` builds for the moved
    // camera, on one device and split.
    let _serial = serial();
    let [fast, slow] = two_devices();
    let scene = scene();
    let all = OutputSet::of(&[Output::Features, Output::Variance, Output::Position]);
    let options = render_options(&scene, all);
    let arrays = SceneArrays::build(&scene, &options.frame).unwrap();
    let mut moved = scene.clone();
    moved.camera.origin += glam::Vec3::new(0.13, -0.05, -0.4);
    moved.camera.target += glam::Vec3::new(0.2, 0.0, 0.0);
    moved.camera.fov_degrees = 33.0;
    moved.camera.lens_radius = 0.02;
    moved.camera.focal_distance = Some(2.5);
    let fresh_arrays = SceneArrays::build(&moved, &options.frame).unwrap();
    let mut fresh = Renderer::with_arrays(fast.clone(), &moved, fresh_arrays, &options).unwrap();
    fresh.render_samples(3).unwrap();
    let mut single = Renderer::with_arrays(fast.clone(), &scene, arrays.clone(), &options).unwrap();
    let mut split = SplitRenderer::new(&[fast, slow], &scene, arrays, &options).unwrap();
    single.render_samples(2).unwrap();
    split.render_samples(2).unwrap();
    single.set_camera(&moved).unwrap();
    split.set_camera(&moved).unwrap();
    assert_eq!(
        single.samples_done(),
        0,
        "moving the camera empties the film"
    );
    single.render_samples(3).unwrap();
    for s in [1, 2] {
        split.render_samples(s).unwrap();
    }
    assert_eq!(single.arrays.params, fresh.arrays.params);
    assert_same(&single.frame(), &fresh.frame(), "one device, camera moved");
    assert_same(
        &split.frame().unwrap(),
        &fresh.frame(),
        "two devices, camera moved",
    );
}
