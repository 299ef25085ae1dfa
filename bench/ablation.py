#!/usr/bin/python3
"""Each mechanism of the fit turned off in turn: what it is worth, medium by medium.

For each medium (the 15-media study of bench/model_accuracy.py by default: tau in
{1, 4.5, 10, 30, 100} x g in {-0.5, 0.3, 0.9}, albedo 0.95, healpix:16 x 45 alpha bins) one
table of 1e5 paths (seed 2) is fitted with hvmf:auto as it is, with each mechanism turned off
(`stf fit --ablate NAME`); every model is judged by its
joint TV against an independent reference (seed 1000) at the model's 45 alpha bins and at 90
(seed 1001): how the exit points spread inside a bin (tilts, turns, blends) is invisible at
the model's own bins, so the finer reference judges it. The raw tables of 1e5 and 3e6 paths
(seeds 2 and 3) are judged too, pooled with their mirror cells (the models are folded over the
mirror, so the fair raw baseline is folded as well; it halves a raw table's variance).

The seed spread: tau 1 g 0.9 is also fitted from --spread-seeds other tables (seeds 4..), full
and ablated, so each mechanism's change can be set against the standard deviation of the full
model's TV over seeds.

A mechanism earns its place where turning it off moves some medium's TV (at either resolution)
up by more than 2% and by more than the seed spread. The verdict per mechanism is in the JSON and the markdown table.

Writes OUT/ablation.json and prints a markdown table (TV per medium and variant; last rows: the
largest change each mechanism's removal makes and the verdict).
Usage: bench/ablation.py [--out DIR] [--media TAU:G,...] [--reference-paths 3e7]
                         [--spread-seeds 4] [--variants full,tilt,...] [--threads T]
Needs build/stf, h5py, numpy.
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
    def __init__(self, out, threads, variants):
        self.stf, self.out, self.threads, self.variants = Stf(), out, threads, variants

    def path(self, name):
        return os.path.join(self.out, name)

    def tv(self, candidate, reference):
        return self.stf.evaluate(candidate, reference, self.path("eval.json"))["joint_tv_distance"]

    def fits(self, table, references, tag):
        """TV of hvmf:auto as it is and of each ablation, against each reference."""
        row = {}
        variants = [("full", ["--model", "hvmf:auto"])]
        variants += [(name, ["--model", "hvmf:auto", "--ablate", name]) for name in ABLATIONS]
        for label, args in variants:
            if label not in self.variants:
                continue
            model = self.path(f"{tag}_model.h5")
            self.stf.fit(table, [*args, "--threads", self.threads], model)
            for suffix, reference in references.items():
                row[label + suffix] = self.tv(model, reference)
        return row

    def medium(self, tau, g, reference_paths):
        m, tag = medium(tau, g), f"tau{tau:g}_g{g:g}"
        table = lambda what: self.path(f"{tag}_{what}.h5")  # noqa: E731
        self.stf.precompute(m, reference_paths, 1000, table("reference"), GRID, BINS, self.threads)
        self.stf.precompute(m, reference_paths, 1001, table("fine"), GRID, 2 * BINS, self.threads)
        references = {"": table("reference"), " @90": table("fine")}
        row = {"tau": tau, "g": g}
        for label, paths, seed in (("raw 1e5", 1e5, 2), ("raw 3e6", 3e6, 3)):
            self.stf.precompute(m, paths, seed, table("raw"), GRID, BINS, self.threads)
            row[label] = self.tv(mirror_pooled(table("raw"), table("pooled")), table("reference"))
        self.stf.precompute(m, 1e5, 2, table("small"), GRID, BINS, self.threads)
        row.update(self.fits(table("small"), references, tag))
        return row

    def spread(self, seeds, reference_paths):
        """The tau 1 g 0.9 models of other seeds, full and ablated (their reference: the study's)."""
        m, tag = medium(1, 0.9), "tau1_g0.9"
        references = {"": self.path(f"{tag}_reference.h5"), " @90": self.path(f"{tag}_fine.h5")}
        for (suffix, reference), seed, bins in zip(references.items(), (1000, 1001), (BINS, 2 * BINS)):
            if not os.path.exists(reference):
                self.stf.precompute(m, reference_paths, seed, reference, GRID, bins, self.threads)
        rows = []
        for seed in range(4, 4 + seeds):
            self.stf.precompute(m, 1e5, seed, self.path("seed.h5"), GRID, BINS, self.threads)
            rows.append(self.fits(self.path("seed.h5"), references, "seed"))
        return rows


def verdicts(rows, spread_rows, variants):
    """Per mechanism: the largest relative rise of TV its removal makes on any medium at either
    resolution, and whether that rise exceeds 2% and the seed spread there."""
    out, sds = {}, {}
    for suffix in ("", " @90"):
        fulls = [r["full" + suffix] for r in spread_rows if "full" + suffix in r]
        sds[suffix] = statistics.stdev(fulls) if len(fulls) > 1 else 0.0
    for name in [v for v in ABLATIONS if v in variants]:
        rises = {(f"tau {r['tau']:g} g {r['g']:g}", suffix): (r[name + suffix] - r["full" + suffix]) / r["full" + suffix]
                 for r in rows for suffix in ("", " @90")}
        worst = max(rises, key=rises.get)
        medium_name, suffix = worst
        absolute = next(r[name + suffix] - r["full" + suffix] for r in rows
                        if f"tau {r['tau']:g} g {r['g']:g}" == medium_name)
        out[name] = {"largest_rise": rises[worst], "where": medium_name + (suffix or " @45"),
                     "largest_rise_absolute": absolute,
                     "earns_its_place": rises[worst] > 0.02 and absolute > sds[suffix]}
    return out, sds


def markdown(rows, verdict, sds, variants):
    names = [v for v in ["full"] + ABLATIONS if v in variants]
    cols = ["raw 1e5", "raw 3e6"] + [n + suffix for n in names for suffix in ("", " @90")]
    lines = ["| medium | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for r in rows:
        lines.append(f"| tau {r['tau']:g} g {r['g']:g} | " + " | ".join(f"{r[c]:.4f}" for c in cols) + " |")
    lines.append("\n| mechanism | largest rise without it | where | earns its place |\n|---|---|---|---|")
    for name, v in verdict.items():
        lines.append(f"| {name} | {v['largest_rise']:+.1%} | {v['where']} | {'yes' if v['earns_its_place'] else 'no'} |")
    lines.append(f"\nSeed spread of the full model at tau 1 g 0.9 (standard deviation): {sds[''] :.4f} at 45 bins, "
                 f"{sds[' @90']:.4f} at 90.")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out/ablation")
    ap.add_argument("--media", default="", help="TAU:G,... (default: the 15-media study)")
    ap.add_argument("--reference-paths", type=float, default=3e7)
    ap.add_argument("--spread-seeds", type=int, default=4)
    ap.add_argument("--threads", default="0")
    ap.add_argument("--variants", default=",".join(["full"] + ABLATIONS), help="full and the ablations to fit")
    a = ap.parse_args()
    variants = a.variants.split(",")
    media = [tuple(float(x) for x in item.split(":")) for item in a.media.split(",")] if a.media else STUDY
    os.makedirs(a.out, exist_ok=True)
    work = os.path.join(a.out, "work")
    os.makedirs(work, exist_ok=True)
    study = Study(work, a.threads, variants)
    rows = []
    for tau, g in media:
        rows.append(study.medium(tau, g, a.reference_paths))
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    spread_rows = study.spread(a.spread_seeds, a.reference_paths)
    verdict, sds = verdicts(rows, spread_rows, variants)
    result = {"reference_paths": a.reference_paths, "media": rows, "spread": spread_rows, "seed_sd": sds,
              "verdicts": verdict}
    with open(os.path.join(a.out, "ablation.json"), "w") as f:
        json.dump(result, f, indent=1)
    shutil.rmtree(work)
    print(markdown(rows, verdict, sds, variants))


if __name__ == "__main__":
    main()
