#!/usr/bin/env bash
# Sourced by scripts/bench-gpu.sh and scripts/gpu-checks.sh (with `log` defined and $device
# empty or a device number): sets $bin to the noisefree binary, makes the GPU visible to
# OpenCL, and sets $device to the first GPU unless one was given.
#
# 1. The binary: $NOISEFREE_BIN (e.g. one built elsewhere and copied to a GPU machine
#    without Rust), else a release build of this checkout.
# 2. NVIDIA drivers in containers often ship libnvidia-opencl.so.1 without the ICD file that
#    registers it with the loader; then this finds the library, writes an
#    OpenCL/vendors/nvidia.icd pointing at it and exports OCL_ICD_VENDORS. It also finds an
#    OpenCL ICD loader (libOpenCL.so.1) if the system has none on its library path (CUDA
#    ships one).
# 3. Lists the OpenCL devices and picks the first GPU; sets $line, $name and $slug for it.

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
        log "no GPU among the OpenCL devices above; pass --device N to use another device"
        exit 1
    fi
fi
# Its line in the list, its name, and the name as a folder (results/gpu/<slug>/).
line=$(echo "$devices" | grep -F "[$device]" | head -n1)
name=$(echo "$line" | sed -E 's/^ *\[[0-9]+\] (.*) \((GPU|CPU|accelerator|other)\).*/\1/')
slug=$(echo "$name" | tr '[:upper:]' '[:lower:]' | sed -E 's/[^a-z0-9]+/-/g; s/^-+|-+$//g')
