//! `noisefree bench --quick` runs every study end to end, so the benchmarks cannot rot. Only
//! completion and well-formed results are checked: timings are never asserted.

mod common;

use common::{noisefree, tempdir};
use noisefree::bench::study;
use noisefree::filters::Purpose;

#[test]
fn quick_benchmark_completes_with_well_formed_results() {
    let out = tempdir("bench-quick");
    let run = noisefree()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["bench", "--quick", "-q", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "bench --quick failed: {stderr}");
    for (study, columns) in [
        ("render-speed", 9),
        ("statistics", 6),
        ("filter-speed", 10),
        ("quality", 9),
        ("accuracy-time", 7),
        ("sweep", 6),
        ("roofline", 14),
        ("tracers", 13),
    ] {
        let csv = std::fs::read_to_string(out.join(format!("{study}.csv")))
            .unwrap_or_else(|e| panic!("{study}.csv: {e}"));
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(header.len(), columns, "{study}: header {header:?}");
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert!(!rows.is_empty(), "{study}.csv has no rows");
        for r in &rows {
            assert_eq!(r.len(), columns, "{study}: row {r:?}");
            assert!(
                r.iter().all(|v| !v.is_empty() && *v != "nan"),
                "{study}: row {r:?}"
            );
        }
        assert!(
            out.join(format!("{study}.md")).exists(),
            "{study}.md missing"
        );
    }
    // The wavefront tracer's and the skip-index walk's films are the megakernel's bytes on
    // every scene of the run.
    let tracers = std::fs::read_to_string(out.join("tracers.csv")).unwrap();
    for row in tracers.lines().skip(1) {
        assert_eq!(row.split(',').nth(7), Some("true"), "tracers: {row}");
    }
    // The quality study runs every denoiser of the registry that changes the quick scene
    // (cornell_diffuse), and the unfiltered image; no row repeats the unfiltered image under
    // the name of a filter that passes it through (aaf-shadows: no sphere light), and
    // the stylized shadows, art direction, have none.
    let quality = std::fs::read_to_string(out.join("quality.csv")).unwrap();
    let methods: Vec<&str> = quality
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(1))
        .collect();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_diffuse.toml");
    let sizes = study::sizes_for(true, None, None);
    let info = study::StudyScene::load(&path, &sizes, 1).unwrap().info;
    let registry = noisefree::filters::Registry::builtin();
    let mut expected = vec!["unfiltered"];
    for f in registry.filters() {
        let c = registry.configure(*f, &Default::default(), &info).unwrap();
        let wanted = f.purpose() == Purpose::Denoise && c.applies();
        assert_eq!(
            methods.contains(&f.name()),
            wanted,
            "{}: a quality.csv row where it {} the image: {methods:?}",
            f.name(),
            if wanted { "changes" } else { "does not change" }
        );
        if wanted {
            expected.push(f.name());
        }
    }
    // sheared filters its diffuse indirect light there (no lens, no sphere light).
    for name in ["aaf-indirect", "ddf", "rpf", "sheared"] {
        assert!(
            expected.contains(&name),
            "{name} must apply on cornell_diffuse"
        );
    }
    for name in ["aaf-shadows", "stylized-shadows"] {
        assert!(
            !expected.contains(&name),
            "{name} has nothing to filter there"
        );
    }
    // OIDN beside them when its environment is set up (scripts/test.sh sets it up and requires
    // it), its three quality modes better than the unfiltered image.
    let oidn = noisefree::bench::oidn::Oidn::find().is_some();
    assert!(
        oidn || std::env::var_os("NOISEFREE_REQUIRE_OIDN").is_none(),
        "{}",
        noisefree::bench::oidn::NOT_SET_UP
    );
    if oidn {
        let rel_mse = |method: &str| -> f64 {
            let header: Vec<&str> = quality.lines().next().unwrap().split(',').collect();
            let col = header.iter().position(|c| *c == "rel_mse").unwrap();
            let row = quality
                .lines()
                .map(|l| l.split(',').collect::<Vec<_>>())
                .find(|r| r[1] == method && r[0] == "cornell_diffuse")
                .unwrap_or_else(|| panic!("no {method} row in quality.csv"));
            row[col].parse().unwrap()
        };
        let unfiltered = rel_mse("unfiltered");
        for q in noisefree::bench::oidn::Quality::ALL {
            let e = rel_mse(&q.label());
            assert!(
                e < unfiltered,
                "{}: {e} vs unfiltered {unfiltered}",
                q.label()
            );
        }
    }
    for png in [
        "filter-speed-cornell_diffuse.png",
        "quality-cornell_diffuse-small.png",
        "images/quality-cornell_diffuse.png",
        "accuracy-time-cornell_diffuse.png",
        "sweep-cornell_diffuse-kw21.png",
    ] {
        let bytes = std::fs::read(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        assert_eq!(&bytes[1..4], b"PNG");
    }
    // A second run resumes: every cell is already measured, nothing is added.
    let before = std::fs::read_to_string(out.join("quality.csv")).unwrap();
    let again = noisefree()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "bench",
            "--quick",
            "-q",
            "--study",
            "quality",
            "--out",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(out.join("quality.csv")).unwrap(),
        before
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// `noisefree bench` runs from any folder: the bundled scenes come from the source tree the binary
/// was built from, and the results go under the current folder. Statistics reads every bundled
/// scene (here, with --quick, Cornell diffuse) and filter-speed one bundled scene by name: the
/// two cheapest studies, a few seconds together.
#[test]
fn quick_benchmark_runs_outside_the_repository() {
    let dir = tempdir("bench-anywhere");
    assert!(!dir.join("scenes").exists());
    let run = noisefree()
        .current_dir(&dir)
        .args([
            "bench",
            "--quick",
            "-q",
            "--study",
            "statistics",
            "--study",
            "filter-speed",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        run.status.success(),
        "bench outside the repository failed: {stderr}"
    );
    for study in ["statistics", "filter-speed"] {
        let csv = std::fs::read_to_string(dir.join("results/quick").join(format!("{study}.csv")))
            .unwrap_or_else(|e| panic!("{study}.csv in the current folder: {e}"));
        assert!(csv.lines().count() > 1, "{study}.csv has no rows");
    }
    let statistics = std::fs::read_to_string(dir.join("results/quick/statistics.csv")).unwrap();
    assert!(statistics.contains("cornell_diffuse"), "{statistics}");
    // A scenes folder that is not there is named in the error, before anything is measured.
    let missing = dir.join("no-such-scenes");
    let bad = noisefree()
        .current_dir(&dir)
        .args([
            "bench",
            "--quick",
            "-q",
            "--study",
            "statistics",
            "--scenes",
        ])
        .arg(&missing)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&bad.stderr);
    // The exit status of an error (src/cli/mod.rs), not a signal or a usage error.
    assert_eq!(bad.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("--scenes"), "{stderr}");
    assert!(stderr.contains("no-such-scenes"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--method` narrows the quality studies to the named methods (and the unfiltered image), and
/// a name that is no method is refused before anything is measured, naming the methods there
/// are.
#[test]
fn method_selects_the_compared_methods() {
    let out = tempdir("bench-method");
    let run = noisefree()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "bench",
            "--quick",
            "-q",
            "--study",
            "quality",
            "--method",
            "bmfr",
            "--scene",
            "scenes/cornell_diffuse.toml",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = std::fs::read_to_string(out.join("quality.csv")).unwrap();
    let methods: std::collections::BTreeSet<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    assert_eq!(
        methods.into_iter().collect::<Vec<_>>(),
        ["bmfr", "bmfr-fit", "bmfr-guided", "unfiltered"],
        "{csv}"
    );
    let bad = noisefree()
        .args(["bench", "--quick", "-q", "--method", "bmrf", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--method bmrf") && stderr.contains("bmfr") && stderr.contains("oidn"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&out);
}

/// Runs `bench --quick --study STUDY` from the source tree into `out` (its references cached
/// under `out` too) and checks that it succeeded.
fn quick_study(study: &str, out: &std::path::Path) {
    let run = noisefree()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["bench", "--quick", "-q", "--study", study, "--out"])
        .arg(out)
        .arg("--cache")
        .arg(out.join("cache"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "bench --study {study}: {stderr}");
}

/// `bench --study aaf-shadows --quick` (Wang 2013 Fig. 3.6 at 64 × 64): its table, report and
/// figures, and the seed's claim in small: adaptive AAF's error is that of Monte Carlo at more
/// light samples than it spent.
#[test]
fn quick_aaf_shadows_study_reproduces_the_claim_in_small() {
    let out = tempdir("bench-aaf");
    quick_study("aaf-shadows", &out);
    let csv = std::fs::read_to_string(out.join("aaf-shadows.csv")).unwrap();
    // 3 Monte Carlo, 2 fixed, 1 adaptive rows; sheared at l = 3 with the shear, without it
    // and with the other sign.
    assert_eq!(csv.lines().count(), 1 + 9, "{csv}");
    for png in ["aaf-shadows-grids.png", "aaf-shadows-time-grids.png"] {
        let bytes = std::fs::read(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        assert_eq!(&bytes[1..4], b"PNG");
    }
    let md = std::fs::read_to_string(out.join("aaf-shadows.md")).unwrap();
    let row = md
        .lines()
        .find(|l| l.starts_with("| aaf-adaptive |"))
        .unwrap_or_else(|| panic!("no adaptive row: {md}"));
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let ratio: f64 = cells[8].parse().unwrap_or_else(|_| panic!("{row}"));
    // Measured 1.26 (24 light spp ~ Monte Carlo at 30); bound 1.1.
    assert!(ratio > 1.1, "{row}");
    // The sheared rows against AAF at equal quality (issue 16).
    for method in ["sheared", "sheared-no-shear", "sheared-other-sign"] {
        assert!(
            md.lines()
                .filter(|l| l.starts_with(&format!("| {method} |")))
                .count()
                == 2,
            "{method}: a row in each table: {md}"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// `bench --study aaf-indirect --quick` (room_gi at 64 × 64): its table, report and figures,
/// and both filters' gain in small: AAF's and the sheared filter's indirect light take the room
/// to the error of Monte Carlo at more samples than they spent, path samples included.
#[test]
fn quick_aaf_indirect_study_filters_the_room_to_many_more_samples() {
    let out = tempdir("bench-aaf-indirect");
    quick_study("aaf-indirect", &out);
    let csv = std::fs::read_to_string(out.join("aaf-indirect.csv")).unwrap();
    // 3 Monte Carlo, 2 fixed and 1 adaptive AAF rows, sheared at l = 3 with and without
    // the shear.
    assert_eq!(csv.lines().count(), 1 + 8, "{csv}");
    assert!(
        csv.lines().skip(1).all(|l| l.starts_with("room_gi,")),
        "{csv}"
    );
    for png in ["aaf-indirect-room_gi.png", "aaf-indirect-time-room_gi.png"] {
        let bytes = std::fs::read(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        assert_eq!(&bytes[1..4], b"PNG");
    }
    assert!(out.join("sheared-gi-steps-room_gi.md").exists());
    let md = std::fs::read_to_string(out.join("aaf-indirect.md")).unwrap();
    let ratio = |method: &str, setting: u32| -> f64 {
        let row = md
            .lines()
            .find(|l| l.starts_with(&format!("| {method} | {setting} |")))
            .unwrap_or_else(|| panic!("no {method} {setting} row: {md}"));
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        // "ratio (rays)": Monte Carlo's spp at equal MSE over the row's path + indirect spp.
        cells[11].parse().unwrap_or_else(|_| panic!("{row}"))
    };
    // Measured 3.56 (sheared, l = 3: Monte Carlo at 89 spp for its 25) and 3.64 (AAF, 16
    // fixed: 116 for 32), against a 256-spp reference at 64 x 64; bound 3.2.
    assert!(ratio("sheared", 3) > 3.2, "{md}");
    assert!(ratio("aaf-fixed", 16) > 3.2, "{md}");
    // The sheared rows against both AAF curves, in MSE and in relMSE.
    for method in ["sheared", "sheared-no-shear"] {
        let rows = md
            .lines()
            .filter(|l| l.starts_with(&format!("| {method} |")))
            .count();
        assert_eq!(
            rows, 5,
            "{method}: the scene table and four comparisons: {md}"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// The path-density study (only when asked, not in the default set): every method at every
/// progressive step, the rejected and down-weighted fractions filled exactly for the cells that
/// run the path-density kernel alone.
#[test]
fn path_density_study_completes_with_well_formed_results() {
    let out = tempdir("bench-path-density");
    quick_study("path-density", &out);
    let csv = std::fs::read_to_string(out.join("path_density.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 10, "{header:?}");
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let steps = noisefree::bench::path_density::SPP.len();
    assert_eq!(rows.len() % steps, 0);
    assert!(rows.len() >= 12 * steps, "{} rows", rows.len());
    for r in &rows {
        assert_eq!(r.len(), 10, "{r:?}");
        let kernel_alone = r[2].starts_with("path-density") && !r[2].contains("->");
        for (i, v) in r.iter().enumerate() {
            let fraction = i == 7 || i == 8;
            assert_eq!(
                v.is_empty(),
                fraction && !kernel_alone,
                "column {} of {r:?}",
                header[i]
            );
            assert_ne!(*v, "nan", "{r:?}");
        }
    }
    assert!(out.join("path_density.md").exists());
    let _ = std::fs::remove_dir_all(&out);
}

/// `bench --study aaf-cost --quick` (issue 15; not in the default set): a row per occluder
/// triangle count and AAF filter, every time a positive number of milliseconds (never compared:
/// timings are not asserted), triangle counts over a 1000× range, and the figure.
#[test]
fn quick_aaf_cost_study_has_a_row_per_triangle_count_and_filter() {
    let out = tempdir("bench-aaf-cost");
    quick_study("aaf-cost", &out);
    let csv = std::fs::read_to_string(out.join("aaf-cost.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header, noisefree::bench::aaf_cost::COLUMNS, "{csv}");
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let counts = noisefree::bench::aaf_cost::TRIANGLES.len();
    assert_eq!(rows.len(), 2 * counts, "{csv}");
    let mut triangles = Vec::new();
    for r in &rows {
        assert_eq!(r.len(), header.len(), "{r:?}");
        assert_eq!(r[0], "64x64", "{r:?}");
        assert!(["aaf-shadows", "aaf-indirect"].contains(&r[2]), "{r:?}");
        for v in &r[3..] {
            let x: f64 = v.parse().unwrap_or_else(|_| panic!("{r:?}"));
            assert!(x.is_finite() && x > 0.0, "{r:?}");
        }
        triangles.push(r[1].parse::<f64>().unwrap());
    }
    let (lo, hi) = triangles
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
    assert!(hi / lo >= 900.0, "{triangles:?}");
    assert!(out.join("aaf-cost.md").exists());
    let png = std::fs::read(out.join("aaf-cost.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let _ = std::fs::remove_dir_all(&out);
}
