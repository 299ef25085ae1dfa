#!/usr/bin/python3
"""Strided rendering against brute force: the same picture, and how much sooner.

For each medium (optical radius tau, albedo, g; sphere radius tau / sigma_t, sigma_t 100)
renders the `stf render` scene
  - a long brute-force reference (REF_SPP per pixel, its own seed),
  - brute force and shell strides at each of SPP samples per pixel (other seeds),
and measures, per method and spp, the image error against the reference
  MSE = mean over pixels of (image - reference)^2, less the reference's own variance_of_mean,
which estimates the error against the true image (noise and bias); without a reference
(--ref-spp 0, for the dense media, whose long references this machine cannot afford) the
images' own variances stand for it, the bias being checked by the block z below. The equal-error speed-up
is (MSE_brute * seconds_brute) / (MSE_stf * seconds_stf) at the largest spp: for unbiased
estimators error^2 * time is a constant of the method, so this is the ratio of the times the
two need for the same error (render time only). The pack is built once through a cache
(ascending tau, so the precompute seconds summed so far are those of the pack each tau needs)
and `frames_to_pay_off` is the precompute time over the render time one frame saves (null, with
`pays_off` false and `pay_off_note`, where the equal-error speed-up is not above 1: strides never
pay).

The bound (docs/render.md, "The bound: ideal strides"): build/bench/stride_bound follows the
medium's camera paths with ideal strides on the render pack's ladder (its smallest and largest
spheres, ratio 2) and gives brute force's collisions B, the shell's C and the strides N per hitting
path; the stride cost c, in collisions, is measured in the strided run itself (its seconds
less its collisions at brute force's seconds per collision, per stride), and
`bound_at_measured_cost` = B / (C + c N), `fraction_of_bound` the speed-up over it.

Correctness, at the largest spp: the strided image against the brute-force one, as 4 x 4
pixel block sums over their combined variance (max |z|, target <= 4.5) and the whole-image
means (relative difference, target within 1%).

Writes OUT/render_bench.json, OUT/render_images.png (per medium: brute, stf, z of the
difference) and OUT/render_error_vs_time.png. The pictures are a pair of their own at
--figure-size pixels and --figure-spp (default: the largest of --spp), seeds 3 and 4, with the
same pack, their largest block z in the JSON (figure_max_block_z); --figure-size 0 draws the
timed images at the last of --spp instead (as --quick does). Usage:
  bench/render_bench.py [--out DIR] [--taus 10,30,100,300] [--media TAU:ALBEDO:G,...] [--dense]
                        [--spp 16,64,256,1024] [--ref-spp 4096] [--size 64] [--tolerance 0.02]
                        [--figure-size 256] [--figure-spp N] [--quick]
--taus are media of albedo 0.999, g 0.8; --dense adds tau 300 and 1000 at albedo 0.9999 and tau
1000 at albedo 0.99999, g 0.85 (a cumulus).
With scene files (bench/render_bench.py SCENE.toml [MORE.toml] [--size N] [--spp N] [--out DIR]) it
is bench/scene_bench.py with --ideal and --pictures: the same measures for `stf render SCENE.toml`
in meshes, in colour, behind glass, at the largest of --spp (default 60 there); its other options
(--densities, --free-radius, --repeats) pass through.
Needs build/stf and Debian's python3-matplotlib and python3-h5py.
"""
import argparse
import json
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402
import render_pair  # noqa: E402
from scene_bench import pay_off  # noqa: E402

SIGMA_T = 100
RATIO = 2  # between neighbouring spheres of stf render's packs (kSphereRatio, render/tracer.cpp)
DENSE = [(300, 0.9999, 0.85), (1000, 0.9999, 0.85), (1000, 0.99999, 0.85)]


def medium(albedo, g):
    return {"sigma_s": SIGMA_T * albedo, "sigma_a": SIGMA_T * (1 - albedo), "g": g}


