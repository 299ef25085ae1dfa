#!/usr/bin/python3
"""What a piecewise exit-point density inside an alpha bin costs.

A model holds one direction density per alpha bin and, within the bin, an exit point spread by
the bin's tilt (uniform in area, p(alpha) piecewise proportional to sin(alpha), before tilts).
For each medium this measures that structure alone, with no fitting involved: the escapes after
two or more collisions of a 90-bin table (models hold the uncollided and once-scattered escapes
exactly, with their exact exit points; here they are kept from the table's own tallies) are
pooled into 45 and 18 bins (summing groups of 2 and 5 bins) and spread back over the 90 bins by
area, as a perfectly fitted flat model of 45 or 18 bins would be, then compared (TV distance of the joint
(alpha bin, cell) distribution of escapes) with an independent 90-bin reference table:
  - `pooled_reference`: the reference pooled and spread back, against itself: the bias of the
    structure (what even an infinitely long table would lose);
  - `pooled_table`: the 1e7-path table pooled and spread back, against the reference; next to
    `raw_table`, the 1e7-path table itself at 90 bins: whether pooling costs more than it
    saves in noise;
  - `interpolated_reference`: the pooled reference spread back by a density linear in
    cos(alpha) between the pooled bins' centres instead of flat: what smoothing in alpha
    would recover;
  - `tilted_reference`: the pooled reference spread back by each pooled bin's tilt
    (stf/tilt.h: a density proportional to exp(tilt u) in the bin's area fraction u), fitted
    here by maximum likelihood to the reference's own sub-bin counts, as `stf fit` fits it;
    what remains is the directions' turning with the exit point inside a bin.
And with fitting: an hvmf:auto model of an independent 45-bin 1e7-path table against the
90-bin reference (`model_45`: as fitted, with tilts, densities that turn with the exit point
inside each bin and, where the held-out data chose it, blended bins; `model_45_blend` is the
blend width, 0 for none), the model fitted with `--ablate turn` (`model_45_still`: densities that
stand still inside each bin), that one without blending (`model_45_tilted`) and without tilts
either (`model_45_flat`: the model as stf built it before all three).

Writes OUT/alpha_bins.json and prints a table. Usage:
  docs/studies/scripts/alpha_bins.py [--out DIR] [--paths 1e7] [--reference-paths 3e7] [--grid healpix:16]
Needs build/stf and Debian's python3-h5py and python3-numpy.
"""
import argparse
import json
import os
import sys

import h5py
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402

MEDIA = [{"sigma_s": 0.95, "sigma_a": 0.05, "g": 0.3}, {"sigma_s": 4.275, "sigma_a": 0.225, "g": 0.3},
         {"sigma_s": 9.5, "sigma_a": 0.5, "g": 0.3}, {"sigma_s": 0.95, "sigma_a": 0.05, "g": 0.9},
         {"sigma_s": 4.275, "sigma_a": 0.225, "g": 0.9}]
BINS = 90


def joint(path):
    """Escapes per (alpha bin, cell) as probabilities, split into what a model fits (two or more
    collisions) and the singular parts it holds exactly (the uncollided delta and the
    once-scattered escapes), and the bins' areas and cos(alpha) edges."""
    with h5py.File(path, "r") as f:
        w = f["escape/weight"][()]
        edges = f["escape/alpha_edges"][()]
        pole = int(np.argmax(f["grid/direction"][()][:, 2]))
        singular = np.zeros_like(w)
        singular[0, pole] = float(f.attrs["uncollided_weight"])
        if "escape/once_half" in f:
            singular += f["escape/once_half"][()].sum(axis=0)
    total = w.sum()
    return (w - singular) / total, singular / total, np.cos(edges[:-1]) - np.cos(edges[1:]), np.cos(edges)


