#!/usr/bin/env bash
# Issue 14's anchor measured side by side: noisefree's path tracer against Mitsuba 3's
# (`llvm_ad_rgb` variant, `path` integrator) on the same scene, machine and settings.
#
#   scripts/mitsuba/anchor.sh [SCENE...]      (default: the bundled diffuse scenes below)
#
# Each scene is exported by examples/mitsuba_scene.rs (its world-space triangles, shading
# normals, uvs, textures as the renderer samples them, camera, lights) and rendered at its own
# size, SPP samples per pixel (default 16; the conference room 4), ROUNDS times (default 3)
# by each renderer in turn at seed 1: noisefree's figure is `render`'s kernel time (the
# comparable one), and beside it the whole `render` command's time as it prints it ("in X
# s": scene loading, BVH build and the kernel build, from the disk cache, included; not
# comparable); Mitsuba's the wall-clock of `mi.render` until the image is in host memory (its
# kernel compiled, or loaded from Dr.Jit's cache, before the timed renders; scene loading not
# counted). Then each
# renders once more at seed 2, and the mean squared difference of its two images, times spp
# / 2, is its variance per sample (RGB, the image's mean over pixels): the time to reach a
# given error is proportional to variance / speed, the last column's ratio (above 1:
# noisefree reaches it sooner). Medians of the rounds; a Markdown table on stdout.
# Set up first: scripts/mitsuba/setup.sh. NOISEFREE_BIN overrides target/release/noisefree.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
venv=${NOISEFREE_MITSUBA_VENV:-$root/cache/mitsuba-venv}
if [ ! -x "$venv/bin/python" ]; then
    echo "anchor: no Mitsuba environment at $venv; run scripts/mitsuba/setup.sh first" >&2
    exit 2
fi
llvm=$(ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* 2>/dev/null | head -1 || true)
if [ -z "$llvm" ]; then
    echo "anchor: libLLVM 19 not found; run scripts/mitsuba/setup.sh first" >&2
    exit 2
fi
export DRJIT_LIBLLVM_PATH=$llvm
(cd "$root" && cargo build --release --quiet --example mitsuba_scene)
export=$root/target/release/examples/mitsuba_scene
bin=${NOISEFREE_BIN:-$root/target/release/noisefree}
[ -n "${NOISEFREE_BIN:-}" ] || (cd "$root" && cargo build --release --quiet)
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then
    scenes=(cornell_diffuse cornell_diffuse_dof curved grids room_gi toasters_dof
        two_lights_shadows conference)
fi
rounds=${ROUNDS:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

# noisefree at seed $2 into $work/n$2.exr; prints "kernel_s wall_s".
noisefree_render() {
    "$bin" render "$root/scenes/$1.toml" --spp "$spp" --seed "$2" --out "$work/n$2.png" \
        --exr "$work/n$2.exr" 2>&1 |
        sed -n 's/.* spp in \([0-9.]*\) s (kernel \([0-9.]*\) s).*/\2 \1/p'
}
# Mitsuba at seed $2 into $work/m$2.exr; prints its one timed round's seconds.
mitsuba_render() {
    "$venv/bin/python" "$root/scripts/mitsuba/render.py" "$work/$1" --spp "$spp" --seed "$2" \
        --rounds 1 --out "$work/m$2.exr" | sed -n 's/.*"seconds": \[\([0-9.e-]*\)\].*/\1/p'
}
mse() { "$bin" compare "$1" "$2" --json | sed -n 's/.*"mse_rgb": \([0-9.e-]*\).*/\1/p'; }
# Relative difference of the two renderers' image means (both seeds' images together): the
# scenes are the same when it is within the noise (a few 1e-4 on the Cornell box).
mean_diff() {
    "$venv/bin/python" -c '
import sys, numpy as np, mitsuba as mi
mi.set_variant("scalar_rgb")
m = lambda f: float(np.mean(np.array(mi.Bitmap(f))))
n = m(sys.argv[1]) + m(sys.argv[2]); k = m(sys.argv[3]) + m(sys.argv[4])
print(f"{(n - k) / k:+.1e}")' "$work/n1.exr" "$work/n2.exr" "$work/m1.exr" "$work/m2.exr"
}

echo "| scene | size | spp | noisefree spp/s (kernel) | noisefree spp/s (whole command) | Mitsuba spp/s | noisefree / Mitsuba (kernel) | variance per sample, noisefree | Mitsuba | equal-error time, Mitsuba / noisefree | image mean, noisefree / Mitsuba - 1 |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for s in "${scenes[@]}"; do
    case $s in conference*) spp=${SPP:-4} ;; *) spp=${SPP:-16} ;; esac
    "$export" "$root/scenes/$s.toml" "$work/$s" >/dev/null
    size=$(sed -n 's/.*"width": \([0-9]*\).*/\1/p' "$work/$s/scene.json")x$(sed -n 's/.*"height": \([0-9]*\).*/\1/p' "$work/$s/scene.json")
    : >"$work/nk" ; : >"$work/nw" ; : >"$work/m"
    for _ in $(seq "$rounds"); do
        read -r k w < <(noisefree_render "$s" 1)
        echo "$k" >>"$work/nk"; echo "$w" >>"$work/nw"
        mitsuba_render "$s" 1 >>"$work/m"
    done
    noisefree_render "$s" 2 >/dev/null
    mitsuba_render "$s" 2 >/dev/null
    nk=$(median <"$work/nk"); nw=$(median <"$work/nw"); m=$(median <"$work/m")
    vn=$(mse "$work/n1.exr" "$work/n2.exr"); vm=$(mse "$work/m1.exr" "$work/m2.exr")
    md=$(mean_diff)
    awk -v md="$md" -v s="$s" -v size="$size" -v spp="$spp" -v nk="$nk" -v nw="$nw" -v m="$m" \
        -v vn="$vn" -v vm="$vm" 'BEGIN {
        vn *= spp / 2; vm *= spp / 2
        printf "| %s | %s | %d | %.3g | %.3g | %.3g | %.3f | %.4g | %.4g | %.3f | %s |\n",
            s, size, spp, spp / nk, spp / nw, spp / m, m / nk, vn, vm, (vm * m) / (vn * nk), md
    }'
done
