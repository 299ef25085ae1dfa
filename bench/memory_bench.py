#!/usr/bin/python3
"""Peak memory of precompute, fit and eval on fine grids, up to the largest table stf allows.

stf refuses a table whose estimate, cells * (16 * alpha_bins + 40) bytes, exceeds 8 GiB
(stf/precompute/precompute.h). This runs grids up to that limit and reports, per case, the estimate,
the measured peak resident memory of `stf precompute` (and of fit and eval where --fit is
given) and their ratio, as JSON; the baseline in the same run is the smallest case.

Usage: bench/memory_bench.py [--out FILE.json] [--largest] [--fit]
--largest adds healpix:512 x 150 alpha bins (an estimate of 7.7 GiB; minutes).
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STF = os.path.join(ROOT, "build", "stf")
CELLS = {"healpix": lambda n: 12 * n * n, "csc": lambda n: 6 * n * n}


def estimate(grid, bins):
    kind, n = grid.split(":")
    return CELLS[kind](int(n)) * (16 * bins + 40)


def peak_of(args):
    """Runs stf; returns (seconds, peak resident bytes) of that child alone."""
    pid = os.fork()
    if pid == 0:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.execv(STF, [STF, *map(str, args)])
    start = time.monotonic()
    _, status, usage = os.wait4(pid, 0)
    if status != 0:
        sys.exit(f"memory_bench: stf {' '.join(map(str, args))} failed")
    return time.monotonic() - start, usage.ru_maxrss * 1024


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "memory_bench.json"))
    ap.add_argument("--largest", action="store_true")
    ap.add_argument("--fit", action="store_true", help="also fit vmf:4 and eval each table")
    a = ap.parse_args()
    cases = [("healpix:16", 90, 1e5), ("healpix:128", 180, 1e5), ("csc:256", 90, 1e4), ("csc:1024", 1, 1e4),
             ("healpix:1024", 1, 1e4), ("healpix:2048", 1, 1e4)]
    if a.largest:
        cases.append(("healpix:512", 150, 1e4))
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for grid, bins, paths in cases:
            table = os.path.join(work, "t.h5")
            seconds, peak = peak_of(["precompute", "--sigma-s", 4, "--sigma-a", 0.5, "--g", 0.3, "--grid", grid,
                                     "--alpha-bins", bins, "--paths", int(paths), "--quiet", "-o", table])
            row = {"grid": grid, "alpha_bins": bins, "paths": paths, "estimate_bytes": estimate(grid, bins),
                   "precompute": {"seconds": seconds, "peak_bytes": peak,
                                  "peak_over_estimate": peak / estimate(grid, bins)},
                   "file_bytes": os.path.getsize(table)}
            if a.fit:
                model = os.path.join(work, "m.h5")
                s, p = peak_of(["fit", table, "--model", "vmf:4", "--quiet", "-o", model])
                row["fit"] = {"seconds": s, "peak_bytes": p}
                s, p = peak_of(["eval", model, "--reference", table, "--json", os.devnull])
                row["eval"] = {"seconds": s, "peak_bytes": p}
            rows.append(row)
            print(f"memory_bench: {grid} x {bins}: estimate {row['estimate_bytes'] / 2**20:.0f} MiB, "
                  f"precompute peak {peak / 2**20:.0f} MiB in {seconds:.1f} s", file=sys.stderr, flush=True)
    base = rows[0]["precompute"]["peak_bytes"]
    for r in rows:
        r["precompute"]["peak_over_smallest_case"] = r["precompute"]["peak_bytes"] / base
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    with open(a.out, "w") as f:
        json.dump({"cases": rows, "limit_bytes": 8 * 2**30}, f, indent=1)
    print(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
