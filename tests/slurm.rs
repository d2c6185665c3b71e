//! The Slurm job scripts (scripts/slurm/, `noisefree reference --slurm N`) on a real cluster:
//! scripts/slurm/local-cluster.sh starts munged, slurmctld and slurmd on this machine with a
//! minimal configuration in a temporary folder; a 4-task job array renders a small reference
//! and the merge job that waits for it stores the merged image, which must equal the
//! one-machine render to float rounding. Then the failure case: one task of the array is
//! cancelled, the merge job fails naming the missing sample range and the task to submit again,
//! writes nothing, and `submit.sh` with only that task completes the reference.
//!
//! Without a cluster: `--dry-run` prints the job and writes nothing, and the job's mistakes are
//! errors before anything is written or submitted.
//!
//! The cluster test is opt-in, as it needs Debian's slurm-wlm and munge packages: `cargo test --release --test
//! slurm -- --ignored`, which scripts/test.sh runs when the packages install. Waiting for the
//! scheduler is bounded ([`WAIT`]) so that a stuck cluster fails the test instead of hanging
//! it; no time is asserted. Every daemon the test started is stopped, by its process id, even
//! when the test fails.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use common::*;

/// The longest the test waits for one job to finish: a bound on a stuck scheduler, far above
/// what the jobs take (the whole test takes about 30 s on this project's loaded 2-core
/// machine), not a speed assertion.
const WAIT: Duration = Duration::from_secs(600);

/// The reference rendered: small, so the test is about the scheduling and the merge.
const ARGS: [&str; 6] = ["--width", "32", "--height", "24", "--spp", "16"];

/// A single-node cluster started by scripts/slurm/local-cluster.sh; stopped when dropped.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

