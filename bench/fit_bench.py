#!/usr/bin/python3
"""Fit seconds per table: 90 alpha bins on csc:45 and healpix:16 (sigma_s 10, g 0.5, 1e6 paths),
models vmf:1/4/8, sh:8/16 and hvmf:auto (the whole pipeline, what `stf fit` does by default),
on one thread and on all cores, as JSON (stdout and --out).
With --baseline BINARY (another build of stf) each fit is also run with it, in turns with
build/stf, and the ratio baseline / build/stf of their seconds is reported: the machine's noise
falls on both alike. With --repeat N each fit runs N times (in turns) and the fastest counts.

Usage: bench/fit_bench.py [--out FILE] [--paths N] [--models A,B] [--grids A,B] [--baseline BINARY] [--repeat N]
Needs build/stf.
"""
import argparse
import json
import os
import subprocess
import tempfile

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STF = os.path.join(ROOT, "build", "stf")


def fit_seconds(binary, table, spec, threads, tmp):
    """The fit's own seconds (the model's fit_time_s) and the model's packed bytes."""
    model = os.path.join(tmp, "model.h5")
    subprocess.run([binary, "fit", table, "--model", spec, "--threads", str(threads), "--quiet", "-o", model],
                   check=True)
    with h5py.File(model, "r") as f:
        return round(float(f.attrs["fit_time_s"]), 3), int(f.attrs["model_bytes"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="")
    ap.add_argument("--paths", default="1e6")
    ap.add_argument("--models", default="vmf:1,vmf:4,vmf:8,sh:8,sh:16,hvmf:auto")
    ap.add_argument("--grids", default="csc:45,healpix:16")
    ap.add_argument("--baseline", default="", help="another stf binary to time in turns with build/stf")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each fit (in turns with the baseline); the fastest counts")
    a = ap.parse_args()
    cores = os.cpu_count()
    results = {"paths": a.paths, "alpha_bins": 90, "cores": cores, "fits": []}
    with tempfile.TemporaryDirectory() as tmp:
        for grid in a.grids.split(","):
            table = os.path.join(tmp, "table.h5")
            subprocess.run([STF, "precompute", "--sigma-s", "10", "--sigma-a", "0", "--g", "0.5", "--grid", grid,
                            "--alpha-bins", "90", "--paths", a.paths, "--quiet", "-o", table], check=True)
            for spec in a.models.split(","):
                row = {"grid": grid, "model": spec}
                for threads in [1, cores]:
                    builds = [("", STF)] + ([("baseline_", a.baseline)] if a.baseline else [])
                    for label, binary in builds * a.repeat:  # in turns: both builds see the same noise
                        seconds, size = fit_seconds(binary, table, spec, threads, tmp)
                        key = f"{label}seconds_{threads}_threads"
                        row[key] = min(row.get(key, seconds), seconds)
                        row[f"{label}model_bytes"] = size
                    if a.baseline:
                        row[f"speedup_{threads}_threads"] = round(
                            row[f"baseline_seconds_{threads}_threads"] / row[f"seconds_{threads}_threads"], 2)
                results["fits"].append(row)
                print(json.dumps(row), flush=True)
    text = json.dumps(results, indent=1)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)
    print(text)


if __name__ == "__main__":
    main()
