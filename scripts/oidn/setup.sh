#!/usr/bin/env bash
# Sets up Intel Open Image Denoise for the benchmarks: a Python virtual environment with the
# `pyoidn` package from PyPI (it bundles the OIDN 2.5 CPU library) and NumPy. Nothing else in
# noisefree uses Python; `noisefree bench` runs OIDN beside its own filters when this
# environment exists, and says how to create it when it does not.
#
#   scripts/oidn/setup.sh [VENV]     (default: cache/oidn-venv, or $NOISEFREE_OIDN_VENV)
set -euo pipefail
cd "$(dirname "$0")/../.."
venv="${1:-${NOISEFREE_OIDN_VENV:-cache/oidn-venv}}"
if ! python3 -c 'import venv' >/dev/null 2>&1; then
    echo "oidn setup: python3 with the venv module is needed (Debian: apt-get install python3-venv)" >&2
    exit 1
fi
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv" || {
        echo "oidn setup: creating $venv failed (Debian: apt-get install python3-venv)" >&2
        exit 1
    }
fi
# Pinned: the figures in results/ were measured with this OIDN.
"$venv/bin/pip" install --quiet --disable-pip-version-check "pyoidn==2.5.1.0" "numpy>=1.24,<3" \
    || "$venv/bin/pip" install --quiet --disable-pip-version-check "pyoidn==2.5.1.0" "numpy>=1.24,<3"
"$venv/bin/python" "scripts/oidn/denoise.py" --version
echo "OIDN ready: $venv (noisefree bench finds it there; elsewhere set NOISEFREE_OIDN_VENV)"
