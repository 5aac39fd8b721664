#!/usr/bin/env python3
"""numpy's matmul (OpenBLAS sgemm) on the batch the host kernel is compared with.

Computes R = V @ W^T for V: points x m readings and W: n x m (float32, both
C-contiguous), i.e. one million points of m = 7 readings to n = 81 bins by
default, writing into a preallocated output (`out=`), and prints one JSON
object: the best and the median wall time of `--runs` runs (after one
warm-up), seconds per point, the thread count OpenBLAS reports and the
numpy version. Called by `host-tools tradeoff` when `python3 -c "import numpy"`
works.

    python3 scripts/numpy_matmul.py [--points 1000000] [--n 81] [--m 7] [--runs 7] [--threads N]
"""
import argparse
import json
import os
import sys
import time


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--n", type=int, default=81)
    ap.add_argument("--m", type=int, default=7)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--threads", type=int, default=None,
                    help="OpenBLAS threads (sets OPENBLAS_NUM_THREADS before numpy loads); default: OpenBLAS's own choice")
    a = ap.parse_args()
    if a.threads is not None:
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = str(a.threads)
    import numpy as np

    rng = np.random.default_rng(1)
    v = rng.uniform(0.0, 300.0, size=(a.points, a.m)).astype(np.float32)
    w = rng.uniform(-50.0, 50.0, size=(a.n, a.m)).astype(np.float32)
    wt = np.ascontiguousarray(w.T)  # m x n: V @ W^T
    out = np.empty((a.points, a.n), dtype=np.float32)
    np.matmul(v, wt, out=out)  # warm-up (page faults, thread pool)
    times = []
    for _ in range(a.runs):
        t0 = time.perf_counter()
        np.matmul(v, wt, out=out)
        times.append(time.perf_counter() - t0)
    times.sort()
    threads = None
    try:
        cfg = np.show_config(mode="dicts")  # numpy >= 1.25
        threads = None if cfg is None else cfg.get("Build Dependencies", {}).get("blas", {}).get("name")
    except Exception:  # noqa: BLE001 - informational only
        pass
    res = {
        "numpy": np.__version__,
        "blas": threads,
        "threads_requested": a.threads,
        "points": a.points,
        "n": a.n,
        "m": a.m,
        "runs": a.runs,
        "best_s": times[0],
        "median_s": times[len(times) // 2],
        "best_s_per_point": times[0] / a.points,
        "checksum": float(out[:: max(1, a.points // 1000)].astype(np.float64).sum()),
    }
    json.dump(res, sys.stdout)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
