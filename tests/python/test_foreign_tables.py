"""Tables stf did not make, written here with h5py and numpy: fitted, smoothed and imported by
the command line (ctest, Debian's python3, STF_BINARY set).
"""
import os
import signal
import subprocess
import tempfile
import unittest

import h5py
import numpy as np

STF = os.environ["STF_BINARY"]
SEED = int(os.environ.get("STF_TEST_SEED", "31"))


def stf(*args):
    """Exit status and stderr of one stf command."""
    done = subprocess.run([STF, *map(str, args)], capture_output=True, text=True)
    return done.returncode, done.stderr


def check(*args):
    status, err = stf(*args)
    if status != 0:
        raise AssertionError(f"stf {' '.join(map(str, args))}: {err}")


def write_bytes(path, data):
    with open(path, "wb") as f:
        f.write(data)


def write_minimal(path, weight, edges, direction, solid_angle, **attrs):
    with h5py.File(path, "w") as f:
        f["escape/weight"] = weight
        f["escape/alpha_edges"] = edges
        f["grid/direction"] = direction
        f["grid/solid_angle"] = solid_angle
        for k, v in attrs.items():
            f.attrs[k] = v


class ForeignTables(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        # The grid's cells, as stf lays them out: from an import of an empty histogram.
        bins, nside = 8, 8
        cls.bins, cls.cells = bins, 12 * nside * nside
        np.save(cls.path("empty.npy"), np.zeros((bins, cls.cells)))
        check("import", cls.path("empty.npy"), "--grid", f"healpix:{nside}", "--alpha-bins", bins, "--quiet",
              "-o", cls.path("layout.h5"))
        with h5py.File(cls.path("layout.h5"), "r") as f:
            cls.edges = f["escape/alpha_edges"][()]
            cls.direction = f["grid/direction"][()]
            cls.solid_angle = f["grid/solid_angle"][()]

    @classmethod
    def tearDownClass(cls):
        cls.dir.cleanup()

    @classmethod
    def path(cls, name):
        return os.path.join(cls.dir.name, name)

    def truth(self):
        """A known exit distribution per (alpha bin, cell): two vMF lobes per bin turning with
        alpha (density at the cell centre times its solid angle, normalised), and an alpha
        marginal in proportion to each bin's area times a falling weight."""
        p = np.zeros((self.bins, self.cells))
        for b in range(self.bins):
            a = 0.5 * (self.edges[b] + self.edges[b + 1])
            for weight, kappa, angle in ((0.7, 12.0, 0.5 * a), (0.3, 3.0, a + 0.6)):
                mean = np.array([np.sin(angle), 0.0, np.cos(angle)])
                p[b] += weight * np.exp(kappa * (self.direction @ mean - 1)) * self.solid_angle
            p[b] /= p[b].sum()
            p[b] *= (np.cos(self.edges[b]) - np.cos(self.edges[b + 1])) * np.exp(-0.3 * b)
        return p / p.sum()

    def test_smoothed_table_is_closer_to_the_truth_than_its_histogram(self):
        # 1e5 draws over 8 x 768 cells: the histogram's expected TV to the truth is
        # 0.5 sum_c sqrt(2 n p_c / pi) / n over the cells (most hold a few draws), about 0.07, and
        # its spread between seeds a few thousandths; lobes fitted to 1e5 draws of lobes miss by
        # the noise of a handful of parameters per bin, a fraction of that. Half the histogram's
        # TV is many standard deviations away from either.
        truth = self.truth()
        rng = np.random.default_rng(SEED)
        counts = rng.multinomial(100000, truth.ravel()).reshape(truth.shape).astype(np.int64)
        table, smoothed = self.path("drawn.h5"), self.path("smoothed.h5")
        write_minimal(table, counts, self.edges, self.direction, self.solid_angle)
        check("smooth", table, "--model", "vmf:auto", "--threads", 2, "--quiet", "-o", smoothed)
        with h5py.File(smoothed, "r") as f:
            smooth = f["escape/weight"][()]
            self.assertEqual(f.attrs["smoothed_from"], table)
            self.assertTrue(f.attrs["smoothed_by"].startswith("vmf:"))
            self.assertEqual(f["grid/direction"].shape, self.direction.shape)
        self.assertAlmostEqual(smooth.sum(), counts.sum(), delta=1e-6 * counts.sum())
        tv_raw = 0.5 * np.abs(counts / counts.sum() - truth).sum()
        tv_smooth = 0.5 * np.abs(smooth / smooth.sum() - truth).sum()
        self.assertLess(tv_smooth, 0.5 * tv_raw, f"smoothed {tv_smooth:.4f}, histogram {tv_raw:.4f}")
        # Every command that reads a table reads the smoothed one; its weights are no counts, so
        # the automatic choices are refused in one line and fixed sizes fit.
        check("eval", smoothed, "--reference", table, "--json", self.path("eval.json"))
        status, err = stf("fit", smoothed, "--model", "auto", "-o", self.path("m.h5"))
        self.assertEqual(status, 2)
        self.assertEqual(err.count("\n"), 1, err)
        self.assertIn("fixed size", err)
        self.assertFalse(os.path.exists(self.path("m.h5")))
        check("fit", smoothed, "--model", "vmf:2", "--quiet", "-o", self.path("m.h5"))

    def test_import_round_trips(self):
        rng = np.random.default_rng(SEED + 1)
        counts = rng.poisson(2.0, (self.bins, self.cells))
        tables = {}
        for name, data in (("i64.npy", counts.astype("<i8")), ("f32.npy", counts.astype("<f4")),
                           ("i32.npy", counts.astype("<i4")), ("f64.npy", counts.astype("<f8"))):
            np.save(self.path(name), data)
            tables[name] = data
        b, c = np.nonzero(counts)
        with open(self.path("rows.csv"), "w") as f:
            f.write("# alpha_bin, cell, count\n")
            f.writelines(f"{i}, {j}, {counts[i, j]}\n" for i, j in zip(b, c))
        # Angles: the bins' middles and the cells' centres.
        middle = 0.5 * (self.edges[:-1] + self.edges[1:])
        theta = np.arccos(np.clip(self.direction[:, 2], -1, 1))
        phi = np.arctan2(self.direction[:, 1], self.direction[:, 0])
        with open(self.path("angles.txt"), "w") as f:
            f.writelines(f"{middle[i]!r}\t{theta[j]!r} {phi[j]!r}  {counts[i, j]}  # one row\n" for i, j in zip(b, c))
        for name in (*tables, "rows.csv", "angles.txt"):
            out = self.path(name + ".h5")
            check("import", self.path(name), "--grid", "healpix:8", "--alpha-bins", self.bins, "--quiet", "-o", out)
            with h5py.File(out, "r") as f:
                np.testing.assert_array_equal(f["escape/weight"][()], counts, err_msg=name)
                self.assertEqual(f.attrs["grid"], "healpix:8")

    def test_import_of_a_million_rows(self):
        rng = np.random.default_rng(SEED + 2)
        rows = 1000000
        b = rng.integers(0, self.bins, rows)
        c = rng.integers(0, self.cells, rows)
        middle = 0.5 * (self.edges[:-1] + self.edges[1:])
        theta = np.arccos(np.clip(self.direction[:, 2], -1, 1))
        phi = np.arctan2(self.direction[:, 1], self.direction[:, 0])
        np.savetxt(self.path("million.txt"), np.column_stack([middle[b], theta[c], phi[c], np.ones(rows)]),
                   fmt=["%.17g", "%.17g", "%.17g", "%d"])
        check("import", self.path("million.txt"), "--grid", "healpix:8", "--alpha-bins", self.bins, "--quiet",
              "--paths", 2 * rows, "--sigma-s", 1, "--sigma-a", 0.1, "--g", 0.2, "-o", self.path("million.h5"))
        expected = np.bincount(b * self.cells + c, minlength=self.bins * self.cells).reshape(self.bins, self.cells)
        with h5py.File(self.path("million.h5"), "r") as f:
            np.testing.assert_array_equal(f["escape/weight"][()], expected)
            self.assertEqual(f.attrs["paths"], 2 * rows)
            self.assertAlmostEqual(f.attrs["tau"], 1.1)

    def test_bad_rows_are_named_by_their_line(self):
        cases = {"0 1 2\n\n# note\n1 2 x\n": "line 4", "0 1 2\n1 2 3 4\n": "line 2",
                 f"0 {self.cells} 1\n": "line 1", "3.5 0.1 0.2 1\n": "line 1", "0 1 -2\n": "line 1",
                 "0 1\n": "line 1"}
        for text, where in cases.items():
            with open(self.path("bad.csv"), "w") as f:
                f.write(text)
            status, err = stf("import", self.path("bad.csv"), "--grid", "healpix:8", "--alpha-bins", self.bins,
                              "-o", self.path("bad.h5"))
            self.assertEqual(status, 2, text)
            self.assertIn(where, err, text)
            self.assertEqual(err.count("\n"), 1, err)
            self.assertFalse(os.path.exists(self.path("bad.h5")))

    def test_npy_files_it_cannot_read_are_refused(self):
        counts = np.ones((self.bins, self.cells))
        np.save(self.path("good.npy"), counts)
        with open(self.path("good.npy"), "rb") as f:
            good = f.read()
        cases = {
            "fortran.npy": (lambda p: np.save(p, np.asfortranarray(counts)), "C order"),
            "shape.npy": (lambda p: np.save(p, counts[:, :-1]), "shape"),
            "big_endian.npy": (lambda p: np.save(p, counts.astype(">f8")), ">f8"),
            "complex.npy": (lambda p: np.save(p, counts.astype("<c16")), "<c16"),
            "negative.npy": (lambda p: np.save(p, -counts), "negative"),
            "nan.npy": (lambda p: np.save(p, np.where(counts > 0, np.nan, counts)), "non-finite"),
            "truncated.npy": (lambda p: write_bytes(p, good[:-8]), "values"),
            "header_only.npy": (lambda p: write_bytes(p, good[:40]), "header"),
            "not.npy": (lambda p: write_bytes(p, b"\x93NUMPX" + good[6:]), "not a .npy"),
        }
        for name, (write, words) in cases.items():
            write(self.path(name))
            status, err = stf("import", self.path(name), "--grid", "healpix:8", "--alpha-bins", self.bins,
                              "-o", self.path("bad.h5"))
            self.assertEqual(status, 2, name)
            self.assertIn(words, err, name)
            self.assertEqual(err.count("\n"), 1, err)
            self.assertFalse(os.path.exists(self.path("bad.h5")), name)

    def test_tables_that_disagree_or_hide_their_grid_are_refused(self):
        counts = np.ones((self.bins, self.cells))
        shuffled = self.direction[np.r_[1, 0, 2:self.cells]]  # cells in another order
        write_minimal(self.path("nested.h5"), counts, self.edges, shuffled, self.solid_angle)
        write_minimal(self.path("halves.h5"), counts, self.edges, self.direction, self.solid_angle)
        with h5py.File(self.path("halves.h5"), "a") as f:
            f["escape/weight_half"] = np.stack([counts, counts])  # sums to twice the weight
        write_minimal(self.path("once.h5"), counts, self.edges, self.direction, self.solid_angle)
        with h5py.File(self.path("once.h5"), "a") as f:
            f["escape/once_half"] = np.zeros((2, self.bins, self.cells))
        for name, words in (("nested.h5", "/grid/direction"), ("halves.h5", "/escape/weight_half"),
                            ("once.h5", "/escape/once_half")):
            status, err = stf("fit", self.path(name), "--model", "vmf:1", "-o", self.path("m.h5"))
            self.assertEqual(status, 2, name)
            self.assertIn(words, err, name)
            self.assertEqual(err.count("\n"), 1, err)

    def refused(self, words, *args):
        """stf refuses `args` in one line holding every one of `words`."""
        status, err = stf(*args)
        self.assertEqual(status, 2, err)
        self.assertEqual(err.count("\n"), 1, err)
        for w in words:
            self.assertIn(w, err)

    def test_what_a_command_would_fail_on_late_is_refused_first(self):
        """A smooth whose output could not hold the input's attributes fails before it fits; a
        samples file claiming more points than memory holds is refused before it is read; a
        report is a folder, not standard output."""
        counts = np.random.default_rng(SEED).poisson(3.0, (self.bins, self.cells)).astype(float)
        with h5py.File(self.path("big_attr.h5"), "w", libver="latest") as f:  # dense attribute storage
            f["escape/weight"], f["escape/alpha_edges"] = counts, self.edges
            f["grid/direction"], f["grid/solid_angle"] = self.direction, self.solid_angle
            f.attrs["notes"] = np.zeros(20000)  # 160 KB: more than a compact attribute holds
        self.refused(["big_attr.h5", "notes"], "smooth", self.path("big_attr.h5"), "--model", "vmf:1",
                     "-o", self.path("s.h5"))
        self.assertFalse(os.path.exists(self.path("s.h5")))
        check("fit", self.path("layout.h5"), "--model", "vmf:1", "--quiet", "-o", self.path("m.h5"))
        with h5py.File(self.path("huge.h5"), "w") as f:
            for name in ("exit_point", "exit_direction"):  # 24 TB as declared, nothing stored
                f.create_dataset("samples/" + name, shape=(10**12, 3), dtype="f8", chunks=(1024, 3))
        self.refused(["huge.h5", "exit_point", "memory"], "sample", self.path("m.h5"), "--eval",
                     self.path("huge.h5"), "-o", self.path("e.h5"))
        self.refused(["a report is a folder"], "report", self.path("m.h5"), "-o", "-")

    def test_npy_headers_are_quoted_printably(self):
        header = b"{'descr': '<f\x008', 'fortran_order': False, 'shape': (8, 768), }"
        header += b" " * (64 - (10 + len(header) + 1) % 64) + b"\n"
        write_bytes(self.path("nul.npy"), b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header)
        self.refused(["nul.npy", "\\x00"], "import", self.path("nul.npy"), "--grid", "healpix:8", "--alpha-bins",
                     self.bins, "-o", self.path("x.h5"))

    def test_a_read_that_never_returns_yields_to_the_first_ctrl_c(self):
        """A table whose weights HDF5 reads from a FIFO no one writes into: the read never returns
        (as a library stuck in a malformed file would not), and the first Ctrl-C ends the command
        at once, exit 130, leaving no lock or temporary."""
        fifo = self.path("weights.fifo")
        os.mkfifo(fifo)
        with h5py.File(self.path("stuck.h5"), "w") as f:
            f.create_dataset("escape/weight", shape=(self.bins, self.cells), dtype="f8",
                             external=[(fifo, 0, h5py.h5f.UNLIMITED)])
            f["escape/alpha_edges"], f["grid/direction"] = self.edges, self.direction
            f["grid/solid_angle"] = self.solid_angle
        run = subprocess.Popen([STF, "fit", self.path("stuck.h5"), "--model", "vmf:1", "-o", self.path("m.h5")],
                               stderr=subprocess.PIPE, text=True, cwd=self.dir.name)
        try:
            run.wait(timeout=1.0)  # still reading: it must not have finished
            self.fail("stf fit returned while its input could not be read")
        except subprocess.TimeoutExpired:
            run.send_signal(signal.SIGINT)
        err = run.communicate(timeout=10)[1]
        self.assertEqual(run.returncode, 130, err)
        self.assertIn("interrupted", err)
        left = [n for n in os.listdir(self.dir.name) if n.startswith("m.h5")]
        self.assertEqual(left, [])

    def edited_copy(self, source, name, edit):
        """A copy of an stf file, its checksum cleared (a file another program changed), edited."""
        with open(source, "rb") as f:
            data = f.read()
        write_bytes(self.path(name), bytes(512) + data[512:])
        with h5py.File(self.path(name), "r+") as f:
            edit(f)
        return self.path(name)

    def test_what_fit_writes_from_odd_tables_reads_back_and_odd_values_are_refused(self):
        check("precompute", "--sigma-s", 4, "--sigma-a", 0.1, "--g", 0.5, "--grid", "healpix:4", "--alpha-bins", 6,
              "--paths", 20000, "--threads", 1, "--quiet", "-o", self.path("own.h5"))
        medium = ("sigma_s", "sigma_a", "g", "radius", "tau", "albedo")
        no_medium = self.edited_copy(self.path("own.h5"), "no_medium.h5", lambda f: [f.attrs.__delitem__(k) for k in medium])
        tiny = self.edited_copy(self.path("own.h5"), "tiny.h5", lambda f: f.attrs.__setitem__("radius", 1e-300))
        check("fit", no_medium, "--model", "vmf:2", "--quiet", "-o", self.path("m.h5"))  # tallies, no medium
        check("sample", self.path("m.h5"), "--count", 100, "-o", self.path("s.h5"))
        # A medium that contradicts the tallies (tau 4e-300, yet most paths scattered) fits no model.
        self.refused(["tiny.h5", "not valid"], "fit", tiny, "--model", "vmf:2", "-o", self.path("x.h5"))
        dense = self.edited_copy(self.path("own.h5"), "dense.h5", lambda f: f.attrs.__setitem__("sigma_s", 2e7))
        self.refused(["dense.h5", "above 1e7"], "fit", dense, "--model", "vmf:2", "-o", self.path("x.h5"))
        check("fit", self.path("own.h5"), "--model", "vmf:2", "--quiet", "-o", self.path("own_m.h5"))
        narrow = self.edited_copy(self.path("own_m.h5"), "narrow.h5", lambda f: f["alpha/edges"].__setitem__(
            slice(None), np.r_[np.linspace(0, np.pi - 1e-12, len(f["alpha/edges"]) - 1), np.pi]))
        self.refused(["narrow.h5", "1e-6"], "sample", narrow, "--count", 100, "-o", self.path("x.h5"))
        write_bytes(self.path("big.txt"), b"0 0 9007199254740993\n")
        self.refused(["big.txt", "2^53"], "import", self.path("big.txt"), "--grid", "healpix:1", "--alpha-bins", 2,
                     "-o", self.path("x.h5"))
        self.refused(["UTF-8"], "pack", self.path("own_m.h5"), "--name", "\udcff\udcfe", "-o", self.path("x.stfpack"))
        self.assertFalse(any(n.startswith("x.") for n in os.listdir(self.dir.name)))

    def test_a_model_beyond_the_size_limits_is_refused_before_the_fit(self):
        """sh:32 over 5000 alpha bins needs SH tables of 5000 * 128 * 256 cells, past the 2^27 a
        model holds: refused at once, not after fitting."""
        check("precompute", "--sigma-s", 2, "--sigma-a", 0.1, "--g", 0.3, "--grid", "healpix:1", "--alpha-bins", 5000,
              "--paths", 2000, "--threads", 1, "--quiet", "-o", self.path("many_bins.h5"))
        self.refused(["many_bins.h5", "band limit 32", "5000 alpha bins"], "fit", self.path("many_bins.h5"),
                     "--model", "sh:32", "-o", self.path("x.h5"))


if __name__ == "__main__":
    unittest.main()
