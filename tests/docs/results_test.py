#!/usr/bin/env python3
"""scripts/results.py: rows come from the data files that exist, and --check sees drift."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCRIPT = os.path.join(ROOT, "scripts", "results.py")
DATA = os.path.join(ROOT, "docs", "results", "data")

CALLGRIND = {
    "machine": "test", "camera": "1920x1080", "map": "synthetic 16384",
    "runs": [
        {"levels": "auto", "kernel": "eight lanes", "revision": "before",
         "instructions": 522000000, "pixels": 2073600, "instructions_per_pixel": 251.7},
        {"levels": "auto", "kernel": "eight lanes", "revision": "after",
         "instructions": 400000000, "pixels": 2073600, "instructions_per_pixel": 192.9},
        {"levels": "0", "kernel": "four columns", "revision": "before",
         "instructions": 1000000000, "pixels": 2073600, "instructions_per_pixel": 482.3},
        {"levels": "0", "kernel": "four columns", "revision": "after",
         "instructions": 900000000, "pixels": 2073600, "instructions_per_pixel": 434.0},
    ],
}


def run(*args):
    return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True)


class ResultsPage(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp()
        self.data = os.path.join(self.tmp, "data")
        shutil.copytree(DATA, self.data)
        self.page = os.path.join(self.tmp, "results.md")

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def write_page(self):
        r = run("--data", self.data, "--out", self.page)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(self.page, encoding="utf-8") as f:
            return f.read()

    def test_every_claim_row_has_a_status_and_a_command(self):
        rows, in_claims = 0, False
        for line in self.write_page().splitlines():
            if line == "| what | target | value | status | command |":
                in_claims = True
            elif not line.startswith("| "):
                in_claims = False
            elif in_claims and not line.startswith("| ---"):
                cells = line.split(" | ")
                self.assertEqual(len(cells), 5, line)
                self.assertIn(cells[3], ("met", "**not met**", "no target"), line)
                self.assertTrue(cells[4].strip(" |"), line)
                rows += 1
        self.assertGreater(rows, 20)

    def test_no_callgrind_file_no_row(self):
        for name in ("caster_callgrind.json", "span_callgrind.json"):
            path = os.path.join(self.data, name)
            if os.path.exists(path):
                os.remove(path)
        self.assertNotIn("callgrind", self.write_page())

    def test_span_callgrind_file_gives_a_row(self):
        doc = {"machine": "test", "camera": "1920x1080", "map": "synthetic 4096",
               "command": "valgrind --tool=callgrind ...",
               "runs": [{"caster": "span", "revision": "before", "view": "issue camera",
                         "instructions": 800000000, "columns": 600000000,
                         "resample": 150000000, "pixels": 2000000},
                        {"caster": "span", "revision": "after", "view": "issue camera",
                         "instructions": 700000000, "columns": 580000000,
                         "resample": 60000000, "pixels": 2000000},
                        {"caster": "span", "revision": "after", "view": "pitch 0",
                         "instructions": 600000000, "columns": 570000000,
                         "resample": 20000000, "pixels": 2000000},
                        {"caster": "fast", "revision": "after", "view": "issue camera",
                         "instructions": 500000000, "pixels": 2000000}]}
        with open(os.path.join(self.data, "span_callgrind.json"), "w") as f:
            json.dump(doc, f)
        page = self.write_page()
        row = [l for l in page.splitlines() if "Span caster instructions per pixel" in l]
        self.assertEqual(len(row), 1, page)
        self.assertIn("span 400 → 350 (columns 300 → 290, resample 75 → 30)", row[0])
        self.assertIn("span / fast 1.40", row[0])
        self.assertIn("pitch 0: span 300 (resample 10)", row[0])

    def test_callgrind_file_gives_a_row(self):
        with open(os.path.join(self.data, "caster_callgrind.json"), "w") as f:
            json.dump(CALLGRIND, f)
        page = self.write_page()
        row = [l for l in page.splitlines() if "before/after reorganisation (callgrind)" in l]
        self.assertEqual(len(row), 1, page)
        self.assertIn("levels auto (eight lanes): 252 → 193 (−23 %)", row[0])
        self.assertIn("levels 0 (four columns): 482 → 434 (−10 %)", row[0])

    def test_check_sees_a_page_that_drifted_from_the_data(self):
        self.write_page()
        self.assertEqual(run("--data", self.data, "--out", self.page, "--check").returncode, 0)
        with open(self.page, "a", encoding="utf-8") as f:
            f.write("| hand-written claim | — | 1 | met | none |\n")
        r = run("--data", self.data, "--out", self.page, "--check")
        self.assertEqual(r.returncode, 1)
        self.assertIn("does not match", r.stderr)

    def test_bad_json_is_named(self):
        with open(os.path.join(self.data, "warp_eval.json"), "w") as f:
            f.write("{not json")
        r = run("--data", self.data, "--out", self.page)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("warp_eval.json", r.stderr)


if __name__ == "__main__":
    unittest.main()
