"""`import stf` against the command line it wraps and against its own pdf (ctest, Debian's python3).

Run by ctest with PYTHONPATH at build/python and STF_BINARY, STF_SOURCE_DIR set.
"""
import _thread
import math
import os
import subprocess
import sys
import tempfile
import threading
import time
import unittest

import h5py
import numpy as np

import stf

STF = os.environ["STF_BINARY"]
SOURCE = os.environ["STF_SOURCE_DIR"]
MEDIUM = ["--sigma-s", "2", "--sigma-a", "0.5", "--g", "0.3", "--alpha-bins", "6", "--grid", "healpix:4"]


# Objects made by __new__ without __init__ (m, p, s), in a child python where a crash fails the
# test alone: each expression of argv must raise stf.Error, and repr() must work.
NEVER_CONSTRUCTED = """
import sys
import numpy as np
import stf
m, p, s = stf.Model.__new__(stf.Model), stf.Pack.__new__(stf.Pack), stf.Spheres.__new__(stf.Spheres)
x, w, r, u = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), np.ones(1), np.zeros((1, 4))
for use in sys.argv[1:]:
    print(use, flush=True)
    try:
        eval(use)
    except stf.Error:
        continue
    sys.exit(use + " raised no stf.Error")
print("repr(m)", flush=True)
print(repr(m))
"""


