"""A Python integrator that strides through a sphere of medium with stf's spheres.

It renders the scene of `stf render` (a sphere of medium at the origin, a pinhole camera on the
-z axis, a sky of radiance 1 with a sun of 50) and returns the image's mean radiance with its
standard error: paths jump through the largest precomputed sphere that fits around them and
track single collisions only near the boundary, where none fits (docs/python.md).

    PYTHONPATH=build/python /usr/bin/python3 examples/python_render.py PACK \\
        SIGMA_S SIGMA_A G RADIUS [PATHS]

The pack's spheres are those of the medium's albedo sigma_s / (sigma_s + sigma_a) and g.
"""
import sys

import numpy as np

import stf

SUN = np.array([1.0, 1.0, -1.0]) / np.sqrt(3.0)


def sky(w):
    """Radiance arriving from directions w [n, 3]."""
    return np.where(w @ SUN >= np.cos(np.radians(5.0)), 50.0, 1.0)


def camera_paths(n, radius, rng):
    """Rays through uniform points of a square image (40 degrees high), from 4 radii away."""
    half = np.tan(np.radians(20.0))
    d = np.column_stack([(2 * rng.random(n) - 1) * half, (1 - 2 * rng.random(n)) * half, np.ones(n)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.array([0.0, 0.0, -4.0 * radius])
    b = d @ o
    disc = b * b - (o @ o - radius * radius)
    hit = (disc > 0) & (b < 0)
    x = o + (-b - np.sqrt(np.where(hit, disc, 0)))[:, None] * d
    return x, d, hit


def scatter(w, g, u, v):
    """Henyey-Greenstein turns of directions w [n, 3] by uniforms u, v."""
    s = (1 - g * g) / (1 - g + 2 * g * u)
    mu = (1 + g * g - s * s) / (2 * g) if g != 0 else 2 * u - 1
    a = np.where(np.abs(w[:, 0:1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(w, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(w, t1)
    sin = np.sqrt(np.maximum(0, 1 - mu * mu))
    phi = 2 * np.pi * v
    return (mu[:, None] * w + (sin * np.cos(phi))[:, None] * t1 + (sin * np.sin(phi))[:, None] * t2)


def render_mean(spheres, sigma_s, sigma_a, g, radius, paths, seed=1):
    """Mean radiance of the image and its standard error, from `paths` camera paths."""
    rng = np.random.default_rng(seed)
    sigma_t, albedo = sigma_s + sigma_a, sigma_s / (sigma_s + sigma_a)
    x, w, hit = camera_paths(paths, radius, rng)
    value = np.where(hit, 0.0, sky(w))
    live = np.flatnonzero(hit)
    weight = np.ones(paths)
    while live.size:
        free = radius - np.linalg.norm(x[live], axis=1)
        j = spheres.jump(x[live], w[live], free, sigma_t, rng.random((live.size, 4)))
        x[live], w[live] = j["point"], j["direction"]
        weight[live] *= j["weight"]
        walk = live[j["sphere"] < 0]  # no sphere fits: one free flight and its collision
        x[walk] += (-np.log1p(-rng.random(walk.size)) / sigma_t)[:, None] * w[walk]
        out = walk[np.einsum("ij,ij->i", x[walk], x[walk]) > radius * radius]
        value[out] = weight[out] * sky(w[out])
        stay = np.setdiff1d(walk, out, assume_unique=True)
        weight[stay] *= albedo
        w[stay] = scatter(w[stay], g, rng.random(stay.size), rng.random(stay.size))
        live = np.setdiff1d(live, out, assume_unique=True)
        low = live[weight[live] < 0.25]  # Russian roulette, as stf render plays it
        dead = low[rng.random(low.size) * 0.25 >= weight[low]]
        weight[low] = 0.25
        live = np.setdiff1d(live, dead, assume_unique=True)
    return value.mean(), value.std(ddof=1) / np.sqrt(paths)


def main():
    if len(sys.argv) not in (6, 7):
        sys.exit(__doc__)
    pack = stf.Pack(sys.argv[1])
    sigma_s, sigma_a, g, radius = map(float, sys.argv[2:6])
    paths = int(float(sys.argv[6])) if len(sys.argv) == 7 else 100000
    spheres = pack.spheres(albedo=sigma_s / (sigma_s + sigma_a), g=g)
    mean, error = render_mean(spheres, sigma_s, sigma_a, g, radius, paths)
    print(f"mean radiance {mean:.5f} +- {error:.5f} ({paths} paths)")


if __name__ == "__main__":
    main()
