#!/usr/bin/python3
"""tools/code_limits.py against a sample whose functions, breaches and traps are known."""
import os
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
TOOL = os.path.join(HERE, "..", "..", "tools", "code_limits.py")
SAMPLE = os.path.join(HERE, "code_limits_sample")


def sample_lines():
    with open(os.path.join(SAMPLE, "sample.cpp"), encoding="utf-8") as f:
        return f.read().count("\n")


def run(*args):
    r = subprocess.run([sys.executable, TOOL, *args, SAMPLE], capture_output=True, text=True)
    return r.returncode, r.stdout.splitlines()


class CodeLimits(unittest.TestCase):
    def test_every_function_is_found_with_its_lines_and_parameters(self):
        _, lines = run("--list")
        listed = {line.split(": ", 1)[1] for line in lines if "(limits" not in line}
        self.assertEqual(listed, {"seven 3 lines, 7 parameters", "six 1 lines, 6 parameters",
                                  "Holder 1 lines, 2 parameters", "Braced 5 lines, 2 parameters",
                                  "three 3 lines, 1 parameters", "operator== 4 lines, 1 parameters",
                                  "braces 5 lines, 0 parameters", "long_one 61 lines, 0 parameters"})

    def test_breaches_are_reported_and_fail(self):
        status, lines = run()
        self.assertEqual(status, 1)
        self.assertEqual([line.split(": ", 1)[1] for line in lines],
                         ["seven: 3 lines, 7 parameters (limits 60 and 6)",
                          "long_one: 61 lines, 0 parameters (limits 60 and 6)"])

    def test_allowed_functions_and_wider_limits_pass(self):
        self.assertEqual(run("--allow", "seven", "--max-function", "61"), (0, []))
        status, lines = run("--max-file", "50", "--allow", "seven", "--max-function", "61")
        self.assertEqual((status, [line.split(": ", 1)[1] for line in lines]), (1, ["%d lines (limit 50)" % sample_lines()]))

    def test_a_folder_without_sources_is_an_error(self):
        r = subprocess.run([sys.executable, TOOL, os.path.join(HERE, "no_such_folder")], capture_output=True, text=True)
        self.assertEqual((r.returncode, r.stdout), (2, ""))
        self.assertIn("no folder of C++ sources", r.stderr)


if __name__ == "__main__":
    unittest.main()
