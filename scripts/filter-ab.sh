#!/usr/bin/env bash
# Kernel times of two builds side by side on saved AOV files (issue 14: before/after ratios
# from one run, per kernel).
#
#   scripts/filter-ab.sh OLD_BINARY NEW_BINARY AOV.exr...
#   FILTER=bmfr KERNELS="bmfr_nlm_packed bmfr_emission_nlm_packed" scripts/filter-ab.sh ...
#
# For each AOV file (written by `noisefree render SCENE --aovs AOV.exr`) runs `noisefree filter
# AOV.exr --filter FILTER --repeat REPEAT --profile` (FILTER default bmfr, REPEAT default 5,
# FILTER_ARGS split on spaces and passed to both) with each binary in turn, ROUNDS times
# (default 3), alternating so that both see the same machine. Prints a Markdown table: per
# file the whole filter's median (of the medians each run prints) and each kernel of KERNELS
# (default: the whole filter only), old and new in ms, their ratio, and whether the two
# filtered EXR images are the same bytes. Render-ab.sh does the same through `render`, one
# run per render; this one repeats the filter and reads the OpenCL profiling events per kernel.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
# shellcheck source=scripts/ab-common.sh
. "$root/scripts/ab-common.sh"
ab_binaries 2,15 3 "$@"
old=$1
new=$2
shift 2
filter=${FILTER:-bmfr}
repeat=${REPEAT:-5}
rounds=${ROUNDS:-3}
read -r -a filter_args <<<"${FILTER_ARGS:-}"
read -r -a kernels <<<"${KERNELS:-}"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# One filter run of binary $1 on file $2 into $work/$3.exr; appends the whole filter's median
# to $work/$3.total and each kernel's time to $work/$3.<kernel>.
measure() {
    local bin=$1 aov=$2 which=$3 log
    log=$("$bin" filter "$aov" --filter "$filter" "${filter_args[@]}" --repeat "$repeat" \
        --profile --exr "$work/$which.exr" 2>&1) || {
        echo "filter-ab: $bin filter $aov failed:" >&2
        echo "$log" >&2
        exit 1
    }
    sed -n "s/^$filter filter.* median \([0-9.]*\) ms.*/\1/p" <<<"$log" >>"$work/$which.total"
    for k in "${kernels[@]}"; do
        awk -v k="$k" '$1 == k {print $3}' <<<"$log" >>"$work/$which.$k"
    done
}

header="| file | old $filter ms | new $filter ms | new / old |"
rule="|---|---|---|---|"
for k in "${kernels[@]}"; do
    header+=" old $k | new $k | new / old |"
    rule+="---|---|---|"
done
echo "$header same bytes |"
echo "$rule---|"
for aov in "$@"; do
    [ -f "$aov" ] || { echo "filter-ab: no AOV file $aov" >&2; exit 2; }
    rm -f "$work"/old.* "$work"/new.*
    for _ in $(seq "$rounds"); do
        measure "$old" "$aov" old
        measure "$new" "$aov" new
    done
    o=$(median <"$work/old.total")
    n=$(median <"$work/new.total")
    row="| $(basename "$aov") | $o | $n | $(ratio "$o" "$n") |"
    for k in "${kernels[@]}"; do
        ko=$(median <"$work/old.$k")
        kn=$(median <"$work/new.$k")
        row+=" $ko | $kn | $(ratio "$ko" "$kn") |"
    done
    same=no
    cmp -s "$work/old.exr" "$work/new.exr" && same=yes
    echo "$row $same |"
done
