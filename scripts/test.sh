#!/usr/bin/env bash
# The test suite on a fresh machine: set up, then run every test on the OpenCL device
# (PoCL on a CPU-only machine), and the viewer's scripted test under Xvfb.
set -euo pipefail
cd "$(dirname "$0")/.."
NOISEFREE_SETUP_TESTS=1 source scripts/setup.sh
./scripts/check-format.sh
# Intel OIDN beside our filters in the benchmarks (tests/bench_quick.rs checks its rows here):
# a Python environment with pyoidn from PyPI.
python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || apt_install python3-venv
scripts/oidn/setup.sh cache/oidn-venv >&2
export NOISEFREE_OIDN_VENV="$PWD/cache/oidn-venv" NOISEFREE_REQUIRE_OIDN=1
cargo test --release --locked "$@"
