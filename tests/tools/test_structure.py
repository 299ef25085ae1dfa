#!/usr/bin/python3
"""tools/structure.py against two small trees whose breaches are known: one tangled (an inside
header included from outside, a public header named without its folder, a cycle), one clean."""
import os
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
TOOL = os.path.join(HERE, "..", "..", "tools", "structure.py")
SAMPLE = os.path.join(HERE, "structure_sample")


def run(folder):
    r = subprocess.run([sys.executable, TOOL, os.path.join(SAMPLE, folder)], capture_output=True, text=True)
    return r.returncode, r.stdout.splitlines()


class Structure(unittest.TestCase):
    def test_every_breach_of_a_tangled_tree_is_reported(self):
        self.assertEqual(run("tangled"), (1, [
            "app/main.cpp: includes inner.h, the inside of lib (use its face, include/stf/lib/)",
            'app/main.cpp: includes "low.h" without its folder: "stf/lib/low.h"',
            "lib: include cycle among inner, pub"]))

    def test_a_clean_tree_passes(self):
        self.assertEqual(run("clean"), (0, []))

    def test_a_tree_without_libraries_is_an_error(self):
        status, _ = run("")
        self.assertEqual(status, 2)


if __name__ == "__main__":
    unittest.main()
