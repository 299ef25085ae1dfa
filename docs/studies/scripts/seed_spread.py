#!/usr/bin/python3
"""How much a model of a small table depends on which paths the table happened to get.

bench/model_accuracy.py judges each medium on one 1e5-path table (seed 2). Here one medium's
model is fitted to 1e5-path tables of several seeds and compared with the same independent
3e7-path reference (seed 1000), next to the raw tables of 1e5 and 3e6 paths (seed 3, the
"worth 30x" mark). Per seed: the joint TV of the (alpha bin, cell) exit distribution (`stf eval`),
and the TV of the alpha marginal of the escapes after two or more collisions alone (the share
that a model takes from its smoothed marginal, a raw table from its counts), with the fit's
seconds. Optionally the same fit with extra `stf fit` options (--variant), e.g. --ablate=alpha-smoothing.

Where the error sits: the mean of the seeds' models (their exit distributions averaged cell by
cell, `stf eval --cells`) keeps what the models share, their bias, and averages out all but a
1/n share of their noise; its TV against the reference bounds the bias from above. And every
TV is split by how dense the reference is in each cell: per alpha bin, its cells ranked by the
reference's density (per steradian) and cut where they hold 50% and 80% of the bin's mass, into
the peak, the shoulder and the tail.

Writes OUT/seed_spread.json and prints a markdown table. Usage:
  docs/studies/scripts/seed_spread.py [--tau 1] [--g 0.9] [--albedo 0.95] [--seeds 2,4,5,6,7]
                       [--model hvmf:auto] [--variant=--ablate=alpha-smoothing] [--out DIR]
Needs build/stf (or $STF_BINARY) and Debian's python3-h5py and python3-numpy.
"""
import argparse
import json
import math
import os
import statistics
import sys

import h5py
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402


def table_marginal(path):
    """Escapes after two or more collisions per alpha bin, per path launched."""
    with h5py.File(path, "r") as f:
        sub = f["escape/multiple_sub_half"][()].sum(axis=(0, 2))
        return sub / float(f.attrs["paths"])


def model_marginal(path, tau):
    """The same from a model: its rest (all but the once-scattered part) per bin, less the
    uncollided delta of bin 0."""
    with h5py.File(path, "r") as f:
        rest = float(f.attrs["escape_probability"]) * (1 - float(f.attrs["once_fraction"]))
        m = rest * f["alpha/probability"][()]
    m[0] -= math.exp(-tau)
    return m


def marginal_tv(m, reference):
    return 0.5 * float(np.abs(m - reference).sum())


def binned(path):
    """Joint (alpha bin, cell) probabilities per escape, as `stf eval --cells` wrote them."""
    with h5py.File(path, "r") as f:
        return f["escape/probability"][()]


def density_parts(reference_path):
    """Per alpha bin, the reference's cells as the peak, shoulder and tail (masks [3, bins, cells])."""
    with h5py.File(reference_path, "r") as f:
        weight = f["escape/weight"][()]
        solid_angle = f["grid/solid_angle"][()]
    parts = np.zeros((3,) + weight.shape, dtype=bool)
    for b in range(weight.shape[0]):
        if weight[b].sum() <= 0:
            parts[2, b] = True  # a bin the reference never reached: all tail
            continue
        order = np.argsort(-weight[b] / solid_angle, kind="stable")
        before = (np.cumsum(weight[b][order]) - weight[b][order]) / weight[b].sum()  # mass of denser cells
        for i, (lo, hi) in enumerate(((0, 0.5), (0.5, 0.8), (0.8, 2))):
            parts[i, b, order[(before >= lo) & (before < hi)]] = True
    return parts


