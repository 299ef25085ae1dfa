#!/usr/bin/python3
"""`stf report`: error against run time for a scene's media, model bytes against error, and the
thesis's run-time studies (its Fig. 4.6-4.8, Tables 4.1-4.2), as PNG plots, report.json and a
short report.md in one folder.

Usage: report.py --stf BIN --media MEDIA.json --out DIR [--full]
MEDIA.json: [{"name": ..., "sigma_s": ..., "sigma_a": ..., "g": ...}, ...] for unit-radius
tables (sigma_s + sigma_a = tau); a name may be empty (a pack entry without one). Each medium is
headed by its name, if any, and its tau, albedo and g (heading()). The default budget takes a minute or two; --full uses the
sizes of bench/error_vs_runtime.py (1e4..1e7 paths, 1e8 reference, 90 alpha bins).
"""
import argparse
import json
import math
import os
import sys
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stf_runs import Stf, power_law  # noqa: E402

MODELS = [("vmf:1", ["--model", "vmf:1"]), ("vmf:4", ["--model", "vmf:4"]), ("hvmf:4", ["--model", "hvmf:4"]),
          ("sh:8", ["--model", "sh:8"]),
          ("sh:16 cheb8", ["--model", "sh:16", "--alpha-degree", "8"])]


def heading(medium):
    """A medium's heading: "NAME: tau T, albedo A, g G", or without a name "tau T, albedo A, g G"."""
    tau = medium["sigma_s"] + medium["sigma_a"]
    params = f"tau {tau:.4g}, albedo {medium['sigma_s'] / tau:.4g}, g {medium['g']:.4g}"
    name = str(medium.get("name") or "").strip()
    return f"{name}: {params}" if name else params


def positive(xs, ys):
    """The points a log-log plot can show (both coordinates finite and > 0): a zero would be
    clipped to the axes' edge and draw its segment out of them."""
    kept = [(x, y) for x, y in zip(xs, ys) if math.isfinite(x) and math.isfinite(y) and x > 0 and y > 0]
    return [x for x, _ in kept], [y for _, y in kept]


def log_limits(values, pad=1.25):
    """Log-axis limits that hold every value, a factor `pad` beyond the extremes."""
    values = [v for v in values if math.isfinite(v) and v > 0]
    if not values:
        return None
    return min(values) / pad, max(values) * pad


def error_study(stf, media, out, budget):
    grid, bins = budget["grid"], budget["alpha_bins"]
    results = []
    for mi, medium in enumerate(media):
        ref = os.path.join(out, f"m{mi}_reference.h5")
        stf.precompute(medium, budget["reference"], 999, ref, grid, bins)
        entry = {"medium": medium, "raw": [], "models": []}
        for paths in budget["paths"]:
            table = os.path.join(out, f"m{mi}_{int(paths)}.h5")
            seconds = stf.precompute(medium, paths, 1, table, grid, bins)
            e = stf.evaluate(table, ref, os.path.join(out, "eval.json"))
            entry["raw"].append({"paths": paths, "seconds": seconds, "tv": e["tv_distance"], "bytes": e["table_bytes"]})
            for label, args in MODELS:
                model = os.path.join(out, f"m{mi}_{int(paths)}_{label.replace(':', '').replace(' ', '_')}.h5")
                fit_seconds, nbytes = stf.fit(table, args, model)
                m = stf.evaluate(model, ref, os.path.join(out, "eval.json"))
                entry["models"].append({"model": label, "paths": paths, "precompute_seconds": seconds,
                                        "fit_seconds": fit_seconds, "tv": m["tv_distance"], "bytes": nbytes})
            print(f"report: {heading(medium)}: {paths:.0e} paths done", file=sys.stderr)
        results.append(entry)
    for f in os.listdir(out):  # the tables and models were means, not results
        if f.endswith(".h5") or f == "eval.json":
            os.remove(os.path.join(out, f))
    return results


