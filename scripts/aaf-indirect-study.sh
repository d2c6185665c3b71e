#!/usr/bin/env bash
# AAF indirect light (seed 000 ch. 4) on cornell_diffuse (or SCENE) against Monte Carlo and ddf:
# renders at SIZE² (256 by default), compares each with the cached reference REF (an EXR from
# `noisefree reference scenes/cornell_diffuse.toml --width 256 --height 256 --spp 2048`), and
# prints one line per render: name, MSE (RGB), relMSE, and the render's spp lines.
# Usage: scripts/aaf-indirect-study.sh REF.exr [OUT_DIR]; SCENE, MC_SPP, AAF_PATH_SPP, FOOTPRINTS,
# DDF_SPP (lists, empty: none), AAF_FLAGS and AAF_TAG choose the rows.
set -euo pipefail
REF=${1:?the reference EXR}
OUT=${2:-out/aaf-indirect-study}
SIZE=${SIZE:-256}
NF=${NF:-target/release/noisefree}
SCENE=${SCENE:-scenes/cornell_diffuse.toml}
mkdir -p "$OUT"
run() {
    local name=$1
    shift
    local log="$OUT/$name.log"
    "$NF" render "$SCENE" --width "$SIZE" --height "$SIZE" --out "$OUT/$name.png" \
        --exr "$OUT/$name.exr" "$@" >"$log" 2>&1
    local m
    m=$("$NF" compare --json "$OUT/$name.exr" "$REF" |
        python3 -c 'import json,sys; j=json.load(sys.stdin); print("%.6g %.5g" % (j["mse_rgb"], j["rel_mse"]))')
    echo "$name $m | $(grep -E 'indirect samples|filter \(kernel' "$log" | tr '\n' ' ')"
}
for spp in ${MC_SPP-16 32 64 128 256}; do run "mc-$spp" --spp "$spp"; done
for spp in ${AAF_PATH_SPP-16}; do
    for fp in ${FOOTPRINTS-1 3 6.666667}; do
        # AAF_FLAGS: more --aafi-* settings; AAF_TAG names the rows they make.
        run "aaf-p$spp-fp$fp${AAF_TAG-}" --spp "$spp" --filter aaf-indirect \
            --aafi-footprints "$fp" ${AAF_FLAGS-} --timings
    done
done
for spp in ${DDF_SPP-16 64}; do run "ddf-$spp" --spp "$spp" --filter ddf --timings; done
