#!/usr/bin/env python3
"""Run one evo command line and print its result as JSON on stdout.

Usage: run_evo.py evo_ape|evo_rpe ARG...

The command runs with `--save_results` into a temporary zip; the printed JSON is
`{"stats": {rmse, mean, median, std, min, max, sse}, "errors": [...]}` where `errors` is
evo's `error_array` (one value per pose pair). Used by host/eval/tests/evo_crosscheck.rs.
"""
import json
import os
import subprocess
import sys
import tempfile
import zipfile

import numpy as np


def main() -> int:
    if len(sys.argv) < 3 or sys.argv[1] not in ("evo_ape", "evo_rpe"):
        print(__doc__, file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        zip_path = os.path.join(tmp, "result.zip")
        command = sys.argv[1:] + ["--save_results", zip_path, "--no_warnings"]
        run = subprocess.run(command, capture_output=True, text=True)
        if run.returncode != 0:
            print(f"{' '.join(command)} failed ({run.returncode}):\n{run.stdout}\n{run.stderr}", file=sys.stderr)
            return 1
        with zipfile.ZipFile(zip_path) as archive:
            stats = json.loads(archive.read("stats.json"))
            with archive.open("error_array.npy") as f:
                errors = np.load(f)
    json.dump({"stats": stats, "errors": [float(e) for e in errors]}, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
