#!/usr/bin/python3
"""Each mechanism of the fit turned off in turn: what it is worth, medium by medium.

For each medium (the 15-media study of bench/model_accuracy.py by default: tau in
{1, 4.5, 10, 30, 100} x g in {-0.5, 0.3, 0.9}, albedo 0.95, healpix:16 x 45 alpha bins) one
table of 1e5 paths (seed 2) is fitted with hvmf:auto as it is, with each mechanism turned off
(`stf fit --ablate NAME`), and with the family choice of `auto`; every model is judged by its
joint TV against an independent reference (seed 1000). The raw tables of 1e5 and 3e6 paths
(seeds 2 and 3) are judged too, pooled with their mirror cells (the models are folded over the
mirror, so the fair raw baseline is folded as well; it halves a raw table's variance).

The seed spread: tau 1 g 0.9 is also fitted from --spread-seeds other tables (seeds 4..), full
and ablated, so each mechanism's change can be set against the standard deviation of the full
model's TV over seeds.

A mechanism earns its place where turning it off moves some medium's TV up by more than 2% and
by more than the seed spread. The verdict per mechanism is in the JSON and the markdown table.

Writes OUT/ablation.json and prints a markdown table (TV per medium and variant; last rows: the
largest change each mechanism's removal makes and the verdict).
Usage: bench/ablation.py [--out DIR] [--media TAU:G,...] [--reference-paths 3e7]
                         [--spread-seeds 4] [--threads T]       Needs build/stf, h5py, numpy.
"""
import argparse
import json
import os
import shutil
import statistics
import sys

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402

ABLATIONS = ["mirror", "pooling", "wide-pools", "alpha-smoothing", "tilt", "turn", "blend", "blend-by-bin"]
STUDY = [(tau, g) for tau in (1, 4.5, 10, 30, 100) for g in (-0.5, 0.3, 0.9)]
ALBEDO = 0.95
GRID, BINS = "healpix:16", 45


def medium(tau, g):
    return {"sigma_s": ALBEDO * tau, "sigma_a": (1 - ALBEDO) * tau, "g": g}


def mirror_pooled(path, out):
    """A copy of a raw table with every cell's weight averaged with its mirror image's (y -> -y),
    in both halves, as the fit folds its escapes: all but the uncollided ones, a delta on the
    axis that stays in its cell. The tallies that do not take part in `stf eval` are left out."""
    with h5py.File(path) as f:
        d = f["grid/direction"][()]
        image = np.argmax(d @ (d * [1, -1, 1]).T, axis=1)
        halves = f["escape/weight_half"][()]
        uncollided = f["escape/uncollided_half"][()] if "escape/uncollided_half" in f else np.zeros(2)
        top = np.flatnonzero(d[:, 2] == d[:, 2].max())
        pole = top[np.argmax(halves[:, 0, top].sum(axis=0))]  # the cell the axis fell in
        halves[:, 0, pole] -= uncollided
        pooled = 0.5 * (halves + halves[:, :, image])
        pooled[:, 0, pole] += uncollided
        attrs = dict(f.attrs)
        edges, omega = f["escape/alpha_edges"][()], f["grid/solid_angle"][()]
    with h5py.File(out, "w") as g:
        for k, v in attrs.items():
            g.attrs[k] = v
        g["escape/weight"] = pooled.sum(axis=0)
        g["escape/weight_half"] = pooled
        g["escape/alpha_edges"] = edges
        g["grid/direction"] = d
        g["grid/solid_angle"] = omega
    return out


