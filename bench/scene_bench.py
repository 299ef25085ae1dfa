#!/usr/bin/python3
"""Render scenes (stf render SCENE.toml) by brute force and in shell strides: the same picture,
and how much sooner, in meshes, in colour, behind glass, with next-event estimation.

For each scene file (and each --densities factor, which scales every medium's coefficients)
  - builds the strides' pack through a cache (a 1-spp strided render; its precompute seconds),
  - renders brute force and strides at --size pixels and --spp samples (seeds 1 and 2) for each
    --free-radius source (grid: the distance grid, query: exact Embree queries), --repeats
    times in turns, the seconds the median of the turns; with --fresh-seeds each turn draws new
    images (seeds 2k + 1 and 2k + 2), and the images of all turns are pooled (their mean, its
    variance): one pair's variance ratio scatters by tens of percent where rare paths find a
    light (variance_ratio_per_seed_pair shows it),
and reports per run: seconds, collisions, strides, distance queries and shadow rays per path,
and brute force's collisions per second; per pair: the equal-error speed-up
  (seconds_brute * variance_brute) / (seconds_stf * variance_stf)
(variance: the images' summed variance of the mean, per channel, then averaged over the
channels; for unbiased estimators variance * time is a constant of the method), the stride's
cost c in collisions measured in the strided run and the bound B / (C + c N) at it, the 4 x 4
block z of their difference (max over channels, target <= 4.5), the per-channel mean ratio
(target within 1%), the per-channel variance ratio and equal-error speed-up, rays per path by
kind, and the frames of this size and spp the pack pays off in at equal error (where the
equal-error speed-up is not above 1, strides never pay: frames_to_pay_off null, pays_off false
and pay_off_note saying so). With --ideal, a
third run with ideal strides (stf render --ideal-strides: the true transport through each
sphere) gives the shell collisions and strides of a perfect model, and the bound
B / (C_ideal + c N_ideal) at the same c.

Media that vary (density grids): --density-tolerances T,T2,... renders the strided run once per
tolerance (stf render --density-tolerance), a row each; --reference-spp N adds a long brute-force
render (seed 1000) per scene and density, and per strided run its bias: the strided mean less the
reference's, per 4 x 4 block in units of the two images' combined noise (bias_max_block_z), per
channel relative to the reference's mean with its standard error (bias_relative,
bias_relative_se, bias_z), beside the noise of a 256-spp render's 4 x 4 blocks
(noise_256spp_block_relative, the median block's); with null collisions per real one for both
methods.

Writes OUT/scene_bench.json and, with --pictures, OUT/NAME_pair.png (brute | strided | z-map);
with several --densities, OUT/NAME_density.png: the equal-error speed-up and the bound against
the density, beside the learned-STF renderer's teaser figures (Leonard, Hoehlein, Westermann,
EG 2021: 2.2, 3.9, 7.5 and 11.8x at 1/8, 1/4, 1/2 and 1 times its scenes' density, at equal
sample count with approximate steps).
Usage:
  bench/scene_bench.py SCENE.toml [MORE.toml] [--out DIR] [--size 64] [--spp 60]
                       [--densities 1] [--free-radius grid,query] [--repeats 3] [--fresh-seeds] [--ideal] [--pictures]
                       [--density-tolerances 0.1] [--reference-spp 0]
Needs build/stf and Debian's python3-matplotlib, python3-h5py and python3-numpy.
"""
import argparse
import json
import os
import subprocess
import sys
import tomllib

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from stf_runs import Stf  # noqa: E402
import render_pair  # noqa: E402


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else str(v)


