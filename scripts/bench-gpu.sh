#!/usr/bin/env bash
# Runs noisefree's full benchmark on a GPU and writes the results folder:
#
#   scripts/bench-gpu.sh [--device N] [--quick] [--out DIR] [-- extra `noisefree bench` flags]
#
# 1. Builds the release binary (or uses $NOISEFREE_BIN, e.g. a binary built elsewhere and
#    copied to a GPU machine without Rust).
# 2. Makes the GPU visible to OpenCL. NVIDIA drivers in containers often ship
#    libnvidia-opencl.so.1 without the ICD file that registers it with the loader; then this
#    script finds the library and writes an OpenCL/vendors/nvidia.icd pointing at it, and
#    exports OCL_ICD_VENDORS. It also finds an OpenCL ICD loader (libOpenCL.so.1) if the
#    system has none on its library path (CUDA ships one).
# 3. Lists the OpenCL devices and picks the first GPU (or --device N).
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
        -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
        *) echo "bench-gpu: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done

log() { echo "bench-gpu: $*" >&2; }

# 1. The binary.
if [ -n "${NOISEFREE_BIN:-}" ]; then
    bin="$NOISEFREE_BIN"
else
    command -v cargo >/dev/null 2>&1 || { log "no cargo here: build elsewhere and set NOISEFREE_BIN=/path/to/noisefree"; exit 1; }
    cargo build --release --locked
    bin="$PWD/target/release/noisefree"
fi
[ -x "$bin" ] || { log "$bin is not an executable"; exit 1; }

# 2. OpenCL: an ICD loader, and an ICD file for NVIDIA's library if the driver shipped none.
find_first() { # find_first NAME DIR... : the first DIR/NAME (or DIR/*/NAME) that exists
    local name="$1"; shift
    for d in "$@"; do
        for f in "$d/$name" "$d"/*/"$name"; do
            [ -e "$f" ] && { readlink -f "$f"; return 0; }
        done
    done
    return 1
}
lib_dirs=(/usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib /usr/local/nvidia/lib64 /usr/local/nvidia/lib
          /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /opt/cuda/lib64)
for d in /usr/local/cuda-*/lib64 /usr/local/cuda-*/targets/x86_64-linux/lib; do [ -d "$d" ] && lib_dirs+=("$d"); done

if ! ldconfig -p 2>/dev/null | grep -q 'libOpenCL\.so\.1'; then
    if loader=$(find_first libOpenCL.so.1 "${lib_dirs[@]}"); then
        export LD_LIBRARY_PATH="$(dirname "$loader")${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
        log "using the OpenCL ICD loader $loader"
    else
        log "no OpenCL ICD loader (libOpenCL.so.1) found; install ocl-icd-libopencl1 or copy one next to the binary"
        exit 1
    fi
fi

has_nvidia_icd() {
    local dirs=("${OCL_ICD_VENDORS:-/etc/OpenCL/vendors}")
    for d in "${dirs[@]}"; do
        grep -qs 'nvidia' "$d"/*.icd 2>/dev/null && return 0
    done
    return 1
}
if ! has_nvidia_icd; then
    nvlib=$(ldconfig -p 2>/dev/null | awk '/libnvidia-opencl\.so\.1/ {print $NF; exit}')
    [ -n "$nvlib" ] || nvlib=$(find_first libnvidia-opencl.so.1 "${lib_dirs[@]}" || true)
    if [ -n "$nvlib" ]; then
        icd_dir="${TMPDIR:-/tmp}/noisefree-icd"
        mkdir -p "$icd_dir/vendors"
        echo "$nvlib" > "$icd_dir/vendors/nvidia.icd"
        # Keep the other vendors (e.g. PoCL) visible too.
        for f in /etc/OpenCL/vendors/*.icd; do [ -e "$f" ] && cp "$f" "$icd_dir/vendors/"; done
        export OCL_ICD_VENDORS="$icd_dir/vendors"
        log "registered $nvlib through $OCL_ICD_VENDORS/nvidia.icd"
    else
        log "no NVIDIA OpenCL library (libnvidia-opencl.so.1) found; using whatever OpenCL platforms exist"
    fi
fi

# 3. The device.
devices=$("$bin" devices)
echo "$devices"
if [ -z "$device" ]; then
    device=$(echo "$devices" | awk -F'[][]' '/\(GPU\)/ {print $2; exit}')
    if [ -z "$device" ]; then
        log "no GPU among the OpenCL devices above; pass --device N to benchmark another device"
        exit 1
    fi
fi
line=$(echo "$devices" | grep -F "[$device]" | head -n1)
name=$(echo "$line" | sed -E 's/^ *\[[0-9]+\] (.*) \((GPU|CPU|accelerator|other)\).*/\1/')
slug=$(echo "$name" | tr '[:upper:]' '[:lower:]' | sed -E 's/[^a-z0-9]+/-/g; s/^-+|-+$//g')
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
