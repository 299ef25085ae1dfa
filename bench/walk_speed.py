#!/usr/bin/python3
"""The walk's seconds against another build of stf, in turns in one run, as JSON.

Each case is precomputed by build/stf and by the baseline binary in turns, REPEATS times; the
walk's seconds are the table's runtime_s (the walk alone, no file writing), the command's are
wall-clock. Reported per case: the best of each, and the ratios baseline / build/stf (above 1:
build/stf is faster). The machine's noise falls on both alike. Where both write the same
datasets, the tables are also compared bit for bit.

A baseline from an older commit:
    git worktree add /tmp/stf-base REV
    cmake -S /tmp/stf-base -B /tmp/stf-base/build -DSTF_BUILD_TESTS=OFF -DSTF_BUILD_BENCH=OFF
    cmake --build /tmp/stf-base/build -j2 --target stf

Usage: bench/walk_speed.py --baseline BINARY [--repeats N] [--out FILE]     Needs build/stf.
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STF = os.path.join(ROOT, "build", "stf")

# (name, arguments): the thin medium of the walk's speed target first.
CASES = [
    ("thin tau 1, healpix:16, 1 thread", ["--sigma-s", "1", "--sigma-a", "0", "--g", "0", "--paths", "2e7",
                                          "--grid", "healpix:16", "--threads", "1"]),
    ("tau 10 g 0.7, csc:20, 1 thread", ["--sigma-s", "9", "--sigma-a", "1", "--g", "0.7", "--paths", "2e6",
                                        "--grid", "csc:20", "--threads", "1"]),
    ("tau 100, healpix:16, 1 thread", ["--sigma-s", "100", "--sigma-a", "0", "--g", "0", "--paths", "2e5",
                                       "--grid", "healpix:16", "--threads", "1"]),
    ("thin tau 1, healpix:16, all cores", ["--sigma-s", "1", "--sigma-a", "0", "--g", "0", "--paths", "2e7",
                                           "--grid", "healpix:16"]),
]


def run(binary, args, out):
    start = time.perf_counter()
    subprocess.run([binary, "precompute", *args, "--quiet", "-o", out], check=True)
    wall = time.perf_counter() - start
    with h5py.File(out) as f:
        return float(f.attrs["runtime_s"]), wall


def same_tables(a, b):
    with h5py.File(a) as fa, h5py.File(b) as fb:
        names = []
        fa.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
        if any(name not in fb for name in names):
            return None  # other layouts: nothing to compare
        return all(np.array_equal(fa[name][()], fb[name][()]) for name in names)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline", required=True, help="another stf binary, timed in turns with build/stf")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default="")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, args in CASES:
            best = {"build": [1e300, 1e300], "baseline": [1e300, 1e300]}
            for _ in range(a.repeats):
                for label, binary in [("baseline", a.baseline), ("build", STF)]:
                    walk, wall = run(binary, args, os.path.join(tmp, label + ".h5"))
                    best[label] = [min(best[label][0], walk), min(best[label][1], wall)]
            rows.append({"case": name, "args": " ".join(args),
                         "walk_s": best["build"][0], "baseline_walk_s": best["baseline"][0],
                         "walk_ratio_baseline_over_build": best["baseline"][0] / best["build"][0],
                         "wall_s": best["build"][1], "baseline_wall_s": best["baseline"][1],
                         "wall_ratio_baseline_over_build": best["baseline"][1] / best["build"][1],
                         "same_tables": same_tables(os.path.join(tmp, "build.h5"), os.path.join(tmp, "baseline.h5"))})
    text = json.dumps({"repeats": a.repeats, "baseline": a.baseline, "cases": rows}, indent=1)
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