def scaled_scene(path, factor, out):
    """The scene with every medium's coefficients times `factor` and file paths made absolute."""
    with open(path, "rb") as f:
        scene = tomllib.load(f)
    folder = os.path.dirname(os.path.abspath(path))
    lines = []
    if "environment" in scene.get("light", {}):
        scene["light"]["environment"] = os.path.join(folder, scene["light"]["environment"])
    for key in ("camera", "light", "ground"):
        if key in scene:
            lines.append(f"[{key}]")
            lines += [f"{k} = {toml_value(v)}" for k, v in scene[key].items()]
    for m in scene["media"]:
        m = dict(m)
        if "grid" in m:
            m["grid"] = os.path.join(folder, m["grid"])
        if "preset" in m:
            m["density"] = m.get("density", 1.0) * factor
        else:
            for k in ("sigma_s", "sigma_a"):
                m[k] = [x * factor for x in m[k]] if isinstance(m[k], list) else m[k] * factor
        lines.append("[[media]]")
        lines += [f"{k} = {toml_value(v)}" for k, v in m.items()]
    for o in scene["objects"]:
        o = dict(o)
        if "mesh" in o:
            o["mesh"] = os.path.join(folder, o["mesh"])
        lines.append("[[objects]]")
        lines += [f"{k} = {toml_value(v)}" for k, v in o.items()]
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    return out


def render(stf, scene, method, out, a, seed, free_radius, extra=()):
    stats = out + ".json"
    stf.run("render", scene, "--method", method, "--width", a.size, "--height", a.size, "--spp", a.spp, "--seed", seed,
            "--free-radius", free_radius, "--quiet", "-o", out, "--json", stats, "--cache", a.cache, *extra)
    with h5py.File(out, "r") as f, open(stats) as s:
        return f["image/mean"][()], f["image/variance_of_mean"][()], json.load(s)


def block_z(mb, vb, ms, vs):
    """z of every 4 x 4 block per channel (tools/render_pair.py's), 0 where neither has variance."""
    z = np.stack([render_pair.block_z(ms[..., c], vs[..., c], mb[..., c], vb[..., c]) for c in range(3)], axis=-1)
    return np.nan_to_num(z)


def per_path(stats, key):
    return stats[key] / stats["paths"]


def pay_off(pack_seconds, speedup, saved):
    """The frames whose saved render seconds (`saved` a frame) pay the pack's precompute off. Where
    the equal-error speed-up is not above 1 strides never pay: frames_to_pay_off is None (null in
    JSON), pays_off false, and pay_off_note says why."""
    if speedup is None or not speedup > 1 or not saved > 0:
        shown = "unknown" if speedup is None else f"{speedup:.3g}"
        return {"frames_to_pay_off": None, "pays_off": False,
                "pay_off_note": f"never: the equal-error speed-up is {shown} (not above 1), so a strided frame "
                                "costs at least as much as a brute-force one at the same error"}
    return {"frames_to_pay_off": pack_seconds / saved, "pays_off": True}


def pooled(runs):
    """Renders of one scene by one method with different seeds as one: the mean of their means,
    and its variance (the sum of theirs over the count squared)."""
    k = len(runs)
    return sum(r[0] for r in runs) / k, sum(r[1] for r in runs) / k**2


def timed_pair(a, stf, scene, name, free_radius, tolerance):
    """Both methods --repeats times in turns; each run's seconds the median of its turns, as this
    machine's load comes and goes. The turns draw the same images (seeds 1 and 2), or with
    --fresh-seeds new ones (seeds 2k + 1 and 2k + 2 in turn k), pooled: a summed pixel variance is
    heavy-tailed where rare paths find a light, and one pair's ratio scatters by tens of percent."""
    turns, strided = [], ("--density-tolerance", tolerance)
    for k in range(a.repeats):
        seed = 2 * k if a.fresh_seeds else 0
        turns.append((render(stf, scene, "brute", os.path.join(a.out, f"{name}_{free_radius}_brute.h5"), a, seed + 1,
                             free_radius),
                      render(stf, scene, "stf", os.path.join(a.out, f"{name}_{free_radius}_stf.h5"), a, seed + 2, free_radius,
                             strided)))
    used = turns if a.fresh_seeds else turns[-1:]
    (mb, vb), (ms, vs) = pooled([t[0] for t in used]), pooled([t[1] for t in used])
    sb, ss = turns[-1][0][2], turns[-1][1][2]
    sb["seconds"] = float(np.median([t[0][2]["seconds"] for t in turns]))
    ss["seconds"] = float(np.median([t[1][2]["seconds"] for t in turns]))
    ratios = [[float(t[1][1][..., c].sum() / t[0][1][..., c].sum()) for c in range(3)] for t in used]
    return mb, vb, sb, ms, vs, ss, ratios


