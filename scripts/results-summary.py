#!/usr/bin/env python3
"""Fills the RESULTS_* placeholders of results/README.md (or prints the tables) from the CSV
files that `noisefree bench` writes, so the summary's numbers are copied, never typed.

    scripts/results-summary.py results/pocl-cpu > /tmp/tables.md
"""
import csv, sys, os
from collections import defaultdict

d = sys.argv[1] if len(sys.argv) > 1 else "results/pocl-cpu"

def rows(name):
    p = os.path.join(d, name + ".csv")
    if not os.path.exists(p):
        return []
    with open(p) as f:
        return list(csv.DictReader(f))

def render_speed():
    r = rows("render-speed")
    out = ["| scene | specialised spp/s | generic spp/s | ratio | Mrays/s (spec.) | ready cold s (spec./gen.) | ready cached s (spec./gen.) |", "|---|---|---|---|---|---|---|"]
    for s in [x for x in r if x["kernel"] == "specialised"]:
        g = next(x for x in r if x["kernel"] == "generic" and x["scene"] == s["scene"])
        ratio = float(s["spp_per_s"]) / float(g["spp_per_s"])
        out.append(f"| {s['scene']} | {s['spp_per_s']} | {g['spp_per_s']} | {ratio:.2f} | {s['mrays_per_s']} | {s['ready_cold_s']} / {g['ready_cold_s']} | {s['ready_cached_s']} / {g['ready_cached_s']} |")
    return "\n".join(out)

def statistics():
    r = rows("statistics")
    by = defaultdict(dict)
    for x in r:
        by[x["scene"]][x["statistics"]] = x
    out = ["| scene | none spp/s | means spp/s | means + variances spp/s | relative (means + variances / none) |", "|---|---|---|---|---|"]
    for scene, v in by.items():
        out.append(f"| {scene} | {v['none']['spp_per_s']} | {v['means']['spp_per_s']} | {v['means+variances']['spp_per_s']} | {v['means+variances']['relative']} |")
    return "\n".join(out)

def filter_speed():
    r = rows("filter-speed")
    res = []
    for x in r:
        k = (x["width"], x["height"])
        if k not in res:
            res.append(k)
    kws = sorted({int(x["kw"]) for x in r})
    out = []
    for (w, h) in res:
        out.append(f"**{w}x{h}**, median ms\n")
        out.append("| variant | work-group | " + " | ".join(f"kw {k}" for k in kws) + " |")
        out.append("|---|---|" + "---|" * len(kws))
        variants = []
        for x in r:
            if (x["width"], x["height"]) == (w, h) and (x["variant"], x["work_group"]) not in variants:
                variants.append((x["variant"], x["work_group"]))
        for v, wg in variants:
            cells = []
            for k in kws:
                m = [x for x in r if (x["width"], x["height"], x["variant"], x["work_group"], x["kw"]) == (w, h, v, wg, str(k))]
                cells.append(m[0]["median_ms"] if m else "")
            out.append(f"| {v} | {wg} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)

def md_section(name, start_marker, end_marker):
    """The text of results file `name`.md from start_marker up to end_marker, or None."""
    p = os.path.join(d, name + ".md")
    if not os.path.exists(p):
        return None
    text = open(p).read()
    start = text.find(start_marker)
    return text[start:text.find(end_marker, start)]

def sweep():
    text = md_section("sweep", "## Hypothesis 1", "## All measurements")
    return "" if text is None else text.replace("## Hypothesis", "### Hypothesis").strip()

def quality():
    r = rows("quality")
    if not r:
        return "(not measured yet)"
    cols = [("unfiltered", "8"), ("ddf", "8"), ("ddf", "16"), ("ddf", "32"), ("rpf", "8"), ("atrous", "8")]
    out = ["MSE in CIELUV against the reference (lower is better); SSIM of the 8 spp images in the last columns.\n",
           "| scene | " + " | ".join(f"{m} {n}" for m, n in cols) + " | SSIM unfiltered / ddf / rpf / à-trous (8 spp) | filter s ddf / rpf / à-trous (8 spp) |",
           "|---|" + "---|" * (len(cols) + 2)]
    scenes = []
    for x in r:
        if x["scene"] not in scenes:
            scenes.append(x["scene"])
    for sc in scenes:
        cell = {(x["method"], x["spp"]): x for x in r if x["scene"] == sc}
        mse = [cell[c]["mse_luv"] if c in cell else "" for c in cols]
        at8 = [cell.get((m, "8")) for m in ("unfiltered", "ddf", "rpf", "atrous")]
        ssim = " / ".join(x["ssim"] if x else "" for x in at8)
        secs = " / ".join(x["filter_s"] if x else "" for x in at8[1:])
        out.append(f"| {sc} | " + " | ".join(mse) + f" | {ssim} | {secs} |")
    return "\n".join(out)

def accuracy():
    text = md_section("accuracy-time", "| scene | method | error at 8 spp", "\n\n")
    return "(not measured yet)" if text is None else text

tables = {
    "RESULTS_RENDER_SPEED": render_speed(),
    "RESULTS_STATISTICS": statistics(),
    "RESULTS_FILTER_SPEED": filter_speed(),
    "RESULTS_SWEEP": sweep(),
    "RESULTS_QUALITY": quality(),
    "RESULTS_ACCURACY": accuracy(),
}
if len(sys.argv) > 2:
    path = sys.argv[2]
    text = open(path).read()
    for k, v in tables.items():
        text = text.replace(k, v)
    open(path, "w").write(text)
else:
    for k, v in tables.items():
        print(f"<!-- {k} -->\n{v}\n")
