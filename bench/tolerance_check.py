#!/usr/bin/python3
"""Certified bounds of a tolerance build against the truth.

For every entry of a built scene (its cache), walks an independent reference table of
--reference-paths paths at the scene's grid and alpha bins and compares the cached model's
joint TV distance to it (`stf eval`) with the bound the build certified. The reference's own
noise only raises the measured TV. Writes JSON (stdout or --out).

  /usr/bin/python3 bench/tolerance_check.py data/scenes/default.toml --cache out/default-scene.cache
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def stf(*args, capture=False):
    cmd = [os.path.join(ROOT, "build", "stf"), *map(str, args)]
    return subprocess.run(cmd, check=True, text=True, capture_output=capture).stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--cache", required=True, help="the cache the scene was built into")
    ap.add_argument("--reference-paths", default="2e7")
    ap.add_argument("--out", help="JSON file (default: stdout)")
    a = ap.parse_args()
    plan = json.loads(stf("build", a.scene, "--plan-only", "--json", "--cache", a.cache, capture=True))
    settings = plan["settings"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for e in plan["entries"]:
            if e["action"] != "cached":
                continue
            model = os.path.join(a.cache, e["key"] + ".model.h5")
            ref = os.path.join(tmp, "ref.h5")
            stf("precompute", "--sigma-s", e["albedo"] * e["tau"], "--sigma-a", (1 - e["albedo"]) * e["tau"],
                "--g", e["g"], "--radius", 1, "--grid", settings["grid"], "--alpha-bins", settings["alpha_bins"],
                "--paths", a.reference_paths, "--seed", 1000, "--quiet", "-o", ref)
            ev = json.loads(stf("eval", model, "--reference", ref, capture=True))
            with h5py.File(model) as f:
                bound, met = float(f.attrs["tv_bound"]), bool(f.attrs["tolerance_met"])
            r = e["resolution"]
            rows.append({"tau": e["tau"], "albedo": e["albedo"], "g": e["g"], "media": e["media"],
                         "grid": r["grid"], "alpha_bins": r["alpha_bins"], "model": r["model"], "paths": r["paths"],
                         "model_bytes": r["model_bytes"], "tv_bound": bound, "tolerance_met": met,
                         "measured_joint_tv": ev["joint_tv_distance"], "covered": ev["joint_tv_distance"] <= bound})
            print(f"tau {e['tau']:<5g} albedo {e['albedo']:.4g} g {e['g']}: {r['grid']}, {r['alpha_bins']} bins, "
                  f"{r['model']}, {r['paths']:.3g} paths: bound {bound:.3g}, measured {ev['joint_tv_distance']:.3g}",
                  file=sys.stderr)
    text = json.dumps({"tolerance": settings["tolerance"], "reference_paths": float(a.reference_paths),
                       "entries": rows}, indent=1)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)
    else:
        print(text)


if __name__ == "__main__":
    main()
