#!/usr/bin/python3
"""tools/code_limits.py against a sample whose functions, breaches and traps are known."""
import os
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
TOOL = os.path.join(HERE, "..", "..", "tools", "code_limits.py")
SAMPLE = os.path.join(HERE, "code_limits_sample")


def run(*args):
    r = subprocess.run([sys.executable, TOOL, *args, SAMPLE], capture_output=True, text=True)
    return r.returncode, r.stdout.splitlines()


class CodeLimits(unittest.TestCase):
    def test_every_function_is_found_with_its_lines_and_parameters(self):
        _, lines = run("--list")
        listed = {line.split(": ", 1)[1] for line in lines if "(limits" not in line}
        self.assertEqual(listed, {"seven 3 lines, 7 parameters", "six 1 lines, 6 parameters",
                                  "Holder 1 lines, 2 parameters", "braces 5 lines, 0 parameters",
                                  "long_one 61 lines, 0 parameters"})

    def test_breaches_are_reported_and_fail(self):
        status, lines = run()
        self.assertEqual(status, 1)
        self.assertEqual([line.split(": ", 1)[1] for line in lines],
                         ["seven: 3 lines, 7 parameters (limits 60 and 6)",
                          "long_one: 61 lines, 0 parameters (limits 60 and 6)"])

    def test_allowed_functions_and_wider_limits_pass(self):
        self.assertEqual(run("--allow", "seven", "--max-function", "61")[0], 0)
        self.assertEqual(run("--max-file", "50", "--allow", "seven", "--max-function", "61")[0], 1)


if __name__ == "__main__":
    unittest.main()
