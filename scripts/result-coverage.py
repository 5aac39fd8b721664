#!/usr/bin/env python3
"""How often a measurement's stated result covers the truth.

For every surface (each material of the NBRDF sets given, the black glass,
and Ward lobes of alpha 0.03 to 0.25), simulate `--lines` lines of it under
the scene's instrument, estimate them with the calibration and its result
(`host-tools estimate --result`), and compare the result with the truth's
mean over the same pixels: whether |value - truth| <= U (k = 2) for each
gloss reading and each bin of the mean BRDF, and |value - truth| / U.

    python3 scripts/result-coverage.py --blob out/cal.blob --scene scenes/handheld.toml --set rgl.json,nielsen.json

The calibration should not have trained on the sets (the vendored MERL set
trains the default prior). Standard library only; runs two surfaces at a
time.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

READINGS = ["gloss_gu", "haze_hu", "distinctness_pct"]


def surfaces(sets):
    out = []
    for path in sets:
        with open(path) as f:
            names = json.load(f)["materials"]
        tag = os.path.splitext(os.path.basename(path))[0]
        for name in names:
            brdf = '{ model = "nbrdf", file = "%s", material = "%s" }' % (os.path.abspath(path), name)
            out.append((f"{tag}:{name}", brdf))
    out.append(("black glass", '{ model = "smooth-dielectric", n = 1.567 }'))
    for alpha in [0.03, 0.06, 0.1, 0.15, 0.25]:
        out.append((f"ward alpha {alpha}", '{ model = "ward", rho_d = 0.2, alpha = %s }' % alpha))
    return out


def read_one(args, i, name, brdf, work):
    d = os.path.join(work, str(i))
    run = lambda *a: subprocess.run([args.host_tools, *a], check=True, capture_output=True)
    run("simulate", args.scene, "--surface", brdf, "--lines", str(args.lines), "--out", d)
    result = os.path.join(d, "result.json")
    run("estimate", "--blob", args.blob, "--readings", os.path.join(d, "points.csv"), "--out",
        os.path.join(d, "e.csv"), "--result", result)
    with open(result) as f:
        r = json.load(f)
    with open(os.path.join(d, "readings.json")) as f:
        truth = json.load(f)["truth"]
    pixels = [p for a, b in r["pixels"] for p in range(a, b + 1)]
    rec = {"name": name}
    for reading in r["readings"]:
        k = READINGS.index(reading["reading"])
        t = statistics.mean(truth["readings"][p][k] for p in pixels)
        rec[reading["reading"]] = (reading["value"], t, reading["expanded_u"])
    b = r["brdf"]
    if b:
        t = [statistics.mean(truth["rho"][p][j] for p in pixels) for j in range(len(b["value"]))]
        rec["bins"] = [abs(v - tj) <= u for v, tj, u in zip(b["value"], t, b["expanded_u"])]
    return rec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blob", required=True, help="the calibration (unsigned or signed)")
    ap.add_argument("--scene", required=True, help="the scene whose instrument reads the surfaces")
    ap.add_argument("--set", default="", help="NBRDF JSON files, comma separated")
    ap.add_argument("--lines", type=int, default=16)
    ap.add_argument("--host-tools", default="target/release/host-tools")
    args = ap.parse_args()
    todo = surfaces([s for s in args.set.split(",") if s])
    with tempfile.TemporaryDirectory() as work, ThreadPoolExecutor(2) as pool:
        recs = list(pool.map(lambda s: read_one(args, s[0], *s[1], work), enumerate(todo)))
    print(f"{len(recs)} surfaces, {args.lines} lines each, the result's zones; covered: |value - truth| <= U (k = 2)")
    print("| quantity | covered | |value - truth| / U: median / 90th | not covered |")
    print("|---|---|---|---|")
    for q in READINGS:
        rows = [(r["name"], *r[q]) for r in recs if q in r]
        z = sorted(abs(v - t) / u for _, v, t, u in rows if u > 0)
        miss = [f"{n} ({v:.1f} vs {t:.1f}, U {u:.1f})" for n, v, t, u in rows if abs(v - t) > u]
        if rows:
            print(f"| {q} | {len(rows) - len(miss)} of {len(rows)} | {statistics.median(z):.2f} / "
                  f"{z[int(0.9 * len(z))]:.2f} | {'; '.join(miss) or '-'} |")
    bins = [c for r in recs for c in r.get("bins", [])]
    if bins:
        print(f"| BRDF bins | {sum(bins)} of {len(bins)} ({100 * sum(bins) / len(bins):.1f} %) | - | - |")


if __name__ == "__main__":
    sys.exit(main())
