#!/usr/bin/python3
"""Exit-direction lobe families that draw in one go, against the hemispherical vMF lobe (hvmf)
that a stride must draw by rejection: how well each fits a table's alpha bins.

    /usr/bin/python3 docs/studies/scripts/lobe_families.py TABLE.h5 [MORE.h5] [--bins 2,7,...] [--lobes 1,2,3,4]
                                            [--out FILE.json]

Per alpha bin [a0, a1] of a table (stf precompute's, exit directions w per HEALPix cell, in the
frame where the exit point's normal is n(alpha) = (sin alpha, 0, cos alpha)), mixtures of K lobes
of each family are fitted to the even-numbered paths' escapes (/escape/weight_half[0]) by the
binned likelihood and scored on the odd-numbered ones (/escape/weight_half[1]):
  - hvmf: a vMF lobe times the bin's mean outward cosine O(w) = mean over alpha of
    max(0, w . n(alpha)), renormalised (stf's `hvmf`; a stride keeps a vMF draw with
    probability O(w): 1.25-2.2 tries a draw);
  - lifted: at exit angle alpha, w = (v + n) / |v + n| for v drawn from a vMF lobe over the whole
    sphere, the half-vector of v and the exit normal (v is n mirrored about w). Its density is
    4 (w . n) vMF(2 (w . n) w - n): the cosine fall-off at grazing of a hemispherical lobe, the
    Lambertian cos / pi at kappa 0, normalised by construction, and a draw is one vMF draw,
    an add and a normalisation;
  - folded: a vMF lobe folded at the exit point's tangent plane, vMF(w) + vMF(w mirrored in it)
    (one vMF draw, mirrored when inward; no fall-off at grazing).
The lifted and folded densities of a bin are averaged over 8 exit angles across it (each about
its own exit normal, the lobe itself fixed), as a stride would draw them at its exit point. No
family's lobes turn with the exit angle (stf's fits may turn them: every family alike here).

Scores per bin and K: the held-out log-likelihood per escape (higher is better) and the total
variation distance of the fitted cell probabilities to the held-out escapes less what a perfect
model would show against as many escapes (its expectation over 20 multinomial draws): the
lack of fit, comparable to the certificates' TV. The joint lack of fit weighs the bins scored by
their share of the escapes. Cells are integrated by their centres (HEALPix 16 cells are 3.7
degrees wide; every family alike), the fit is L-BFGS from 3 starts. Needs python3-scipy.
"""
import argparse
import json

import h5py
import numpy as np
from scipy.optimize import minimize

FAMILIES = ("hvmf", "lifted", "folded")
NODES = 8  # exit angles a bin's lifted and folded densities are averaged over


def log_vmf(kappa, c):
    """log of the vMF density per steradian at cosine c, stable for kappa -> 0 and large."""
    k = np.maximum(kappa, 1e-9)
    return np.log(k / (2 * np.pi * -np.expm1(-2 * k))) + k * (c - 1)


class Bin:
    """One alpha bin's cells, seen by each family: what its density needs at the cell centres."""

    def __init__(self, x, omega, a0, a1):
        self.x, self.omega = x, omega
        alphas = a0 + (np.arange(NODES) + 0.5) / NODES * (a1 - a0)
        normals = np.stack([np.sin(alphas), 0 * alphas, np.cos(alphas)], 1)
        self.outward = np.maximum(0, x @ normals.T).mean(1)  # hvmf's O(w)
        mid = 0.5 * (a0 + a1)
        self.nodes = []  # per exit angle: w . n, n mirrored about w, w mirrored in the tangent plane
        for n in normals:
            c = x @ n
            self.nodes.append((c, 2 * c[:, None] * x - n, x - 2 * c[:, None] * n))
        self.mid_normal = np.array([np.sin(mid), 0, np.cos(mid)])

    def density(self, family, mean, kappa):
        """One lobe's density per steradian at the cell centres (mean in the bin's middle frame)."""
        if family == "hvmf":
            d = np.exp(log_vmf(kappa, self.x @ mean)) * self.outward
            return d / max((d * self.omega).sum(), 1e-300)
        total = 0
        for c, mirrored_n, mirrored_w in self.nodes:
            if family == "lifted":
                total = total + 4 * np.maximum(c, 0) * np.exp(log_vmf(kappa, mirrored_n @ mean))
            else:
                total = total + (c > 0) * (np.exp(log_vmf(kappa, self.x @ mean)) + np.exp(log_vmf(kappa, mirrored_w @ mean)))
        return total / NODES

    def start_mean(self, family, cell):
        """Where a lobe should sit to peak at a cell: the lifted family's v is n mirrored about w."""
        w = self.x[cell]
        n = self.mid_normal
        return 2 * (w @ n) * w - n if family == "lifted" else w


