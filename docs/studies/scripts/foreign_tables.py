#!/usr/bin/python3
"""What a table stf did not make loses against stf's own, and what smoothing it gains.

For media of the 15-media study (bench/model_accuracy.py; albedo 0.95, unit radius, healpix:16 x
45 alpha bins by default): an independent reference table (3e7 paths, seed 1000), a 1e5-path
table (seed 2) and a raw 1e6-path table (seed 3). The 1e5-path table is written again as a table
stf did not make: its four datasets alone ("bare"), and with the medium and paths attributes
("medium"); each form and stf's own table ("extras") is smoothed by `stf smooth` (--model auto),
and every table is compared with the reference by `stf eval` (joint TV of the (alpha bin, cell)
exit distribution). The target: the smoothed bare table is closer to the reference than the raw
1e6-path table (worth 10x its paths).

Also `stf import` of a text file of 1e6 rows `alpha theta phi count` (bins' middles, cells'
centres): its seconds, and whether the counts come back exactly.

Writes OUT/foreign_tables.json and prints a markdown table.
Usage: docs/studies/scripts/foreign_tables.py [--out DIR] [--reference-paths N] [--media K] [--threads T]
"""
import argparse
import json
import os
import sys
import time

import h5py
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402

ALBEDO = 0.95
MEDIA = [(1, 0.9), (4.5, 0.3), (10, 0.9), (4.5, -0.5), (1, -0.5), (10, 0.3)]
DATASETS = ("escape/weight", "escape/alpha_edges", "grid/direction", "grid/solid_angle")


def medium(tau, g):
    return {"name": f"tau {tau} g {g}", "sigma_s": ALBEDO * tau, "sigma_a": (1 - ALBEDO) * tau, "g": g}


def strip(table, out, attributes=()):
    """The table's four datasets (and the named root attributes) alone."""
    with h5py.File(table, "r") as f, h5py.File(out, "w") as g:
        for d in DATASETS:
            g[d] = f[d][()]
        for a in attributes:
            g.attrs[a] = f.attrs[a]


def joint_tv(stf, candidate, reference, work):
    return stf.evaluate(candidate, reference, os.path.join(work, "eval.json"))["joint_tv_distance"]


def smooth(stf, table, out, threads):
    start = time.monotonic()
    stf.run("smooth", table, "--threads", threads, "--quiet", "-o", out)
    seconds = time.monotonic() - start
    with h5py.File(out, "r") as f:
        return seconds, str(f.attrs["smoothed_by"])


def study(stf, m, reference_paths, grid, bins, work, threads):
    tag = f"tau{m['sigma_s'] + m['sigma_a']:g}_g{m['g']:g}"
    path = lambda what: os.path.join(work, f"{tag}_{what}.h5")  # noqa: E731
    ref, small, large = path("reference"), path("small"), path("large")
    stf.precompute(m, reference_paths, 1000, ref, grid, bins, threads)
    stf.precompute(m, 1e5, 2, small, grid, bins, threads)
    stf.precompute(m, 1e6, 3, large, grid, bins, threads)
    row = {"medium": m, "raw_1e5": joint_tv(stf, small, ref, work), "raw_1e6": joint_tv(stf, large, ref, work),
           "smoothed": {}}
    strip(small, path("bare"))
    strip(small, path("medium"), ("sigma_s", "sigma_a", "g", "radius", "paths"))
    for form, table in (("bare", path("bare")), ("medium", path("medium")), ("extras", small)):
        seconds, spec = smooth(stf, table, path("smoothed"), threads)
        row["smoothed"][form] = {"joint_tv": joint_tv(stf, path("smoothed"), ref, work), "model": spec,
                                 "seconds": seconds}
    for f in (ref, small, large, path("bare"), path("medium"), path("smoothed")):
        os.remove(f)
    row["worth_10x"] = row["smoothed"]["bare"]["joint_tv"] <= row["raw_1e6"]
    return row


def import_timing(stf, work, rows=1000000, nside=16, bins=45):
    """Seconds of `stf import` of `rows` text rows, and whether every count comes back."""
    np.save(os.path.join(work, "empty.npy"), np.zeros((bins, 12 * nside * nside)))
    layout = os.path.join(work, "layout.h5")
    stf.run("import", os.path.join(work, "empty.npy"), "--grid", f"healpix:{nside}", "--alpha-bins", bins,
            "--quiet", "-o", layout)
    with h5py.File(layout, "r") as f:
        edges, direction = f["escape/alpha_edges"][()], f["grid/direction"][()]
    rng = np.random.default_rng(1)
    b, c = rng.integers(0, bins, rows), rng.integers(0, len(direction), rows)
    middle = 0.5 * (edges[:-1] + edges[1:])
    theta, phi = np.arccos(np.clip(direction[:, 2], -1, 1)), np.arctan2(direction[:, 1], direction[:, 0])
    text = os.path.join(work, "rows.txt")
    np.savetxt(text, np.column_stack([middle[b], theta[c], phi[c], np.ones(rows)]), fmt=["%.17g"] * 3 + ["%d"])
    out = os.path.join(work, "imported.h5")
    start = time.monotonic()
    stf.run("import", text, "--grid", f"healpix:{nside}", "--alpha-bins", bins, "--quiet", "-o", out)
    seconds = time.monotonic() - start
    expected = np.bincount(b * len(direction) + c, minlength=bins * len(direction)).reshape(bins, -1)
    with h5py.File(out, "r") as f:
        exact = bool(np.array_equal(f["escape/weight"][()], expected))
    for f in (text, out, layout, os.path.join(work, "empty.npy")):
        os.remove(f)
    return {"rows": rows, "seconds": seconds, "exact_counts": exact}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=os.path.join(ROOT, "out", "foreign_tables"))
    p.add_argument("--reference-paths", type=float, default=3e7)
    p.add_argument("--media", type=int, default=4, help="how many of the study's media (up to %d)" % len(MEDIA))
    p.add_argument("--grid", default="healpix:16")
    p.add_argument("--alpha-bins", type=int, default=45)
    p.add_argument("--threads", default="0")
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    stf = Stf()
    rows = [study(stf, medium(*m), a.reference_paths, a.grid, a.alpha_bins, a.out, a.threads)
            for m in MEDIA[:a.media]]
    timing = import_timing(stf, a.out)
    report = {"reference_paths": a.reference_paths, "grid": a.grid, "alpha_bins": a.alpha_bins, "media": rows,
              "import": timing}
    with open(os.path.join(a.out, "foreign_tables.json"), "w") as f:
        json.dump(report, f, indent=1)
    print(f"joint TV against a {a.reference_paths:.0e}-path reference ({a.grid} x {a.alpha_bins} bins)\n")
    print("| medium | raw 1e5 | raw 1e6 | smoothed, bare | smoothed, medium | smoothed, extras | worth 10x |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        s = r["smoothed"]
        print(f"| {r['medium']['name']} | {r['raw_1e5']:.4f} | {r['raw_1e6']:.4f} | {s['bare']['joint_tv']:.4f} "
              f"({s['bare']['model']}) | {s['medium']['joint_tv']:.4f} ({s['medium']['model']}) | "
              f"{s['extras']['joint_tv']:.4f} ({s['extras']['model']}) | {'yes' if r['worth_10x'] else 'no'} |")
    print(f"\nstf import of {timing['rows']:.0e} text rows: {timing['seconds']:.2f} s, "
          f"counts {'exact' if timing['exact_counts'] else 'NOT exact'}")


if __name__ == "__main__":
    main()
