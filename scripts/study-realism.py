#!/usr/bin/env python3
"""Issue 45's sensitivity table (docs/realism/sensitivity.md and its figure) from the runs
scripts/study-realism.sh kept in docs/realism/runs/<world>/<key>/ (cell.json, metrics.json,
timing.json of each run of configs/study/realism/):

- the ladder: every system on S3 under `ideal`, `paper`, `typical` and `field`, ATE RMSE
  mean ± sample std over the seeds, drift per 100 m, false loops and wrong joins of the
  final map, dropped messages; the ranking of the systems on each rung;
- the rates: where a system has run over more seeds than the ladder's three (rates-paper-
  world.toml), how often it broke, k of n with a Wilson interval;
- the factors: each factor family of `field` switched on alone over `typical` (the seeds
  run), ATE RMSE and its change against `typical` under the same seed, and which factor
  costs each system most.

    python3 scripts/study-realism.py [--kept DIR] [--out FILE] [--figure FILE]
    python3 scripts/study-realism.py --resume configs/study/realism/X.toml --kept DIR/<world>

A run's key hashes the plugin library's bytes, which change with a rebuild; `--resume`
writes, beside the sweep file, one narrowed copy per point of its axes and variants and
seed that still lacks a kept run of some system, with only those systems, so that a study
spread over sessions (and rebuilds) runs each cell once.
"""

import argparse
import json
import math
import statistics
from pathlib import Path

from studylib import load, resume_files, wilson

RUNGS = ["ideal", "paper", "typical", "field"]
# The ladder's seeds: every rung and system has these (rates-paper-world.toml adds seeds to
# some systems on some rungs, which the rates section counts).
LADDER_SEEDS = {0, 1, 2}
# A run's ATE RMSE above this counts as broken in the rates section (S3 is about 230 m long:
# 0.5 m is ten times what the lidar systems score when they hold).
BROKEN_M = 0.5
# Published S3 figures as context, not as a target: Hroob et al. 2021, Table 2 (ATE, m).
PAPER_S3 = {"lio-sam": 0.40, "staticmapping": 1.51, "orbslam2": 5.22, "rtabmap": 0.07}


def normal(point):
    """A point as a dict, the baseline variant `typical` dropped: a factor sweep's
    `typical` is the same run as the ladder's `typical` rung (the same world, so the
    same key), and a run kept by either stands for both."""
    p = dict(point)
    if p.get("variant") == '"typical"':
        del p["variant"]
    return p


def fmt_paper(system):
    """The paper's S3 figure for a system it ran, else a dash."""
    return f"{PAPER_S3[system]:.2f}" if system in PAPER_S3 else "–"


def summary(values):
    """`mean ± std (n)` of a list (std the sample's; a single value alone)."""
    if not values:
        return "–"
    if len(values) == 1:
        return f"{values[0]:.3f}"
    return f"{statistics.mean(values):.3f} ± {statistics.stdev(values):.3f}"


def row_of(run):
    """(system, rung, variant, seed) of a run and its numbers."""
    c, m, t = run["cell"], run["metrics"], run["timing"]
    p = normal(c["point"])
    rung = json.loads(p.get("profile", '"?"'))
    variant = json.loads(p["variant"]) if "variant" in p else None
    # transport-*.toml: paced with the system's own bounded subscriber queues.
    if c.get("queue_size"):
        variant = "transport"
    ok = c["status"] == "ok" and m is not None
    joins = (m or {}).get("joins") or {}
    drift = (m or {}).get("drift") or {}
    return {
        "world": run["world"], "system": c["label"], "rung": rung, "variant": variant,
        "seed": c["seed"], "ok": ok, "status": c["status"],
        "ate": m["ape"]["rmse"] if ok else None,
        "drift_pct": drift.get("translation_percent") if ok else None,
        "drift_deg": drift.get("rotation_deg_per_100m") if ok else None,
        "false_loops": m["loops"]["accepted_false"] if ok else None,
        "wrong_joins": joins.get("wrong_joins") if ok else None,
        "dropped": sum((t or {}).get("dropped", {}).values()),
    }


