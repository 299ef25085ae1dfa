#!/usr/bin/python3
"""The density grids of the shipped grid scenes, written into data/scenes/grids/ (not in git):
  cored_ball.npy   64^3 over [-1, 1]^3: density 1 within radius 0.8 (the constant core, where
                   strides are exact at any tolerance), falling to about 0.5 at radius 1 with a
                   three-wave ripple of up to +-20% growing outward (where the tolerance decides);
  cloud.vdb        `stf grid cloud --size SIZE` (a procedural cumulus, docs/render.md).
Usage: bench/make_grids.py [--size 128]   (needs build/stf and Debian's python3-numpy)
"""
import argparse
import os
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRIDS = os.path.join(ROOT, "data", "scenes", "grids")


def cored_ball(n=64):
    c = (np.arange(n) + 0.5) / n * 2 - 1
    x, y, z = np.meshgrid(c, c, c, indexing="ij")
    r = np.sqrt(x * x + y * y + z * z)
    s = np.clip((r - 0.8) / 0.2, 0, 1)
    ripple = np.sin(9 * x) * np.sin(7 * y + 1) * np.sin(8 * z + 2)
    return ((1 - 0.5 * s) * (1 + 0.2 * s * ripple)).astype(np.float32)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", type=int, default=128)
    a = p.parse_args()
    os.makedirs(GRIDS, exist_ok=True)
    np.save(os.path.join(GRIDS, "cored_ball.npy"), cored_ball())
    stf = os.environ.get("STF_BINARY", os.path.join(ROOT, "build", "stf"))
    subprocess.run([stf, "grid", "cloud", "--size", str(a.size), "--quiet", "-o", os.path.join(GRIDS, "cloud.vdb")],
                   check=True, stdout=sys.stdout)


if __name__ == "__main__":
    main()
