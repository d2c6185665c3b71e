# Sourced by render-ab.sh and filter-ab.sh, the two side-by-side speed scripts: their
# arguments' checks and the figures they print.

# ab_binaries USAGE_LINES N_MIN "$@": prints the calling script's usage (its header's lines
# USAGE_LINES, e.g. 2,17) and exits 2 with fewer than N_MIN arguments, or when either of the
# first two is not an executable file.
ab_binaries() {
    local lines=$1 min=$2 b
    shift 2
    if [ $# -lt "$min" ]; then
        sed -n "${lines}p" "$0" >&2
        exit 2
    fi
    for b in "$1" "$2"; do
        if [ ! -x "$b" ]; then
            echo "$(basename "$0" .sh): $b is not an executable noisefree binary" >&2
            exit 2
        fi
    done
}

# The median of the numbers on stdin, one per line.
median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

# NEW / OLD to three decimals ("—" when OLD is 0).
ratio() { awk -v a="$1" -v b="$2" 'BEGIN {if (a > 0) printf "%.3f", b / a; else printf "—"}'; }
