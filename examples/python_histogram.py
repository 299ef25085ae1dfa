"""Draw exits from a model, histogram their directions on HEALPix cells with healpy, and
compare with the table the model was fitted to, in one alpha bin (docs/python.md).

    PYTHONPATH=build/python /usr/bin/python3 examples/python_histogram.py TABLE.h5 MODEL.h5 [ALPHA_BIN]
"""
import sys

import h5py
import healpy as hp
import numpy as np

import stf


def local_directions(s):
    """Exit directions turned about z so that each exit point lies in the x-z plane: the frame
    in which a table stores them."""
    p, d = s["exit_point"], s["exit_direction"]
    beta = np.arctan2(p[:, 1], p[:, 0])
    c, sn = np.cos(beta), np.sin(beta)
    return np.column_stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1], d[:, 2]])


def main():
    table, model = h5py.File(sys.argv[1]), stf.Model(sys.argv[2])
    b = int(sys.argv[3]) if len(sys.argv) > 3 else 10
    edges = table["escape/alpha_edges"][()]
    counts = table["escape/weight"][b]
    nside = hp.npix2nside(counts.size)
    s = model.sample(2_000_000, seed=1)
    alpha = np.arccos(np.clip(s["exit_point"][:, 2], -1, 1))
    mine = (s["component"] == 0) & (alpha >= edges[b]) & (alpha < edges[b + 1])
    w = local_directions(s)[mine]
    drawn = np.bincount(hp.vec2pix(nside, w[:, 0], w[:, 1], w[:, 2]), minlength=counts.size)
    halves = table["escape/weight_half"][:, b]
    tv = lambda x, y: 0.5 * np.abs(x / x.sum() - y / y.sum()).sum()
    print(f"alpha bin {b} ({np.degrees(edges[b]):.1f}-{np.degrees(edges[b + 1]):.1f} deg), {counts.size} cells: "
          f"{mine.sum()} draws against {counts.sum():.0f} table escapes, TV {tv(drawn, counts):.3f}; "
          f"the table's two halves against each other: TV {tv(halves[0], halves[1]):.3f}")


if __name__ == "__main__":
    main()
