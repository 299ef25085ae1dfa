"""`import stf` against the command line it wraps and against its own pdf (ctest, Debian's python3).

Run by ctest with PYTHONPATH at build/python and STF_BINARY, STF_SOURCE_DIR set.
"""
import math
import os
import subprocess
import sys
import tempfile
import unittest

import h5py
import numpy as np

import stf

STF = os.environ["STF_BINARY"]
SOURCE = os.environ["STF_SOURCE_DIR"]
MEDIUM = ["--sigma-s", "2", "--sigma-a", "0.5", "--g", "0.3", "--alpha-bins", "6", "--grid", "healpix:4"]


def run(*args):
    subprocess.run([STF, *args], check=True, capture_output=True)


def chi2_p(observed, expected):
    """Upper tail of the chi-square statistic (Wilson-Hilferty), bins of expectation < 5 pooled."""
    order = np.argsort(expected)
    obs, exp, pooled_o, pooled_e = [], [], 0.0, 0.0
    for i in order:
        pooled_o += observed[i]
        pooled_e += expected[i]
        if pooled_e >= 5:
            obs.append(pooled_o), exp.append(pooled_e)
            pooled_o = pooled_e = 0.0
    if pooled_e > 0:
        obs[-1] += pooled_o
        exp[-1] += pooled_e
    obs, exp = np.array(obs), np.array(exp)
    return chi2_tail(float(((obs - exp) ** 2 / exp).sum()), len(obs) - 1)


def chi2_tail(x, k):
    """P(chi-square with k degrees of freedom > x), by Wilson-Hilferty."""
    z = ((x / k) ** (1 / 3) - (1 - 2 / (9 * k))) / math.sqrt(2 / (9 * k))
    return 0.5 * math.erfc(z / math.sqrt(2))


def two_sample_p(a, b):
    """Homogeneity of two histograms of equal totals: sum (a - b)^2 / (a + b) over the bins
    holding 10 or more, k - 1 degrees of freedom."""
    keep = a + b >= 10
    return chi2_tail(float(((a[keep] - b[keep]) ** 2 / (a[keep] + b[keep])).sum()), int(keep.sum()) - 1)


