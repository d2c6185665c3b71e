#!/usr/bin/env bash
# Sets up a fresh Debian/Ubuntu machine for noisefree: an OpenCL platform (PoCL, the portable
# CPU driver) with the ICD loader to link against, and a Rust toolchain. Installs only what is
# missing. Sourced by scripts/render.sh and scripts/test.sh.
set -euo pipefail

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

# apt-get install, retried once after a fresh update: a mirror caught mid-sync or a lock held
# by unattended upgrades fails the first attempt now and then.
apt_install() {
    local attempt
    for attempt in 1 2; do
        if as_root apt-get update -qq &&
            DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq "$@" >/dev/null; then
            return 0
        fi
        [ "$attempt" = 1 ] && { echo "setup: apt-get failed; retrying once" >&2; sleep 5; }
    done
    return 1
}

have_opencl_platform() {
    # An ICD file registers a platform with the loader; the loader itself must be linkable.
    compgen -G "/etc/OpenCL/vendors/*.icd" >/dev/null 2>&1 || [ -n "${OCL_ICD_VENDORS:-}" ] || return 1
    ldconfig -p 2>/dev/null | grep -q 'libOpenCL\.so\.1' || return 1
    ldconfig -p 2>/dev/null | grep -q 'libOpenCL\.so ' || [ -e /usr/lib/x86_64-linux-gnu/libOpenCL.so ] || return 1
}

if ! have_opencl_platform; then
    echo "setup: no OpenCL platform found; installing PoCL and the OpenCL ICD loader (apt)" >&2
    apt_install pocl-opencl-icd ocl-icd-opencl-dev
fi
if command -v dpkg-query >/dev/null 2>&1; then
    echo "setup: $(dpkg-query -W -f='${Package} ${Version}' pocl-opencl-icd 2>/dev/null || echo 'pocl-opencl-icd not installed (another OpenCL driver is used)')" >&2
fi

if ! command -v cargo >/dev/null 2>&1; then
    if [ -x "$HOME/.cargo/bin/cargo" ]; then
        export PATH="$HOME/.cargo/bin:$PATH"
    else
        echo "setup: installing a Rust toolchain with rustup" >&2
        command -v curl >/dev/null 2>&1 || { as_root apt-get update -qq; as_root apt-get install -y -qq curl ca-certificates >/dev/null; }
        curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal >/dev/null
        export PATH="$HOME/.cargo/bin:$PATH"
    fi
fi
if ! command -v cc >/dev/null 2>&1; then
    apt_install build-essential
fi

# The tests (scripts/test.sh sets NOISEFREE_SETUP_TESTS=1) also drive the viewer under a
# virtual X server (tests/view.rs): Xvfb, and the X libraries the viewer's window (minifb)
# loads at run time, libX11 and libXcursor.
if [ "${NOISEFREE_SETUP_TESTS:-0}" = 1 ]; then
    missing=()
    command -v Xvfb >/dev/null 2>&1 || missing+=(xvfb)
    ldconfig -p 2>/dev/null | grep -q 'libX11\.so\.6' || missing+=(libx11-6)
    ldconfig -p 2>/dev/null | grep -q 'libXcursor\.so\.1' || missing+=(libxcursor1)
    if [ "${#missing[@]}" -gt 0 ]; then
        echo "setup: installing ${missing[*]} for the viewer's tests (apt)" >&2
        apt_install "${missing[@]}"
    fi
fi
