#!/usr/bin/env bash
# Path-tracer speed of two builds side by side (issue 14: before/after ratios from one run).
#
#   scripts/render-ab.sh OLD_BINARY NEW_BINARY [SCENE...]
#
# For each bundled scene (default: all of scenes/*.toml) renders it at its own size with each
# binary in turn, ROUNDS times (default 3), alternating so that both see the same machine, and
# prints a Markdown table: the median samples per pixel per second (kernel time, as `render`
# reports it) of each binary, their ratio, and whether the two linear EXR images are the same
# bytes. SPP (default 16; conference scenes 4, outside scenes 32) sets the samples per render.
# Build the old binary from the old commit first, e.g.
#   git worktree add /tmp/old OLD_COMMIT && (cd /tmp/old && cargo build --release)
set -euo pipefail
if [ $# -lt 2 ]; then
    sed -n 2,12p "$0" >&2
    exit 2
fi
old=$1
new=$2
shift 2
root=$(cd "$(dirname "$0")/.." && pwd)
for b in "$old" "$new"; do
    if [ ! -x "$b" ]; then
        echo "render-ab: $b is not an executable noisefree binary" >&2
        exit 2
    fi
done
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then
    for f in "$root"/scenes/*.toml; do scenes+=("$(basename "$f" .toml)"); done
fi
rounds=${ROUNDS:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

echo "| scene | spp | old spp/s | new spp/s | new / old | same bytes |"
echo "|---|---|---|---|---|---|"
for scene in "${scenes[@]}"; do
    file="$root/scenes/$scene.toml"
    [ -f "$file" ] || { echo "render-ab: no scene $file" >&2; exit 2; }
    case $scene in
        conference*) spp=${SPP:-4} ;;
        outside*) spp=${SPP:-32} ;;
        *) spp=${SPP:-16} ;;
    esac
    : >"$work/old.txt"
    : >"$work/new.txt"
    for _ in $(seq "$rounds"); do
        for which in old new; do
            bin=$old
            [ $which = new ] && bin=$new
            "$bin" render "$file" --spp "$spp" --out "$work/$which.png" --exr "$work/$which.exr" 2>&1 \
                | grep -o '[0-9.]* spp/s' | cut -d' ' -f1 >>"$work/$which.txt"
        done
    done
    o=$(median <"$work/old.txt")
    n=$(median <"$work/new.txt")
    same=no
    cmp -s "$work/old.exr" "$work/new.exr" && same=yes
    echo "| $scene | $spp | $o | $n | $(awk -v a="$o" -v b="$n" 'BEGIN {printf "%.3f", b / a}') | $same |"
done
