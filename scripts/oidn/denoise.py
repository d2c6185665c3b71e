#!/usr/bin/env python3
"""Runs Intel Open Image Denoise (pyoidn, CPU) on one image for `noisefree bench`.

Inputs are raw little-endian float32 RGB files of width x height pixels, rows top to bottom,
written by src/bench/oidn.rs: the noisy colour (linear HDR), and the albedo and normal
auxiliaries. As OIDN's documentation recommends for noisy auxiliaries, albedo and normal are
first denoised by their own filters ("prefiltered") and the colour filter is told so
(cleanAux). The output is written the same way. One line of JSON on stdout gives the time of
each call of the colour filter (after one warm-up call, which includes OIDN's set-up) and of
the prefiltering, in seconds.
"""
import argparse
import json
import sys
import time

import numpy as np
import pyoidn

QUALITIES = {
    "fast": pyoidn.OIDN_QUALITY_FAST,
    "balanced": pyoidn.OIDN_QUALITY_BALANCED,
    "high": pyoidn.OIDN_QUALITY_HIGH,
}


def load(path, w, h):
    a = np.fromfile(path, dtype="<f4")
    if a.size != w * h * 3:
        sys.exit(f"{path}: {a.size} floats, expected {w * h * 3}")
    return np.ascontiguousarray(a.reshape(h, w, 3).astype(np.float32))


def run_filter(device, images, quality, out, hdr=False, clean_aux=False):
    """One RT filter over `images` ((name, array) pairs) into `out`; returns the execute time."""
    with pyoidn.Filter(device, pyoidn.OIDN_FILTER_TYPE_RT) as f:
        for name, img in images:
            f.set_image(name, img, pyoidn.OIDN_FORMAT_FLOAT3)
        f.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
        if hdr:
            f.set_bool("hdr", True)
        if clean_aux:
            f.set_bool("cleanAux", True)
        f.set_quality(QUALITIES[quality])
        f.commit()
        start = time.perf_counter()
        f.execute()
        return time.perf_counter() - start


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--version", action="store_true")
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.add_argument("--color")
    p.add_argument("--albedo")
    p.add_argument("--normal")
    p.add_argument("--out")
    p.add_argument("--quality", choices=sorted(QUALITIES), default="high")
    p.add_argument("--repeat", type=int, default=1)
    a = p.parse_args()
    if a.version:
        print(f"OIDN {pyoidn.version.oidn_version} (pyoidn)")
        return
    w, h = a.width, a.height
    color, albedo, normal = (load(x, w, h) for x in (a.color, a.albedo, a.normal))
    with pyoidn.Device(pyoidn.OIDN_DEVICE_TYPE_CPU) as device:
        device.commit()
        clean_albedo = np.zeros_like(albedo)
        clean_normal = np.zeros_like(normal)
        out = np.zeros_like(color)
        aux = [(pyoidn.OIDN_IMAGE_ALBEDO, clean_albedo), (pyoidn.OIDN_IMAGE_NORMAL, clean_normal)]
        times, prefilter = [], []
        for i in range(a.repeat + 1):  # the first call is a warm-up
            t_albedo = run_filter(device, [(pyoidn.OIDN_IMAGE_ALBEDO, albedo)], a.quality, clean_albedo)
            t_normal = run_filter(device, [(pyoidn.OIDN_IMAGE_NORMAL, normal)], a.quality, clean_normal)
            t = run_filter(
                device, [(pyoidn.OIDN_IMAGE_COLOR, color)] + aux, a.quality, out, hdr=True, clean_aux=True
            )
            if i > 0:
                times.append(t)
                prefilter.append(t_albedo + t_normal)
        err = device.get_error()
        if err is not None:
            sys.exit(f"OIDN: {err}")
    out.astype("<f4").tofile(a.out)
    print(json.dumps({"seconds": times, "prefilter_seconds": prefilter}))


if __name__ == "__main__":
    main()
