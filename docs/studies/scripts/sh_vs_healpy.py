#!/usr/bin/python3
"""stf's SH fit against a plain healpy projection at the same band limit.

For each medium: a healpix table of 1e5 paths (seed 1) and an independent reference of 1e7
paths (seed 99). Per alpha bin, healpy's map2alm of the bin's density, alm2map back at the same
NSIDE, clipped at zero and renormalised, gives the peer's cell probabilities; `stf fit --model
sh:L` (window and smoothing chosen on held-out data) is evaluated by `stf eval`. Both are
compared with the reference by the alpha-weighted TV distance. Writes JSON to --out.

Usage: docs/studies/scripts/sh_vs_healpy.py [--out FILE.json] [--paths N] [--reference-paths N]
Needs Debian's python3-healpy.
"""
import argparse
import json
import os
import sys
import tempfile

import h5py
import healpy as hp
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402

MEDIA = [{"name": "tau 4.5, g 0.3", "sigma_s": 4, "sigma_a": 0.5, "g": 0.3},
         {"name": "tau 1, g 0", "sigma_s": 1, "sigma_a": 0, "g": 0},
         {"name": "tau 4, albedo 0.75, g 0.7", "sigma_s": 3, "sigma_a": 1, "g": 0.7}]


def healpy_tv(table, reference, nside, lmax):
    with h5py.File(table, "r") as f, h5py.File(reference, "r") as r:
        w, ref = f["/escape/weight"][:], r["/escape/weight"][:]
    marginal = ref.sum(axis=1) / ref.sum()
    tv = 0.0
    for b in range(w.shape[0]):
        if w[b].sum() <= 0 or ref[b].sum() <= 0:
            continue
        density = w[b] / w[b].sum() / hp.nside2pixarea(nside)
        smooth = np.clip(hp.alm2map(hp.map2alm(density, lmax=lmax, iter=3), nside, lmax=lmax), 0, None)
        p = smooth / smooth.sum()
        tv += marginal[b] * 0.5 * np.abs(p - ref[b] / ref[b].sum()).sum()
    return tv


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "sh_vs_healpy.json"))
    ap.add_argument("--paths", type=float, default=1e5)
    ap.add_argument("--reference-paths", type=float, default=1e7)
    ap.add_argument("--nside", type=int, default=8)
    ap.add_argument("--alpha-bins", type=int, default=18)
    a = ap.parse_args()
    stf, grid, rows = Stf(), f"healpix:{a.nside}", []
    with tempfile.TemporaryDirectory() as work:
        for m in MEDIA:
            table, ref = os.path.join(work, "t.h5"), os.path.join(work, "ref.h5")
            stf.precompute(m, a.paths, 1, table, grid, a.alpha_bins)
            stf.precompute(m, a.reference_paths, 99, ref, grid, a.alpha_bins)
            raw = stf.evaluate(table, ref, os.path.join(work, "e.json"))["tv_distance"]
            for lmax in (4, 8, 16):
                model = os.path.join(work, "m.h5")
                stf.fit(table, ["--model", f"sh:{lmax}"], model)
                ours = stf.evaluate(model, ref, os.path.join(work, "e.json"))["tv_distance"]
                with h5py.File(model, "r") as f:
                    window, t = f["/sh"].attrs["window"], float(f["/sh"].attrs["smoothing"])
                rows.append({"medium": m["name"], "L": lmax, "raw_tv": raw, "stf_tv": ours,
                             "healpy_tv": healpy_tv(table, ref, a.nside, lmax), "window": str(window), "t": t})
                print(json.dumps(rows[-1]), flush=True)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    with open(a.out, "w") as f:
        json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
