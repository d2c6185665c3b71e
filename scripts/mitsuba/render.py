"""Renders a scene exported by `examples/mitsuba_scene.rs` with Mitsuba 3 (issue 14's anchor).

    render.py SCENE_DIR --spp N --seed S --out IMAGE.exr [--variant llvm_ad_rgb] [--rounds R]

Mitsuba's `path` integrator with the renderer's settings: next event estimation (Mitsuba
weights it against BSDF sampling by MIS; noisefree counts emission only where no light
connection was made, the same rays either way), Russian roulette from the same vertex with
the same survival probability (the path weight's largest component, capped at 0.95; Mitsuba's
`rr_depth` counts surfaces shaded, noisefree's `max_depth` the vertex about to be traced, so
they take the same number), a box pixel filter, independent samples. The first render
compiles Mitsuba's kernel (cached by Dr.Jit after that) and is not timed; then `--rounds`
renders are timed, each until its image is in host memory, and the last one is written.
Prints one JSON line: the variant, the threads and each timed round's seconds.
"""

import argparse
import json
import os
import sys
import time


def build(mi, spec, scene_dir, spp, seed):
    cam = spec["camera"]
    r = spec["render"]
    to_world = mi.ScalarTransform4f().look_at(
        origin=cam["origin"], target=cam["target"], up=cam["up"]
    )
    film = {
        "type": "hdrfilm",
        "width": r["width"],
        "height": r["height"],
        "rfilter": {"type": "box"},
        "pixel_format": "rgb",
        "component_format": "float32",
    }
    sensor = {
        "type": "perspective",
        "fov": cam["fov_degrees"],
        "fov_axis": "y",
        "to_world": to_world,
        "film": film,
        "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
    }
    if cam["lens_radius"] > 0:
        sensor["type"] = "thinlens"
        sensor["aperture_radius"] = cam["lens_radius"]
        sensor["focus_distance"] = cam["focal_distance"]
    if r["russian_roulette"]:
        integrator = {"type": "path", "max_depth": -1, "rr_depth": r["max_depth"]}
    else:
        # noisefree traces max_depth vertices; Mitsuba's max_depth counts the camera ray's
        # emitter hit as depth 1, so one more.
        integrator = {"type": "path", "max_depth": r["max_depth"] + 1, "rr_depth": 1 << 30}
    scene = {"type": "scene", "integrator": integrator, "sensor": sensor}

    def bsdf(m):
        if m["emitter"]:
            return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
        if m["texture"]:
            refl = {
                "type": "bitmap",
                "filename": os.path.join(scene_dir, m["texture"]),
                "filter_type": "bilinear",
                "wrap_mode": "repeat",
                "raw": True,
            }
        else:
            refl = {"type": "rgb", "value": m["color"]}
        return {"type": "diffuse", "reflectance": refl}

    def emitter(m):
        if max(m["emission"]) > 0:
            return {"type": "area", "radiance": {"type": "rgb", "value": m["emission"]}}
        return None

    for i, m in enumerate(spec["materials"]):
        if m["mesh"]:
            shape = {
                "type": "ply",
                "filename": os.path.join(scene_dir, m["mesh"]),
                "face_normals": False,
                "bsdf": bsdf(m),
            }
            e = emitter(m)
            if e:
                shape["emitter"] = e
            scene[f"mesh{i}"] = shape
    for i, s in enumerate(spec["spheres"]):
        m = spec["materials"][s["material"]]
        shape = {"type": "sphere", "center": s["center"], "radius": s["radius"], "bsdf": bsdf(m)}
        e = emitter(m)
        if e:
            shape["emitter"] = e
        scene[f"sphere{i}"] = shape
    return mi.load_dict(scene)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("scene_dir")
    p.add_argument("--spp", type=int, required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True)
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--rounds", type=int, default=3)
    a = p.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(a.variant)
    with open(os.path.join(a.scene_dir, "scene.json")) as f:
        spec = json.load(f)
    scene = build(mi, spec, a.scene_dir, a.spp, a.seed)
    # Compiles (or loads from Dr.Jit's cache) the kernel; not timed.
    img = mi.render(scene, spp=a.spp, seed=a.seed)
    dr.eval(img)
    img.numpy()
    times = []
    for _ in range(a.rounds):
        t0 = time.perf_counter()
        img = mi.render(scene, spp=a.spp, seed=a.seed)
        arr = img.numpy()  # waits for the render and copies it to host memory
        times.append(time.perf_counter() - t0)
    mi.Bitmap(arr, pixel_format=mi.Bitmap.PixelFormat.RGB).write(a.out)
    print(
        json.dumps(
            {
                "mitsuba": mi.__version__,
                "variant": a.variant,
                "threads": dr.thread_count(),
                "spp": a.spp,
                "seconds": times,
            }
        )
    )


if __name__ == "__main__":
    sys.exit(main())
