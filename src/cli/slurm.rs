//! Slurm job arrays (`reference --slurm N`, `bench --slurm N`): a render too long for one
//! machine becomes N sample ranges, one array task each, and a merge job that waits for them.
//! Noisefree does not schedule anything itself: it writes a job folder with the scripts of
//! scripts/slurm/ (compiled in, so the folder does not depend on the source tree) and a
//! `job.env` saying what to render, and submits it with the folder's `submit.sh`.
//!
//! The folder:
//! - `job.env`: the binary, the folder the commands run in (`WORKDIR`, where noisefree was
//!   called, so relative paths mean what they meant there), `TASKS` ranges per render,
//!   `RENDERS`, and per render r: `NAME_r`, `SPP_r`, `RENDER_r` (the `render` arguments of its
//!   parts), `MERGE_r` (the command that merges them, the part files appended); `FINAL`, a
//!   command to run after every merge succeeded (the benchmark).
//! - `render.sbatch`, `merge.sbatch`, `submit.sh` (scripts/slurm/, documented there);
//! - `parts/NAME/part-A-B.nfp`, written by the tasks; `logs/`, Slurm's output.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context as _, Result, bail};

/// The scripts of scripts/slurm/, as compiled in.
const SCRIPTS: [(&str, &str); 3] = [
    (
        "render.sbatch",
        include_str!("../../scripts/slurm/render.sbatch"),
    ),
    (
        "merge.sbatch",
        include_str!("../../scripts/slurm/merge.sbatch"),
    ),
    ("submit.sh", include_str!("../../scripts/slurm/submit.sh")),
];

/// One render of a job: `spp` samples split into the job's ranges.
#[derive(Clone, Debug)]
pub struct JobRender {
    /// Names its parts folder: letters, digits, `-`, `_` and `.` only.
    pub name: String,
    pub spp: u32,
    /// `noisefree render` arguments of every part (the range and file are added per task).
    pub render: Vec<String>,
    /// The noisefree command that merges the parts (the part files are appended).
    pub merge: Vec<String>,
}

/// A job array: every render in `tasks` sample ranges, then the merges and `final_command`.
#[derive(Clone, Debug)]
pub struct Job {
    /// What it is, for job.env's first line.
    pub what: String,
    pub tasks: u32,
    pub renders: Vec<JobRender>,
    pub final_command: Option<Vec<String>>,
}