def with_value(a, index, value):
    """A copy of array a with a[index] = value."""
    a = a.copy()
    a[index] = value
    return a


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
        self.assertEqual(len(pack.spheres(albedo=0.8, g=0.3)), 2)
        self.assertEqual(pack.media, [(0.8, 0.3)])

    def test_repr_prints_digits_find_reads_back(self):
        """What repr shows finds the entry again: every digit the pack stores is printed."""
        pack = stf.Pack(self.path("p.stfpack"))
        for _, model in pack:
            fields = repr(model).strip("<>").split()
            tau, albedo, g = (float(fields[i + 1]) for i in (fields.index("tau"), fields.index("albedo"), fields.index("g")))
            self.assertEqual((tau, albedo, g), (model.tau, model.albedo, model.g))
            self.assertEqual(pack.find(tau=tau, albedo=albedo, g=g).tau, model.tau)

    def test_world_jumps_are_model_draws_moved_and_turned(self):
        n = 1000
        rng = np.random.default_rng(2)
        x = rng.random((n, 3))
        w = np.tile([0.0, 0.0, 1.0], (n, 1))
        u = rng.random((n, 4))
        e = self.model.sample_world(x, w, np.full(n, 2.0), u)
        self.assertTrue(np.allclose(np.linalg.norm(e["exit_point"] - x, axis=1), 2.0))
        spheres = stf.Pack(self.path("p.stfpack")).spheres(albedo=0.8, g=0.3)
        j = spheres.jump(x, w, np.r_[np.full(n // 2, 0.4), np.full(n - n // 2, 0.6)], 5.0, u)
        self.assertTrue(np.all(j["sphere"][: n // 2] == -1))  # tau 2.5 needs a free radius of 0.5
        self.assertTrue(np.array_equal(j["point"][: n // 2], x[: n // 2]))
        self.assertTrue(np.all(j["sphere"][n // 2:] == 0))
        self.assertTrue(np.allclose(j["weight"][n // 2:], self.model.escape_probability))

    def test_strides_of_the_stride_form_draw_what_jumps_draw(self):
        n = 200000
        x, w, free = np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.full(n, 0.6)
        spheres = stf.Pack(self.path("p.stfpack")).spheres(albedo=0.8, g=0.3)
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
        with self.assertRaisesRegex(stf.Error, "n .* must be a whole number in 0"):
            self.model.sample(-1)
        with self.assertRaisesRegex(stf.Error, "no sphere of the medium albedo 0.9 g 0.3"):
            stf.Pack(self.path("p.stfpack")).spheres(albedo=0.9, g=0.3)
        with self.assertRaises(TypeError):  # by medium, never by name
            stf.Pack(self.path("p.stfpack")).spheres("a")

    def paths(self, n=4):
        """n paths at the origin heading +z, spheres of radius 2 about them, uniforms in [0, 1)."""
        return (np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.full(n, 2.0),
                np.random.default_rng(6).random((n, 4)))

    def test_uniforms_off_zero_to_one_are_refused(self):
        self.assertTrue(issubclass(stf.Error, ValueError))
        x, w, r, u = self.paths()
        spheres = stf.Pack(self.path("p.stfpack")).spheres(albedo=0.8, g=0.3)
        for bad in (np.nan, np.inf, -np.inf, -1e300, 1e300, 1.0, -1.0):
            one = u.copy()
            one[2, 1] = bad
            for uniforms in (np.full((4, 4), bad), one):
                with self.subTest(bad=bad, all=uniforms is not one):
                    with self.assertRaisesRegex(stf.Error, "uniforms"):
                        self.model.sample_world(x, w, r, uniforms)
                    with self.assertRaisesRegex(stf.Error, "uniforms"):
                        spheres.jump(x, w, np.full(4, 0.6), 5.0, uniforms)

    def test_paths_off_their_domain_are_refused(self):
        """Positions not finite, directions not unit vectors, radii not finite and > 0 (free radii:
        finite), sigma_t not finite and > 0: for sample_world, jump and stride."""
        x, w, r, u = self.paths()
        free, nan, inf = np.full(4, 0.6), np.nan, np.inf
        spheres = stf.Pack(self.path("p.stfpack")).spheres(albedo=0.8, g=0.3)
        cases = [("positions", with_value(x, (3, 0), bad), w, r, free, 5.0) for bad in (nan, inf, -inf)]
        cases += [("directions", x, with_value(w, 1, bad), r, free, 5.0)
                  for bad in ([0, 0, 2.0], [0, 0, 0.0], [nan, 0, 1.0], [0.5, 0.5, 0.5])]
        cases += [("radii", x, w, with_value(r, 3, bad), free, 5.0) for bad in (0.0, -1.0, nan, inf)]
        cases += [("free_radii", x, w, r, with_value(free, 3, bad), 5.0) for bad in (nan, inf, -inf)]
        cases += [("sigma_t", x, w, r, free, bad) for bad in (0.0, -1.0, nan, inf)]
        for i, (what, xs, ws, rs, fs, sigma_t) in enumerate(cases):
            with self.subTest(i=i, what=what):
                if what not in ("free_radii", "sigma_t"):
                    with self.assertRaisesRegex(stf.Error, what):
                        self.model.sample_world(xs, ws, rs, u)
                if what != "radii":
                    with self.assertRaisesRegex(stf.Error, what):
                        spheres.jump(xs, ws, fs, sigma_t, u)
                    with self.assertRaisesRegex(stf.Error, what):
                        spheres.stride(xs, ws, fs, sigma_t, seed=1)

    def test_inputs_at_the_edges_of_their_domains_still_draw(self):
        x, w, r, u = self.paths()
        u[0], u[1], u[2] = 0.0, -0.0, np.nextafter(1.0, 0.0)
        w[3] = np.array([1.0, 2.0, 3.0]) / math.sqrt(14)
        e = self.model.sample_world(x, w, r, u)
        self.assertTrue(np.allclose(np.linalg.norm(e["exit_point"] - x, axis=1), 2.0))
        # A free radius of 0, or just below as rounding leaves it on a sphere's surface, fits no sphere.
        j = stf.Pack(self.path("p.stfpack")).spheres(albedo=0.8, g=0.3).jump(x, w, np.array([0.0, -1e-15, 0.6, 0.6]), 5.0, u)
        self.assertEqual(list(j["sphere"]), [-1, -1, 0, 0])

    def test_objects_never_constructed_raise_stf_error(self):
        """stf.Model.__new__(stf.Model) and the like, without __init__: not a crash."""
        uses = {"Model": ["m.sample(3)", "m.tau", "m.escape_probability", "m.family", "m.alpha_edges",
                          "m.pdf(x, w)", "m.sample_world(x, w, r, u)"],
                "Pack": ["len(p)", "p.find(tau=1, albedo=0.8, g=0.3)", "p[0]", "p.spheres(albedo=0.8, g=0.3)"],
                "Spheres": ["len(s)", "s.jump(x, w, r, 1.0, u)", "s.stride(x, w, r, 1.0, seed=1)"]}
        for kind, exprs in uses.items():
            with self.subTest(kind):
                child = subprocess.run([sys.executable, "-c", NEVER_CONSTRUCTED, *exprs], capture_output=True,
                                       text=True, timeout=60)
                self.assertEqual(child.returncode, 0, child.stdout + child.stderr)
                self.assertIn("stf.Model", child.stdout.splitlines()[-1])

    def test_what_is_no_model_or_pack_raises_stf_error(self):
        os.makedirs(self.path("folder"), exist_ok=True)
        for make, path in ((stf.Pack, self.path("folder")), (stf.Model, self.path("folder")),
                           (stf.Pack, "/dev/zero"), (stf.Model, "/dev/zero"),  # not read forever
                           (stf.Pack, "/nonexistent"), (stf.Model, "/nonexistent"),
                           (stf.Model, self.path("t.h5")), (stf.Pack, self.path("t.h5"))):
            with self.subTest(make=make.__name__, path=path):
                with self.assertRaises(stf.Error):
                    make(path)

    def test_file_names_with_a_nul_are_refused(self):
        for make, name in ((stf.Model, "m.h5"), (stf.Pack, "p.stfpack")):
            with self.subTest(name):
                with self.assertRaisesRegex(stf.Error, "NUL"):
                    make(self.path(name) + "\x00junk")

    def test_long_draws_stop_at_ctrl_c(self):
        """One thread draws 2^23 exits in 8 rounds of 2^20 and looks for a Ctrl-C after each."""
        start = time.perf_counter()
        self.model.sample(2**20, threads=1)
        whole = 8 * (time.perf_counter() - start)
        timer = threading.Timer(0.2, _thread.interrupt_main)
        start = time.perf_counter()
        timer.start()
        try:
            with self.assertRaises(KeyboardInterrupt):
                self.model.sample(2**23, threads=1)
        finally:
            timer.cancel()
        self.assertLess(time.perf_counter() - start, 0.2 + whole / 2)
        self.assertEqual(self.model.sample(3)["pdf"].shape, (3,))

    def test_corrupted_models_are_refused_by_their_checksum(self):
        """stf writes the xxh3 of what follows the 512-byte user block into it: a flipped byte
        after the block (or a byte too many or too few) is refused; with the block cleared the
        file is one stf did not write, and loads."""
        with open(self.path("m.h5"), "rb") as f:
            good = f.read()
        self.assertTrue(good.startswith(b"stf-checksum xxh3-64 "))
        flipped = [good[:k] + bytes([good[k] ^ 1]) + good[k + 1:] for k in (512, 513, len(good) // 2, len(good) - 1)]
        for i, bad in enumerate([*flipped, good[:-1], good + b"\0"]):
            with self.subTest(i):
                with open(self.path("c.h5"), "wb") as f:
                    f.write(bad)
                with self.assertRaisesRegex(stf.Error, "checksum"):
                    stf.Model(self.path("c.h5"))
        with open(self.path("c.h5"), "wb") as f:
            f.write(bytes(512) + good[512:])
        self.assertEqual(stf.Model(self.path("c.h5")).tau, self.model.tau)

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
        mean, error = python_render.render_mean(stf.Pack(self.path("fog.stfpack")).spheres(albedo=8 / 8.2, g=0.6), 8, 0.2, 0.6, 2, 200000)
        render_error = math.sqrt(variance.sum()) / image.size
        self.assertLess(abs(mean - image.mean()), 4.5 * math.hypot(error, render_error))


if __name__ == "__main__":
    unittest.main()
