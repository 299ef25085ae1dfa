"""Running the stf CLI from Python: the pieces bench/ and `stf report` share."""
import json
import math
import os
import subprocess
import sys

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class Stf:
    def __init__(self, binary=None):
        self.binary = binary or os.environ.get("STF_BINARY") or os.path.join(ROOT, "build", "stf")

    def run(self, *args):
        """Runs stf quietly; its stderr is shown only when it fails."""
        done = subprocess.run([self.binary, *map(str, args)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True)
        if done.returncode != 0:
            sys.stderr.write(done.stderr)
            done.check_returncode()

    def precompute(self, medium, paths, seed, path, grid, bins, threads=0):
        """Walks a table; returns its wall-clock seconds (the runtime_s attribute)."""
        self.run("precompute", "--sigma-s", medium["sigma_s"], "--sigma-a", medium["sigma_a"], "--g", medium["g"],
                 "--paths", int(paths), "--seed", seed, "--grid", grid, "--alpha-bins", bins, "--threads", threads,
                 "--quiet", "-o", path)
        with h5py.File(path, "r") as f:
            return float(f.attrs["runtime_s"])

    def fit(self, table, fit_args, path):
        """Fits a model; returns (fit seconds, model bytes)."""
        self.run("fit", table, *fit_args, "--quiet", "-o", path)
        with h5py.File(path, "r") as f:
            return float(f.attrs["fit_time_s"]), int(f.attrs["model_bytes"])

    def render(self, medium, radius, spp, method, out, seed=1, size=64, extra=()):
        """Renders the test scene; returns (image mean, variance of mean, stats of --json)."""
        stats = out + ".json"
        self.run("render", "--sigma-s", medium["sigma_s"], "--sigma-a", medium["sigma_a"], "--g", medium["g"],
                 "--radius", radius, "--width", size, "--height", size, "--spp", int(spp), "--method", method,
                 "--seed", seed, "--quiet", "-o", out, "--json", stats, *extra)
        with h5py.File(out, "r") as f, open(stats) as s:
            return f["image/mean"][()], f["image/variance_of_mean"][()], json.load(s)

    def below_tangent(self, model, out, count=1000000, seed=5):
        """Share of a model's samples of its smooth part that leave below the tangent plane at
        their exit point (w . y < 0): mass a family on the outward hemisphere would put
        elsewhere."""
        self.run("sample", model, "--count", count, "--seed", seed, "-o", out)
        with h5py.File(out, "r") as f:
            y, w = f["samples/exit_point"][()], f["samples/exit_direction"][()]
            smooth = f["samples/component"][()] == 0
        os.remove(out)
        return float(((y * w).sum(axis=1) < 0)[smooth].sum()) / len(smooth)

    def evaluate(self, candidate, reference, out, cells=None):
        """`stf eval`'s JSON; with `cells`, also writes the candidate binned there (--cells)."""
        self.run("eval", candidate, "--reference", reference, "--json", out, *(["--cells", cells] if cells else []))
        with open(out) as f:
            return json.load(f)


def power_law(points):
    """Least squares of log y = log a + b log x; returns (a, b)."""
    xs = [math.log(x) for x, _ in points]
    ys = [math.log(y) for _, y in points]
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    return math.exp(my - b * mx), b
