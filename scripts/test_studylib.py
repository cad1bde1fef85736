"""Tests of studylib.resume_files and keep_runs: what a study spread over sessions runs next
and keeps
(`python3 -m unittest discover -s scripts -p 'test_*.py'`, from scripts/test.sh)."""

import json
import tempfile
import tomllib
import unittest
from pathlib import Path

from studylib import keep_runs, resume_files

SWEEP = """# a study
scenarios = ["s0", "s1", "s2"]
seeds = [0, 1]
align = "se3"

[axes]
"profile" = ["typical"]

[variants.none]
[variants.rtk]
"sensors.gnss.profile" = "rtk"

[[plugins]]
name = "ekf"
label = "ekf"

[[plugins]]
name = "lio-sam"
label = "lio-sam-gps"
[plugins.params.gps]
enabled = true
"""


def keep(kept, key, label, scenario, seed, variant):
    """A kept run as scripts/studylib.sh's keep_sweep_runs leaves it (its cell.json)."""
    d = Path(kept) / key
    d.mkdir(parents=True)
    point = [["variant", json.dumps(variant)], ["profile", '"typical"']]
    (d / "cell.json").write_text(json.dumps({
        "key": key, "label": label, "scenario": scenario, "seed": seed, "point": point,
        "status": "ok"}))


class ResumeFiles(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = Path(self.tmp.name)
        self.sweep = self.dir / "study.toml"
        self.sweep.write_text(SWEEP)
        self.kept = self.dir / "kept"
        self.kept.mkdir()

    def tearDown(self):
        self.tmp.cleanup()

    def narrowed(self):
        files = resume_files(self.sweep, self.kept, self.dir)
        out = {}
        for f in files:
            cfg = tomllib.loads(f.read_text())
            variant = next(iter(cfg["variants"]))
            labels = [p["label"] for p in cfg["plugins"]]
            out[(variant, cfg["seeds"][0])] = (cfg["scenarios"], labels)
        return out

    def test_nothing_kept_runs_every_cell(self):
        self.assertEqual(self.narrowed(), {
            (v, seed): (["s0", "s1", "s2"], ["ekf", "lio-sam-gps"])
            for v in ["none", "rtk"] for seed in [0, 1]})

    def test_only_the_missing_systems_and_routes_run(self):
        n = 0
        for label in ["ekf", "lio-sam-gps"]:
            for scenario in ["s0", "s1", "s2"]:
                for seed in [0, 1]:
                    for variant in ["none", "rtk"]:
                        # Left out: rtk seed 1's lio-sam on s2, and every s1 and s2 of
                        # none seed 1 (a group cut short after its first route).
                        if (variant, seed, label, scenario) == ("rtk", 1, "lio-sam-gps", "s2"):
                            continue
                        if (variant, seed) == ("none", 1) and scenario != "s0":
                            continue
                        n += 1
                        keep(self.kept, f"k{n}", label, scenario, seed, variant)
        self.assertEqual(self.narrowed(), {
            ("rtk", 1): (["s2"], ["lio-sam-gps"]),
            ("none", 1): (["s1", "s2"], ["ekf", "lio-sam-gps"]),
        })

    def test_a_run_of_another_point_does_not_count(self):
        keep(self.kept, "other", "ekf", "s0", 0, "consumer")
        self.assertEqual(len(self.narrowed()), 4)

    def grouped(self):
        out = {}
        for f in resume_files(self.sweep, self.kept, self.dir, group_variants=True):
            cfg = tomllib.loads(f.read_text())
            labels = [p["label"] for p in cfg["plugins"]]
            out[cfg["seeds"][0]] = (sorted(cfg["variants"]), cfg["scenarios"], labels)
        return out

    def test_grouped_variants_run_together_what_any_of_them_lacks(self):
        self.assertEqual(self.grouped(), {
            seed: (["none", "rtk"], ["s0", "s1", "s2"], ["ekf", "lio-sam-gps"])
            for seed in [0, 1]})
        n = 0
        for label in ["ekf", "lio-sam-gps"]:
            for scenario in ["s0", "s1", "s2"]:
                for seed in [0, 1]:
                    for variant in ["none", "rtk"]:
                        # Left out: seed 1's rtk lio-sam on s2 and none's ekf on s1.
                        if (seed, variant, label, scenario) in [
                                (1, "rtk", "lio-sam-gps", "s2"), (1, "none", "ekf", "s1")]:
                            continue
                        n += 1
                        keep(self.kept, f"k{n}", label, scenario, seed, variant)
        self.assertEqual(self.grouped(), {
            1: (["none", "rtk"], ["s1", "s2"], ["ekf", "lio-sam-gps"])})


class KeepRuns(unittest.TestCase):
    def test_a_cell_kept_under_another_key_is_not_kept_twice(self):
        with tempfile.TemporaryDirectory() as tmp:
            results, kept = Path(tmp) / "results", Path(tmp) / "kept"
            keep(kept / "w", "old", "ekf", "s0", 0, "rtk")
            # The same cell run again by another build, and a new one.
            for key, scenario in [("again", "s0"), ("new", "s1")]:
                keep(results / "w" / "runs", key, "ekf", scenario, 0, "rtk")
                (results / "w" / "runs" / key / "metrics.json").write_text("{}")
            self.assertEqual(keep_runs(results, kept), 2)
            self.assertEqual(sorted(p.name for p in (kept / "w").iterdir()), ["new", "old"])
            self.assertTrue((kept / "w" / "new" / "metrics.json").exists())
            self.assertEqual(keep_runs(results, kept), 2, "a second save adds nothing")


if __name__ == "__main__":
    unittest.main()
