#!/usr/bin/env bash
# rustfmt, when the toolchain has it (a minimal rustup profile may not).
set -euo pipefail
cd "$(dirname "$0")/.."
if cargo fmt --version >/dev/null 2>&1; then
    cargo fmt --check
else
    echo "check-format: rustfmt is not installed; skipping the format check" >&2
fi
