#!/usr/bin/python3
"""Where a scene's render time goes, by brute force and in strides: the strides themselves, the
free radius (distance grid or exact queries), rays against the boundary (Embree), the
collisions (free flights, phase draws, shadow rays) and the rest, per camera path.

Both methods run on one thread under `perf record` (after a small run that puts the strides'
pack in stf render's cache), one after the other;
each profile's shares are taken of the render alone (the distance grid's and the pack's set-up
are left out), times the run's seconds per path. Functions are put in parts by name, so time
inlined into a caller counts as the caller's, and libm's (the logs of free flights and of lobe
draws alike) as the collisions'. A profile is one run, so its shares are not
shifted by the load of a shared machine the way separate timings are. Also reported:
  - free_strides_speed_up: brute force's ns per path over the strided path's without its
    strides, the speed-up at equal sample count if a stride cost nothing;
  - speed_up: the same with the strides, brute over strided ns per path;
  - ns_per_event: each part's time per collision, stride, free-radius look and ray.
JSON on stdout.
Usage:
  bench/render_profile.py SCENE.toml [--size 64] [--spp 300] [--brute-spp 80] [--pack PACK]
Needs build/stf (STF_BINARY to override) and perf.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The first rule a symbol (or its library) matches names its part; set-up parts are left out.
PARTS = [
    ("rays", lambda dso, sym: "embree" in dso or "Boundary::intersect" in sym or "SceneGeometry::trace" in sym),
    ("strides", lambda dso, sym: any(s in sym for s in ("ScenePaths::stride", "StrideForm", "OnceScattered",
                                                          "SphereLookup::find", "alpha_turn"))),
    ("free_radius", lambda dso, sym: "free_radius" in sym or "look_closer" in sym),
    ("set_up", lambda dso, sym: any(s in sym for s in ("DistanceGrid", "squared_distance", "rasterise", "closer_triangle",
                                                         "deep_bound", "introsort", "mean_under_lobe", "Stf", "Shell",
                                                         "build"))),
    ("collisions", lambda dso, sym: "libm" in dso or any(s in sym for s in ("medium_step", "around", "sample_hg",
                                                                             "nee_at", "survives", "transmittance"))),
]


def part_of(dso, sym):
    for name, rule in PARTS:
        if rule(dso, sym):
            return name
    return "other"


def render_command(binary, scene, method, size, spp, pack, work):
    command = [binary, "render", scene, "--method", method, "--spp", str(spp), "--width", str(size), "--height",
               str(size), "--threads", "1", "--quiet", "-o", os.path.join(work, method + ".h5"), "--json",
               os.path.join(work, method + ".json")]
    return command + (["--pack", pack] if pack and method == "stf" else [])


def profile(binary, scene, method, size, spp, pack, work):
    data, stats = os.path.join(work, method + ".perf"), os.path.join(work, method + ".json")
    # A first small run builds the pack into the cache, so that the profile holds no precompute.
    subprocess.run(render_command(binary, scene, method, 4, 1, pack, work), check=True, stdout=subprocess.DEVNULL)
    command = render_command(binary, scene, method, size, spp, pack, work)
    subprocess.run(["perf", "record", "-q", "-F", "2000", "-o", data, "--"] + command, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    report = subprocess.run(["perf", "report", "-i", data, "--no-children", "--stdio", "--sort", "dso,sym"],
                            check=True, capture_output=True, text=True).stdout
    shares = {}
    for line in report.splitlines():
        m = re.match(r"\s+([0-9.]+)%\s+(\S+)\s+\[.\]\s+(.*)", line)
        if m:
            part = part_of(m.group(2), m.group(3))
            shares[part] = shares.get(part, 0.0) + float(m.group(1))
    with open(stats) as f:
        s = json.load(f)
    rendering = 100.0 - shares.pop("set_up", 0.0)
    ns_per_path = 1e9 * s["seconds"] / s["paths"]
    per_path = {k: round(ns_per_path * v / rendering, 1) for k, v in sorted(shares.items())}
    counts = {k: s[k] / s["paths"] for k in ("collisions", "strides", "distance_queries", "rays", "shadow_rays")}
    # Each part's ns per event it is named for (a collision's part also holds every step's
    # bookkeeping, a stride's its sphere lookup).
    events = {"collisions": "collisions", "strides": "strides", "free_radius": "distance_queries", "rays": "rays"}
    per_event = {k: round(per_path[k] / counts[e], 1) for k, e in events.items() if k in per_path and counts[e] > 0}
    return {"method": method, "spp": spp, "ns_per_path": round(ns_per_path, 1), "ns_per_path_by_part": per_path,
            "per_path": {k: round(v, 2) for k, v in counts.items()}, "ns_per_event": per_event}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene")
    p.add_argument("--size", type=int, default=64)
    p.add_argument("--spp", type=int, default=300, help="strided samples per pixel")
    p.add_argument("--brute-spp", type=int, default=80)
    p.add_argument("--pack", help="the scene's pack (default: stf render builds or finds it in its cache)")
    a = p.parse_args()
    binary = os.environ.get("STF_BINARY") or os.path.join(ROOT, "build", "stf")
    if not shutil.which("perf"):
        sys.exit("render_profile: needs perf (Debian: apt install linux-perf)")
    with tempfile.TemporaryDirectory() as work:
        try:
            stf = profile(binary, a.scene, "stf", a.size, a.spp, a.pack, work)
            brute = profile(binary, a.scene, "brute", a.size, a.brute_spp, None, work)
        except subprocess.CalledProcessError as e:
            sys.exit(f"render_profile: {' '.join(e.cmd[:3])} ... failed (exit {e.returncode})"
                     + ("" if e.cmd[0] == binary else ": perf may be barred (kernel.perf_event_paranoid)"))
    without = stf["ns_per_path"] - stf["ns_per_path_by_part"].get("strides", 0.0)
    print(json.dumps({"scene": a.scene, "size": a.size, "brute": brute, "stf": stf,
                      "speed_up": round(brute["ns_per_path"] / stf["ns_per_path"], 2),
                      "free_strides_speed_up": round(brute["ns_per_path"] / without, 2)}, indent=1))


if __name__ == "__main__":
    main()
