//! Records the commit the binary is built from as NOISEFREE_COMMIT, for the provenance of
//! results (`bench`'s device.md, `--version`): a binary copied to a GPU machine
//! (scripts/bench-gpu.sh with NOISEFREE_BIN) reports the source it was built from, not
//! whatever checkout sits on that machine at run time. "unknown" outside a git checkout.
use std::path::Path;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    let commit = git(&["rev-parse", "--short", "HEAD"]).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=NOISEFREE_COMMIT={commit}");
    // A commit moves HEAD or the branch it names (a loose ref, or packed-refs after a gc).
    if let Some(dir) = git(&["rev-parse", "--git-dir"]) {
        let dir = Path::new(&dir);
        for f in ["HEAD", "packed-refs"] {
            if dir.join(f).exists() {
                println!("cargo:rerun-if-changed={}", dir.join(f).display());
            }
        }
        if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
            let r = dir.join(branch);
            if r.exists() {
                println!("cargo:rerun-if-changed={}", r.display());
            }
        }
    } else {
        println!("cargo:rerun-if-changed=build.rs");
    }
}
