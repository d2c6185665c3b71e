#!/usr/bin/env bash
# RPF's filter time of two builds side by side (issue 14: ≤ 40 s at 512 × 512, 8 spp).
#
#   scripts/rpf-ab.sh OLD_BINARY NEW_BINARY [SCENE...]
#
# For each scene (default: the five of results/README.md's RPF table) renders it at 512 × 512,
# 8 spp, with `--filter rpf` and each binary in turn, ROUNDS times (default 1; a frame takes
# 40-50 s on the 2-core build machine), alternating so that both see the same machine, and
# prints a Markdown table: the median filter wall-clock time (as `render` reports it) of each
# binary, their ratio, and whether the two filtered EXR images are the same bytes. Build the
# old binary from the old commit first, e.g.
#   git worktree add /tmp/old OLD_COMMIT && (cd /tmp/old && cargo build --release)
set -euo pipefail
if [ $# -lt 2 ]; then
    sed -n 2,11p "$0" >&2
    exit 2
fi
old=$1
new=$2
shift 2
root=$(cd "$(dirname "$0")/.." && pwd)
for b in "$old" "$new"; do
    if [ ! -x "$b" ]; then
        echo "rpf-ab: $b is not an executable noisefree binary" >&2
        exit 2
    fi
done
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then
    scenes=(cornell_diffuse cornell_glossy cornell_plane outside conference)
fi
rounds=${ROUNDS:-1}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

echo "| scene | old RPF s | new RPF s | new / old | same bytes |"
echo "|---|---|---|---|---|"
for scene in "${scenes[@]}"; do
    file="$root/scenes/$scene.toml"
    [ -f "$file" ] || { echo "rpf-ab: no scene $file" >&2; exit 2; }
    : >"$work/old.txt"
    : >"$work/new.txt"
    for _ in $(seq "$rounds"); do
        for which in old new; do
            bin=$old
            [ $which = new ] && bin=$new
            "$bin" render "$file" --spp 8 --width 512 --height 512 --filter rpf \
                --out "$work/$which.png" --exr "$work/$which.exr" 2>&1 \
                | sed -n 's/^rpf filter.* median \([0-9.]*\) ms.*/\1/p' \
                | awk '{printf "%.2f\n", $1 / 1000}' >>"$work/$which.txt"
        done
    done
    o=$(median <"$work/old.txt")
    n=$(median <"$work/new.txt")
    same=no
    cmp -s "$work/old.exr" "$work/new.exr" && same=yes
    echo "| $scene | $o | $n | $(awk -v a="$o" -v b="$n" 'BEGIN {printf "%.3f", b / a}') | $same |"
done
