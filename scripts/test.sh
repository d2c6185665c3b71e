#!/usr/bin/env bash
# The test suite on a fresh machine: set up, then run every test on the OpenCL device
# (PoCL on a CPU-only machine).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
./scripts/check-format.sh
cargo test --release --locked "$@"
