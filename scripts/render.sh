#!/usr/bin/env bash
# The main job on a fresh machine: set up, build, and render the bundled Cornell diffuse scene
# (512 x 512, 8 spp) with the data-driven filter into out/, keeping the unfiltered image too.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
cargo build --release --locked
mkdir -p out
./target/release/noisefree devices
./target/release/noisefree render scenes/cornell_diffuse.toml --filter ddf --timings \
    --out out/cornell_diffuse.png --exr out/cornell_diffuse.exr \
    --exr-unfiltered out/cornell_diffuse_unfiltered.exr "$@"
