#!/usr/bin/python3
"""How far a tabulated stride would draw from the model: tables against each pack entry.

    PYTHONPATH=build/python /usr/bin/python3 docs/studies/scripts/stride_tables.py PACK [--out FILE.json]

A stride form without lobes (no logarithm, no rejection: build/bench/stride_cost's
`table_draw_floor` times its draw) would hold, per sub-bin of exit angles (equal area, S of
them), the density of exit directions on an equal-area (z, phi) grid about the exit normal
(nz rows, 2 nz columns; --frame start: about the start direction), and draw a cell and a
uniform point of it. Its error is the model's
smooth part against the table, as a total variation distance over exit point and direction:

  - constant: each cell's mean density (the table an alias draw samples as it is);
  - bilinear: the density interpolated between the grid's vertices at the sub-bin's middle
    (sampled exactly by inverting a linear marginal and a linear conditional: two square roots
    more), renormalised to the sub-bin's mass.

Both are integrated by a midpoint rule of 3 (constant) or 4 (bilinear) points per cell edge in
exit angle, z and phi, with the model's own pdf (stf.Model.pdf) at every point. The table's bytes
are those the draw reads: 8 per cell (a float threshold and an index of the alias table), and
for bilinear 4 more per vertex.
"""
import argparse
import json

import numpy as np

import stf

GRIDS = [(90, 8), (90, 16), (90, 32), (180, 32)]


def model_pdf(m, cos_alpha, z, phi, about_normal=True):
    """The model's density at exit points (sin a, 0, cos a) and directions (z, phi) about their
    normals (else about the start direction +z), on the outer product of the three arrays."""
    c, zz, p = np.meshgrid(cos_alpha, z, phi, indexing="ij")
    sa, rho = np.sqrt(np.maximum(0, 1 - c * c)), np.sqrt(np.maximum(0, 1 - zz * zz))
    wa, wb = rho * np.cos(p), rho * np.sin(p)
    point = np.stack([sa, np.zeros_like(sa), c], -1).reshape(-1, 3)
    direction = (np.stack([wa * c + zz * sa, wb, zz * c - wa * sa], -1) if about_normal
                 else np.stack([wa, wb, zz], -1)).reshape(-1, 3)
    return m.pdf(point, direction).reshape(c.shape)


def table_tv(m, subs, nz, bilinear, about_normal=True):
    """TV distance of the table of `subs` sub-bins and nz x 2 nz cells from the model."""
    k = 4 if bilinear else 3
    t = (np.arange(k) + 0.5) / k
    cols = 2 * nz
    z = ((np.arange(nz)[:, None] + t) / nz * 2 - 1).ravel()
    phi = ((np.arange(cols)[:, None] + t) / cols * 2 * np.pi).ravel()
    z_vertex, phi_vertex = np.linspace(-1, 1, nz + 1), np.linspace(0, 2 * np.pi, cols + 1)
    iz, fz = np.repeat(np.arange(nz), k), np.tile(t, nz)
    ip, fp = np.repeat(np.arange(cols), k), np.tile(t, cols)
    deviation = mass = 0.0
    for s in range(subs):
        p = model_pdf(m, 1 - 2 * (s + t) / subs, z, phi, about_normal)
        if bilinear:
            v = model_pdf(m, np.array([1 - 2 * (s + 0.5) / subs]), z_vertex, phi_vertex, about_normal)[0]
            q = ((v[iz][:, ip] * (1 - fp) + v[iz][:, ip + 1] * fp) * (1 - fz)[:, None]
                 + (v[iz + 1][:, ip] * (1 - fp) + v[iz + 1][:, ip + 1] * fp) * fz[:, None])
            q = np.broadcast_to(q * p.sum() / (k * q.sum()), p.shape)
        else:
            cells = p.reshape(k, nz, k, cols, k)
            q = np.broadcast_to(cells.mean(axis=(0, 2, 4), keepdims=True), cells.shape).reshape(p.shape)
        deviation += np.abs(p - q).sum()
        mass += p.sum()
    return 0.5 * deviation / mass


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("pack")
    ap.add_argument("--out")
    ap.add_argument("--frame", choices=("normal", "start"), default="normal",
                    help="the grid's pole: each exit point's normal, or the start direction")
    a = ap.parse_args()
    pack = stf.Pack(a.pack)
    rows = []
    for i in range(len(pack)):
        _, m = pack[i]
        for subs, nz in GRIDS:
            cells = subs * nz * 2 * nz
            row = {"tau": m.tau, "model": f"{m.family}:{m.size}", "sub_bins": subs, "nz": nz,
                   "frame": a.frame, "constant_bytes": 8 * cells,
                   "constant_tv": round(table_tv(m, subs, nz, False, a.frame == "normal"), 5),
                   "bilinear_bytes": 8 * cells + 4 * subs * (nz + 1) * (2 * nz + 1),
                   "bilinear_tv": round(table_tv(m, subs, nz, True, a.frame == "normal"), 5)}
            rows.append(row)
            print(json.dumps(row), flush=True)
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
