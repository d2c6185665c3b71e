#!/usr/bin/env bash
# Sets up Mitsuba 3 for issue 14's anchor (scripts/mitsuba/anchor.sh): a Python virtual
# environment with the `mitsuba` package from PyPI, and an LLVM that its `llvm_ad_rgb` variant
# can compile with (Dr.Jit 1.x emits `llvm.minimum`, which Debian 12's LLVM 14/15 that PoCL
# uses cannot select on x86: "LLVM ERROR: Cannot select ... fminimum"; Debian's libllvm19
# can). Nothing else in noisefree uses Mitsuba or this LLVM.
#
#   scripts/mitsuba/setup.sh [VENV]     (default: cache/mitsuba-venv, or $NOISEFREE_MITSUBA_VENV)
set -euo pipefail
cd "$(dirname "$0")/../.."
venv="${1:-${NOISEFREE_MITSUBA_VENV:-cache/mitsuba-venv}}"
if ! ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1; then
    if [ "$(id -u)" != 0 ]; then
        echo "mitsuba setup: libllvm19 is needed: sudo apt-get install libllvm19" >&2
        exit 1
    fi
    apt-get install -y -q libllvm19 >/dev/null \
        || { apt-get update -q >/dev/null && apt-get install -y -q libllvm19 >/dev/null; }
fi
if ! python3 -c 'import venv' >/dev/null 2>&1; then
    echo "mitsuba setup: python3 with the venv module is needed (Debian: apt-get install python3-venv)" >&2
    exit 1
fi
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
# Pinned: the figures in results/ were measured with this Mitsuba.
"$venv/bin/pip" install --quiet --disable-pip-version-check "mitsuba==3.9.1" "numpy>=1.24,<3" \
    || "$venv/bin/pip" install --quiet --disable-pip-version-check "mitsuba==3.9.1" "numpy>=1.24,<3"
echo "Mitsuba ready: $venv"
