#!/usr/bin/env bash
# Speed of two builds side by side (issue 14: before/after ratios from one run).
#
#   scripts/render-ab.sh OLD_BINARY NEW_BINARY [SCENE...]
#   FILTER=rpf scripts/render-ab.sh OLD_BINARY NEW_BINARY [SCENE...]
#   FILTER=ddf FILTER_ARGS=--holes scripts/render-ab.sh OLD_BINARY NEW_BINARY [SCENE...]
#
# For each bundled scene (default: all of scenes/*.toml) renders it with each binary in turn,
# ROUNDS times (default 3), alternating so that both see the same machine, and prints a
# Markdown table of the medians, their ratio, and whether the two linear EXR images are the
# same bytes. Without FILTER: the path tracer's samples per pixel per second (kernel time, as
# `render` reports it) at the scene's own size; SPP (default 16; conference scenes 4, outside
# scenes 32) sets the samples per render. With FILTER=NAME: that filter's time as `render`
# reports it (RPF: wall-clock seconds; a device filter: kernel milliseconds from the OpenCL
# profiling events) at 512 × 512 and SPP (default 8), the filtered images compared; for RPF
# the default scenes are the five of results/README.md's RPF table. FILTER_ARGS (split on
# spaces) go to both binaries' `render` after the filter, e.g. `--holes` or `--kw 21`.
# Build the old binary from the old commit first, e.g.
#   git worktree add /tmp/old OLD_COMMIT && (cd /tmp/old && cargo build --release)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
# shellcheck source=scripts/ab-common.sh
. "$root/scripts/ab-common.sh"
ab_binaries 2,17 2 "$@"
old=$1
new=$2
shift 2
filter=${FILTER:-}
read -r -a filter_args <<<"${FILTER_ARGS:-}"
# RPF runs for tens of seconds, a device filter for milliseconds.
unit=ms
divisor=1
[ "$filter" = rpf ] && { unit=s; divisor=1000; }
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then
    if [ "$filter" = rpf ]; then
        scenes=(cornell_diffuse cornell_glossy cornell_plane outside conference)
    else
        for f in "$root"/scenes/*.toml; do scenes+=("$(basename "$f" .toml)"); done
    fi
fi
rounds=${ROUNDS:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT


# One render with binary $1 into $work/$2.{png,exr}; prints the measured figure.
measure() {
    local bin=$1 which=$2
    if [ -n "$filter" ]; then
        "$bin" render "$file" --spp "$spp" --width 512 --height 512 --filter "$filter" \
            "${filter_args[@]}" --out "$work/$which.png" --exr "$work/$which.exr" 2>&1 \
            | sed -n "s/^$filter filter.* median \([0-9.]*\) ms.*/\1/p" \
            | awk -v d="$divisor" '{printf "%.2f\n", $1 / d}'
    else
        "$bin" render "$file" --spp "$spp" --out "$work/$which.png" --exr "$work/$which.exr" 2>&1 \
            | grep -o '[0-9.]* spp/s' | cut -d' ' -f1
    fi
}

if [ -n "$filter" ]; then
    label="$filter${FILTER_ARGS:+ $FILTER_ARGS}"
    echo "| scene | spp | old $label $unit | new $label $unit | new / old | same bytes |"
else
    echo "| scene | spp | old spp/s | new spp/s | new / old | same bytes |"
fi
echo "|---|---|---|---|---|---|"
for scene in "${scenes[@]}"; do
    file="$root/scenes/$scene.toml"
    [ -f "$file" ] || { echo "render-ab: no scene $file" >&2; exit 2; }
    if [ -n "$filter" ]; then
        spp=${SPP:-8}
    else
        case $scene in
            conference*) spp=${SPP:-4} ;;
            outside*) spp=${SPP:-32} ;;
            *) spp=${SPP:-16} ;;
        esac
    fi
    : >"$work/old.txt"
    : >"$work/new.txt"
    for _ in $(seq "$rounds"); do
        measure "$old" old >>"$work/old.txt"
        measure "$new" new >>"$work/new.txt"
    done
    o=$(median <"$work/old.txt")
    n=$(median <"$work/new.txt")
    same=no
    cmp -s "$work/old.exr" "$work/new.exr" && same=yes
    echo "| $scene | $spp | $o | $n | $(ratio "$o" "$n") | $same |"
done
