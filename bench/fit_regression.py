#!/usr/bin/python3
"""What the fit's mechanisms buy on the media that showed it, against the study's figures.

Each case fits one 1e5-path table (seed 2) with the full pipeline and with mechanisms turned
off (`stf fit --ablate`), judges every model by `stf eval` against an independent reference,
and checks the ordering the mechanism was kept for. These are single-seed measurements: they
live here, not in ctest. The joint TVs are also compared with the figures of the run recorded
in bench/fit_regression_figures.json (docs/studies/2026-12-fit-regression.md): a model more
than --slack (default 10%) farther than its recorded figure is flagged.

  folding and pooling   tau 4.5 g 0.9, albedo 0.95, hvmf:auto without blends, against 3e6
                        paths: folded over the mirror closer than not, pooled closer again;
  pools bin by bin      tau 1 g 0.9: pooled (sloped and wide pools both chosen) within 0.8 of
                        every bin alone; blend widths by bin closer than the one width;
  turning bins          tau 1 g 0.9 against 1e7 paths at 90 alpha bins: turning within 0.8 of
                        standing still, and at the model's own 45 bins (another 1e7-path
                        table) no more than 5% farther. The rates of the first five bins lie
                        in 1.2..1.8 (the headings of a 3e7-path table turn at 1.66).

Writes OUT/fit_regression.json, prints one line per check, exits 1 when a check fails.
Usage: bench/fit_regression.py [--out DIR] [--slack 0.1] [--record]   Needs build/stf.
(--record writes the run's figures to bench/fit_regression_figures.json.)
"""
import argparse
import json
import os
import sys
import tempfile

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402

FIGURES = os.path.join(ROOT, "bench", "fit_regression_figures.json")
THIN = {"sigma_s": 0.95, "sigma_a": 0.05, "g": 0.9}      # tau 1, albedo 0.95
DENSER = {"sigma_s": 4.275, "sigma_a": 0.225, "g": 0.9}  # tau 4.5


class Case:
    def __init__(self, stf, work):
        self.stf, self.work, self.tv, self.reports, self.checks = stf, work, {}, {}, []

    def path(self, name):
        return os.path.join(self.work, name)

    def table(self, medium, paths, seed, name, bins=45):
        self.stf.precompute(medium, paths, seed, self.path(name), "healpix:16", bins)
        return self.path(name)

    def fit(self, label, table, args, references):
        model, report = self.path(label + ".h5"), self.path(label + ".json")
        self.stf.fit(table, ["--model", "hvmf:auto", "--report", report, *args], model)
        with open(report) as f:
            self.reports[label] = json.load(f)
        for ref_name, ref in references.items():
            e = self.stf.evaluate(model, ref, self.path("eval.json"))
            self.tv[f"{label} vs {ref_name}"] = e["joint_tv_distance"]
        return model

    def check(self, name, ok, detail):
        self.checks.append({"check": name, "ok": bool(ok), "detail": detail})


def folding_and_pooling(c):
    small = c.table(DENSER, 1e5, 2, "dense_small.h5")
    ref = {"3e6": c.table(DENSER, 3e6, 1000, "dense_ref.h5")}
    c.fit("plain", small, ["--ablate", "mirror,pooling,blend"], ref)
    c.fit("folded", small, ["--ablate", "pooling,blend"], ref)
    c.fit("pooled", small, ["--ablate", "blend"], ref)
    plain, folded, pooled = (c.tv[f"{k} vs 3e6"] for k in ("plain", "folded", "pooled"))
    c.check("folding brings tau 4.5 g 0.9 closer", folded < plain, f"{folded:.4f} < {plain:.4f}")
    c.check("pooling brings it closer again", pooled < folded, f"{pooled:.4f} < {folded:.4f}")
    c.check("pooling is chosen", c.reports["pooled"].get("neighbour_weight") == 0.5,
            f"neighbour_weight {c.reports['pooled'].get('neighbour_weight')}")


def pools_and_blends(c, small, references):
    c.fit("full", small, [], references)
    c.fit("alone", small, ["--ablate", "pooling"], references)
    c.fit("one width", small, ["--ablate", "blend-by-bin"], references)
    full, alone, one = (c.tv[f"{k} vs 90 bins"] for k in ("full", "alone", "one width"))
    c.check("pools bin by bin: within 0.8 of every bin alone", full < 0.8 * alone, f"{full:.4f} < 0.8 x {alone:.4f}")
    bins = c.reports["full"]["per_alpha"]
    sloped = sum(1 for b in bins if b.get("pool_sloped"))
    wide = sum(1 for b in bins if not b.get("pool_sloped") and b.get("pool_width", 0) > 1)
    c.check("sloped and wide pools both chosen", sloped > 0 and wide > 0, f"{sloped} sloped, {wide} wide")
    r = c.reports["full"]
    widths = r.get("alpha_blend_width", [])
    c.check("blend widths by bin, narrow near the axis", len(widths) == 45 and widths[0] < widths[20],
            f"widths {widths[:3]}..{widths[20:23]}")
    c.check("widths by bin closer than one width", full < one, f"{full:.4f} < {one:.4f}")


def turning(c, small, references):
    c.fit("still", small, ["--ablate", "turn"], references)
    turning_fine, still_fine = c.tv["full vs 90 bins"], c.tv["still vs 90 bins"]
    turning_own, still_own = c.tv["full vs 45 bins"], c.tv["still vs 45 bins"]
    c.check("turning bins hold at finer alpha", turning_fine < 0.8 * still_fine,
            f"{turning_fine:.4f} < 0.8 x {still_fine:.4f}")
    c.check("and no farther at their own", turning_own < 1.05 * still_own, f"{turning_own:.4f} < 1.05 x {still_own:.4f}")
    with h5py.File(c.path("full.h5")) as f:
        rates = f["alpha/turn"][:5].tolist()
    c.check("first five rates in 1.2..1.8", all(1.2 < x < 1.8 for x in rates), " ".join(f"{x:.2f}" for x in rates))


def compare_with_figures(c, slack):
    if not os.path.exists(FIGURES):
        return
    with open(FIGURES) as f:
        recorded = json.load(f)["joint_tv"]
    for key, tv in c.tv.items():
        if key in recorded:
            c.check(f"{key} within {slack:.0%} of its figure", tv <= (1 + slack) * recorded[key],
                    f"{tv:.4f} against {recorded[key]:.4f}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out/fit_regression")
    ap.add_argument("--slack", type=float, default=0.1)
    ap.add_argument("--record", action="store_true")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    with tempfile.TemporaryDirectory() as work:
        c = Case(Stf(), work)
        folding_and_pooling(c)
        small = c.table(THIN, 1e5, 2, "thin_small.h5")
        references = {"90 bins": c.table(THIN, 1e7, 1000, "thin_90.h5", bins=90),
                      "45 bins": c.table(THIN, 1e7, 1001, "thin_45.h5")}
        pools_and_blends(c, small, references)
        turning(c, small, references)
        compare_with_figures(c, a.slack)
    result = {"joint_tv": c.tv, "checks": c.checks}
    with open(os.path.join(a.out, "fit_regression.json"), "w") as f:
        json.dump(result, f, indent=1)
    if a.record:
        with open(FIGURES, "w") as f:
            json.dump({"joint_tv": c.tv}, f, indent=1)
            f.write("\n")
    for check in c.checks:
        print(("ok   " if check["ok"] else "FAIL ") + check["check"] + ": " + check["detail"])
    sys.exit(0 if all(check["ok"] for check in c.checks) else 1)


if __name__ == "__main__":
    main()
