#!/usr/bin/env bash
# Runs noisefree's full benchmark on a GPU and writes the results folder:
#
#   scripts/bench-gpu.sh [--device N] [--quick] [--out DIR] [-- extra `noisefree bench` flags]
#
# 1-3. scripts/gpu-env.sh: the binary (a release build, or $NOISEFREE_BIN: one built elsewhere
#    and copied to a GPU machine without Rust), the GPU made visible to OpenCL (an ICD file
#    for NVIDIA's library where the driver shipped none, an ICD loader where the system has
#    none), and the device: the first GPU, or --device N.
# 4. Records the device, driver, OpenCL version and clocks (nvidia-smi, where present).
# 5. Runs `noisefree bench` on that device into results/gpu/<device>/ (or --out).
set -euo pipefail
cd "$(dirname "$0")/.."

device=""
quick=""
out=""
extra=()
while [ $# -gt 0 ]; do
    case "$1" in
        --device) device="$2"; shift 2 ;;
        --quick) quick="--quick"; shift ;;
        --out) out="$2"; shift 2 ;;
        --) shift; extra=("$@"); break ;;
        -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
        *) echo "bench-gpu: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done

log() { echo "bench-gpu: $*" >&2; }

# 1-3. The binary, OpenCL and the device (scripts/gpu-env.sh).
source scripts/gpu-env.sh

out="${out:-results/gpu/$slug}"
mkdir -p "$out"
log "benchmarking device $device ($name) into $out"

# 4. What it ran on.
{
    echo "# Environment"
    echo
    echo "- date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    # The binary's own commit (build.rs), not this checkout's: NOISEFREE_BIN may be older.
    echo "- binary: $("$bin" --version)"
    echo "- command: scripts/bench-gpu.sh --device $device $quick ${extra[*]:-}"
    echo "- OpenCL device: $line"
    echo "- host CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //') ($(nproc) threads)"
    if command -v nvidia-smi >/dev/null 2>&1; then
        echo
        echo '```'
        nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.sm,clocks.max.sm,clocks.mem,clocks.max.mem,power.limit,temperature.gpu --format=csv 2>&1 || true
        echo '```'
    fi
} > "$out/environment.md"

# 5. The benchmark.
"$bin" bench --device "$device" --out "$out" $quick "${extra[@]}"
log "done: $out"
