#!/usr/bin/python3
"""Precompute past one process: MPI efficiency, checkpoint overhead, and what a production
table would cost.

- ranks: the same run (tau 30, albedo 1, g 0) on 1 MPI rank and on 2 ranks of one thread
  each, and on one process of 1 and 2 threads, in the same session: speed-up and efficiency.
- checkpoints: the same run with --checkpoint-seconds 1 against checkpoints never due (the
  default of 30 s is rarer still, so its overhead is at most 1/30 of what 1 s costs).
- estimate: ns per collision measured at tau 100 on one thread, scaled to a tau 1000, g 0 table
  of 1e9 paths ((1 - g) tau^2 / 2 = 5e5 collisions per path) on 1, 64 and 1024 cores, assuming
  the measured per-core rate (the walk shares nothing between chunks).

Usage: bench/scaling_bench.py [--out FILE.json] [--paths N]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STF = os.path.join(ROOT, "build", "stf")
MEDIUM = ["precompute", "--sigma-s", "30", "--sigma-a", "0", "--g", "0", "--alpha-bins", "90", "--grid", "healpix:16", "--quiet"]


def timed(args, mpi_ranks=0):
    cmd = [STF, *args]
    if mpi_ranks:
        cmd = ["mpirun", "--oversubscribe", "-n", str(mpi_ranks)] + (["--allow-run-as-root"] if os.geteuid() == 0 else []) + cmd
    start = time.monotonic()
    subprocess.run(cmd, check=True)
    return time.monotonic() - start


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "scaling_bench.json"))
    ap.add_argument("--paths", default="3e6", help="paths of the timed run (tau 30: ~450 collisions each)")
    a = ap.parse_args()
    result = {}
    with tempfile.TemporaryDirectory() as work:
        table = os.path.join(work, "t.h5")
        run = MEDIUM + ["--paths", a.paths, "-o", table]
        one_thread = timed(run + ["--threads", "1"])
        two_threads = timed(run + ["--threads", "2"])
        ranks = {}
        for n in (1, 2):
            try:
                ranks[n] = timed(run + ["--threads", "1"], mpi_ranks=n)
            except (subprocess.CalledProcessError, FileNotFoundError):
                ranks = {}
                break
        result["processes"] = {"one_process_1_thread_s": one_thread, "one_process_2_threads_s": two_threads,
                               "threads_speedup": one_thread / two_threads}
        if ranks:
            result["mpi"] = {"ranks_1_s": ranks[1], "ranks_2_s": ranks[2], "speedup": ranks[1] / ranks[2],
                             "efficiency": ranks[1] / ranks[2] / 2}
        never = timed(run + ["--checkpoint-seconds", "1e9"])
        every_second = timed(run + ["--checkpoint-seconds", "1"])
        result["checkpoints"] = {"never_s": never, "every_1s_s": every_second,
                                 "overhead_every_1s": every_second / never - 1,
                                 "overhead_every_30s_bound": (every_second / never - 1) / 30}
        # ns per collision on one thread, deep in the diffusive regime.
        deep = os.path.join(work, "deep.h5")
        timed(["precompute", "--sigma-s", "100", "--sigma-a", "0", "--g", "0", "--paths", "2e4", "--threads", "1",
               "--quiet", "-o", deep])
        with h5py.File(deep, "r") as f:
            ns = 1e9 * float(f.attrs["runtime_s"]) / float(f.attrs["collisions"])
        collisions = 1e9 * 0.5 * 1000 ** 2
        result["estimate_tau1000_1e9_paths"] = {
            "ns_per_collision_one_core": ns, "collisions": collisions,
            "days_on": {str(c): collisions * ns * 1e-9 / c / 86400 for c in (1, 64, 1024)}}
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    with open(a.out, "w") as f:
        json.dump(result, f, indent=1)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