def probabilities(params, family, b):
    k = len(params) // 5
    weights = np.exp(params[4 * k:] - params[4 * k:].max())
    weights /= weights.sum()
    p = 0
    for j in range(k):
        mean = params[4 * j:4 * j + 3] / np.linalg.norm(params[4 * j:4 * j + 3])
        p = p + weights[j] * b.density(family, mean, np.exp(np.clip(params[4 * j + 3], -20, 20)))
    p = p * b.omega
    return p / p.sum()


def log_likelihood(params, family, b, counts):
    return (counts * np.log(np.maximum(probabilities(params, family, b), 1e-300))).sum() / counts.sum()


def fit(family, k, b, counts, rng, starts=3):
    order = np.argsort(-counts)
    best = None
    for s in range(starts):
        x0 = []
        for j in range(k):
            cell = order[j * 7] if s == 0 else order[rng.integers(0, 40)]
            x0 += list(b.start_mean(family, cell)) + [np.log(rng.uniform(1, 20))]
        x0 = np.array(x0 + [0.0] * k)
        r = minimize(lambda p: -log_likelihood(p, family, b, counts), x0, method="L-BFGS-B",
                     options={"maxiter": 3000})
        if best is None or r.fun < best.fun:
            best = r
    return best.x


def lack_of_fit(p, counts, rng, draws=20):
    n = counts.sum()
    tv = 0.5 * np.abs(p - counts / n).sum()
    noise = np.mean([0.5 * np.abs(p - rng.multinomial(int(round(n)), p) / round(n)).sum() for _ in range(draws)])
    return tv - noise


def score_table(path, bins, lobes, rng):
    with h5py.File(path, "r") as f:
        half = f["escape/weight_half"][()]
        edges = f["escape/alpha_edges"][()]
        x, omega = f["grid/direction"][()], f["grid/solid_angle"][()]
        tau = float(f.attrs["tau"])
    share = half.sum(axis=(0, 2)) / half.sum()
    rows = []
    for bb in bins:
        b = Bin(x, omega, edges[bb], edges[bb + 1])
        row = {"tau": tau, "bin": bb, "alpha_degrees": float(np.degrees(0.5 * (edges[bb] + edges[bb + 1]))),
               "share": float(share[bb]), "escapes": float(half[:, bb].sum())}
        for family in FAMILIES:
            for k in lobes:
                params = fit(family, k, b, half[0, bb], rng)
                p = probabilities(params, family, b)
                row[f"{family}_{k}"] = {"heldout_log_likelihood": float(log_likelihood(params, family, b, half[1, bb])),
                                        "lack_of_fit_tv": float(lack_of_fit(p, half[1, bb], rng))}
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


def joint(rows, lobes):
    """Per table and family, the lack of fit weighted by the scored bins' shares of the escapes."""
    out = {}
    for tau in sorted({r["tau"] for r in rows}):
        mine = [r for r in rows if r["tau"] == tau]
        weight = sum(r["share"] for r in mine)
        out[f"{tau:g}"] = {f"{fam}_{k}": sum(r["share"] * r[f"{fam}_{k}"]["lack_of_fit_tv"] for r in mine) / weight
                           for fam in FAMILIES for k in lobes}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("tables", nargs="+")
    ap.add_argument("--bins", default="2,7,12,17,22,27,32,37,42")
    ap.add_argument("--lobes", default="1,2,3,4")
    ap.add_argument("--out", default="lobe_families.json")
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    bins, lobes = [int(b) for b in a.bins.split(",")], [int(k) for k in a.lobes.split(",")]
    rows = [r for path in a.tables for r in score_table(path, bins, lobes, rng)]
    result = {"bins": rows, "joint_lack_of_fit_tv": joint(rows, lobes)}
    with open(a.out, "w") as f:
        json.dump(result, f, indent=1)
    print(json.dumps(result["joint_lack_of_fit_tv"], indent=1))


if __name__ == "__main__":
    main()
