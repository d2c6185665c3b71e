#!/usr/bin/env bash
# The test suite on a fresh machine: set up, then run every test on the OpenCL device
# (PoCL on a CPU-only machine). Then the Slurm test (tests/slurm.rs: a single-node cluster on
# this machine), with Debian's slurm-wlm and munge installed for it; if they do not install,
# it says so and the rest of the suite still counts. Arguments go to `cargo test`; with any,
# only those tests run.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
./scripts/check-format.sh

have_slurm() {
    local p
    for p in slurmctld slurmd munged mungekey sbatch; do
        command -v "$p" >/dev/null 2>&1 || [ -x "/usr/sbin/$p" ] || return 1
    done
}

if (($# == 0)) && ! have_slurm; then
    echo "test: installing slurm-wlm and munge (apt) for the Slurm test" >&2
    for attempt in 1 2; do
        if as_root apt-get update -qq &&
            DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq \
                --no-install-recommends slurm-wlm munge >/dev/null; then
            break
        fi
        if ((attempt == 1)); then
            echo "test: apt-get failed; trying once more in 10 s" >&2
            sleep 10
        fi
    done
fi

cargo test --release --locked "$@"

if (($# == 0)); then
    if have_slurm; then
        cargo test --release --locked --test slurm -- --ignored
    else
        echo "test: slurm-wlm and munge did not install: the Slurm test (tests/slurm.rs) did not run" >&2
    fi
fi
