#!/usr/bin/env python3
"""Issue 47's GNSS table (docs/gnss/study.md) from the runs scripts/study-gnss.sh kept in
docs/gnss/runs/<world>/<key>/ (cell.json, metrics.json, timing.json of each run of
configs/study/gnss/<world>.toml):

per world and profile, each system (with its GNSS switched on) under each receiver — none,
consumer, RTK with the block's sky, RTK under an open sky — on S0-S3: ATE RMSE (SE(3)
alignment), its horizontal part, and the worst APE within the run's longest GNSS outage,
mean ± sample std over the seeds; and the wrong joins of the final maps, summed.

    python3 scripts/study-gnss.py [--kept DIR] [--out FILE]
    python3 scripts/study-gnss.py --resume configs/study/gnss/X.toml --kept DIR/<world>
"""

import argparse
import json
import statistics
import tomllib
from pathlib import Path

from studylib import load, resume_files

PROFILES = ["typical", "field"]
VARIANTS = ["no-gnss", "consumer", "rtk", "rtk-open-sky"]
SCENARIOS = ["s0", "s1", "s2", "s3"]


def order(path):
    """The order narrowed sweep files run in: `typical` before `field`, then the seed,
    then the receiver (none first), so that one profile's seed 0 is whole first."""
    cfg = tomllib.loads(Path(path).read_text())
    profile = cfg["axes"].get("profile", ["?"])[0]
    variant = next(iter(cfg.get("variants", {"?": {}})))
    rank = lambda xs, x: xs.index(x) if x in xs else len(xs)
    return (rank(PROFILES, profile), cfg["seeds"][0], rank(VARIANTS, variant), str(path))


def mean_std(values, digits=3):
    """`mean ± std` (sample), one value alone, or a dash."""
    if not values:
        return "–"
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{statistics.mean(values):.{digits}f} ± {statistics.stdev(values):.{digits}f}"


def tables(runs):
    """One table per (world, profile): rows system × receiver, a column per scenario."""
    cells = {}
    for run in runs:
        c, m = run["cell"], run["metrics"]
        if m is None or c.get("status") != "ok":
            continue
        point = dict(c["point"])
        profile = json.loads(point.get("profile", '"?"'))
        variant = json.loads(point.get("variant", '"?"'))
        key = (run["world"], profile, c["label"], variant)
        per = cells.setdefault(key, {})
        gnss = m.get("gnss") or {}
        per.setdefault(c["scenario"], []).append({
            "ate": m["ape"]["rmse"],
            # Every run's since `horizontal_rmse_m`; before, only GNSS-fed runs had it.
            "horizontal": m.get("horizontal_rmse_m", gnss.get("horizontal_rmse_m")),
            "outage": gnss.get("worst_error_in_outage_m"),
            "wrong": (m.get("joins") or {}).get("wrong_joins", 0),
        })
    out = []
    worlds = sorted({k[0] for k in cells})
    for world in worlds:
        for profile in PROFILES:
            rows = sorted((k for k in cells if k[0] == world and k[1] == profile),
                          key=lambda k: (k[2], VARIANTS.index(k[3]) if k[3] in VARIANTS else 9))
            if not rows:
                continue
            out.append(f"## {world}, `{profile}`\n")
            out.append("Each cell: ATE RMSE / horizontal RMSE / worst APE in the longest "
                       "outage (m), mean ± std over the seeds (n); wrong joins summed over "
                       "the cells.\n")
            out.append("| system | receiver | " + " | ".join(s.upper() for s in SCENARIOS)
                       + " | wrong joins |")
            out.append("|---|---|" + "---|" * len(SCENARIOS) + "---|")
            for key in rows:
                per = cells[key]
                parts, wrong = [], 0
                for s in SCENARIOS:
                    rs = per.get(s, [])
                    wrong += sum(r["wrong"] for r in rs)
                    if not rs:
                        parts.append("–")
                        continue
                    pick = lambda f: [r[f] for r in rs if r[f] is not None]
                    parts.append(f"{mean_std(pick('ate'))} / {mean_std(pick('horizontal'))}"
                                 f" / {mean_std(pick('outage'))} ({len(rs)})")
                out.append(f"| {key[2]} | {key[3]} | " + " | ".join(parts) + f" | {wrong} |")
            out.append("")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--kept", default="docs/gnss/runs")
    ap.add_argument("--out", default="docs/gnss/study.md")
    ap.add_argument("--resume", metavar="SWEEP.toml",
                    help="write beside it the narrowed sweep files of what --kept (a world's "
                         "folder) lacks, print their paths in the order to run them, stop")
    args = ap.parse_args()
    if args.resume:
        for f in sorted(resume_files(args.resume, args.kept, Path(args.resume).parent),
                        key=order):
            print(f)
        return
    runs = load(args.kept)
    head = ("# GNSS study (issue 47)\n\n"
            "Written by `scripts/study-gnss.py` from the runs kept in "
            f"`{args.kept}/` ({len(runs)} runs); how they were made: "
            "[README.md](README.md). In the `no-gnss` rows a system that asks for GNSS "
            "gets none and runs without it.\n\n")
    Path(args.out).write_text(head + tables(runs))
    print(f"{args.out}: {len(runs)} runs")


if __name__ == "__main__":
    main()