def svg_ladder(rows, systems, path):
    """ATE RMSE (log scale) of each system on each rung, mean and the seeds' range."""
    w, h, left, right, top, bottom = 720, 420, 70, 190, 20, 50
    vals = [r["ate"] for r in rows if r["ate"]] + [PAPER_S3[s] for s in systems if s in PAPER_S3]
    if not vals:
        return
    lo = 10 ** math.floor(math.log10(min(vals)))
    hi = 10 ** math.ceil(math.log10(max(vals)))
    columns = RUNGS + ["Hroob et al. S3"]
    x = lambda i: left + (i + 0.5) * (w - left - right) / len(columns)
    y = lambda v: top + (math.log10(hi) - math.log10(v)) / (math.log10(hi) - math.log10(lo)) * (h - top - bottom)
    colours = ["#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d",
               "#666666", "#1f78b4"]
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{w}" height="{h}" fill="white"/>']
    d = lo
    while d <= hi * 1.0001:
        out.append(f'<line x1="{left}" x2="{w - right}" y1="{y(d):.1f}" y2="{y(d):.1f}" stroke="#ddd"/>')
        out.append(f'<text x="{left - 6}" y="{y(d) + 4:.1f}" text-anchor="end">{d:g}</text>')
        d *= 10
    for i, rung in enumerate(columns):
        out.append(f'<text x="{x(i):.1f}" y="{h - bottom + 18}" text-anchor="middle">{rung}</text>')
    out.append(f'<text x="14" y="{(h - bottom + top) / 2:.0f}" transform="rotate(-90 14 '
               f'{(h - bottom + top) / 2:.0f})" text-anchor="middle">ATE RMSE (m), S3</text>')
    for k, system in enumerate(systems):
        colour = colours[k % len(colours)]
        dx = (k - (len(systems) - 1) / 2) * 4
        line = []
        for i, rung in enumerate(RUNGS):
            v = [r["ate"] for r in rows if r["system"] == system and r["rung"] == rung and r["ate"]]
            if not v:
                continue
            m = statistics.mean(v)
            line.append(f"{x(i) + dx:.1f},{y(m):.1f}")
            out.append(f'<line x1="{x(i) + dx:.1f}" x2="{x(i) + dx:.1f}" y1="{y(min(v)):.1f}" '
                       f'y2="{y(max(v)):.1f}" stroke="{colour}"/>')
            out.append(f'<circle cx="{x(i) + dx:.1f}" cy="{y(m):.1f}" r="3.5" fill="{colour}"/>')
        if system in PAPER_S3:
            # The paper's own figure, as context: a hollow marker.
            out.append(f'<circle cx="{x(len(RUNGS)) + dx:.1f}" cy="{y(PAPER_S3[system]):.1f}" '
                       f'r="3.5" fill="none" stroke="{colour}" stroke-width="1.5"/>')
        if len(line) > 1:
            out.append(f'<polyline points="{" ".join(line)}" fill="none" stroke="{colour}" '
                       f'stroke-width="1.5"/>')
        ly = top + 16 * k + 8
        out.append(f'<circle cx="{w - right + 16}" cy="{ly}" r="4" fill="{colour}"/>')
        out.append(f'<text x="{w - right + 26}" y="{ly + 4}">{system}</text>')
    out.append("</svg>")
    Path(path).write_text("\n".join(out) + "\n")


def rates(rows, systems, world):
    """The rungs where a system has runs beyond the ladder's seeds: how often it broke (a
    false loop accepted or a wrong join of the final map; an ATE RMSE over BROKEN_M; not
    ended ok), k of n with the 95 % Wilson interval."""
    cells = []
    for s in systems:
        for rung in RUNGS:
            here = [r for r in rows if r["system"] == s and r["rung"] == rung]
            if len({r["seed"] for r in here} - LADDER_SEEDS) == 0:
                continue
            ok = [r for r in here if r["ok"]]
            joined = [r for r in ok if (r["false_loops"] or 0) + (r["wrong_joins"] or 0) > 0]
            far = [r for r in ok if r["ate"] > BROKEN_M]
            cells.append((s, rung, here, ok, joined, far))
    if not cells:
        return []

    def rate(k, n):
        lo, hi = wilson(k, n)
        return f"{k} of {n} [{lo:.2f}, {hi:.2f}]"

    seeds = sorted({r["seed"] for c in cells for r in c[2]})
    out = [f"## {world}: how often a system breaks (S3, seeds {seeds[0]}–{seeds[-1]})\n",
           "Runs with a false loop accepted or a wrong join of the final map, and runs whose "
           f"ATE RMSE is over {BROKEN_M} m, k of n with the 95 % Wilson interval; the ATE "
           "RMSE's median and range over the runs that ended ok:\n",
           "| system | rung | false loop or wrong join | ATE over "
           f"{BROKEN_M} m | not ok | ATE RMSE median [min, max] (m) |",
           "|---|---|---|---|---:|---|"]
    for s, rung, here, ok, joined, far in cells:
        ates = [r["ate"] for r in ok]
        spread = (f"{statistics.median(ates):.3f} [{min(ates):.3f}, {max(ates):.3f}]"
                  if ates else "–")
        out.append(f"| {s} | {rung} | {rate(len(joined), len(ok)) if ok else '–'} | "
                   f"{rate(len(far), len(ok)) if ok else '–'} | {len(here) - len(ok)} | "
                   f"{spread} |")
    out.append("")
    return out