def plot_errors(results, out):
    """error_vs_runtime.png and bytes_vs_error.png, one panel per medium; each axis' limits are set
    from every curve's points (so no curve leaves its axes), the legend beside the axes."""
    for name, xlabel, x_of in (("error_vs_runtime.png", "precompute (+ fit) seconds",
                                (lambda r: r["seconds"], lambda m: m["precompute_seconds"] + m["fit_seconds"])),
                               ("bytes_vs_error.png", "bytes", (lambda r: r["bytes"], lambda m: m["bytes"]))):
        fig, axes = plt.subplots(1, len(results), figsize=(7.5 * len(results), 4.5), squeeze=False)
        line = "-" if name == "error_vs_runtime.png" else ""
        for ax, entry in zip(axes[0], results):
            curves = [("raw table", "k" + line + "o", [x_of[0](r) for r in entry["raw"]], [r["tv"] for r in entry["raw"]])]
            for label, _ in MODELS:
                pts = [m for m in entry["models"] if m["model"] == label]
                curves.append((label, line + "s", [x_of[1](m) for m in pts], [m["tv"] for m in pts]))
            xs, ys = [], []
            for label, style, x, y in curves:
                x, y = positive(x, y)
                ax.loglog(x, y, style, label=label)
                xs += x
                ys += y
            if log_limits(xs):
                ax.set_xlim(*log_limits(xs))
                ax.set_ylim(*log_limits(ys))
            ax.set_xlabel(xlabel)
            ax.set_ylabel("TV distance to reference")
            ax.set_title("\n".join(textwrap.wrap(heading(entry["medium"]), 60)), fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
        fig.tight_layout()
        fig.savefig(os.path.join(out, name), dpi=100)
        plt.close(fig)


def runtime_studies(stf, out, budget):
    """The thesis's run-time studies: seconds against paths, sigma_s and g (one thread)."""
    tmp = os.path.join(out, "runtime.h5")
    walk = lambda s, g, p: stf.precompute({"sigma_s": s, "sigma_a": 0, "g": g}, p, 1, tmp, "healpix:4", 18, 1)
    studies = {"paths": [], "sigma_s": [], "g": []}
    for p in budget["runtime_paths"]:
        studies["paths"].append({"paths": p, "seconds": walk(10, 0.0, p)})
    for g in (-0.5, 0.0, 0.5):
        for s in (1, 2, 4, 8, 16, 32):
            studies["sigma_s"].append({"sigma_s": s, "g": g, "seconds": walk(s, g, budget["sigma_paths"])})
    for g in (-0.9, -0.6, -0.3, 0.0, 0.3, 0.6, 0.9):
        studies["g"].append({"g": g, "seconds": walk(8, g, budget["g_paths"])})
    os.remove(tmp)
    a, b = power_law([(r["paths"], r["seconds"]) for r in studies["paths"]])
    studies["paths_exponent"] = b
    studies["sigma_s_exponent"] = {}
    for g in (-0.5, 0.0, 0.5):
        pts = [(r["sigma_s"], r["seconds"]) for r in studies["sigma_s"] if r["g"] == g and r["sigma_s"] >= 4]
        studies["sigma_s_exponent"][str(g)] = power_law(pts)[1]

    fig, ax = plt.subplots(1, 3, figsize=(16, 4.2))
    ax[0].plot([r["paths"] for r in studies["paths"]], [r["seconds"] for r in studies["paths"]], "o-")
    ax[0].set_xlabel("paths")
    ax[0].set_title(f"thesis Fig. 4.6\nsigma_s 10, g 0: seconds ~ paths^{b:.2f}", fontsize=9)
    seconds = []
    for g in (-0.5, 0.0, 0.5):
        pts = [r for r in studies["sigma_s"] if r["g"] == g]
        x, y = positive([r["sigma_s"] for r in pts], [r["seconds"] for r in pts])
        ax[1].loglog(x, y, "o-", label=f"g {g}")
        seconds += y
    if log_limits(seconds):
        ax[1].set_ylim(*log_limits(seconds))
    ax[1].set_xlabel("sigma_s (r = 1)")
    ax[1].set_title("thesis Fig. 4.7\nseconds against sigma_s", fontsize=9)
    ax[1].legend(fontsize=8)
    ax[2].plot([r["g"] for r in studies["g"]], [r["seconds"] for r in studies["g"]], "o-")
    ax[2].set_xlabel("g")
    ax[2].set_title("thesis Fig. 4.8\nsigma_s 8: seconds against g", fontsize=9)
    for a_ in ax:
        a_.set_ylabel("seconds (one thread)")
        a_.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "runtime_studies.png"), dpi=100)
    return studies