class Study:
    def __init__(self, out, threads):
        self.stf, self.out, self.threads = Stf(), out, threads

    def path(self, name):
        return os.path.join(self.out, name)

    def tv(self, candidate, reference):
        return self.stf.evaluate(candidate, reference, self.path("eval.json"))["joint_tv_distance"]

    def fits(self, table, reference, tag):
        """TV of hvmf:auto as it is, of each ablation, and of auto."""
        row = {}
        variants = [("full", ["--model", "hvmf:auto"]), ("auto", ["--model", "auto"])]
        variants += [(name, ["--model", "hvmf:auto", "--ablate", name]) for name in ABLATIONS]
        for label, args in variants:
            model = self.path(f"{tag}_model.h5")
            self.stf.fit(table, [*args, "--threads", self.threads], model)
            row[label] = self.tv(model, reference)
        return row

    def medium(self, tau, g, reference_paths):
        m, tag = medium(tau, g), f"tau{tau:g}_g{g:g}"
        table = lambda what: self.path(f"{tag}_{what}.h5")  # noqa: E731
        self.stf.precompute(m, reference_paths, 1000, table("reference"), GRID, BINS, self.threads)
        row = {"tau": tau, "g": g}
        for label, paths, seed in (("raw 1e5", 1e5, 2), ("raw 3e6", 3e6, 3)):
            self.stf.precompute(m, paths, seed, table("raw"), GRID, BINS, self.threads)
            row[label] = self.tv(mirror_pooled(table("raw"), table("pooled")), table("reference"))
        self.stf.precompute(m, 1e5, 2, table("small"), GRID, BINS, self.threads)
        row.update(self.fits(table("small"), table("reference"), tag))
        return row

    def spread(self, seeds, reference_paths):
        """The tau 1 g 0.9 models of other seeds, full and ablated (their reference: the study's)."""
        m, tag = medium(1, 0.9), "tau1_g0.9"
        reference = self.path(f"{tag}_reference.h5")
        if not os.path.exists(reference):
            self.stf.precompute(m, reference_paths, 1000, reference, GRID, BINS, self.threads)
        rows = []
        for seed in range(4, 4 + seeds):
            self.stf.precompute(m, 1e5, seed, self.path("seed.h5"), GRID, BINS, self.threads)
            rows.append(self.fits(self.path("seed.h5"), reference, "seed"))
        return rows


def verdicts(rows, spread_rows):
    """Per mechanism: the largest relative rise of TV its removal makes on any medium, and
    whether that rise exceeds 2% and the seed spread."""
    fulls = [r["full"] for r in spread_rows]
    sd = statistics.stdev(fulls) if len(fulls) > 1 else 0.0
    out = {}
    for name in ABLATIONS + ["auto"]:
        rises = {f"tau {r['tau']:g} g {r['g']:g}": (r[name] - r["full"]) / r["full"] for r in rows}
        worst = max(rises, key=rises.get)
        absolute = max(r[name] - r["full"] for r in rows)
        out[name] = {"largest_rise": rises[worst], "where": worst, "largest_rise_absolute": absolute,
                     "earns_its_place": rises[worst] > 0.02 and absolute > sd}
    return out, sd


def markdown(rows, verdict, sd):
    cols = ["raw 1e5", "raw 3e6", "full", "auto"] + ABLATIONS
    lines = ["| medium | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for r in rows:
        lines.append(f"| tau {r['tau']:g} g {r['g']:g} | " + " | ".join(f"{r[c]:.4f}" for c in cols) + " |")
    lines.append("| largest rise | | | | " + " | ".join(f"{verdict[c]['largest_rise']:+.1%}" for c in ["auto"] + ABLATIONS) + " |")
    lines.append("| earns its place | | | | " + " | ".join("yes" if verdict[c]["earns_its_place"] else "no"
                                                        for c in ["auto"] + ABLATIONS) + " |")
    lines.append(f"\nSeed spread of the full model at tau 1 g 0.9: standard deviation {sd:.4f}.")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out/ablation")
    ap.add_argument("--media", default="", help="TAU:G,... (default: the 15-media study)")
    ap.add_argument("--reference-paths", type=float, default=3e7)
    ap.add_argument("--spread-seeds", type=int, default=4)
    ap.add_argument("--threads", default="0")
    a = ap.parse_args()
    media = [tuple(float(x) for x in item.split(":")) for item in a.media.split(",")] if a.media else STUDY
    os.makedirs(a.out, exist_ok=True)
    work = os.path.join(a.out, "work")
    os.makedirs(work, exist_ok=True)
    study = Study(work, a.threads)
    rows = []
    for tau, g in media:
        rows.append(study.medium(tau, g, a.reference_paths))
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    spread_rows = study.spread(a.spread_seeds, a.reference_paths)
    verdict, sd = verdicts(rows, spread_rows)
    result = {"reference_paths": a.reference_paths, "media": rows, "spread": spread_rows, "seed_sd": sd,
              "verdicts": verdict}
    with open(os.path.join(a.out, "ablation.json"), "w") as f:
        json.dump(result, f, indent=1)
    shutil.rmtree(work)
    print(markdown(rows, verdict, sd))


if __name__ == "__main__":
    main()
