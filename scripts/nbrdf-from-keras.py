#!/usr/bin/env python3
"""Converts NBRDF networks saved by Keras (.h5, the form Sztrajman et al.
publish their fits in: the MERL, RGL-EPFL isotropic and Nielsen et al. sets)
into the NBRDF JSON set host-tools reads (`accuracy --set`, `pixel-map
--set`, `train --prior`, `surface.brdf = { model = "nbrdf", ... }`).

    pip install h5py numpy
    python3 scripts/nbrdf-from-keras.py OUT.json DIR_OR_FILE.h5 [...]

Each material is named after its file (`blue-acrylic.h5` -> `blue-acrylic`).
The weights are copied as they are (8 significant digits), in the layout of
host-tools/data/merl-nbrdf.json: `{"format": "nbrdf-mlp-6-21-21-3",
"materials": {NAME: {"w1": 6x21, "b1": 21, "w2": 21x21, "b2": 21, "w3": 21x3,
"b3": 3}}}`. A file that is not such a network is refused with its name and
nothing is written; the output is written whole or not at all.
"""
import json
import os
import sys
import tempfile

SHAPES = {"w1": (6, 21), "b1": (21,), "w2": (21, 21), "b2": (21,), "w3": (21, 3), "b3": (3,)}
# Keras names the three dense layers dense_1..dense_3 (kernel and bias each).
KERAS = {"w1": "dense_1/dense_1/kernel:0", "b1": "dense_1/dense_1/bias:0",
         "w2": "dense_2/dense_2/kernel:0", "b2": "dense_2/dense_2/bias:0",
         "w3": "dense_3/dense_3/kernel:0", "b3": "dense_3/dense_3/bias:0"}


def fail(msg):
    sys.exit(f"nbrdf-from-keras: {msg}")


def rounded(a):
    if a.ndim == 1:
        return [float(f"{x:.8g}") for x in a]
    return [[float(f"{x:.8g}") for x in row] for row in a]


def material(path, h5py, np):
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        fail(f"{path}: not an HDF5 file ({e}); give the .h5 files of an NBRDF set")
    with f:
        out = {}
        for key, name in KERAS.items():
            if name not in f:
                fail(f"{path}: no {name}: not a 6-21-21-3 NBRDF network saved by Keras")
            a = np.array(f[name], dtype=float)
            if a.shape != SHAPES[key]:
                fail(f"{path}: {name} is {a.shape}, not {SHAPES[key]}")
            if not np.all(np.isfinite(a)):
                fail(f"{path}: {name} holds a non-finite value")
            out[key] = rounded(a)
        return out


def main():
    if len(sys.argv) < 3:
        fail("usage: nbrdf-from-keras.py OUT.json DIR_OR_FILE.h5 [...]")
    try:
        import h5py
        import numpy as np
    except ImportError:
        fail("needs h5py and numpy: pip install h5py numpy")
    out_path, inputs = sys.argv[1], sys.argv[2:]
    files = []
    for p in inputs:
        if os.path.isdir(p):
            files += sorted(os.path.join(p, n) for n in os.listdir(p) if n.endswith(".h5"))
        elif p.endswith(".h5"):
            files.append(p)
        else:
            fail(f"{p}: neither a directory nor an .h5 file")
    if not files:
        fail(f"no .h5 files in {' '.join(inputs)}")
    materials = {}
    for p in files:
        name = os.path.basename(p)[:-3]
        if name in materials:
            fail(f"{p}: a second material named {name!r}")
        materials[name] = material(p, h5py, np)
    doc = {"format": "nbrdf-mlp-6-21-21-3", "materials": materials}
    folder = os.path.dirname(os.path.abspath(out_path))
    with tempfile.NamedTemporaryFile("w", dir=folder, delete=False, suffix=".tmp") as t:
        tmp = t.name
        try:
            json.dump(doc, t)
        except BaseException:
            t.close()
            os.unlink(tmp)
            raise
    os.replace(tmp, out_path)
    print(f"wrote {out_path}: {len(materials)} material(s)")


if __name__ == "__main__":
    main()