def split_tv(p, q, parts):
    """Joint TV of p against q, whole and per part (peak, shoulder, tail)."""
    d = 0.5 * np.abs(p - q)
    return {"joint_tv": float(d.sum()), "peak": float(d[parts[0]].sum()), "shoulder": float(d[parts[1]].sum()),
            "tail": float(d[parts[2]].sum())}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tau", type=float, default=1)
    ap.add_argument("--g", type=float, default=0.9)
    ap.add_argument("--albedo", type=float, default=0.95)
    ap.add_argument("--seeds", default="2,4,5,6,7")
    ap.add_argument("--model", default="hvmf:auto")
    ap.add_argument("--variant", default="", help="extra stf fit options for a second model per seed")
    ap.add_argument("--grid", default="healpix:16")
    ap.add_argument("--alpha-bins", type=int, default=45)
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "seed_spread"))
    a = ap.parse_args()
    medium = {"sigma_s": a.albedo * a.tau, "sigma_a": (1 - a.albedo) * a.tau, "g": a.g}
    os.makedirs(a.out, exist_ok=True)
    stf = Stf()
    path = lambda what: os.path.join(a.out, what + ".h5")  # noqa: E731
    scratch = os.path.join(a.out, "eval.json")
    stf.precompute(medium, 3e7, 1000, path("reference"), a.grid, a.alpha_bins)
    reference = table_marginal(path("reference"))
    cells_path = path("cells")
    parts = density_parts(path("reference"))
    with h5py.File(path("reference"), "r") as f:
        reference_cells = f["escape/weight"][()]
    reference_cells /= reference_cells.sum()  # per escape, as eval normalises the reference
    stf.precompute(medium, 3e6, 3, path("worth"), a.grid, a.alpha_bins)
    worth = {"joint_tv": stf.evaluate(path("worth"), path("reference"), scratch, cells_path)["joint_tv_distance"],
             "marginal_tv": marginal_tv(table_marginal(path("worth")), reference),
             "split": split_tv(binned(cells_path), reference_cells, parts)}
    variants = {a.model: []}
    if a.variant:
        variants[a.model + " " + a.variant] = a.variant.split()
    rows, summed = [], {}
    for seed in [int(s) for s in a.seeds.split(",")]:
        stf.precompute(medium, 1e5, seed, path("small"), a.grid, a.alpha_bins)
        row = {"seed": seed, "raw": {"joint_tv": stf.evaluate(path("small"), path("reference"), scratch)["joint_tv_distance"],
                                     "marginal_tv": marginal_tv(table_marginal(path("small")), reference)}}
        for name, extra in variants.items():
            seconds, _ = stf.fit(path("small"), ["--model", a.model, *extra], path("model"))
            row[name] = {"joint_tv": stf.evaluate(path("model"), path("reference"), scratch, cells_path)["joint_tv_distance"],
                         "marginal_tv": marginal_tv(model_marginal(path("model"), a.tau), reference),
                         "fit_seconds": seconds}
            model_cells = binned(cells_path)
            row[name]["split"] = split_tv(model_cells, reference_cells, parts)
            summed[name] = summed.get(name, 0) + model_cells
        rows.append(row)
        print(f"seed_spread: seed {seed} done", file=sys.stderr, flush=True)
    for what in ("reference", "worth", "small", "model", "cells"):
        if os.path.exists(path(what)):
            os.remove(path(what))
    os.remove(scratch)
    means = {name: statistics.mean(r[name]["joint_tv"] for r in rows) for name in ["raw", *variants]}
    mean_model = {name: split_tv(total / len(rows), reference_cells, parts) for name, total in summed.items()}
    mean_split = {name: {k: statistics.mean(r[name]["split"][k] for r in rows) for k in worth["split"]}
                  for name in variants}
    with open(os.path.join(a.out, "seed_spread.json"), "w") as f:
        json.dump({"medium": medium, "tau": a.tau, "worth_3e6": worth, "seeds": rows, "mean_joint_tv": means,
                   "mean_split": mean_split, "mean_of_models": mean_model}, f, indent=1)
    names = list(variants)
    print(f"tau {a.tau:g} g {a.g:g}, albedo {a.albedo:g}: raw 3e6-path table {worth['joint_tv']:.4f} "
          f"(alpha marginal {worth['marginal_tv']:.4f})")
    print("| seed | raw 1e5: joint / marginal | " + " | ".join(f"{n}: joint / marginal / fit s" for n in names) + " |")
    print("|---" * (2 + len(names)) + "|")
    for r in rows:
        cells = [str(r["seed"]), f"{r['raw']['joint_tv']:.4f} / {r['raw']['marginal_tv']:.4f}"]
        cells += [f"{r[n]['joint_tv']:.4f} / {r[n]['marginal_tv']:.4f} / {r[n]['fit_seconds']:.1f}" for n in names]
        print("| " + " | ".join(cells) + " |")
    print("| mean | " + " | ".join(f"{means[n]:.4f}" for n in ["raw", *names]) + " |")
    print()
    print("Joint TV by the reference's density: whole / peak / shoulder / tail")
    print("| what | joint | peak (densest 50%) | shoulder (next 30%) | tail (last 20%) |")
    print("|---|---|---|---|---|")
    line = lambda what, t: print(f"| {what} | {t['joint_tv']:.4f} | {t['peak']:.4f} | {t['shoulder']:.4f} | {t['tail']:.4f} |")  # noqa: E731
    line("raw 3e6-path table", worth["split"])
    for n in names:
        line(f"{n}, mean over seeds", mean_split[n])
        line(f"{n}, the mean of the {len(rows)} models", mean_model[n])


if __name__ == "__main__":
    main()