def bias(ms, vs, reference, spp):
    """The strided image against the long brute-force reference (mean, variance of the mean): per
    channel the relative bias of the image mean with its standard error, and per 4 x 4 block the
    noise a 256-spp render has (the median over blocks, relative to the block's mean): the bias is
    below that noise where |bias| + 2 se is."""
    mr, vr = reference
    z = block_z(mr, vr, ms, vs)
    out = {"bias_max_block_z": float(np.abs(z).max()), "bias_relative": [], "bias_relative_se": [], "bias_z": [],
           "noise_256spp_block_relative": []}
    for c in range(3):
        n = mr[..., c].size
        out["bias_relative"].append(float(ms[..., c].mean() / mr[..., c].mean() - 1))
        out["bias_relative_se"].append(float(np.sqrt(vs[..., c].sum() + vr[..., c].sum()) / n / mr[..., c].mean()))
        out["bias_z"].append(out["bias_relative"][-1] / out["bias_relative_se"][-1])
        h, w = mr.shape[:2]
        blocks = lambda img: img[:h // 4 * 4, :w // 4 * 4, c].reshape(h // 4, 4, w // 4, 4).sum(axis=(1, 3))
        noise = np.sqrt(blocks(vs) * spp / 256) / np.maximum(blocks(mr), 1e-30)
        out["noise_256spp_block_relative"].append(float(np.median(noise)))
    return out


def compare(a, stf, scene, name, free_radius, pack_seconds, tolerance=0.1, reference=None):
    mb, vb, sb, ms, vs, ss, ratios = timed_pair(a, stf, scene, name, free_radius, tolerance)
    efficiency = [(sb["seconds"] * vb[..., c].sum()) / (ss["seconds"] * vs[..., c].sum()) for c in range(3)]
    speedup = np.mean(efficiency)
    z = block_z(mb, vb, ms, vs)
    # What strides save on one frame at brute force's error: nothing where they do not pay.
    saved = sb["seconds"] * (1 - 1 / speedup) if speedup > 1 else 0
    row = {"scene": name, "free_radius": free_radius, "density_tolerance": tolerance, "equal_error_speedup": float(speedup),
           "equal_error_speedup_per_channel": [float(e) for e in efficiency],
           "variance_ratio_per_channel": [float(vs[..., c].sum() / vb[..., c].sum()) for c in range(3)],
           "variance_ratio_per_seed_pair": ratios,
           "max_block_z": float(np.abs(z).max()),
           "mean_ratio": [float(ms[..., c].mean() / mb[..., c].mean()) for c in range(3)],
           "mean_z": [float((ms[..., c].sum() - mb[..., c].sum()) / np.sqrt(vb[..., c].sum() + vs[..., c].sum()))
                      for c in range(3)],
           "pack_seconds": pack_seconds, **pay_off(pack_seconds, speedup, saved),
           "brute_collisions_per_second": sb["collisions"] / sb["seconds"]}
    # The bound at the measured stride cost (docs/render.md): brute force's seconds per collision
    # price everything a path does; what the strided run spent beyond its collisions, per stride,
    # is the stride's cost c in collisions, and B / (C + c N) what strides of that cost can give.
    per_collision = sb["seconds"] / sb["collisions"]
    if ss["strides"] > 0:
        cost = (ss["seconds"] - ss["collisions"] * per_collision) / ss["strides"] / per_collision
        bound = sb["collisions"] / (ss["collisions"] + cost * ss["strides"])
        row.update({"stride_cost_collisions": cost, "bound_at_measured_cost": bound, "fraction_of_bound": speedup / bound})
    if a.ideal and ss["strides"] > 0:
        # Ideal strides (the true transport through each sphere, stf render --ideal-strides): the
        # shell collisions and strides of a perfect model, and the bound at the cost c measured.
        _, _, si = render(stf, scene, "stf", os.path.join(a.out, f"{name}_{free_radius}_ideal.h5"), a, 3, free_radius,
                          ("--ideal-strides",))
        ideal = sb["collisions"] / (si["collisions"] + row["stride_cost_collisions"] * si["strides"])
        row.update({"ideal_collisions_per_path": per_path(si, "collisions"), "ideal_strides_per_path": per_path(si, "strides"),
                    "ideal_bound_at_measured_cost": ideal, "fraction_of_ideal_bound": speedup / ideal})
    for tag, s in (("brute", sb), ("stf", ss)):
        row[tag] = {"seconds": s["seconds"], "collisions_per_path": per_path(s, "collisions"),
                    "strides_per_path": per_path(s, "strides"), "distance_queries_per_path": per_path(s, "distance_queries"),
                    "shadow_rays_per_path": per_path(s, "shadow_rays"), "rays_per_path": per_path(s, "rays"),
                    "rays_by_kind_per_path": {k: v / s["paths"] for k, v in s.get("rays_by_kind", {}).items()},
                    "once_scattered_exits_per_stride": s.get("once_scattered_exits", 0) / max(1, s["strides"]),
                    "null_collisions_per_collision": s.get("null_collisions", 0) / max(1, s["collisions"]),
                    "grid_bytes": s["grid_bytes"], "density_grid_bytes": s.get("density_grid_bytes", 0)}
    if reference is not None:
        row.update(bias(ms, vs, reference, a.spp * (a.repeats if a.fresh_seeds else 1)))
    if a.pictures:
        picture(mb, ms, z, os.path.join(a.out, f"{name}_pair.png"), a.exposure)
    return row


def picture(mb, ms, z, path, exposure):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(18, 6.4))  # panels of 512 pixels or more
    for i, (img, title) in enumerate(((mb, "brute force"), (ms, "shell strides"))):
        ax[i].imshow(render_pair.tone(img, exposure))
        ax[i].set_title(title)
    im = ax[2].imshow(np.abs(z).max(axis=2), cmap="magma", vmin=0, vmax=4.5)
    ax[2].set_title("|z| of 4x4 blocks (max over channels)")
    fig.colorbar(im, ax=ax[2], fraction=0.046)
    for x in ax:
        x.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


