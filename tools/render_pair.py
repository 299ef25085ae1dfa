#!/usr/bin/python3
"""Brute force and shell strides side by side, with the z-map of their difference.

  tools/render_pair.py BRUTE.h5 STF.h5 -o PAIR.png [--title TEXT]

Reads two `stf render` images of the same scene (same size) and writes one figure:
  - both images through the same radiance window (window() says which) in a warm colour map,
    so that the medium's glow and its shading by the sun show against the sky;
  - z = (stf - brute) / sqrt(var_stf + var_brute) per 4 x 4 pixel block, from the images' own
    variances, on a diverging map over [-4.5, 4.5]: a correct strided render is noise
    there, with no structure.
Needs Debian's python3-matplotlib and python3-h5py.
"""
import argparse
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read(path):
    try:
        with h5py.File(path, "r") as f:
            return (np.array(f["/image/mean"]), np.array(f["/image/variance_of_mean"]),
                    {k: f.attrs[k] for k in f.attrs})
    except (OSError, KeyError) as e:
        sys.exit(f"render_pair: {path}: not an stf render image ({e})")


def window(images, k=4):
    """One radiance window for both: from the 2nd percentile of the pixels to the 99.5th of
    their 4 x 4 block means (so single bright paths, the sun seen through the medium, do not set
    it). Under a uniform sky a nearly white medium is about as bright as the sky; what tells
    them apart is the sun's glow, some tens of percent, which this window spreads over the map."""
    lo = min(np.percentile(im, 2) for im in images)
    hi = max(np.percentile(block_means(im, k), 99.5) for im in images)
    return lo, max(hi, lo * (1 + 1e-6) + 1e-12)


def block_sums(x, k=4):
    """Sums over k x k pixel blocks (a last partial row or column of blocks left out)."""
    h, w = x.shape
    return x[: h - h % k, : w - w % k].reshape(h // k, k, w // k, k).sum(axis=(1, 3))


def block_means(x, k=4):
    return block_sums(x, k) / (k * k)


def block_z(a, var_a, b, var_b, k=4):
    """z of each block's difference; blocks without variance (sky alone) are NaN."""
    var = block_sums(var_a, k) + block_sums(var_b, k)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(var > 0, (block_sums(a, k) - block_sums(b, k)) / np.sqrt(var), np.nan)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("brute")
    ap.add_argument("stf")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    brute, var_b, attrs_b = read(a.brute)
    stf, var_s, attrs_s = read(a.stf)
    if brute.shape != stf.shape:
        sys.exit(f"render_pair: the images differ in size: {brute.shape} and {stf.shape}")
    lo, hi = window([brute, stf])
    z = block_z(stf, var_s, brute, var_b)
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.4))
    for ax, image, attrs, name in ((axes[0], brute, attrs_b, "brute force"), (axes[1], stf, attrs_s, "shell strides")):
        ax.imshow(np.clip((image - lo) / (hi - lo), 0, 1) ** (1 / 1.5), cmap="inferno", vmin=0, vmax=1,
                  interpolation="nearest")
        ax.set_title(f"{name}: {int(attrs['spp'])} spp, {float(attrs['seconds']):.3g} s")
        ax.axis("off")
    finite = z[np.isfinite(z)]
    im = axes[2].imshow(z, cmap="RdBu_r", vmin=-4.5, vmax=4.5, interpolation="nearest")
    axes[2].set_title(f"z of 4x4 blocks: max |z| {np.max(np.abs(finite)) if finite.size else 0:.2f}")
    axes[2].axis("off")
    fig.colorbar(im, ax=axes[2], fraction=0.046)
    tau = float(attrs_b["radius"]) * (float(attrs_b["sigma_s"]) + float(attrs_b["sigma_a"]))
    albedo = float(attrs_b["sigma_s"]) / (float(attrs_b["sigma_s"]) + float(attrs_b["sigma_a"]))
    fig.suptitle(a.title or f"sphere of tau {tau:g}, albedo {albedo:g}, g {float(attrs_b['g']):g} "
                 f"(radiance {lo:.3g} black to {hi:.3g} white; the sky is 1, the sun upper right)")
    fig.tight_layout()
    fig.savefig(a.output, dpi=100)


if __name__ == "__main__":
    main()
