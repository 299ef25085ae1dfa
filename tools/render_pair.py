#!/usr/bin/python3
"""Brute force and shell strides side by side, with the z-map of their difference.

  tools/render_pair.py BRUTE.h5 STF.h5 -o PAIR.png [--title TEXT]

Reads two `stf render` images of the same scene (same size) and writes one figure:
  - a sphere's grey images through the same radiance window (window() says which) in a warm
    colour map, so that the medium's glow and its shading by the sun show against the sky; a
    scene's RGB images tone-mapped as `stf render --png` does (filmic curve, sRGB);
  - z = (stf - brute) / sqrt(var_stf + var_brute) per 4 x 4 pixel block, from the images' own
    variances, on a diverging map over [-4.5, 4.5] (for RGB, the channel of largest |z|): a
    correct strided render is noise there, with no structure.
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


def tone(x, exposure=-0.5):
    """Radiance to sRGB as `stf render --png` (render/image_file.cpp): 2^exposure, Narkowicz's
    ACES fit, the sRGB curve."""
    x = np.maximum(x * 2.0 ** exposure, 0)
    y = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    return np.where(y <= 0.0031308, 12.92 * y, 1.055 * np.power(y, 1 / 2.4) - 0.055)


def rgb_z(a, var_a, b, var_b, k=4):
    """Per block, the z of the channel with the largest |z|."""
    zs = np.stack([block_z(a[..., c], var_a[..., c], b[..., c], var_b[..., c], k) for c in range(3)])
    pick = np.nanargmax(np.where(np.isfinite(zs), np.abs(zs), -1), axis=0)
    return np.take_along_axis(zs, pick[None], axis=0)[0]


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
    colour = brute.ndim == 3
    lo, hi = (0, 1) if colour else window([brute, stf])
    z = rgb_z(stf, var_s, brute, var_b) if colour else block_z(stf, var_s, brute, var_b)
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.4))
    for ax, image, attrs, name in ((axes[0], brute, attrs_b, "brute force"), (axes[1], stf, attrs_s, "shell strides")):
        shown = tone(image) if colour else np.clip((image - lo) / (hi - lo), 0, 1) ** (1 / 1.5)
        ax.imshow(shown, cmap=None if colour else "inferno", vmin=0, vmax=1, interpolation="nearest")
        ax.set_title(f"{name}: {int(attrs['spp'])} spp, {float(attrs['seconds']):.3g} s")
        ax.axis("off")
    finite = z[np.isfinite(z)]
    im = axes[2].imshow(z, cmap="RdBu_r", vmin=-4.5, vmax=4.5, interpolation="nearest")
    axes[2].set_title(f"z of 4x4 blocks: max |z| {np.max(np.abs(finite)) if finite.size else 0:.2f}")
    axes[2].axis("off")
    fig.colorbar(im, ax=axes[2], fraction=0.046)
    if colour:
        scene = attrs_b["scene"].decode() if isinstance(attrs_b["scene"], bytes) else str(attrs_b["scene"])
        fig.suptitle(a.title or f"{scene}: brute force and shell strides (4x4 blocks: the channel of largest |z|)")
        fig.tight_layout()
        fig.savefig(a.output, dpi=100)
        return
    tau = float(attrs_b["radius"]) * (float(attrs_b["sigma_s"]) + float(attrs_b["sigma_a"]))
    albedo = float(attrs_b["sigma_s"]) / (float(attrs_b["sigma_s"]) + float(attrs_b["sigma_a"]))
    fig.suptitle(a.title or f"sphere of tau {tau:g}, albedo {albedo:g}, g {float(attrs_b['g']):g} "
                 f"(radiance {lo:.3g} black to {hi:.3g} white; the sky is 1, the sun upper right)")
    fig.tight_layout()
    fig.savefig(a.output, dpi=100)


if __name__ == "__main__":
    main()