def tables(runs, figure):
    rows = [row_of(r) for r in runs]
    out = []
    for world in sorted({r["world"] for r in rows}):
        wrows = [r for r in rows if r["world"] == world]
        ladder = [r for r in wrows if r["variant"] is None and r["seed"] in LADDER_SEEDS]
        systems = sorted({r["system"] for r in wrows})
        out.append(f"## {world}: the ladder (S3, mean ± sample std over seeds)\n")
        out.append("ATE RMSE (m), in brackets each seed's (seeds in order); runs that did not "
                   "end ok are counted apart.\n")
        out.append("| system | " + " | ".join(RUNGS) + " | Hroob et al. Table 2, S3 |")
        out.append("|---|" + "---:|" * (len(RUNGS) + 1))
        for s in systems:
            cells = []
            for rung in RUNGS:
                here = [r for r in ladder if r["system"] == s and r["rung"] == rung]
                ok = [r["ate"] for r in sorted(here, key=lambda r: r["seed"]) if r["ok"]]
                bad = len(here) - len(ok)
                # Each seed's figure beside the mean: one diverged seed makes a mean and std
                # that describe no run.
                each = ", ".join(f"{a:.3f}" for a in ok)
                cell = summary(ok) + (f" ({each})" if len(ok) > 1 else "")
                cells.append(cell + (f", {bad} failed" if bad else "") if here else "–")
            out.append(f"| {s} | " + " | ".join(cells) + f" | {fmt_paper(s)} |")
        out.append("")
        out.append("Drift per 100 m (translation % / rotation °), mean over seeds; false loops, "
                   "wrong joins of the final map and dropped messages, summed over seeds:\n")
        out.append("| system | " + " | ".join(RUNGS) + " |")
        out.append("|---|" + "---|" * len(RUNGS))
        for s in systems:
            cells = []
            for rung in RUNGS:
                ok = [r for r in ladder if r["system"] == s and r["rung"] == rung and r["ok"]]
                if not ok:
                    cells.append("–")
                    continue
                pct = statistics.mean(r["drift_pct"] for r in ok)
                deg = statistics.mean(r["drift_deg"] for r in ok)
                fl = sum(r["false_loops"] or 0 for r in ok)
                wj = sum(r["wrong_joins"] or 0 for r in ok)
                dr = sum(r["dropped"] for r in ok)
                cells.append(f"{pct:.2f} % / {deg:.1f}°; {fl} false, {wj} wrong, {dr} dropped")
            out.append(f"| {s} | " + " | ".join(cells) + " |")
        out.append("")
        out.append("The systems ranked by median ATE RMSE over the seeds on each rung (best "
                   "first; the median, so that one diverged seed does not decide the order):\n")
        for rung in RUNGS:
            means = []
            for s in systems:
                ok = [r["ate"] for r in ladder if r["system"] == s and r["rung"] == rung and r["ok"]]
                if ok:
                    means.append((statistics.median(ok), s))
            if means:
                out.append(f"- `{rung}`: " + ", ".join(s for _, s in sorted(means)))
        out.append("")
        if figure:
            svg_ladder([r for r in ladder if r["ok"]], systems, Path(figure).with_name(
                f"{Path(figure).stem}-{world}.svg"))
            out.append(f"![ATE RMSE per rung]({Path(figure).stem}-{world}.svg)\n")

        out.extend(rates([r for r in wrows if r["variant"] is None], systems, world))
        factor_rows = [r for r in wrows if r["variant"] is not None
                       or r["rung"] == "typical"]
        variants = sorted({r["variant"] for r in factor_rows if r["variant"]})
        if variants:
            seeds = sorted({r["seed"] for r in factor_rows if r["variant"]})
            named = ", ".join(str(x) for x in seeds)
            out.append(f"## {world}: each factor alone over `typical` (S3, seeds {named})\n")
            out.append(
                "ATE RMSE (m), the median over seeds, and the change each seed's run made "
                "against `typical` under the same seed: the median change, then each seed's in seed order. The factor "
                "that costs a system most is the one with the largest median change; a "
                "factor whose changes differ in sign between seeds is within the seeds' "
                "spread. `transport`: each system paced at real time behind its own ROS "
                "node's subscriber queues (transport-*.toml), with the messages it dropped.\n")
            out.append("| system | typical | " + " | ".join(variants) + " | costs most |")
            out.append("|---|---:|" + "---:|" * len(variants) + "---|")
            for s in systems:
                base = {r["seed"]: r for r in factor_rows if r["system"] == s
                        and r["variant"] is None and r["rung"] == "typical"}
                # `typical` over the seeds this system's factors ran at.
                own = {r["seed"] for r in factor_rows if r["system"] == s and r["variant"]}
                used = [base[x] for x in sorted(own) if x in base]
                base_ok = [r["ate"] for r in used if r["ok"]]
                cells, worst = [], None
                for v in variants:
                    here = sorted((r for r in factor_rows if r["system"] == s
                                   and r["variant"] == v), key=lambda r: r["seed"])
                    if not here:
                        cells.append("–")
                        continue
                    ok = [r for r in here if r["ok"]]
                    bad = len(here) - len(ok)
                    tail = f", {bad} failed" if bad else ""
                    # A bounded queue's cost is also what it dropped.
                    dropped = sum(r["dropped"] for r in ok)
                    if dropped or any(r["variant"] == "transport" for r in ok):
                        tail += f", {dropped} dropped"
                    if not ok:
                        cells.append(f"failed ({here[0]['status']})")
                        continue
                    ate = statistics.median(r["ate"] for r in ok)
                    pairs = [r["ate"] - base[r["seed"]]["ate"] for r in ok
                             if r["seed"] in base and base[r["seed"]]["ok"]]
                    if not pairs:
                        cells.append(f"{ate:.3f}{tail}")
                        continue
                    d = statistics.median(pairs)
                    each = "; " + ", ".join(f"{x:+.3f}" for x in pairs) if len(pairs) > 1 else ""
                    cells.append(f"{ate:.3f} ({d:+.3f}{each}){tail}")
                    if worst is None or d > worst[0]:
                        worst = (d, v)
                # A cost shown as +0.000 m is none.
                most = (f"{worst[1]} ({worst[0]:+.3f} m)" if worst and worst[0] >= 0.0005
                        else "–")
                b = f"{statistics.median(base_ok):.3f}" if base_ok else "–"
                out.append(f"| {s} | {b} | " + " | ".join(cells) + f" | {most} |")
            out.append("")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--kept", default="docs/realism/runs")
    ap.add_argument("--out", default="docs/realism/sensitivity.md")
    ap.add_argument("--figure", default="docs/realism/sensitivity.svg",
                    help="the ladder figure's path; one per world, the world's name appended")
    ap.add_argument("--resume", metavar="SWEEP.toml",
                    help="write beside it the narrowed sweep files of what --kept (a world's "
                         "folder) lacks, print their paths and stop")
    args = ap.parse_args()
    if args.resume:
        for f in resume_files(args.resume, args.kept, Path(args.resume).parent, normal):
            print(f)
        return
    runs = load(args.kept)
    head = ("# Sensitivity of the systems to the realism ladder (issue 45)\n\n"
            "Written by `scripts/study-realism.py` from the runs kept in "
            f"`{args.kept}/` ({len(runs)} runs); how they were made: "
            "[README.md](README.md).\n\n")
    Path(args.out).write_text(head + tables(runs, args.figure))
    print(f"{args.out}: {len(runs)} runs")


if __name__ == "__main__":
    main()