fn script() -> PathBuf {
    repo_path("scripts/slurm/local-cluster.sh")
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        let out = Command::new(script())
            .args(["start".as_ref(), dir.as_os_str()])
            .output()
            .expect("running scripts/slurm/local-cluster.sh");
        assert!(
            out.status.success(),
            "the local Slurm cluster did not start: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let conf = String::from_utf8_lossy(&out.stdout).trim().to_string();
        Cluster {
            dir: dir.to_path_buf(),
            conf: PathBuf::from(conf),
        }
    }

    /// `program` talking to this cluster.
    fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// Runs `program args` against this cluster and returns its stdout; it must succeed.
    fn run(&self, program: impl AsRef<std::ffi::OsStr>, args: &[&str], cwd: &Path) -> String {
        let name = program.as_ref().to_string_lossy().into_owned();
        let out = self
            .command(program)
            .args(args)
            .current_dir(cwd)
            .output()
            .unwrap_or_else(|e| panic!("running {name}: {e}"));
        assert!(
            out.status.success(),
            "{name} {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// The states of a job, one per array task (`scontrol show job`).
    fn states(&self, job: &str) -> Vec<String> {
        self.run("scontrol", &["show", "job", "-o", job], &self.dir)
            .lines()
            .filter_map(|l| l.split(' ').find_map(|f| f.strip_prefix("JobState=")))
            .map(String::from)
            .collect()
    }

    /// Waits (at most [`WAIT`]) until every task of `job` has finished; returns their states.
    fn wait(&self, job: &str) -> Vec<String> {
        let start = Instant::now();
        loop {
            let states = self.states(job);
            let done = |s: &String| {
                [
                    "COMPLETED",
                    "FAILED",
                    "CANCELLED",
                    "TIMEOUT",
                    "NODE_FAIL",
                    "OUT_OF_MEMORY",
                ]
                .contains(&s.as_str())
            };
            if !states.is_empty() && states.iter().all(done) {
                return states;
            }
            assert!(
                start.elapsed() < WAIT,
                "job {job} has not finished after {WAIT:?}: {states:?}\n{}",
                self.run("squeue", &[], &self.dir)
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let status = Command::new(script())
            .args(["stop".as_ref(), self.dir.as_os_str()])
            .status();
        if !matches!(status, Ok(s) if s.success()) {
            eprintln!(
                "stopping the local Slurm cluster in {}: {status:?}",
                self.dir.display()
            );
        }
    }
}

/// The job ids in submit.sh's "submitted job array A (tasks ...) and merge job M in DIR".
fn job_ids(stdout: &str) -> (String, String) {
    let word_after = |key: &str| -> String {
        let at = stdout
            .find(key)
            .unwrap_or_else(|| panic!("no {key:?} in {stdout:?}"));
        stdout[at + key.len()..]
            .split_whitespace()
            .next()
            .unwrap()
            .to_string()
    };
    (word_after("job array "), word_after("merge job "))
}

/// `noisefree reference SCENE ARGS --cache CACHE` plus `extra`, run in `cwd` against the
/// cluster; returns stdout.
fn reference(cluster: &Cluster, cwd: &Path, cache: &str, extra: &[&str]) -> String {
    let scene = bundled_scene_path("cornell_diffuse").display().to_string();
    let mut args = vec!["reference", &scene, "--cache", cache, "-q"];
    args.extend(ARGS);
    args.extend(extra);
    cluster.run(env!("CARGO_BIN_EXE_noisefree"), &args, cwd)
}

/// The single reference file in `cache`.
fn cached(cache: &Path) -> PathBuf {
    let files: Vec<PathBuf> = std::fs::read_dir(cache)
        .unwrap_or_else(|e| panic!("{}: {e}", cache.display()))
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    files[0].clone()
}

/// The merged reference against the one-machine render. Both are colour means: the render's
/// float running means over all 16 samples, the merge's of four float running means combined
/// in double precision. Measured (PoCL): 2.7e-7 relative (absolute below 1e-3); bound 1e-6.
fn assert_equal_to_float_rounding(merged: &Path, one: &Path) {
    assert_eq!(merged.file_name(), one.file_name(), "the same reference");
    let read = |p: &Path| noisefree::imaging::read_exr_rgb(p).unwrap();
    let d = max_rel_diff(&read(merged), &read(one));
    eprintln!("merged reference within {d:.2e} of the one-machine render");
    assert!(d <= 1e-6, "{}: differs by {d:e}", merged.display());
}

#[test]
#[ignore = "needs slurm-wlm and munge (scripts/test.sh runs it when they install)"]
fn a_job_array_renders_a_reference_and_a_killed_task_is_rendered_again() {
    let dir = tempdir("slurm");
    let cluster = Cluster::start(&dir.join("cluster"));
    // On one machine first: the reference to compare with, and the kernels built into the
    // driver's cache before four tasks could build them at once.
    reference(&cluster, &dir, "one", &[]);
    let one = cached(&dir.join("one"));

    // Four ranges and the merge into the cache.
    let out = reference(
        &cluster,
        &dir,
        "array",
        &["--slurm", "4", "--job-dir", "job"],
    );
    let (array, merge) = job_ids(&out);
    let tasks = cluster.wait(&array);
    assert_eq!(tasks, ["COMPLETED"; 4], "the array's tasks");
    assert_eq!(cluster.wait(&merge), ["COMPLETED"], "the merge job");
    let mut parts: Vec<String> =
        std::fs::read_dir(dir.join("job/parts/cornell_diffuse-32x24-16spp"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
    parts.sort();
    assert_eq!(
        parts,
        [
            "part-0-4.nfp",
            "part-12-16.nfp",
            "part-4-8.nfp",
            "part-8-12.nfp"
        ]
    );
    assert_equal_to_float_rounding(&cached(&dir.join("array")), &one);

    // A task killed: submitted while the partition is down, so that task 1 is cancelled
    // before it can start (no race with the scheduler), then the partition comes up.
    let partition = |state: &str| {
        let state = format!("State={state}");
        cluster.run("scontrol", &["update", "PartitionName=debug", &state], &dir);
    };
    partition("DOWN");
    let out = reference(
        &cluster,
        &dir,
        "again",
        &["--slurm", "4", "--job-dir", "job2"],
    );
    let (array, merge) = job_ids(&out);
    cluster.run("scancel", &[&format!("{array}_1")], &dir);
    let pending = cluster.run("squeue", &["-h", "-r", "-j", &array, "-o", "%K"], &dir);
    assert_eq!(
        pending.split_whitespace().collect::<Vec<_>>(),
        ["0", "2", "3"]
    );
    partition("UP");
    // A task cancelled while pending leaves no record: the other three remain.
    assert_eq!(cluster.wait(&array), ["COMPLETED"; 3]);
    assert_eq!(
        cluster.wait(&merge),
        ["FAILED"],
        "the merge job of a partial array"
    );
    let log = std::fs::read_to_string(dir.join(format!("job2/logs/merge-{merge}.out"))).unwrap();
    for needle in [
        "error: missing samples 4..8 of the whole image",
        "task(s) 1 left no part",
        "job2/submit.sh 1",
    ] {
        assert!(
            log.contains(needle),
            "{needle:?} is not in the merge log:\n{log}"
        );
    }
    assert!(!dir.join("again").exists(), "nothing is written");

    // Only that task again, and the merge.
    let out = cluster.run(dir.join("job2/submit.sh"), &["1"], &dir);
    assert!(out.contains("(tasks 1)"), "{out}");
    let (array, merge) = job_ids(&out);
    assert_eq!(cluster.wait(&array), ["COMPLETED"], "the task again");
    assert_eq!(cluster.wait(&merge), ["COMPLETED"], "the merge again");
    assert_equal_to_float_rounding(&cached(&dir.join("again")), &one);
    drop(cluster);
    let _ = std::fs::remove_dir_all(&dir);
}

// ---- Without a cluster ----

#[test]
fn dry_run_prints_the_job_and_writes_nothing() {
    let dir = tempdir("slurm-dry-run");
    let scene = bundled_scene_path("cornell_diffuse").display().to_string();
    let run = |args: &[&str]| {
        let out = noisefree().args(args).current_dir(&dir).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {stderr}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let mut args = vec![
        "reference",
        &scene,
        "--cache",
        "refs",
        "--slurm",
        "4",
        "--dry-run",
    ];
    args.extend(ARGS);
    let job = run(&args);
    for line in [
        "TASKS=4",
        "RENDERS=1",
        "NAME_0=cornell_diffuse-32x24-16spp",
        "SPP_0=16",
        &format!("WORKDIR={}", dir.display()),
        &format!("NOISEFREE={}", env!("CARGO_BIN_EXE_noisefree")),
        &format!(
            "RENDER_0=({scene} --spp 16 --width 32 --height 24 --seed 1592598600 --filter none)"
        ),
        &format!(
            "MERGE_0=(reference {scene} --spp 16 --width 32 --height 24 --seed 1592598600 \
             --cache refs --from-parts)"
        ),
        "sbatch --parsable --array=0-3 render.sbatch",
        "sbatch --parsable --dependency=afterany:<array job> merge.sbatch",
    ] {
        assert!(
            job.lines().any(|l| l.trim_start_matches("#   ") == line),
            "{line:?} is not in:\n{job}"
        );
    }
    // bench: one render per reference its studies need, then the benchmark in the merge job.
    let scenes = repo_path("scenes").display().to_string();
    let bench = run(&[
        "bench",
        "--quick",
        "--scenes",
        &scenes,
        "--slurm",
        "2",
        "--dry-run",
    ]);
    assert!(bench.contains("RENDERS=1\n"), "{bench}");
    assert!(
        bench.contains("NAME_0=cornell_diffuse-64x64-256spp"),
        "{bench}"
    );
    let final_line = format!("FINAL=(bench --quick --scenes {scenes} --cache cache/references)");
    assert!(
        bench.lines().any(|l| l == final_line),
        "{final_line:?} is not in:\n{bench}"
    );
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "a dry run writes nothing"
    );
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

#[test]
fn slurm_job_mistakes_are_errors_before_anything_is_written() {
    let dir = tempdir("slurm-errors");
    let scene = bundled_scene_path("cornell_diffuse").display().to_string();
    let fails_in = |args: &[&str], path: Option<&str>, needles: &[&str]| {
        let mut c = noisefree();
        c.args(args).current_dir(&dir);
        if let Some(p) = path {
            c.env("PATH", p);
        }
        fails_with(ERROR, &mut c, needles);
    };
    let reference = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = ["reference", &scene, "--cache", "refs"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        v.extend(ARGS.iter().chain(extra).map(|s| s.to_string()));
        v
    };
    fails_in(
        &strs(&reference(&["--slurm", "0", "--dry-run"])),
        None,
        &["--slurm 0: a job array needs at least one task"],
    );
    fails_in(
        &strs(&reference(&["--slurm", "17", "--dry-run"])),
        None,
        &["16 spp, fewer than the 17 tasks"],
    );
    // No sbatch: the job is not written either.
    let empty = dir.join("no-programs");
    std::fs::create_dir(&empty).unwrap();
    fails_in(
        &strs(&reference(&["--slurm", "4"])),
        Some(&empty.display().to_string()),
        &["sbatch is not on PATH", "--dry-run"],
    );
    assert!(!dir.join("slurm").exists(), "no job folder");
    // A job folder in use is not overwritten.
    let used = dir.join("used");
    std::fs::create_dir(&used).unwrap();
    std::fs::write(used.join("job.env"), "keep").unwrap();
    fails_in(
        &strs(&reference(&["--slurm", "4", "--job-dir", "used"])),
        None,
        &["the job folder", "exists already", "submit.sh"],
    );
    assert_eq!(
        std::fs::read_to_string(used.join("job.env")).unwrap(),
        "keep"
    );
    usage_fails(&["reference", &scene, "--dry-run"], &["--slurm"]);
}
