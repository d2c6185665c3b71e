//! What the sheared filters' tests share (tests/sheared_*.rs): the device-vs-reference step
//! errors, a host frame holding a light field, renders for the shadows effect, and the
//! command line's online == offline check.

use noisefree::layout::FilterVector;

/// Largest |a − b| over every channel of two images.
pub fn max_diff(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// The sheared DOF / GI device steps against their reference: the largest
/// |device − reference| / max(1, |reference|) of prepare, 1a, 1b and 2a.
pub fn sheared_step_errors(
    d: &noisefree::filters::sheared::DofIntermediates,
    guide: &[[f32; 4]],
    steps: [&[f32]; 3],
) -> [f32; 4] {
    let rel = |x: &[f32], y: &[f32]| {
        x.iter()
            .zip(y)
            .map(|(a, b)| (a - b).abs() / b.abs().max(1.0))
            .fold(0.0f32, f32::max)
    };
    let flat = |g: &[[f32; 4]]| g.iter().flatten().copied().collect::<Vec<f32>>();
    [
        rel(&flat(&d.guide), &flat(guide)),
        rel(&d.p1a, steps[0]),
        rel(&d.g1b, steps[1]),
        rel(&d.q2a, steps[2]),
    ]
}

/// A host frame of the sheared DOF / GI filters: F's direct and indirect terms and the light
/// field, w × h from `p`.
pub fn sheared_host_frame(
    p: &noisefree::layout::ShearedParams,
    field: &[noisefree::layout::LightFieldPixel],
    direct: &[[f32; 3]],
    indirect: &[[f32; 3]],
) -> noisefree::render::Frame {
    use noisefree::layout::outputs::{BufferId, Output, OutputSet};
    use noisefree::render::{Frame, FrameInfo, HostBuffer, SceneInfo, VarianceForm};
    let fv: Vec<FilterVector> = direct
        .iter()
        .zip(indirect)
        .map(|(d, i)| FilterVector {
            direct: *d,
            indirect: *i,
            ..Default::default()
        })
        .collect();
    Frame::on_host(
        FrameInfo {
            width: p.width,
            height: p.height,
            spp: 1,
            sample_capacity: 0,
            shadow_lights: Vec::new(),
            scene: SceneInfo::unknown(),
        },
        OutputSet::of(&[Output::Colour, Output::LightField]),
        VarianceForm::Variances,
        vec![
            (BufferId::FilterVectors, HostBuffer::from_slice(&fv)),
            (BufferId::LightFieldPixels, HostBuffer::from_slice(field)),
        ],
    )
    .unwrap_or_else(|e| panic!("{e:#}"))
}

/// `spp` path samples of `scene` at w × h (seed `seed`) with the shadow output and the light
/// field sampled as the sheared filter `s` asks (every filtered light a plane).
pub fn sheared_renderer(
    scene: &noisefree::scene::Scene,
    w: u32,
    h: u32,
    spp: u32,
    seed: u32,
    s: &noisefree::filters::sheared::ShearedSettings,
) -> noisefree::render::Renderer {
    use noisefree::layout::outputs::{Output, OutputSet};
    let mut o = super::options(scene, w, h, seed);
    o.outputs = OutputSet::of(&[Output::Shadows, Output::LightField]);
    o.shadows = s.sampling();
    let mut r = noisefree::render::Renderer::new(super::gpu(), scene, &o)
        .unwrap_or_else(|e| panic!("{e:#}"));
    r.render_samples(spp).unwrap();
    r
}

/// `noisefree render SCENE --filter sheared --sheared-side 2` at 40 × 32, 1 spp, with its AOV
/// file, then `noisefree filter` of that file: asserts both succeed and give the same bytes
/// (online == offline) and returns the stderr of the render and the image.
pub fn cli_online_equals_offline(
    test: &str,
    scene: &str,
) -> (String, noisefree::imaging::RgbImage) {
    let dir = super::tempdir(test);
    let scene = super::repo_path(scene);
    let (exr, aovs, off) = (
        dir.join("online.exr"),
        dir.join("aovs.exr"),
        dir.join("offline.exr"),
    );
    let out = super::noisefree()
        .arg("render")
        .arg(&scene)
        .args([
            "--width", "40", "--height", "32", "--spp", "1", "--filter", "sheared",
        ])
        .args(["--sheared-side", "2", "--out"])
        .arg(dir.join("online.png"))
        .arg("--exr")
        .arg(&exr)
        .arg("--aovs")
        .arg(&aovs)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    assert!(dir.join("online.png").exists());
    let out = super::noisefree()
        .arg("filter")
        .arg(&aovs)
        .args(["--filter", "sheared", "--sheared-side", "2", "--exr"])
        .arg(&off)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (a, b) = (
        noisefree::imaging::read_exr_rgb(&exr).unwrap(),
        noisefree::imaging::read_exr_rgb(&off).unwrap(),
    );
    assert_eq!(a.pixels, b.pixels, "online == offline");
    assert!(a.pixels.iter().flatten().all(|c| c.is_finite()));
    (err, a)
}
