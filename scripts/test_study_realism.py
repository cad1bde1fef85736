"""Tests of scripts/study-realism.py's factor table: each factor's run is set against
`typical`'s run of the same seed (`python3 -m unittest discover -s scripts -p 'test_*.py'`,
from scripts/test.sh)."""

import importlib.util
import json
import unittest
from pathlib import Path

spec = importlib.util.spec_from_file_location(
    "study_realism", Path(__file__).with_name("study-realism.py"))
study_realism = importlib.util.module_from_spec(spec)
spec.loader.exec_module(study_realism)


def run(label, seed, ate, variant=None, status="ok", false_loops=0, rung="typical"):
    """A kept run as studylib.load gives it: the ladder's `typical` rung when `variant` is
    None (as a factor sweep's `typical` variant is the same run), else a factor over it."""
    point = [["profile", json.dumps(rung)]]
    if variant is not None:
        point.append(["variant", json.dumps(variant)])
    metrics = None if status != "ok" else {
        "ape": {"rmse": ate}, "loops": {"accepted_false": false_loops},
        "drift": {"translation_percent": 1.0, "rotation_deg_per_100m": 1.0}}
    return {"world": "paper-world", "timing": {},
            "cell": {"label": label, "seed": seed, "point": point, "status": status},
            "metrics": metrics}


def factor_row(text, system):
    """The cells of `system`'s row in the factor table."""
    table = text[text.index("each factor alone"):]
    line = next(l for l in table.splitlines() if l.startswith(f"| {system} |"))
    return [c.strip() for c in line.strip("|").split("|")]


class FactorTable(unittest.TestCase):
    def test_each_factor_is_set_against_typical_of_its_own_seed(self):
        # Seed 0 of `typical` broke (1.6 m) and the factor's seed 0 a little less: seed by
        # seed, the factor costs 1 and 2 cm in seeds 1 and 2, and gains 0.3 m in seed 0.
        runs = [run("a", 0, 1.6), run("a", 1, 0.03), run("a", 2, 0.04),
                run("a", 0, 1.3, "range"), run("a", 1, 0.04, "range"),
                run("a", 2, 0.06, "range"),
                run("a", 0, 1.6, "mount"), run("a", 1, 0.03, "mount"),
                run("a", 2, 0.04, "mount")]
        row = factor_row(study_realism.tables(runs, None), "a")
        self.assertEqual(row[0], "a")
        self.assertEqual(row[1], "0.040", "typical: the median over the seeds")
        self.assertEqual(row[2], "0.040 (+0.000; +0.000, +0.000, +0.000)")
        self.assertEqual(row[3], "0.060 (+0.010; -0.300, +0.010, +0.020)")
        # The largest median change, not the largest mean (-0.09 m).
        self.assertEqual(row[4], "range (+0.010 m)")

    def test_a_failed_factor_run_is_counted_apart(self):
        runs = [run("a", 0, 0.10), run("a", 1, 0.20),
                run("a", 0, 0.15, "range"), run("a", 1, None, "range", status="failed")]
        row = factor_row(study_realism.tables(runs, None), "a")
        self.assertEqual(row[2], "0.150 (+0.050), 1 failed")

    def test_a_system_no_factor_touches_has_no_cost(self):
        runs = [run("a", 0, 0.10), run("a", 0, 0.1004, "range"), run("b", 0, 0.5)]
        text = study_realism.tables(runs, None)
        self.assertEqual(factor_row(text, "a")[-1], "–")
        self.assertEqual(factor_row(text, "b")[2:], ["–", "–"])


    def test_typical_is_taken_at_the_seeds_a_systems_factors_ran_at(self):
        # a's factor ran at seed 0 only, b's at seeds 0 and 1.
        runs = [run("a", 0, 0.10), run("a", 1, 0.30), run("a", 2, 0.50),
                run("a", 0, 0.12, "range"),
                run("b", 0, 1.0), run("b", 1, 2.0), run("b", 0, 1.5, "clock"),
                run("b", 1, 2.5, "clock")]
        text = study_realism.tables(runs, None)
        self.assertEqual(factor_row(text, "a")[1], "0.100")
        self.assertEqual(factor_row(text, "b")[1], "1.500")
        self.assertEqual(factor_row(text, "b")[2], "2.000 (+0.500; +0.500, +0.500)")


class Rates(unittest.TestCase):
    def test_breaks_are_counted_over_every_seed_and_the_ladder_keeps_its_three(self):
        # Ten seeds under `typical`: seed 0 with false loops and a metre and a half off, seed
        # 4 with a false loop that cost nothing, seed 7 failed; `ideal` has the ladder's three.
        runs = [run("a", x, 0.03, false_loops=1 if x == 4 else 0) for x in range(1, 10)
                if x != 7]
        runs += [run("a", 0, 1.6, false_loops=9), run("a", 7, None, status="failed")]
        runs += [run("a", x, 0.02, rung="ideal") for x in range(3)]
        text = study_realism.tables(runs, None)
        rates = text[text.index("how often a system breaks"):]
        rows = [l for l in rates.splitlines() if l.startswith("| a |")]
        self.assertEqual(len(rows), 1, "only the rung with seeds beyond the ladder's")
        cells = [c.strip() for c in rows[0].strip("|").split("|")]
        self.assertEqual(cells[1], "typical")
        self.assertEqual(cells[2], "2 of 9 [0.06, 0.55]")
        self.assertEqual(cells[3], "1 of 9 [0.02, 0.43]")
        self.assertEqual(cells[4], "1")
        self.assertEqual(cells[5], "0.030 [0.030, 1.600]")
        # The ladder's `typical` cell: seeds 0-2 only, seed 0's 1.6 m among them.
        ladder = next(l for l in text.splitlines() if l.startswith("| a |"))
        self.assertIn("(1.600, 0.030, 0.030)", ladder)


if __name__ == "__main__":
    unittest.main()
