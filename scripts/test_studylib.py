"""Tests of studylib.resume_files: what a study spread over sessions runs next
(`python3 -m unittest discover -s scripts -p 'test_*.py'`, from scripts/test.sh)."""

import json
import tempfile
import tomllib
import unittest
from pathlib import Path

from studylib import resume_files

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


if __name__ == "__main__":
    unittest.main()
