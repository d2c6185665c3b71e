//! Online == offline: filtering at the end of a render and filtering the AOV (or samples) file
//! it wrote give the same bytes, for every registered filter on every bundled scene; and an
//! output's bytes do not depend on which other outputs a render gathers, so two renders of the
//! same samples agree whatever else they were asked for.

mod common;

use common::*;
use noisefree::filters::{FilterRequest, Registry};
use noisefree::imaging::RgbImage;
use noisefree::layout::outputs::{BufferId, Output, OutputSet};
use noisefree::layout::{DepthShift, FilterVector, WelfordSums};
use noisefree::render::{LightPlanes, RenderOptions, Renderer, SceneArrays, SceneInfo};
use noisefree::stats::RenderRecord;
use noisefree::stats::samples::SampleSet;

fn bytes(img: &RgbImage) -> Vec<u32> {
    img.pixels.iter().flatten().map(|v| v.to_bits()).collect()
}

#[test]
fn every_filter_on_every_bundled_scene_gives_the_same_bytes_from_its_aov_file() {
    let registry = Registry::builtin();
    let dir = tempdir("online-offline");
    let (w, h, spp) = (24, 20, 4);
    let scenes = bundled_scenes();
    assert_eq!(
        scenes.len(),
        15,
        "the five thesis scenes, their DOF variants, Grids, Curved and two_lights_shadows \
         (the shadow filters' sphere-light scenes), toasters_dof (sheared shadows with \
         depth of field) and room_gi (sheared GI beside a sphere light)"
    );
    for path in scenes {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let scene = noisefree::scene::load_scene(&path).unwrap();
        let mut o = RenderOptions::for_scene(&scene);
        (o.frame.width, o.frame.height) = (w, h);
        let arrays = SceneArrays::build(&scene, &o.frame).unwrap();
        let info = SceneInfo::new(&scene, &arrays);
        // The scene file's [filter.<name>] tables, as `render` takes them (room_gi asks the
        // sheared filter for GI beside its sphere light).
        let request = FilterRequest {
            scene: scene.filter.settings.clone(),
            scene_origin: path.display().to_string(),
            scene_lines: scene.filter.lines.clone(),
            ..Default::default()
        };
        let configured = registry.configure_all(&request, &info).unwrap();
        // A frame holds one kind of light field: the shadow fields when the shadow output is
        // gathered, else the lens or v-plane field. The filters that read the v-plane field (the
        // sheared filter's GI: room_gi asks for it beside a sphere light that aaf-shadows reads)
        // get a render of their own.
        let wants_gi = |c: &noisefree::filters::Configured| {
            let mut wants = RenderOptions::for_scene(&scene);
            c.adjust_render(&mut wants);
            wants.shadows.light_field_gi
        };
        let groups: Vec<Vec<&noisefree::filters::Configured>> = [false, true]
            .into_iter()
            .map(|gi| {
                configured
                    .iter()
                    .filter(|c| wants_gi(c) == gi)
                    .collect::<Vec<_>>()
            })
            .filter(|g| !g.is_empty())
            .collect();
        for (group_index, group) in groups.into_iter().enumerate() {
            let name = format!("{name}-{group_index}");
            let mut o = o.clone();
            let arrays = arrays.clone();
            // One render gathers what every filter of the group, the AOV file and the samples
            // file need.
            let mut outputs = OutputSet::of(&[Output::Features, Output::Variance, Output::Samples]);
            for c in &group {
                outputs = outputs.union(c.needs());
            }
            o.outputs = outputs;
            // The shadow output holds a plane for every sphere light some filter reads
            // (aaf-shadows, stylized-shadows and sheared: all of them).
            // Without the shadow output, the light field is the one the sheared filter samples
            // (the lens or, with GI, the v-plane), and the frame records which.
            let (mut lights, mut gi) = (0, false);
            for c in &group {
                let mut wants = o.clone();
                c.adjust_render(&mut wants);
                lights |= wants.shadows.lights.0;
                gi |= wants.shadows.light_field_gi;
            }
            o.shadows.lights = LightPlanes(lights.max(1));
            o.shadows.light_field_gi = gi;
            o.sample_capacity = spp;
            let mut r = Renderer::with_arrays(gpu(), &scene, arrays, &o).unwrap();
            assert_eq!(r.scene_info, info);
            r.render_samples(1).unwrap();
            r.render_samples(spp - 1).unwrap();
            let frame = r.frame();
            let record = RenderRecord {
                scene: Some(r.scene_info.clone()),
                filter: None,
                settings: configured
                    .iter()
                    .map(|c| (c.name().to_string(), c.requested().clone()))
                    .collect(),
                extra: Default::default(),
            };
            let aov = dir.join(format!("{name}.exr"));
            let samples = dir.join(format!("{name}.bin"));
            noisefree::stats::aov::write_aov_exr(&aov, &frame, &record).unwrap();
            SampleSet::from_frame(&frame, record.clone())
                .unwrap()
                .write(&samples)
                .unwrap();
            let (aov_frame, aov_record) = noisefree::stats::aov::read_aov_exr(&aov).unwrap();
            let set = SampleSet::read(&samples).unwrap();
            assert_eq!(aov_record, record, "{name}: the AOV header's record");
            assert_eq!(set.record, record, "{name}: the samples file's record");
            let samples_frame = set.into_frame().unwrap();
            for c in &group {
                let online = c
                    .prepare(frame.info(), &gpu())
                    .unwrap()
                    .run(&frame)
                    .unwrap()
                    .image;
                // Offline: the file that holds what the filter reads, configured from the record.
                let file_frame = if aov_frame.outputs().covers(c.needs()) {
                    &aov_frame
                } else {
                    &samples_frame
                };
                assert!(
                    file_frame.outputs().covers(c.needs()),
                    "{name} {}",
                    c.name()
                );
                let request = FilterRequest {
                    recorded: aov_record.settings.clone(),
                    ..Default::default()
                };
                let offline_config = registry
                    .configure(
                        registry.get(c.name()).unwrap(),
                        &request,
                        &file_frame.info().scene,
                    )
                    .unwrap();
                assert_eq!(
                    offline_config.effective(),
                    c.effective(),
                    "{name} {}",
                    c.name()
                );
                let offline = offline_config
                    .prepare(file_frame.info(), &gpu())
                    .unwrap()
                    .run(file_frame)
                    .unwrap()
                    .image;
                assert!(
                    bytes(&online) == bytes(&offline),
                    "{name}: the {} filter gives other bytes offline",
                    c.name()
                );
            }
        }
    }
}

