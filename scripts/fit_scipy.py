#!/usr/bin/env python3
"""The reproduction's Ward fits with SciPy, for a fair speed comparison.

Fits the same problem as `host-tools reproduce` (same rays, same noisy
readings, same bounds, same relative residuals, same variable-projection start
scan, SciPy's default tolerances) with scipy.optimize.least_squares:
  - method="trf": SciPy's default bounded trust-region solver, bounds native;
  - method="lm":  MINPACK lmder (what the Rust baseline ports), bounds by the
                  same sine reparametrisation the Rust fit uses.
and prints RMSE and time for all test patterns per condition.

    cargo run --release -p host-tools -- reproduce --dump-fit-problem out/fit_problem.json
    python3 scripts/fit_scipy.py out/fit_problem.json

Needs numpy and scipy (`python3 -m pip install numpy scipy`).
"""
import argparse
import json
import statistics
import time

import numpy as np
from scipy.optimize import least_squares


def pack(rays):
    """Rays per reading -> padded (m x K) arrays of weight, wc, tan2."""
    m, k = len(rays), max(len(r) for r in rays)
    W, C, T = np.zeros((m, k)), np.zeros((m, k)), np.zeros((m, k))
    for i, r in enumerate(rays):
        a = np.asarray(r, dtype=float)
        W[i, : len(r)], C[i, : len(r)], T[i, : len(r)] = a[:, 0], a[:, 1], a[:, 2]
    return W, C, T


def model_and_jac(p, W, C, T):
    d, s, a = p
    ia2 = 1.0 / (a * a)
    g = C * ia2 * np.exp(-T * ia2)
    pred = d * W.sum(1) + s * g.sum(1)
    J = np.empty((W.shape[0], 3))
    J[:, 0] = W.sum(1)
    J[:, 1] = g.sum(1)
    J[:, 2] = s * (g * (2.0 * T * ia2 / a - 2.0 / a)).sum(1)
    return pred, J


def bounded_linear_2(A, B, v, w, dr, sr):
    """Exact min of sum w^2 (d A + s B - v)^2 over the box (same as the Rust scan)."""
    a, b, y = A * w, B * w, v * w
    saa, sab, sbb, say, sby = a @ a, a @ b, b @ b, a @ y, b @ y

    def cost(d, s):
        return 0.5 * float(((d * a + s * b - y) ** 2).sum())

    det = saa * sbb - sab * sab
    if det > 1e-12 * saa * sbb:
        d = (say * sbb - sby * sab) / det
        s = (sby * saa - say * sab) / det
        if dr[0] <= d <= dr[1] and sr[0] <= s <= sr[1]:
            return d, s, cost(d, s)
    best = (dr[0], sr[0], np.inf)
    cands = [(d, (sby - d * sab) / sbb if sbb > 0 else sr[0]) for d in dr]
    cands += [((say - s * sab) / saa if saa > 0 else dr[0], s) for s in sr]
    cands += [(d, s) for d in dr for s in sr]
    for d, s in cands:
        d, s = min(max(d, dr[0]), dr[1]), min(max(s, sr[0]), sr[1])
        c = cost(d, s)
        if c < best[2]:
            best = (d, s, c)
    return best


def starts(v, w, W, C, T, lo, hi, k, nstarts):
    alphas = lo[2] * (hi[2] / lo[2]) ** (np.arange(k) / (k - 1))
    scan = []
    for a in alphas:
        ia2 = 1.0 / (a * a)
        A, B = W.sum(1), (C * ia2 * np.exp(-T * ia2)).sum(1)
        d, s, c = bounded_linear_2(A, B, v, w, (lo[0], hi[0]), (lo[1], hi[1]))
        scan.append(((d, s, a), c))
    costs = [c for _, c in scan]
    minima = [q for q in range(k) if (q == 0 or costs[q] <= costs[q - 1]) and (q + 1 == k or costs[q] <= costs[q + 1])]
    minima.sort(key=lambda q: costs[q])
    return [np.array(scan[q][0]) for q in minima[:nstarts]]


def fit(v, W, C, T, lo, hi, k, nstarts, method):
    w = 1.0 / np.maximum(v, 1e-6 * v.max())
    span = hi - lo
    best, nfev, njev = None, 0, 0
    for x0 in starts(v, w, W, C, T, lo, hi, k, nstarts):
        x0 = np.clip(x0, lo + 1e-4 * span, hi - 1e-4 * span)
        if method == "trf":
            fun = lambda p: (model_and_jac(p, W, C, T)[0] - v) * w
            jac = lambda p: model_and_jac(p, W, C, T)[1] * w[:, None]
            r = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf")
            p = r.x
        else:  # MINPACK lm with the sine transform
            ext = lambda u: lo + span * 0.5 * (1.0 + np.sin(u))
            fun = lambda u: (model_and_jac(ext(u), W, C, T)[0] - v) * w
            jac = lambda u: model_and_jac(ext(u), W, C, T)[1] * w[:, None] * (span * 0.5 * np.cos(u))
            u0 = np.arcsin(2.0 * (x0 - lo) / span - 1.0)
            r = least_squares(fun, u0, jac=jac, method="lm")
            p = ext(r.x)
        nfev += r.nfev
        njev += r.njev or 0
        if best is None or r.cost < best[1]:
            best = (p, r.cost)
    return best[0], nfev, njev


def ward_on_grid(p, bins_deg, view_deg):
    d, s, a = p
    ti, to = np.radians(bins_deg), np.radians(view_deg)
    t2 = np.tan((ti - to) / 2.0) ** 2
    return d + s * np.exp(-t2 / (a * a)) / (4.0 * a * a * np.sqrt(np.cos(ti) * np.cos(to)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("problem", help="JSON from `host-tools reproduce --dump-fit-problem`")
    ap.add_argument("--runs", type=int, default=3, help="timed runs per condition (median reported)")
    args = ap.parse_args()
    pb = json.load(open(args.problem))
    lo, hi = np.array(pb["bounds"]["lo"]), np.array(pb["bounds"]["hi"])
    V = [np.array(v) for v in pb["readings"]]
    truth = np.array(pb["truth"])  # K x n
    bins = np.array(pb["bins_deg"])
    print(f"{len(V)} test patterns, {len(V[0])} readings each; scipy.optimize.least_squares, default tolerances")
    print(f"{'condition':<22} {'method':<5} {'RMSE':>8} {'time [s]':>10} {'per fit [us]':>13} {'nfev/fit':>9} {'njev/fit':>9}")
    for cond, rays in pb["rays"].items():
        W, C, T = pack(rays)
        for method in ["trf", "lm"]:
            times = []
            for _ in range(max(1, args.runs)):
                t0 = time.perf_counter()
                res = [fit(v, W, C, T, lo, hi, pb["alpha_grid"], pb["starts"], method) for v in V]
                times.append(time.perf_counter() - t0)
            sec = statistics.median(times)
            est = np.array([ward_on_grid(p, bins, pb["view_deg"]) for p, _, _ in res])
            rmse = float(np.sqrt(((est - truth) ** 2).mean()))
            nfev = np.mean([r[1] for r in res])
            njev = np.mean([r[2] for r in res])
            print(f"{cond:<22} {method:<5} {rmse:>8.4f} {sec:>10.3e} {sec / len(V) * 1e6:>13.1f} {nfev:>9.1f} {njev:>9.1f}")


if __name__ == "__main__":
    main()