class Stf(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        run("precompute", *MEDIUM, "--paths", "2e5", "--quiet", "-o", cls.path("t.h5"))
        run("fit", cls.path("t.h5"), "--model", "vmf:2", "--quiet", "-o", cls.path("m.h5"))
        run("precompute", *MEDIUM, "--radius", "2", "--paths", "1e5", "--quiet", "-o", cls.path("t2.h5"))
        run("fit", cls.path("t2.h5"), "--model", "vmf:2", "--quiet", "-o", cls.path("m2.h5"))
        run("pack", cls.path("m.h5"), cls.path("m2.h5"), "--name", "a", "--name", "a", "-o", cls.path("p.stfpack"))
        cls.model = stf.Model(cls.path("m.h5"))

    @classmethod
    def path(cls, name):
        return os.path.join(cls.dir.name, name)

    @classmethod
    def tearDownClass(cls):
        cls.dir.cleanup()

    def test_draws_are_those_of_stf_sample(self):
        run("sample", self.path("m.h5"), "--count", "50000", "--seed", "3", "-o", self.path("s.h5"))
        mine = self.model.sample(50000, seed=3)
        with h5py.File(self.path("s.h5")) as f:
            for key in ("exit_point", "exit_direction", "pdf", "component"):
                self.assertTrue(np.array_equal(mine[key], f["samples"][key][()]), key)

    def test_pdf_is_that_of_stf_sample_eval(self):
        run("sample", self.path("m.h5"), "--count", "20000", "--seed", "4", "-o", self.path("s4.h5"))
        run("sample", self.path("m.h5"), "--eval", self.path("s4.h5"), "-o", self.path("e.h5"))
        with h5py.File(self.path("s4.h5")) as s, h5py.File(self.path("e.h5")) as e:
            p = self.model.pdf(s["samples/exit_point"][()], s["samples/exit_direction"][()])
            self.assertTrue(np.array_equal(p, e["samples/pdf"][()]))

    def test_threads_give_the_same_draws(self):
        one = self.model.sample(300000, seed=9, threads=1)
        for threads in (2, 3):
            many = self.model.sample(300000, seed=9, threads=threads)
            for key in one:
                self.assertTrue(np.array_equal(one[key], many[key]), (threads, key))

    def test_draws_match_the_pdf_chi_square(self):
        """Exit points binned by the model's alpha bins and exit directions (in the frame where the
        point lies in the x-z plane) by z and the sign of y; expected counts integrate pdf() by
        Gauss-Legendre in cos(alpha) and direction z, and the midpoint rule in azimuth. The
        singular parts are two more bins of their probabilities."""
        m, n = self.model, 400000
        s = m.sample(n, seed=5)
        smooth = s["component"] == 0
        p, d = s["exit_point"][smooth], s["exit_direction"][smooth]
        beta = np.arctan2(p[:, 1], p[:, 0])
        c, sn = np.cos(-beta), np.sin(-beta)
        local = np.column_stack([c * d[:, 0] - sn * d[:, 1], sn * d[:, 0] + c * d[:, 1], d[:, 2]])
        cos_edges = np.cos(m.alpha_edges)[::-1]  # increasing
        z_edges = np.linspace(-1, 1, 7)
        a = np.clip(np.searchsorted(cos_edges, p[:, 2], side="right") - 1, 0, m.alpha_bins - 1)
        z = np.clip(np.searchsorted(z_edges, local[:, 2], side="right") - 1, 0, 5)
        observed = np.bincount((a * 6 + z) * 2 + (local[:, 1] >= 0), minlength=m.alpha_bins * 12).astype(float)
        expected = np.zeros_like(observed)
        nodes, weights = np.polynomial.legendre.leggauss(8)
        phi = (np.arange(256) + 0.5) * 2 * np.pi / 256
        for i in range(m.alpha_bins):
            for ca, wa in zip(*self._gauss(cos_edges[i], cos_edges[i + 1], nodes, weights)):
                point = np.array([math.sqrt(1 - ca * ca), 0, ca])
                for k in range(6):
                    for wz, ww in zip(*self._gauss(z_edges[k], z_edges[k + 1], nodes, weights)):
                        r = math.sqrt(max(0, 1 - wz * wz))
                        dirs = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full_like(phi, wz)])
                        f = m.pdf(np.tile(point, (phi.size, 1)), dirs) * (2 * np.pi / phi.size) * ww * wa * 2 * np.pi
                        j = (i * 6 + k) * 2
                        expected[j + 1] += f[dirs[:, 1] >= 0].sum()
                        expected[j] += f[dirs[:, 1] < 0].sum()
        singular = [m.uncollided_probability, m.once_probability]
        self.assertAlmostEqual(expected.sum() + sum(singular), 1, delta=2e-3)
        observed = np.append(observed, [(s["component"] == 1).sum(), (s["component"] == 2).sum()])
        expected = np.append(expected * n, [n * f for f in singular])
        self.assertGreater(chi2_p(observed, expected), 1e-6)

    @staticmethod
    def _gauss(lo, hi, nodes, weights):
        return 0.5 * (hi - lo) * nodes + 0.5 * (hi + lo), 0.5 * (hi - lo) * weights

    def test_shapes_dtypes_and_attributes(self):
        s = self.model.sample(7)
        self.assertEqual(s["exit_point"].shape, (7, 3))
        self.assertEqual(s["exit_direction"].dtype, np.float64)
        self.assertEqual(s["pdf"].shape, (7,))
        self.assertEqual(s["component"].dtype, np.int8)
        self.assertEqual(self.model.sample(0)["pdf"].shape, (0,))
        self.assertAlmostEqual(self.model.tau, 2.5)
        self.assertAlmostEqual(self.model.albedo, 0.8)
        self.assertEqual((self.model.family, self.model.size, self.model.alpha_bins), ("vmf", 2, 6))
        with h5py.File(self.path("m.h5")) as f:
            self.assertEqual(self.model.escape_probability, f.attrs["escape_probability"])

    def test_pack_entries_and_lookup(self):
        pack = stf.Pack(self.path("p.stfpack"))
        self.assertEqual(len(pack), 2)
        self.assertEqual(pack[0][0], "a")
        self.assertAlmostEqual(pack.find(tau=3, albedo=0.8, g=0.3).tau, 2.5)
        self.assertAlmostEqual(pack.find(tau=5, albedo=0.8, g=0.3).tau, 5)
        self.assertAlmostEqual(pack.find(tau=500, albedo=0.8, g=0.3).tau, 5)
        self.assertIsNone(pack.find(tau=2, albedo=0.8, g=0.3))
        self.assertIsNone(pack.find(tau=5, albedo=0.9, g=0.3))
        self.assertEqual(len(pack.spheres("a")), 2)

    def test_world_jumps_are_model_draws_moved_and_turned(self):
        n = 1000
        rng = np.random.default_rng(2)
        x = rng.random((n, 3))
        w = np.tile([0.0, 0.0, 1.0], (n, 1))
        u = rng.random((n, 4))
        e = self.model.sample_world(x, w, np.full(n, 2.0), u)
        self.assertTrue(np.allclose(np.linalg.norm(e["exit_point"] - x, axis=1), 2.0))
        spheres = stf.Pack(self.path("p.stfpack")).spheres("a")
        j = spheres.jump(x, w, np.r_[np.full(n // 2, 0.4), np.full(n - n // 2, 0.6)], 5.0, u)
        self.assertTrue(np.all(j["sphere"][: n // 2] == -1))  # tau 2.5 needs a free radius of 0.5
        self.assertTrue(np.array_equal(j["point"][: n // 2], x[: n // 2]))
        self.assertTrue(np.all(j["sphere"][n // 2:] == 0))
        self.assertTrue(np.allclose(j["weight"][n // 2:], self.model.escape_probability))

    def test_strides_of_the_stride_form_draw_what_jumps_draw(self):
        n = 200000
        x, w, free = np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.full(n, 0.6)
        spheres = stf.Pack(self.path("p.stfpack")).spheres("a")
        j = spheres.jump(x, w, free, 5.0, np.random.default_rng(3).random((n, 4)))
        s = spheres.stride(x, w, free, 5.0, seed=4)
        again = spheres.stride(x, w, free, 5.0, seed=4, threads=3)
        for key in ("point", "direction", "weight", "sphere"):
            self.assertTrue(np.array_equal(s[key], again[key]), key)  # any thread count
            if key != "point" and key != "direction":
                self.assertTrue(np.array_equal(s[key], j[key]), key)
        self.assertTrue(np.allclose(np.linalg.norm(s["point"], axis=1), 0.5))  # tau 2.5 at sigma_t 5

        def cells(e):  # cos(alpha) of the exit point and the exit direction's z, 12 x 12
            h = np.histogram2d(e["point"][:, 2] / 0.5, e["direction"][:, 2], bins=12, range=[[-1, 1], [-1, 1]])
            return h[0].ravel()

        self.assertGreater(two_sample_p(cells(j), cells(s)), 1e-6)
        other = spheres.stride(x, w, free, 5.0, seed=5)
        self.assertFalse(np.array_equal(s["point"], other["point"]))

    def test_errors_carry_the_command_lines_line(self):
        with open(self.path("x.json"), "w") as f:
            f.write("{}")
        cli = subprocess.run([STF, "sample", self.path("x.json"), "-o", self.path("y.h5")], capture_output=True, text=True)
        with self.assertRaises(stf.Error) as caught:
            stf.Model(self.path("x.json"))
        self.assertEqual("stf: error: " + str(caught.exception) + "\n", cli.stderr)
        with self.assertRaisesRegex(stf.Error, "No such file"):
            stf.Model(self.path("none.h5"))
        with self.assertRaisesRegex(stf.Error, "STFPACK|pack"):
            stf.Pack(self.path("m.h5"))
        with self.assertRaisesRegex(stf.Error, r"shape \[4, 3\], got \[4, 2\]"):
            self.model.pdf(np.zeros((4, 3)), np.zeros((4, 2)))
        with self.assertRaisesRegex(stf.Error, "n must be >= 0"):
            self.model.sample(-1)
        with self.assertRaisesRegex(stf.Error, "no sphere of medium 'b'"):
            stf.Pack(self.path("p.stfpack")).spheres("b")

    def test_the_python_integrator_agrees_with_stf_render(self):
        """examples/python_render.py strides through the same pack as `stf render --pack`: the
        image means agree within their standard errors."""
        scene = self.path("fog.toml")
        with open(scene, "w") as f:
            f.write('[settings]\npaths = 20000\ngrid = "healpix:4"\nalpha_bins = 18\nmodel = "vmf:2"\n'
                    '[[media]]\nname = "fog"\nsigma_s = 8.0\nsigma_a = 0.2\ng = 0.6\nradius_min = 0.25\nradius_max = 2.0\n')
        run("build", scene, "--quiet", "--cache", self.path("cache"), "-o", self.path("fog.stfpack"))
        run("render", "--sigma-s", "8", "--sigma-a", "0.2", "--g", "0.6", "--radius", "2", "--method", "stf", "--pack",
            self.path("fog.stfpack"), "--spp", "64", "--quiet", "-o", self.path("r.h5"))
        with h5py.File(self.path("r.h5")) as f:
            image, variance = f["image/mean"][()], f["image/variance_of_mean"][()]
        sys.path.insert(0, os.path.join(SOURCE, "examples"))
        import python_render
        mean, error = python_render.render_mean(stf.Pack(self.path("fog.stfpack")).spheres("fog"), 8, 0.2, 0.6, 2, 200000)
        render_error = math.sqrt(variance.sum()) / image.size
        self.assertLess(abs(mean - image.mean()), 4.5 * math.hypot(error, render_error))


if __name__ == "__main__":
    unittest.main()