def mse(image, var, ref, ref_var):
    """Error against the reference, less the reference's own variance; without one, the
    image's variance (an unbiased estimator's error)."""
    if ref is None:
        return float(np.mean(var))
    return float(np.mean((image - ref) ** 2) - np.mean(ref_var))


def run_medium(stf, spec, a, cache, out):
    tau, albedo, g = spec
    m = medium(albedo, g)
    radius = tau / SIGMA_T
    name = f"tau{tau:g}_a{albedo:g}_g{g:g}"
    ref = ref_var = None
    row = {"tau": tau, "albedo": albedo, "g": g, "radius": radius, "reference_spp": a.ref_spp, "runs": []}
    if a.ref_spp > 0:
        print(f"tau {tau:g} albedo {albedo:g} g {g:g}: reference, {a.ref_spp} spp brute force", file=sys.stderr)
        ref, ref_var, ref_stats = stf.render(m, radius, a.ref_spp, "brute", os.path.join(out, f"{name}_ref.h5"),
                                             seed=1000, size=a.size)
        row["reference_seconds"] = ref_stats["seconds"]
    stf_args = ["--tolerance", a.tolerance, "--cache", cache]
    last = {}
    for spp in a.spp:
        for method, seed, extra in (("brute", 1, ()), ("stf", 2, stf_args)):
            path = os.path.join(out, f"{name}_{method}_{spp}.h5")
            mean, var, stats = stf.render(m, radius, spp, method, path, seed=seed, size=a.size, extra=extra)
            if method == "stf" and "precompute_seconds" not in row:
                row["precompute_seconds"] = stats["precompute_seconds"]
                row["spheres"] = stats["spheres"]
                row["smallest_sphere_tau"] = stats["smallest_sphere_tau"]
                row["largest_sphere_tau"] = stats["largest_sphere_tau"]
            run = {"method": method, "spp": spp, "seconds": stats["seconds"], "mse": mse(mean, var, ref, ref_var),
                   "mean_variance": float(np.mean(var)), "collisions": stats["collisions"],
                   "strides": stats["strides"], "paths": stats["paths"], "mean_radiance": stats["mean_radiance"]}
            row["runs"].append(run)
            last[method] = (mean, var, run)
            print(f"  {method:5s} {spp:5d} spp: {stats['seconds']:.3g} s, rmse {np.sqrt(max(run['mse'], 0)):.3g}",
                  file=sys.stderr)
    (bm, bv, br), (sm, sv, sr) = last["brute"], last["stf"]
    z = render_pair.block_z(sm, sv, bm, bv)
    row["brute_collisions_per_second"] = br["collisions"] / br["seconds"]
    row["max_block_z"] = float(np.nanmax(np.abs(z)))
    row["mean_relative_difference"] = float(sm.mean() / bm.mean() - 1)
    row["mean_difference_z"] = float((sm.sum() - bm.sum()) / np.sqrt(sv.sum() + bv.sum()))
    row["speedup_equal_error"] = (br["mse"] * br["seconds"]) / (sr["mse"] * sr["seconds"]) if sr["mse"] > 0 else None
    row["speedup_equal_variance"] = (br["mean_variance"] * br["seconds"]) / (sr["mean_variance"] * sr["seconds"])
    add_bound(row, br, sr)
    if a.figure_size > 0:
        bm, bv, _ = stf.render(m, radius, a.figure_spp, "brute", os.path.join(out, f"{name}_figure_brute.h5"), seed=3,
                               size=a.figure_size)
        sm, sv, _ = stf.render(m, radius, a.figure_spp, "stf", os.path.join(out, f"{name}_figure_stf.h5"), seed=4,
                               size=a.figure_size, extra=stf_args)
        z = render_pair.block_z(sm, sv, bm, bv)
        row["figure_max_block_z"] = float(np.nanmax(np.abs(z)))
    return row, (bm, sm, z)