# The learned-STF renderer's speed-ups at 1/8 .. 1 times its scenes' density (equal sample count).
THEIRS = {0.125: 2.2, 0.25: 3.9, 0.5: 7.5, 1.0: 11.8}


def density_plot(rows, factors, path):
    """Speed-up and bound against density (one scene's rows, one per factor), beside THEIRS."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    biased = "bias_relative" in rows[0]
    fig, axes = plt.subplots(1, 2 if biased else 1, figsize=(11 if biased else 6, 4.2), squeeze=False)
    ax = axes[0][0]
    ax.plot(factors, [r["equal_error_speedup"] for r in rows], "o-", label="stf strides (equal error)")
    ax.plot(factors, [r.get("bound_at_measured_cost", np.nan) for r in rows], "s--", label="bound B / (C + c N) at the measured c")
    ax.plot(factors, [r["brute"]["collisions_per_path"] / r["stf"]["collisions_per_path"] for r in rows], "d-.",
            label="bound with free strides, B / C")
    ax.plot(list(THEIRS), list(THEIRS.values()), "^:", label="learned STF, EG 2021 (equal sample count, approximate steps)")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("density (times the scene's)")
    ax.set_ylabel("speed-up over brute force")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if biased:
        bias_panel(axes[0][1], rows, factors)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def bias_panel(ax, rows, factors):
    """The strided mean's bias against the long reference per channel (+-2 standard errors), and
    the block noise of a 256-spp render it is held against."""
    for c, colour in enumerate("rgb"):
        bias = [100 * r["bias_relative"][c] for r in rows]
        se = [200 * r["bias_relative_se"][c] for r in rows]
        ax.errorbar(factors, bias, yerr=se, fmt="o-", color=colour, capsize=3, label=f"bias +- 2 se, {'RGB'[c]}")
        noise = [100 * r["noise_256spp_block_relative"][c] for r in rows]
        ax.plot(factors, noise, ":", color=colour, lw=1)
        ax.plot(factors, [-n for n in noise], ":", color=colour, lw=1)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xscale("log", base=2)
    ax.set_xlabel("density (times the scene's)")
    ax.set_ylabel("bias (%); dotted: a 256-spp render's block noise")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def reference_image(a, stf, scene, name):
    """The long brute-force render (--reference-spp, seed 1000): (mean, variance of the mean), or None."""
    if a.reference_spp <= 0:
        return None
    out = os.path.join(a.out, f"{name}_reference.h5")
    stf.run("render", scene, "--method", "brute", "--width", a.size, "--height", a.size, "--spp", a.reference_spp,
            "--seed", 1000, "--quiet", "-o", out)
    with h5py.File(out, "r") as f:
        return f["image/mean"][()], f["image/variance_of_mean"][()]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenes", nargs="+")
    p.add_argument("--out", default="scene_bench")
    p.add_argument("--size", type=int, default=64)
    p.add_argument("--spp", type=int, default=60)
    p.add_argument("--densities", default="1")
    p.add_argument("--free-radius", default="grid,query")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--fresh-seeds", action="store_true")
    p.add_argument("--ideal", action="store_true")
    p.add_argument("--pictures", action="store_true")
    p.add_argument("--exposure", type=float, default=-0.5)
    p.add_argument("--density-tolerances", default="0.1")
    p.add_argument("--reference-spp", type=int, default=0)
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    a.cache = os.path.join(a.out, "cache")
    stf, rows = Stf(), []
    for path in a.scenes:
        for factor in (float(x) for x in a.densities.split(",")):
            name = os.path.splitext(os.path.basename(path))[0] + (f"_x{factor:g}" if factor != 1 else "")
            scene = scaled_scene(path, factor, os.path.join(a.out, name + ".toml"))
            warm = os.path.join(a.out, name + "_warm.h5")
            stf.run("render", scene, "--method", "stf", "--spp", 3, "--width", 4, "--height", 4, "--quiet", "-o", warm,
                    "--json", warm + ".json", "--cache", a.cache)
            with open(warm + ".json") as f:
                pack_seconds = json.load(f)["precompute_seconds"]
            reference = reference_image(a, stf, scene, name)
            for free_radius in a.free_radius.split(","):
                for tolerance in (float(x) for x in a.density_tolerances.split(",")):
                    rows.append(compare(a, stf, scene, name, free_radius, pack_seconds, tolerance, reference))
                    rows[-1]["density"] = factor
                    print(json.dumps(rows[-1]), flush=True)
        factors = [float(x) for x in a.densities.split(",")]
        if len(factors) > 1:
            base = os.path.splitext(os.path.basename(path))[0]
            for free_radius in a.free_radius.split(","):
                for tolerance in (float(x) for x in a.density_tolerances.split(",")):
                    mine = [r for r in rows if r["scene"].startswith(base) and r["free_radius"] == free_radius
                            and r["density_tolerance"] == tolerance][-len(factors):]
                    density_plot(mine, factors, os.path.join(a.out, f"{base}_{free_radius}_t{tolerance:g}_density.png"))
    with open(os.path.join(a.out, "scene_bench.json"), "w") as f:
        json.dump({"size": a.size, "spp": a.spp, "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