/// `s` quoted for bash.
fn quote(s: &str) -> String {
    if !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-_./=:,+@%".contains(&b))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

fn array(values: &[String]) -> String {
    let q: Vec<String> = values.iter().map(|v| quote(v)).collect();
    format!("({})", q.join(" "))
}

impl Job {
    fn check(&self) -> Result<()> {
        if self.tasks == 0 {
            bail!("--slurm 0: a job array needs at least one task");
        }
        if self.renders.is_empty() {
            bail!("nothing to render: the job has no renders");
        }
        for r in &self.renders {
            if r.spp < self.tasks {
                bail!(
                    "{} has {} spp, fewer than the {} tasks of --slurm {}: every task renders \
                     at least one sample",
                    r.name,
                    r.spp,
                    self.tasks,
                    self.tasks
                );
            }
            let fine = |c: char| c.is_ascii_alphanumeric() || "-_.".contains(c);
            if r.name.is_empty() || !r.name.chars().all(fine) {
                bail!("{:?} cannot name a parts folder", r.name);
            }
        }
        Ok(())
    }

    /// The job.env of this job.
    pub fn env(&self, noisefree: &Path, workdir: &Path) -> String {
        let mut s = format!(
            "# {}\n# Written by noisefree; sourced by render.sbatch, merge.sbatch and submit.sh.\n",
            self.what
        );
        let path = |p: &Path| quote(&p.display().to_string());
        let _ = writeln!(s, "NOISEFREE={}", path(noisefree));
        let _ = writeln!(s, "WORKDIR={}", path(workdir));
        let _ = writeln!(s, "TASKS={}", self.tasks);
        let _ = writeln!(s, "RENDERS={}", self.renders.len());
        for (i, r) in self.renders.iter().enumerate() {
            let _ = writeln!(s, "NAME_{i}={}", quote(&r.name));
            let _ = writeln!(s, "SPP_{i}={}", r.spp);
            let _ = writeln!(s, "RENDER_{i}={}", array(&r.render));
            let _ = writeln!(s, "MERGE_{i}={}", array(&r.merge));
        }
        if let Some(f) = &self.final_command {
            let _ = writeln!(s, "FINAL={}", array(f));
        }
        s
    }

    /// Writes the job folder `dir` (which must not exist yet, or be empty) and, unless
    /// `dry_run`, submits it; a dry run prints job.env and the submission instead and writes
    /// nothing.
    pub fn run(&self, dir: &Path, dry_run: bool) -> Result<()> {
        self.check()?;
        let noisefree = std::env::current_exe().context("finding the noisefree binary")?;
        let workdir = std::env::current_dir().context("reading the current folder")?;
        let dir = workdir.join(dir);
        let env = self.env(&noisefree, &workdir);
        let tasks = self.tasks as usize * self.renders.len();
        if dry_run {
            say!(
                "# {}/job.env (--dry-run: nothing written or submitted)",
                dir.display()
            );
            let _ = std::io::Write::write_all(&mut std::io::stdout().lock(), env.as_bytes());
            say!(
                "# {}/submit.sh would run, from {}:\n#   sbatch --parsable --array=0-{} \
                 render.sbatch\n#   sbatch --parsable --dependency=afterany:<array job> \
                 merge.sbatch",
                dir.display(),
                dir.display(),
                tasks - 1
            );
            return Ok(());
        }
        if dir.exists() && std::fs::read_dir(&dir).is_ok_and(|mut d| d.next().is_some()) {
            bail!(
                "the job folder {} exists already: submit its tasks again with {}/submit.sh \
                 [TASK...], or remove it (or give another --job-dir)",
                dir.display(),
                dir.display()
            );
        }
        if !on_path("sbatch") {
            bail!(
                "sbatch is not on PATH (is this a Slurm login node?); --dry-run prints the job \
                 without submitting it"
            );
        }
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        std::fs::write(dir.join("job.env"), env)?;
        for (name, text) in SCRIPTS {
            let p = dir.join(name);
            std::fs::write(&p, text)?;
            make_executable(&p)?;
        }
        let out = Command::new(dir.join("submit.sh"))
            .output()
            .with_context(|| format!("running {}/submit.sh", dir.display()))?;
        let _ = std::io::Write::write_all(&mut std::io::stdout().lock(), &out.stdout);
        if !out.status.success() {
            bail!(
                "submitting the job failed ({}): {}; the job folder {} is written, submit it \
                 with its submit.sh",
                out.status,
                String::from_utf8_lossy(&out.stderr).trim(),
                dir.display()
            );
        }
        Ok(())
    }
}

fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(program).is_file()))
}

#[cfg(unix)]
fn make_executable(p: &Path) -> Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o755))
        .with_context(|| format!("making {} executable", p.display()))
}

#[cfg(not(unix))]
fn make_executable(_: &Path) -> Result<()> {
    Ok(())
}

/// A path as an argument of the job's commands.
pub fn arg(p: &Path) -> String {
    p.display().to_string()
}

/// The default job folder: `slurm/NAME` under the current folder.
pub fn default_dir(name: &str) -> PathBuf {
    PathBuf::from("slurm").join(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoting_survives_bash() {
        let values: Vec<String> = ["plain", "with space", "it's", "", "$HOME", "a\"b"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let script = format!("A={}; printf '%s\\n' \"${{A[@]}}\"", array(&values));
        let out = Command::new("bash")
            .arg("-c")
            .arg(&script)
            .output()
            .unwrap();
        let lines: Vec<String> = String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        assert_eq!(lines, values);
    }
}
