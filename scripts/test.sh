#!/usr/bin/env bash
# The test suite on a fresh machine: set up, then run every test on the OpenCL device
# (PoCL on a CPU-only machine), the viewer's scripted test under Xvfb among them. Then the
# Slurm test (tests/slurm.rs: a single-node cluster on this machine), with Debian's slurm-wlm and munge installed for it; if they do not install,
# it says so and the rest of the suite still counts. Arguments go to `cargo test`; with any,
# only those tests run.
set -euo pipefail
cd "$(dirname "$0")/.."
NOISEFREE_SETUP_TESTS=1 source scripts/setup.sh
./scripts/check-format.sh
# Intel OIDN beside our filters in the benchmarks (tests/bench_quick.rs checks its rows here):
# a Python environment with pyoidn from PyPI.
python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || apt_install python3-venv
scripts/oidn/setup.sh cache/oidn-venv >&2
export NOISEFREE_OIDN_VENV="$PWD/cache/oidn-venv" NOISEFREE_REQUIRE_OIDN=1

have_slurm() {
    local p
    for p in slurmctld slurmd munged mungekey sbatch; do
        command -v "$p" >/dev/null 2>&1 || [ -x "/usr/sbin/$p" ] || return 1
    done
}

if (($# == 0)) && ! have_slurm; then
    echo "test: installing slurm-wlm and munge (apt) for the Slurm test" >&2
    apt_install --no-install-recommends slurm-wlm munge || true
fi

cargo test --release --locked "$@"

if (($# == 0)); then
    if have_slurm; then
        cargo test --release --locked --test slurm -- --ignored
    else
        echo "test: slurm-wlm and munge did not install: the Slurm test (tests/slurm.rs) did not run" >&2
    fi
fi
