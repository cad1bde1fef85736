#!/usr/bin/env python3
"""Issue 47's GNSS table (docs/gnss/study.md) from the runs scripts/study-gnss.sh kept in
docs/gnss/runs/<world>/<key>/ (cell.json, metrics.json, timing.json of each run of
configs/study/gnss/<world>.toml):

per world and profile, a figure (study-<world>-<profile>.svg beside the table: every run's
horizontal RMSE, log scale, by system and receiver) and each system (with its GNSS switched
on) under each receiver — none,
consumer, RTK with the block's sky, RTK under an open sky — on S0-S3: ATE RMSE (SE(3)
alignment), its horizontal part, and the worst APE within the run's longest GNSS outage,
mean ± sample std over the seeds; and the wrong joins of the final maps, summed.

    python3 scripts/study-gnss.py [--kept DIR] [--out FILE]
    python3 scripts/study-gnss.py --resume configs/study/gnss/X.toml --kept DIR/<world>
"""

import argparse
import json
import math
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

COLOURS = {"no-gnss": "#666666", "consumer": "#d95f02", "rtk": "#1b9e77",
           "rtk-open-sky": "#7570b3"}


def svg_receivers(cells, path):
    """Every run's horizontal RMSE (log scale): a column of dots per system and receiver,
    one dot a run (scenario and seed), the bar the median."""
    systems = sorted({k[2] for k in cells})
    vals = [r["horizontal"] for per in cells.values() for rs in per.values() for r in rs
            if r["horizontal"]]
    if not vals:
        return False
    w, h, left, right, top, bottom = 760, 380, 64, 130, 16, 56
    lo = 10 ** math.floor(math.log10(min(vals)))
    hi = 10 ** math.ceil(math.log10(max(vals)))
    group = (w - left - right) / len(systems)
    y = lambda v: top + (math.log10(hi) - math.log10(v)) / (math.log10(hi) - math.log10(lo)) * (h - top - bottom)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{w}" height="{h}" fill="white"/>']
    d = lo
    while d <= hi * 1.0001:
        out.append(f'<line x1="{left}" x2="{w - right}" y1="{y(d):.1f}" y2="{y(d):.1f}" stroke="#ddd"/>')
        out.append(f'<text x="{left - 6}" y="{y(d) + 4:.1f}" text-anchor="end">{d:g}</text>')
        d *= 10
    out.append(f'<text x="14" y="{(h - bottom + top) / 2:.0f}" transform="rotate(-90 14 '
               f'{(h - bottom + top) / 2:.0f})" text-anchor="middle">horizontal RMSE (m)</text>')
    for i, system in enumerate(systems):
        cx = left + (i + 0.5) * group
        out.append(f'<text x="{cx:.1f}" y="{h - bottom + 18}" text-anchor="middle">{system}</text>')
        for j, variant in enumerate(VARIANTS):
            x = cx + (j - 1.5) * group / 5
            rs = [r["horizontal"] for s, per in cells.items() if s[2] == system and s[3] == variant
                  for rr in per.values() for r in rr if r["horizontal"]]
            for k, v in enumerate(sorted(rs)):
                dx = (k % 5 - 2) * 1.6
                out.append(f'<circle cx="{x + dx:.1f}" cy="{y(v):.1f}" r="2.4" '
                           f'fill="{COLOURS[variant]}" fill-opacity="0.75"/>')
            if rs:
                m = statistics.median(rs)
                out.append(f'<line x1="{x - 7:.1f}" x2="{x + 7:.1f}" y1="{y(m):.1f}" '
                           f'y2="{y(m):.1f}" stroke="black" stroke-width="1.5"/>')
    for j, variant in enumerate(VARIANTS):
        ly = top + 18 * j + 8
        out.append(f'<circle cx="{w - right + 16}" cy="{ly}" r="4" fill="{COLOURS[variant]}"/>')
        out.append(f'<text x="{w - right + 26}" y="{ly + 4}">{variant}</text>')
    out.append(f'<text x="{w - right + 10}" y="{top + 18 * 4 + 12}">bar: median</text>')
    out.append("</svg>")
    Path(path).write_text("\n".join(out) + "\n")
    return True


def tables(runs, figures=None):
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
            figure = f"study-{world}-{profile}.svg"
            here = {k: v for k, v in cells.items() if k[0] == world and k[1] == profile}
            if figures is not None and svg_receivers(here, Path(figures) / figure):
                out.append(f"![every run's horizontal RMSE by system and receiver]({figure})\n")
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
        for f in sorted(resume_files(args.resume, args.kept, Path(args.resume).parent,
                                     group_variants=True),
                        key=order):
            print(f)
        return
    runs = load(args.kept)
    head = ("# GNSS study (issue 47)\n\n"
            "Written by `scripts/study-gnss.py` from the runs kept in "
            f"`{args.kept}/` ({len(runs)} runs); how they were made: "
            "[README.md](README.md). In the `no-gnss` rows a system that asks for GNSS "
            "gets none and runs without it.\n\n")
    Path(args.out).write_text(head + tables(runs, Path(args.out).parent))
    print(f"{args.out}: {len(runs)} runs")


if __name__ == "__main__":
    main()