def summary(results, studies, budget):
    lines = ["# stf report", "", f"Tables on {budget['grid']} with {budget['alpha_bins']} alpha bins; "
             f"reference {budget['reference']:.0e} paths.", "", "## Error against run time", ""]
    for entry in results:
        raw = entry["raw"]
        coeff, slope = power_law([(r["paths"], r["tv"]) for r in raw])
        lines.append(f"**{heading(entry['medium'])}**: raw TV {raw[0]['tv']:.3f} at {raw[0]['paths']:.0e} paths to "
                     f"{raw[-1]['tv']:.3f} at {raw[-1]['paths']:.0e} (TV ~ paths^{slope:.2f}).")
        best = None
        for m in entry["models"]:
            needed = (m["tv"] / coeff) ** (1 / slope)
            m["precompute_time_ratio"] = needed / m["paths"]
            m["bytes_fraction"] = m["bytes"] / raw[0]["bytes"]
            if best is None or m["precompute_time_ratio"] > best["precompute_time_ratio"]:
                best = m
        lines.append(f"Best: {best['model']} from {best['paths']:.0e} paths, TV {best['tv']:.3f}: a raw table needs "
                     f"{best['precompute_time_ratio']:.0f}x the paths; {100 * best['bytes_fraction']:.2f}% of its bytes.")
        lines.append("")
    lines += ["## Run time (thesis chapter 4)", "",
              f"- seconds grow like paths^{studies['paths_exponent']:.2f} (linear: thesis Fig. 4.6, Table 4.1)",
              "- against sigma_s (4..32): exponent " + ", ".join(
                  f"{v:.2f} at g {k}" for k, v in studies["sigma_s_exponent"].items()) +
              " (thesis Fig. 4.7: quadratic)",
              f"- against g at sigma_s 8: {studies['g'][0]['seconds']:.3f} s at g -0.9 to "
              f"{studies['g'][-1]['seconds']:.3f} s at g 0.9 (thesis Fig. 4.8: more for backward scattering)", "",
              "Plots: error_vs_runtime.png, bytes_vs_error.png, runtime_studies.png; figures: report.json."]
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--stf", required=True)
    ap.add_argument("--media", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--full", action="store_true")
    a = ap.parse_args()
    with open(a.media) as f:
        media = json.load(f)
    budget = {"grid": "healpix:8", "alpha_bins": 18, "paths": [1e3, 1e4, 1e5], "reference": 2e6,
              "runtime_paths": [1e5, 2e5, 4e5, 8e5], "sigma_paths": 20000, "g_paths": 100000}
    if a.full:
        budget = {"grid": "healpix:16", "alpha_bins": 90, "paths": [1e4, 1e5, 1e6, 1e7], "reference": 1e8,
                  "runtime_paths": [5e5, 1e6, 2e6, 4e6], "sigma_paths": 200000, "g_paths": 1000000}
    os.makedirs(a.out, exist_ok=True)
    stf = Stf(a.stf)
    results = error_study(stf, media, a.out, budget)
    plot_errors(results, a.out)
    studies = runtime_studies(stf, a.out, budget)
    text = summary(results, studies, budget)
    with open(os.path.join(a.out, "report.json"), "w") as f:
        json.dump({"budget": budget, "media": results, "runtime": studies}, f, indent=1)
    with open(os.path.join(a.out, "report.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    try:
        main()
    except OSError as e:  # a full disk: one line naming the file, for stf's error
        sys.exit(f"cannot write {e.filename or 'the report'}: {e.strerror or e}")
