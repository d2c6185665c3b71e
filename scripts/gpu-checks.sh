#!/usr/bin/env bash
# Checks on a GPU what PoCL cannot show, each a pass/fail line in a Markdown report:
#
#   scripts/gpu-checks.sh [--device N] [--out FILE]   (default results/gpu/<device>/checks.md)
#
# 1. Every registered filter builds and runs on the device: `render --filter NAME`, 48 x 40,
#    4 spp, on five scenes that between them turn on every filter's paths (a lens, a sky,
#    indirect light, sphere lights, two lights); a filter that does not apply to a scene
#    passes its frame through.
# 2. The megakernel, the wavefront tracer and the skip-index walk give the same bytes
#    (256 x 256, 8 spp, every bundled scene; `cmp` of their EXRs: on an H200 128 x 128 at
#    4 spp matched where the tracers study at 512 x 512 did not).
# 3. The same frame on this device and on the first CPU device (PoCL), through
#    `noisefree compare`: the rounding difference between devices, as numbers.
# 4. Known faults, kept until they pass: cornell_plane with the features output and no
#    variances at 256 spp per launch (CL_NV_INVALID_MEM_ACCESS on an H200, stop 48).
#
# The binary, OpenCL and the device as for scripts/bench-gpu.sh (scripts/gpu-env.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

device=""
out=""
while [ $# -gt 0 ]; do
    case "$1" in
        --device) device="$2"; shift 2 ;;
        --out) out="$2"; shift 2 ;;
        -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
        *) echo "gpu-checks: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done

log() { echo "gpu-checks: $*" >&2; }
source scripts/gpu-env.sh

out="${out:-results/gpu/$slug/checks.md}"
mkdir -p "$(dirname "$out")"
cpu=$(echo "$devices" | awk -F'[][]' '/\(CPU\)/ {print $2; exit}')
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failed=0

# render ARGS...: runs `noisefree render` on the device quietly; its log in $work/log.
render() { "$bin" render "$@" -q > "$work/log" 2>&1; }
first_error() { grep -v '^\s*$' "$work/log" | grep -iv 'build options' | head -n 3 | tr '\n' ' '; }

{
    echo "# GPU checks"
    echo
    echo "- date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "- binary: $("$bin" --version)"
    echo "- OpenCL device: $line"
    echo "- command: scripts/gpu-checks.sh --device $device"
    echo
    echo "## 1. Every filter builds and runs (render --filter, 48 x 40, 4 spp)"
    echo
    echo "| filter | scene | result |"
    echo "|---|---|---|"
} > "$out"
# The registry's names, from the refusal of an unknown one.
filters=$({ "$bin" filter /dev/null --filter '?' --exr "$work/x.exr" 2>&1 || true; } \
    | sed -n 's/.*noisefree has: none, //p' | tr -d ',')
[ -n "$filters" ] || { log "could not list the filters"; exit 1; }
for f in $filters; do
    for scene in cornell_diffuse_dof outside room_gi two_lights_shadows decoro/two_lights; do
        if render "scenes/$scene.toml" --width 48 --height 40 --spp 4 --device "$device" \
            --filter "$f" --out "$work/x.png" --no-exr; then
            result=ok
        else
            result="FAIL: $(first_error)"
            failed=$((failed + 1))
        fi
        echo "| $f | $scene | $result |" >> "$out"
    done
done

{
    echo
    echo "## 2. The three tracers give the same bytes (256 x 256, 8 spp)"
    echo
    echo "| scene | wavefront = megakernel | skip-index = wide BVH |"
    echo "|---|---|---|"
} >> "$out"
for toml in scenes/*.toml; do
    scene=$(basename "$toml" .toml)
    common=(--width 256 --height 256 --spp 8 --device "$device" --out "$work/x.png")
    row="| $scene |"
    if render "$toml" "${common[@]}" --exr "$work/mega.exr" \
        && render "$toml" "${common[@]}" --tracer wavefront --exr "$work/wave.exr" \
        && render "$toml" "${common[@]}" --bvh skip --exr "$work/skip.exr"; then
        for other in wave skip; do
            if cmp -s "$work/mega.exr" "$work/$other.exr"; then
                row="$row yes |"
            else
                row="$row NO: $("$bin" compare "$work/$other.exr" "$work/mega.exr" 2>&1 | head -n 1) |"
                failed=$((failed + 1))
            fi
        done
    else
        row="$row FAIL: $(first_error) | |"
        failed=$((failed + 1))
    fi
    echo "$row" >> "$out"
done

{
    echo
    echo "## 3. This device against the first CPU device (64 x 64, 4 spp)"
    echo
} >> "$out"
if [ -n "$cpu" ] && [ "$cpu" != "$device" ]; then
    echo "| scene | noisefree compare (this device against the CPU's) |" >> "$out"
    echo "|---|---|" >> "$out"
    for scene in cornell_glossy outside conference_dof; do
        common=(--width 64 --height 64 --spp 4 --out "$work/x.png")
        if render "scenes/$scene.toml" "${common[@]}" --device "$device" --exr "$work/gpu.exr" \
            && render "scenes/$scene.toml" "${common[@]}" --device "$cpu" --exr "$work/cpu.exr"; then
            echo "| $scene | $("$bin" compare "$work/gpu.exr" "$work/cpu.exr" 2>&1 | head -n 1) |" >> "$out"
        else
            echo "| $scene | FAIL: $(first_error) |" >> "$out"
            failed=$((failed + 1))
        fi
    done
else
    echo "No CPU device besides this one: nothing to compare." >> "$out"
fi

{
    echo
    echo "## 4. Known faults"
    echo
    echo "| case | result |"
    echo "|---|---|"
} >> "$out"
for seed in 1 7 8; do
    case_="cornell_plane, 128 x 128, 256 spp, --gather features, seed $seed"
    if render scenes/cornell_plane.toml --width 128 --height 128 --spp 256 --gather features \
        --seed "$seed" --device "$device" --out "$work/x.png" --no-exr; then
        echo "| $case_ | ok |" >> "$out"
    else
        echo "| $case_ | FAIL: $(first_error) |" >> "$out"
        failed=$((failed + 1))
    fi
done

echo >> "$out"
echo "$failed check(s) failed." >> "$out"
log "$failed check(s) failed; report: $out"
cat "$out"
