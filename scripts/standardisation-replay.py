#!/usr/bin/env python3
"""A white standardisation replayed offline, against the truth.

Under a scene (whose `led-drift` may give each LED its own rate), read a
sample at calibration (line 0) and `--drift-line` lines on with the
calibration as trained; standardise it on a white tile read 32 lines from
`--drift-line + 4`; and read the sample again 40 lines after the drift
line with the standardised calibration, its readings taken to the new
white (`estimate --corrected-with`), and once more without. For each:
the BRDF error per point (RMS over the bins over the truth's peak),
median and 90th percentile; the gloss reading's relative error, median
and 90th percentile; the share of bins within 2u; and the result (the
centre zones' mean gloss, with U at k = 2) beside the truth's mean over
the same pixels.

    python3 scripts/standardisation-replay.py --blob out/cal.blob --scene out/uneven.toml

Standard library only.
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

WHITE = '{ model = "lambertian", rho = 0.99 }'


def quantile(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def read(args, work, tag, blob, line, extra=()):
    """Simulate the sample from `line` on and estimate it with `blob`."""
    d = os.path.join(work, tag)
    run = lambda *a: subprocess.run([args.host_tools, *a], check=True, capture_output=True)
    run("simulate", args.scene, "--surface", args.surface, "--line", str(line), "--lines", str(args.lines),
        "--out", d)
    run("estimate", "--blob", blob, "--readings", os.path.join(d, "points.csv"), "--out", os.path.join(d, "e.csv"),
        "--json", os.path.join(d, "e.json"), "--result", os.path.join(d, "r.json"), *extra)
    with open(os.path.join(d, "readings.json")) as f:
        truth = json.load(f)["truth"]
    with open(os.path.join(d, "e.json")) as f:
        points = json.load(f)["points"]
    with open(os.path.join(d, "r.json")) as f:
        result = json.load(f)
    errors, gloss, covered, bins = [], [], 0, 0
    for p in points:
        t = truth["rho"][p["pixel"]]
        errors.append(math.sqrt(sum((a - b) ** 2 for a, b in zip(p["rho"], t)) / len(t)) / max(t))
        covered += sum(abs(a - b) <= 2 * u for a, u, b in zip(p["rho"], p["u_rho"], t))
        bins += len(t)
        g = truth["readings"][p["pixel"]][0]
        gloss.append(abs(p["gloss_gu"] - g) / g)
    pixels = [q for a, b in result["pixels"] for q in range(a, b + 1)]
    g = result["readings"][0]
    return {
        "error": (statistics.median(errors), quantile(errors, 0.9)),
        "gloss": (100 * statistics.median(gloss), 100 * quantile(gloss, 0.9)),
        "covered": 100 * covered / bins,
        "result": (g["value"], g["expanded_u"], statistics.mean(truth["readings"][q][0] for q in pixels)),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blob", required=True, help="the calibration as trained (unsigned or signed)")
    ap.add_argument("--scene", required=True, help="the scene it was trained for, with its drift")
    ap.add_argument("--surface", default='{ model = "ward", rho_d = 0.2, alpha = 0.15 }', help="the sample")
    ap.add_argument("--drift-line", type=int, default=2500)
    ap.add_argument("--lines", type=int, default=16, help="lines of the sample per reading")
    ap.add_argument("--key", default="host-tools/keys/dev-NOT-FOR-PRODUCTION.key")
    ap.add_argument("--host-tools", default="target/release/host-tools")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        tile = os.path.join(work, "tile")
        subprocess.run([args.host_tools, "simulate", args.scene, "--surface", WHITE, "--line",
                        str(args.drift_line + 4), "--lines", "32", "--out", tile], check=True, capture_output=True)
        std = os.path.join(work, "std.blob")
        found = subprocess.run([args.host_tools, "standardise", "--blob", args.blob, "--readings",
                                os.path.join(tile, "points.csv"), "--tile-rf", "0.99", "--tile-u", "0.003", "--key",
                                args.key, "--out", std], check=True, capture_output=True, text=True).stdout
        rows = [
            ("as trained", args.blob, 0, ()),
            ("as trained", args.blob, args.drift_line, ()),
            (f"standardised at {args.drift_line + 4}", std, args.drift_line + 40, ("--corrected-with", args.blob)),
            ("the same, without --corrected-with", std, args.drift_line + 40, ()),
        ]
        print(found.strip())
        print(f"| line | calibration | BRDF error median / 90th | gloss error median / 90th | bins within 2u | "
              f"result GU (U) | truth GU |")
        print("|---|---|---|---|---|---|---|")
        for i, (what, blob, line, extra) in enumerate(rows):
            r = read(args, work, str(i), blob, line, extra)
            print(f"| {line} | {what} | {r['error'][0]:.3f} / {r['error'][1]:.3f} | {r['gloss'][0]:.2f} / "
                  f"{r['gloss'][1]:.2f} % | {r['covered']:.1f} % | {r['result'][0]:.2f} ({r['result'][1]:.2f}) | "
                  f"{r['result'][2]:.2f} |")


if __name__ == "__main__":
    sys.exit(main())
