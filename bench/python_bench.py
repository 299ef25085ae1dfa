#!/usr/bin/python3
"""stf.Model.sample against the same draws in C++ (build/bench/draw_time), in turns, one run.

    PYTHONPATH=build/python /usr/bin/python3 bench/python_bench.py MODEL [--draws N] [--out FILE.json]

Reports the seconds of N draws from Python on one thread and on all cores, the C++ loop's
seconds for the same draws, and the ratio Python / C++ (one thread each), best of 5 turns.
"""
import argparse
import json
import os
import subprocess
import time

import numpy as np

import stf

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("--draws", type=float, default=1e6)
    ap.add_argument("--out")
    a = ap.parse_args()
    n = int(a.draws)
    model = stf.Model(a.model)
    best = {"python_1_thread": 1e9, "python_all_cores": 1e9, "cpp_1_thread": 1e9}
    for _ in range(5):
        for threads, key in ((1, "python_1_thread"), (0, "python_all_cores")):
            start = time.perf_counter()
            s = model.sample(n, seed=1, threads=threads)
            best[key] = min(best[key], time.perf_counter() - start)
        cpp = subprocess.run([os.path.join(ROOT, "build/bench/draw_time"), a.model, str(n), "1"],
                             check=True, capture_output=True, text=True)
        run = json.loads(cpp.stdout)
        assert run["check"] == s["pdf"][-1], "the C++ loop drew other samples"
        best["cpp_1_thread"] = min(best["cpp_1_thread"], run["seconds"])
    best["draws"] = n
    best["python_over_cpp"] = best["python_1_thread"] / best["cpp_1_thread"]
    text = json.dumps(best, indent=1)
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
