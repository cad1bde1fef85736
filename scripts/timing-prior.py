#!/usr/bin/env python3
"""Writes a bench file's `timing_prior` from a bench's results folder: each system's wall
seconds per simulated second over its runs there (the sum of their `timing.json` wall_s
over the sum of their simulated_s), by label.

    python3 scripts/timing-prior.py results/paper > configs/paper.timing.toml
"""

import argparse
import datetime
import json
import platform
from pathlib import Path


def cpu_model():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", help="a bench's results folder (<scenario>/<label>/timing.json)")
    args = ap.parse_args()
    sums = {}
    for f in sorted(Path(args.results).glob("*/*/timing.json")):
        t = json.loads(f.read_text())
        if t.get("simulated_s", 0) > 0 and t.get("wall_s") is not None:
            wall, sim = sums.get(f.parent.name, (0.0, 0.0))
            sums[f.parent.name] = (wall + t["wall_s"], sim + t["simulated_s"])
    if not sums:
        raise SystemExit(f"{args.results}: no run with a timing.json")
    print(f"# Each system's wall seconds per simulated second in {args.results}")
    print(f"# ({sum(1 for _ in Path(args.results).glob('*/*/timing.json'))} runs; "
          f"{cpu_model()}, {datetime.date.today()}): a prior for the bench's progress")
    print("# estimate where its results folder holds no previous results, rescaled to the")
    print("# machine by the runs as they end (scripts/timing-prior.py).")
    print("[wall_s_per_simulated_s]")
    for label, (wall, sim) in sorted(sums.items()):
        print(f'"{label}" = {wall / sim:.4f}')


if __name__ == "__main__":
    main()
