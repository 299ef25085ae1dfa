#!/usr/bin/python3
"""Draw the thesis's theta-phi direction plots (its Fig. 4.2-4.5) from the panel data that
`stf plot` prepares. Raw table against fitted model (`stf plot --model`): the two side by
side on one colour scale. Otherwise one row per table, two columns:

  left:  the thesis's method: densities at the cell centres, linearly interpolated over a
         Delaunay triangulation in (phi, theta). Wherever no cell centre lies near (phi = +-pi
         close to the poles), nothing is drawn: the thesis's "dead spots".
  right: every pixel shows the density of the cell its direction falls in: the table itself,
         without interpolation.

Usage: plot_directions.py PANELS.h5 OUT.png   (Debian's python3-matplotlib and python3-h5py)
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.tri as mtri  # noqa: E402
import numpy as np  # noqa: E402


def draw_side_by_side(f, names, out_path):
    """Raw table and fitted model, each pixel coloured by its cell, on one colour scale."""
    fig, axes = plt.subplots(1, len(names), figsize=(6.5 * len(names), 4.2), squeeze=False,
                             constrained_layout=True)
    vmax = max(max(f[n]["raster"][:].max() for n in names), 1e-300)
    for ax, name in zip(axes[0], names):
        g = f[name]
        im = ax.imshow(g["raster"][:], extent=[-180, 180, 180, 0], aspect="auto", cmap="viridis", vmin=0,
                       vmax=vmax, interpolation="nearest")
        title = g.attrs["title"]
        ax.set_title(title if isinstance(title, str) else title.decode(), fontsize=8)
        ax.set_xlabel("phi [deg]")
        ax.set_ylabel("theta [deg]")
    fig.colorbar(im, ax=axes[0].tolist(), label="p(w' | alpha)  [1/sr]")
    fig.savefig(out_path, dpi=100, format="png")


def draw(panels_path, out_path):
    with h5py.File(panels_path, "r") as f:
        names = sorted(f.keys(), key=lambda n: int(n[len("panel"):]))
        if f.attrs.get("side_by_side", 0):
            draw_side_by_side(f, names, out_path)
            return
        fig, axes = plt.subplots(len(names), 2, figsize=(13, 4.2 * len(names)), squeeze=False,
                                 constrained_layout=True)
        for row, name in enumerate(names):
            g = f[name]
            raster = g["raster"][:]
            theta, phi, density = g["cell_theta"][:], g["cell_phi"][:], g["cell_density"][:]
            vmax = max(raster.max(), 1e-300)
            extent = [-180, 180, 180, 0]

            ax = axes[row][0]
            tri = mtri.Triangulation(np.degrees(phi), np.degrees(theta))
            grid_phi, grid_theta = np.meshgrid(np.linspace(-180, 180, raster.shape[1]),
                                               np.linspace(0, 180, raster.shape[0]))
            interp = mtri.LinearTriInterpolator(tri, density)(grid_phi, grid_theta)
            ax.imshow(np.ma.masked_invalid(interp), extent=extent, aspect="auto", cmap="viridis",
                      vmin=0, vmax=vmax, interpolation="nearest")
            ax.set_facecolor("white")
            ax.set_title("interpolated cell centres (thesis method)", fontsize=9)

            ax = axes[row][1]
            im = ax.imshow(raster, extent=extent, aspect="auto", cmap="viridis", vmin=0, vmax=vmax,
                           interpolation="nearest")
            ax.set_title("cell of each direction (no interpolation)", fontsize=9)
            fig.colorbar(im, ax=axes[row].tolist(), label="p(w' | alpha)  [1/sr]")
            title = g.attrs["title"]
            title = title if isinstance(title, str) else title.decode()
            for ax in axes[row]:
                ax.set_title(title + "\n" + ax.get_title(), fontsize=8)
            for ax in axes[row]:
                ax.set_xlabel("phi [deg]")
                ax.set_ylabel("theta [deg]")
        fig.savefig(out_path, dpi=100, format="png")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: plot_directions.py PANELS.h5 OUT.png")
    try:
        draw(sys.argv[1], sys.argv[2])
    except OSError as e:  # a full disk: one line naming the file, for stf's error
        sys.exit(f"cannot write {e.filename or sys.argv[2]}: {e.strerror or e}")