/// The bytes of one buffer of a frame.
fn buffer_bits(frame: &noisefree::render::Frame, id: BufferId) -> Vec<u8> {
    frame.host(id).unwrap().as_bytes().to_vec()
}

#[test]
fn outputs_do_not_depend_on_the_other_outputs() {
    // Cornell glossy (mirror and metal: texture2 and the direction lanes see real values) and
    // Outside (sky: depth mixes SKY_DEPTH with surface depths, the hardest case for the
    // depth mean's rounding).
    for name in ["cornell_glossy", "outside"] {
        let scene = bundled_scene(name);
        let render = |outputs: &[Output]| {
            let mut o = options(&scene, 32, 24, 3);
            o.outputs = OutputSet::of(outputs);
            o.sample_capacity = 5;
            render_frame(&scene, &o, 5)
        };
        let features = render(&[Output::Features]);
        let variance = render(&[Output::Variance]);
        let all = render(&[Output::Variance, Output::Position, Output::Samples]);
        for f in [&variance, &all] {
            assert_eq!(
                buffer_bits(&features, BufferId::FilterVectors),
                buffer_bits(f, BufferId::FilterVectors),
                "{name}: F depends on the other outputs"
            );
            assert_eq!(
                buffer_bits(&features, BufferId::DepthShifts),
                buffer_bits(f, BufferId::DepthShifts),
                "{name}: the depth shift depends on the other outputs"
            );
        }
        assert_eq!(
            buffer_bits(&variance, BufferId::WelfordSums),
            buffer_bits(&all, BufferId::WelfordSums),
            "{name}: S_n depends on the other outputs"
        );
        // The means are the means: F.depth = K + mean(x - K) with K the first sample.
        let fv: &[FilterVector] = features.filter_vectors().unwrap();
        let ds: &[DepthShift] = features.host_slice(BufferId::DepthShifts).unwrap();
        for (f, d) in fv.iter().zip(ds) {
            assert_eq!(f.depth, d.shift + d.mean);
        }
        let s: &[WelfordSums] = variance.host_slice(BufferId::WelfordSums).unwrap();
        assert!(s.iter().all(|g| g.depth >= 0.0 && g.depth.is_finite()));
    }
}

