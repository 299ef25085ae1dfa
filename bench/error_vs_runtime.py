#!/usr/bin/python3
"""Error against run time: raw tables vs fitted models (the fitter's headline claim).

For each medium: precompute tables at 1e4 .. 1e7 paths and a large reference, fit vMF and SH
models of several sizes to each table, and measure the total variation distance of every raw
table and every model to the reference (`stf eval`). Writes OUT/error_vs_runtime.json and
OUT/error_vs_runtime.png: TV against seconds (precompute, or precompute + fit).

The claim measured: a fitted model reaches the error of a raw table that took 100x the
precompute time, at under 1% of its bytes. Precompute time is linear in paths (the thesis's
Fig. 4.6; small runs here are dominated by fixed start-up costs), so for every model the JSON
gives the paths a raw table needs for the same TV, from a power-law fit of the raw curve
(TV ~ a paths^b, b ~ -1/2 while noise dominates), divided by the paths of the model's own
table: the precompute time ratio.

Usage: bench/error_vs_runtime.py [--out DIR] [--reference-paths N] [--quick]
Needs build/stf and Debian's python3-matplotlib.
"""
import argparse
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf, power_law  # noqa: E402

MEDIA = [
    {"name": "dense forward (sigma_s 10, g 0.5)", "sigma_s": 10, "sigma_a": 0, "g": 0.5},
    {"name": "absorbing backward (sigma_s 2, sigma_a 0.5, g -0.3)", "sigma_s": 2, "sigma_a": 0.5, "g": -0.3},
]
# (label, stf fit arguments): vMF lobes, smoothed SH, and SH compressed across alpha.
MODELS = [("vmf:1", ["--model", "vmf:1"]), ("vmf:4", ["--model", "vmf:4"]), ("sh:8", ["--model", "sh:8"]),
          ("sh:16", ["--model", "sh:16"]), ("sh:16 cheb8", ["--model", "sh:16", "--alpha-degree", "8"])]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "error_vs_runtime"))
    ap.add_argument("--reference-paths", type=float, default=1e8)
    ap.add_argument("--quick", action="store_true", help="1e4..1e6 paths, 1e7 reference, 18 alpha bins")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    stf = Stf()
    grid, bins = "healpix:16", 90
    path_counts = [1e4, 1e5, 1e6, 1e7]
    if a.quick:
        path_counts, a.reference_paths, bins = [1e4, 1e5, 1e6], 1e7, 18
    results = {"grid": grid, "alpha_bins": bins, "reference_paths": a.reference_paths, "media": []}
    fig, axes = plt.subplots(1, len(MEDIA), figsize=(7 * len(MEDIA), 5), squeeze=False)
    for mi, medium in enumerate(MEDIA):
        tag = f"m{mi}"
        ref = os.path.join(a.out, f"{tag}_reference.h5")
        print(f"{medium['name']}: reference {a.reference_paths:.0e} paths", file=sys.stderr)
        ref_seconds = stf.precompute(medium, int(a.reference_paths), 999, ref, grid, bins)
        entry = {"medium": medium, "reference_seconds": ref_seconds, "raw": [], "models": []}
        for paths in path_counts:
            table = os.path.join(a.out, f"{tag}_{int(paths)}.h5")
            seconds = stf.precompute(medium, int(paths), 1, table, grid, bins)
            e = stf.evaluate(table, ref, os.path.join(a.out, "eval.json"))
            entry["raw"].append({"paths": paths, "seconds": seconds, "tv": e["tv_distance"],
                                 "bytes": e["table_bytes"]})
            print(f"  {paths:.0e} paths: raw tv {e['tv_distance']:.4f} ({seconds:.2f} s)", file=sys.stderr)
            for spec, fit_args in MODELS:
                model = os.path.join(a.out, f"{tag}_{int(paths)}_{spec.replace(':', '').replace(' ', '_')}.h5")
                fit_seconds, _ = stf.fit(table, fit_args, model)
                m = stf.evaluate(model, ref, os.path.join(a.out, "eval.json"))
                entry["models"].append({"model": spec, "paths": paths, "precompute_seconds": seconds,
                                        "fit_seconds": fit_seconds, "tv": m["tv_distance"],
                                        "bytes": m["model_bytes"], "table_bytes": m["table_bytes"]})
                print(f"    {spec}: tv {m['tv_distance']:.4f}, fit {fit_seconds:.2f} s, {m['model_bytes']} bytes",
                      file=sys.stderr)
        coeff, slope = power_law([(r["paths"], r["tv"]) for r in entry["raw"]])
        seconds_per_path = entry["raw"][-1]["seconds"] / entry["raw"][-1]["paths"]
        entry["raw_power_law"] = {"a": coeff, "b": slope, "seconds_per_path": seconds_per_path}
        for m in entry["models"]:
            # Paths (so precompute time) a raw table needs for the model's TV, over the model's own.
            needed = (m["tv"] / coeff) ** (1 / slope)
            m["raw_paths_for_same_tv"] = needed
            m["raw_seconds_for_same_tv"] = needed * seconds_per_path
            m["precompute_time_ratio"] = needed / m["paths"]
            m["bytes_fraction"] = m["bytes"] / m["table_bytes"]
        best = max(entry["models"], key=lambda m: m["precompute_time_ratio"])
        entry["headline"] = {"model": best["model"], "paths": best["paths"],
                             "precompute_time_ratio": best["precompute_time_ratio"],
                             "bytes_fraction": best["bytes_fraction"], "tv": best["tv"]}
        results["media"].append(entry)

        ax = axes[0][mi]
        ax.loglog([r["seconds"] for r in entry["raw"]], [r["tv"] for r in entry["raw"]], "k-o", label="raw table")
        for spec, _ in MODELS:
            pts = [m for m in entry["models"] if m["model"] == spec]
            ax.loglog([m["precompute_seconds"] + m["fit_seconds"] for m in pts], [m["tv"] for m in pts], "-s",
                      label=f"{spec} ({pts[-1]['bytes']} B)")
        ax.set_xlabel("precompute (+ fit) seconds")
        ax.set_ylabel("TV distance to reference")
        ax.set_title(medium["name"], fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "error_vs_runtime.png"), dpi=100)
    with open(os.path.join(a.out, "error_vs_runtime.json"), "w") as f:
        json.dump(results, f, indent=1)
    for entry in results["media"]:
        h = entry["headline"]
        print(f"{entry['medium']['name']}: {h['model']} from {h['paths']:.0e} paths matches a raw table "
              f"{h['precompute_time_ratio']:.0f}x its precompute time, at {100 * h['bytes_fraction']:.2f}% of the bytes")


if __name__ == "__main__":
    main()