def pooled(p, singular, area, group):
    """p pooled into groups of `group` bins, spread back over them in proportion to area; the
    singular parts stay where they are."""
    bins, cells = p.shape
    sums = p.reshape(bins // group, group, cells).sum(axis=1)
    a = area.reshape(bins // group, group)
    share = (a / a.sum(axis=1, keepdims=True)).reshape(bins)
    return np.repeat(sums, group, axis=0) * share[:, None] + singular


def interpolated(p, singular, area, edges_cos, group):
    """p pooled as in pooled(), but spread back by the per-area density interpolated linearly
    in cos(alpha) between the pooled bins' centres (held flat beyond the outer centres), then
    renormalised: what a model smooth in alpha could reach."""
    bins, cells = p.shape
    sums = p.reshape(bins // group, group, cells).sum(axis=1)
    coarse_area = area.reshape(bins // group, group).sum(axis=1)
    density = sums / coarse_area[:, None]
    coarse_edges = edges_cos[::group]
    coarse_centres = 0.5 * (coarse_edges[:-1] + coarse_edges[1:])
    fine_centres = 0.5 * (edges_cos[:-1] + edges_cos[1:])
    # np.interp wants ascending abscissae; cos(alpha) descends with the bin index.
    fine = np.stack([np.interp(fine_centres[::-1], coarse_centres[::-1], density[::-1, c])[::-1]
                     for c in range(cells)], axis=1) * area[:, None]
    fine *= sums.sum() / fine.sum()
    return np.clip(fine, 0, None) + singular


def tilt_mass(t, u0, u1):
    if abs(t) < 1e-8:
        return u1 - u0
    return (np.expm1(t * u1) - np.expm1(t * u0)) / np.expm1(t)


def fit_tilt(edges, counts):
    """Maximum-likelihood tilt from counts in [edges[k], edges[k+1]] (golden section; the
    log-likelihood is concave)."""
    if counts.sum() <= 0:
        return 0.0
    def ll(t):
        return float((counts * np.log(np.maximum(tilt_mass(t, edges[:-1], edges[1:]), 1e-300))).sum())
    lo, hi, r = -40.0, 40.0, 0.6180339887498949
    a, b = hi - r * (hi - lo), lo + r * (hi - lo)
    fa, fb = ll(a), ll(b)
    while hi - lo > 1e-6:
        if fa < fb:
            lo, a, fa = a, b, fb
            b = lo + r * (hi - lo)
            fb = ll(b)
        else:
            hi, b, fb = b, a, fa
            a = hi - r * (hi - lo)
            fa = ll(a)
    return 0.5 * (lo + hi)


def sub_counts(path):
    with h5py.File(path, "r") as f:
        return f["escape/multiple_sub_half"][()].sum(axis=0)  # [bins, sub_bins]


def tilted(p, singular, area, subs, group):
    """p pooled as in pooled(), spread back by each pooled bin's tilt fitted to the sub-bin
    counts of its fine bins (their parts at their area fractions of the group)."""
    bins, cells = p.shape
    sums = p.reshape(bins // group, group, cells).sum(axis=1)
    out = np.empty_like(p)
    s = subs.shape[1]
    for j in range(bins // group):
        a = area[j * group:(j + 1) * group] / area[j * group:(j + 1) * group].sum()
        below = np.concatenate([[0.0], np.cumsum(a)])
        edges = np.concatenate([below[i] + a[i] * np.arange(s) / s for i in range(group)] + [[1.0]])
        t = fit_tilt(edges, subs[j * group:(j + 1) * group].reshape(-1))
        for i in range(group):
            out[j * group + i] = sums[j] * tilt_mass(t, below[i], min(1.0, below[i + 1]))
    return out + singular


def variant(model, path, tilts):
    """The model (fitted with --ablate turn) without blended bins and, unless `tilts`, without its
    tilts (uniform in area inside every bin)."""
    with open(model, "rb") as src, open(path, "wb") as dst:
        data = src.read()
        if data.startswith(b"stf-checksum "):  # an edited copy is a file stf did not write
            data = bytes(512) + data[512:]
        dst.write(data)
    with h5py.File(path, "r+") as f:
        f.attrs["alpha_blend"] = 0
        if not tilts and "alpha/tilt" in f:
            del f["alpha/tilt"]


def tv(p, q):
    return float(0.5 * np.abs(p - q).sum())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "alpha_bins"))
    ap.add_argument("--paths", type=float, default=1e7)
    ap.add_argument("--reference-paths", type=float, default=3e7)
    ap.add_argument("--grid", default="healpix:16")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    stf = Stf()
    rows = []
    print("| tau | g | raw table (90 bins) | pooled table 45 / 18 | pooled reference 45 / 18 | "
          "interpolated reference 45 / 18 | tilted reference 45 / 18 | "
          "45-bin model, flat / tilted / still / as fitted |")
    for i, m in enumerate(MEDIA):
        table, ref = os.path.join(a.out, f"m{i}_table.h5"), os.path.join(a.out, f"m{i}_reference.h5")
        stf.precompute(m, a.paths, 1, table, a.grid, BINS)
        stf.precompute(m, a.reference_paths, 2, ref, a.grid, BINS)
        p, dp, area, edges_cos = joint(table)
        r, dr, _, _ = joint(ref)
        subs = sub_counts(ref)
        full_r = r + dr
        row = {"medium": m, "tau": m["sigma_s"] + m["sigma_a"], "raw_table": tv(p + dp, full_r)}
        for group, bins in ((2, 45), (5, 18)):
            row[f"pooled_table_{bins}"] = tv(pooled(p, dp, area, group), full_r)
            row[f"pooled_reference_{bins}"] = tv(pooled(r, dr, area, group), full_r)
            row[f"interpolated_reference_{bins}"] = tv(interpolated(r, dr, area, edges_cos, group), full_r)
            row[f"tilted_reference_{bins}"] = tv(tilted(r, dr, area, subs, group), full_r)
        table45, model45 = os.path.join(a.out, f"m{i}_table45.h5"), os.path.join(a.out, f"m{i}_model45.h5")
        stf.precompute(m, a.paths, 3, table45, a.grid, BINS // 2)
        still45 = os.path.join(a.out, f"m{i}_model45_still.h5")
        stf.fit(table45, ["--model", "hvmf:auto"], model45)
        stf.fit(table45, ["--model", "hvmf:auto", "--ablate", "turn"], still45)
        scratch = os.path.join(a.out, "eval.json")
        row["model_45"] = stf.evaluate(model45, ref, scratch)["joint_tv_distance"]
        row["model_45_still"] = stf.evaluate(still45, ref, scratch)["joint_tv_distance"]
        with h5py.File(model45, "r") as f:
            row["model_45_blend"] = int(f.attrs["alpha_blend"])
        for name, tilts in (("flat", False), ("tilted", True)):
            other = os.path.join(a.out, f"m{i}_model45_{name}.h5")
            variant(still45, other, tilts)
            row[f"model_45_{name}"] = stf.evaluate(other, ref, scratch)["joint_tv_distance"]
        rows.append(row)
        print(f"| {row['tau']:g} | {m['g']:g} | {row['raw_table']:.4f} | {row['pooled_table_45']:.4f} / "
              f"{row['pooled_table_18']:.4f} | {row['pooled_reference_45']:.4f} / {row['pooled_reference_18']:.4f} | "
              f"{row['interpolated_reference_45']:.4f} / {row['interpolated_reference_18']:.4f} | "
              f"{row['tilted_reference_45']:.4f} / {row['tilted_reference_18']:.4f} | "
              f"{row['model_45_flat']:.4f} / {row['model_45_tilted']:.4f} / {row['model_45_still']:.4f} / "
              f"{row['model_45']:.4f}"
              f"{' (blend ' + str(row['model_45_blend']) + ')' if row['model_45_blend'] else ''} |")
    with open(os.path.join(a.out, "alpha_bins.json"), "w") as f:
        json.dump({"paths": a.paths, "reference_paths": a.reference_paths, "grid": a.grid, "media": rows}, f, indent=1)


if __name__ == "__main__":
    main()