/// The command line, as a user runs it: `render --filter NAME` against `render --aovs` and
/// `filter`, and a scene file's `[filter]` tables recorded in the AOV file.
/// Runs the command line in this process; panics with the error.
fn run(registry: &Registry, args: &[String]) {
    let mut v = vec!["noisefree".to_string()];
    v.extend_from_slice(args);
    noisefree::cli::run_args(registry, v).unwrap_or_else(|e| panic!("{args:?}: {e:#}"));
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn same_exr(a: &std::path::Path, b: &std::path::Path) -> bool {
    let a = noisefree::imaging::read_exr_rgb(a).unwrap();
    let b = noisefree::imaging::read_exr_rgb(b).unwrap();
    bytes(&a) == bytes(&b)
}

/// The command line, as a user runs it: `render --filter NAME` against `render --aovs` and
/// `filter`, and a scene file's `[filter]` tables recorded in the AOV file.
#[test]
fn command_line_renders_and_filters_agree() {
    let dir = tempdir("online-offline-cli");
    let registry = Registry::builtin();
    let p = |name: &str| dir.join(name).to_string_lossy().to_string();
    let scene = bundled_scene_path("cornell_glossy")
        .to_string_lossy()
        .to_string();
    let size = strings(&["--width", "32", "--height", "24", "--spp", "4", "-q"]);
    // A render that only gathers the AOVs, filtered afterwards by each device filter, gives
    // the bytes of renders that run the filter themselves (and gather only what it needs).
    let aov = p("plain.exr");
    run(
        &registry,
        &[
            strings(&[
                "render",
                &scene,
                "--aovs",
                &aov,
                "--out",
                &p("plain.png"),
                "--no-exr",
            ]),
            size.clone(),
        ]
        .concat(),
    );
    for (filter, extra) in [
        ("ddf", vec![]),
        ("ddf", vec!["--holes", "--kw", "9"]),
        ("atrous", vec!["--atrous-iterations", "3"]),
    ] {
        let tag = format!("{filter}{}", extra.len());
        let (online, offline) = (
            p(&format!("{tag}-online.exr")),
            p(&format!("{tag}-offline.exr")),
        );
        let extra = strings(&extra);
        run(
            &registry,
            &[
                strings(&[
                    "render",
                    &scene,
                    "--filter",
                    filter,
                    "--out",
                    &p("x.png"),
                    "--exr",
                    &online,
                ]),
                size.clone(),
                extra.clone(),
            ]
            .concat(),
        );
        run(
            &registry,
            &[
                strings(&["filter", &aov, "--filter", filter, "--exr", &offline, "-q"]),
                extra.clone(),
            ]
            .concat(),
        );
        assert!(
            same_exr(online.as_ref(), offline.as_ref()),
            "{filter} {extra:?}: online and offline differ"
        );
    }
    // A scene file's [filter] table: its method and settings are recorded in the AOV file and
    // `filter` with no flags repeats the render's own filter, settings and specialisation.
    let text = std::fs::read_to_string(&scene).unwrap()
        + "\n[filter]\nmethod = \"ddf\"\n\n[filter.ddf]\nkw = 7\nsigma_dc = 0.5\nholes = true\n";
    let tabled = dir.join("tabled.toml");
    std::fs::write(&tabled, text).unwrap();
    // Relative asset paths resolve against the scene's folder: copy the assets it names.
    for sub in ["models", "textures"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        for e in std::fs::read_dir(repo_path(&format!("scenes/{sub}")))
            .unwrap()
            .flatten()
        {
            std::fs::copy(e.path(), dir.join(sub).join(e.file_name())).unwrap();
        }
    }
    let (aov, online, offline) = (
        p("tabled-aovs.exr"),
        p("tabled-online.exr"),
        p("tabled-offline.exr"),
    );
    let tabled = tabled.to_string_lossy().to_string();
    run(
        &registry,
        &[
            strings(&[
                "render",
                &tabled,
                "--aovs",
                &aov,
                "--out",
                &p("t.png"),
                "--exr",
                &online,
            ]),
            size,
        ]
        .concat(),
    );
    run(
        &registry,
        &strings(&["filter", &aov, "--exr", &offline, "-q"]),
    );
    assert!(
        same_exr(online.as_ref(), offline.as_ref()),
        "the scene's [filter] table is not repeated offline"
    );
    let (_, record) = noisefree::stats::aov::read_aov_exr(aov.as_ref()).unwrap();
    assert_eq!(record.filter.as_deref(), Some("ddf"));
    assert_eq!(record.settings["ddf"]["kw"].as_integer(), Some(7));
    assert_eq!(record.settings["ddf"]["holes"].as_bool(), Some(true));
}