def add_bound(row, br, sr):
    """The ideal bound at the stride cost this run measured (module docstring)."""
    ns_collision = br["seconds"] / br["collisions"]
    cost = (sr["seconds"] - sr["collisions"] * ns_collision) / max(sr["strides"], 1) / ns_collision
    tool = os.path.join(ROOT, "build", "bench", "stride_bound")
    smallest = row.get("smallest_sphere_tau", 0)
    if not os.path.exists(tool) or smallest <= 0:
        return
    out = subprocess.run([tool, "20000", str(row["tau"]), str(row["albedo"]), str(row["g"]), str(smallest), str(RATIO),
                          str(row["largest_sphere_tau"])],
                         check=True, capture_output=True, text=True).stdout
    b = json.loads(out)
    row["stride_cost_collisions"] = cost
    row["ideal"] = b
    row["bound_at_measured_cost"] = b["brute_collisions"] / (b["shell_collisions"] + cost * b["strides"])
    speedup = row["speedup_equal_error"] or row["speedup_equal_variance"]
    row["fraction_of_bound"] = speedup / row["bound_at_measured_cost"]


def plot_images(rows, images, path):
    """Per medium: brute force and strides through one radiance window in a warm map (as
    tools/render_pair.py draws the Quick start's pair), and the block z of their difference."""
    fig, axes = plt.subplots(len(rows), 3, figsize=(11, 3.6 * len(rows)), squeeze=False)
    for ax_row, row, (bm, sm, z) in zip(axes, rows, images):
        lo, hi = render_pair.window([bm, sm])
        for ax, image, title in ((ax_row[0], bm, "brute force"), (ax_row[1], sm, f"stf ({row['spheres']} spheres)")):
            ax.imshow(np.clip((image - lo) / (hi - lo), 0, 1) ** (1 / 1.5), cmap="inferno", vmin=0, vmax=1,
                      interpolation="nearest")
            ax.set_title(f"tau {row['tau']:g}, albedo {row['albedo']:g}, g {row['g']:g}: {title}, "
                         f"{image.shape[1]} x {image.shape[0]}", fontsize=8)
        im = ax_row[2].imshow(z, cmap="RdBu_r", vmin=-4.5, vmax=4.5, interpolation="nearest")
        ax_row[2].set_title(f"z, 4x4 blocks (max {np.nanmax(np.abs(z)):.2f})", fontsize=8)
        fig.colorbar(im, ax=ax_row[2])
        for ax in ax_row:
            ax.set_xticks([]), ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def plot_error(rows, path):
    fig, ax = plt.subplots(figsize=(7, 5))
    for i, row in enumerate(rows):
        color = f"C{i}"
        for method, style in (("brute", "o--"), ("stf", "s-")):
            runs = [r for r in row["runs"] if r["method"] == method and r["mse"] > 0]
            ax.loglog([r["seconds"] for r in runs], [np.sqrt(r["mse"]) for r in runs], style, color=color,
                      label=f"tau {row['tau']:g} a {row['albedo']:g} {method}")
    ax.set_xlabel("render seconds (wall clock)")
    ax.set_ylabel("RMSE against the brute-force reference (or the image's own noise)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def media(a):
    """(tau, albedo, g) of --taus (albedo 0.999, g 0.8), --media and --dense, by medium then tau."""
    specs = [(float(t), 0.999, 0.8) for t in a.taus.split(",") if t]
    specs += [tuple(float(x) for x in m.split(":")) for m in a.media.split(",") if m]
    specs += DENSE if a.dense else []
    return sorted(set(specs), key=lambda s: (s[1], s[2], s[0]))


def accumulate_precompute(rows):
    """Ascending tau through one cache per (albedo, g): the precompute seconds so far are those
    of the pack each medium needs; and the frames that pay them off."""
    total = {}
    for row in rows:
        key = (row["albedo"], row["g"])
        total[key] = total.get(key, 0.0) + row["precompute_seconds"]
        row["precompute_seconds"] = total[key]
        br = next(r for r in reversed(row["runs"]) if r["method"] == "brute")
        sr = next(r for r in reversed(row["runs"]) if r["method"] == "stf")
        # Brute force's seconds at the strided frame's error, less the strided frame's.
        speedup = row["speedup_equal_error"] or row["speedup_equal_variance"]
        saved = sr["seconds"] * (speedup - 1) if speedup else 0
        row.update(pay_off(row["precompute_seconds"], speedup, saved))


def print_table(rows):
    print("| tau | albedo | g | brute s | stf s | speed-up at equal error | bound at measured c (c) | fraction "
          "| mean rel. diff | max block z | precompute s | frames to pay off |")
    for row in rows:
        br = next(r for r in reversed(row["runs"]) if r["method"] == "brute")
        sr = next(r for r in reversed(row["runs"]) if r["method"] == "stf")
        speedup = row["speedup_equal_error"] or row["speedup_equal_variance"]
        bound = (f"{row['bound_at_measured_cost']:.2f} ({row['stride_cost_collisions']:.2f})"
                 if "bound_at_measured_cost" in row else "n/a")
        fraction = f"{row['fraction_of_bound']:.2f}" if "fraction_of_bound" in row else "n/a"
        frames = f"{row['frames_to_pay_off']:.1f}" if row["pays_off"] else "never (speed-up <= 1)"
        print(f"| {row['tau']:g} | {row['albedo']:g} | {row['g']:g} | {br['seconds']:.3g} | {sr['seconds']:.3g} | "
              f"{speedup:.2f} | {bound} | {fraction} | {100 * row['mean_relative_difference']:+.2f}% | "
              f"{row['max_block_z']:.2f} | {row['precompute_seconds']:.0f} | {frames} |")


def scene_bench(argv):
    """Hands scene files to bench/scene_bench.py (with the bound and the pictures)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", default="60")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "scene_bench"))
    a, rest = ap.parse_known_args(argv)
    spp = max(int(s) for s in a.spp.split(","))
    script = os.path.join(ROOT, "bench", "scene_bench.py")
    os.execv(sys.executable, [sys.executable, script, *rest, "--spp", str(spp), "--out", a.out, "--ideal", "--pictures"])


def main():
    if any(arg.endswith(".toml") for arg in sys.argv[1:]):
        scene_bench(sys.argv[1:])
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "render_bench"))
    ap.add_argument("--taus", default="10,30,100,300")
    ap.add_argument("--media", default="", help="TAU:ALBEDO:G,... beside --taus")
    ap.add_argument("--dense", action="store_true", help="add tau 300 and 1000 at albedo 0.9999, 1000 at 0.99999")
    ap.add_argument("--spp", default="16,64,256,1024")
    ap.add_argument("--ref-spp", type=int, default=4096, help="0: no reference, the images' variances stand in")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--tolerance", type=float, default=0.02)
    ap.add_argument("--figure-size", type=int, default=256, help="pixels of the pictures' own pair (0: the timed images)")
    ap.add_argument("--figure-spp", type=int, default=0, help="their samples per pixel (default: the largest of --spp)")
    ap.add_argument("--quick", action="store_true", help="tau 10 and 30, 32 x 32 pixels, fewer samples")
    a = ap.parse_args()
    if a.quick:
        a.taus, a.spp, a.ref_spp, a.size, a.figure_size = "10,30", "16,64", 256, 32, 0
    a.spp = [int(s) for s in a.spp.split(",")]
    a.figure_spp = a.figure_spp or max(a.spp)
    os.makedirs(a.out, exist_ok=True)
    stf = Stf()
    cache = os.path.join(a.out, "cache")
    rows, images = [], []
    for spec in media(a):
        row, image = run_medium(stf, spec, a, cache, a.out)
        rows.append(row)
        images.append(image)
    accumulate_precompute(rows)
    result = {"sigma_t": SIGMA_T, "size": a.size, "spp": a.spp, "tolerance": a.tolerance, "media": rows}
    with open(os.path.join(a.out, "render_bench.json"), "w") as f:
        json.dump(result, f, indent=1)
    plot_images(rows, images, os.path.join(a.out, "render_images.png"))
    plot_error(rows, os.path.join(a.out, "render_error_vs_time.png"))
    print_table(rows)


if __name__ == "__main__":
    main()
