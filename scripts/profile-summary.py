#!/usr/bin/env python3
"""Summarise `vinebench bench` results folders as Markdown: accuracy, loops and speed per
label and scenario, and the graph-update profile of every run that wrote `updates.csv`
(`profile_csv = "updates.csv"` in lio-sam's or rtabmap's parameters).

    python3 scripts/profile-summary.py results/backends [results/backends-isam2 ...]
        [--bins 100,300] [--per-scenario]

Reads each folder's table.json and, per run, <scenario>/<label>/timing.json and
updates.csv (columns poses,full,seconds: one line per graph update). Prints:

1. ATE RMSE (m) per label and scenario;
2. loops accepted / judged false by the host, per label and scenario;
3. real-time factor (simulated s per wall s) and the plugin's own (simulated s per s
   spent in the plugin's callbacks, from timing.json), per label and scenario;
4. incremental updates (full = 0): count, p50 and p99 of their time (ms) in bins of graph
   size (poses; default bins <= 100, 101-300, > 300), pooled over the label's scenarios
   (--per-scenario: one row per run); full updates (full = 1): count, p50 and max (ms);
5. failed runs with their reason (table.json's status) and the last error line of the
   run's worker.log if there is one.

Percentiles are nearest-rank. Standard library only.
"""

import argparse
import csv
import json
import math
import os
import sys


def percentile(values, p):
    """Nearest-rank percentile of a non-empty list (p in 0..100)."""
    s = sorted(values)
    rank = max(1, math.ceil(p / 100.0 * len(s)))
    return s[rank - 1]


def scenario_key(name):
    return (len(name), name)


def load(folders):
    """{label: {scenario: record}} with record = table.json entry + run folder."""
    runs = {}
    scenarios = set()
    labels = []
    for folder in folders:
        path = os.path.join(folder, "table.json")
        with open(path) as f:
            table = json.load(f)
        for scenario, by_label in table.items():
            scenarios.add(scenario)
            for label, rec in by_label.items():
                if label not in runs:
                    runs[label] = {}
                    labels.append(label)
                rec = dict(rec)
                rec["dir"] = os.path.join(folder, scenario, label)
                runs[label][scenario] = rec
    return labels, sorted(scenarios, key=scenario_key), runs


def read_updates(run_dir):
    path = os.path.join(run_dir, "updates.csv")
    if not os.path.exists(path):
        return None
    rows = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            rows.append((int(row["poses"]), row["full"] == "1", float(row["seconds"])))
    return rows


def read_timing(run_dir):
    path = os.path.join(run_dir, "timing.json")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


def worker_error(run_dir):
    path = os.path.join(run_dir, "worker.log")
    if not os.path.exists(path):
        return None
    last = None
    with open(path, errors="replace") as f:
        for line in f:
            low = line.lower()
            if "error" in low or "panick" in low or "fail" in low:
                last = line.strip()
    return last


def ok(rec):
    return rec is not None and rec.get("status") == "ok"


def fmt(x, digits=3):
    return "–" if x is None else f"{x:.{digits}f}"


def bin_names(edges):
    names = [f"≤ {edges[0]}"]
    for lo, hi in zip(edges, edges[1:]):
        names.append(f"{lo + 1}–{hi}")
    names.append(f"> {edges[-1]}")
    return names


def bin_of(poses, edges):
    for i, e in enumerate(edges):
        if poses <= e:
            return i
    return len(edges)


def matrix(title, labels, scenarios, runs, cell):
    out = [f"**{title}**", ""]
    out.append("| label | " + " | ".join(s.upper() for s in scenarios) + " |")
    out.append("|---|" + "---|" * len(scenarios))
    for label in labels:
        cells = []
        for s in scenarios:
            rec = runs[label].get(s)
            if rec is None:
                cells.append("")
            elif not ok(rec):
                cells.append("failed")
            else:
                cells.append(cell(rec))
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    out.append("")
    return out


def profile_row(name, rows, edges):
    inc = [[] for _ in range(len(edges) + 1)]
    full = []
    for poses, is_full, seconds in rows:
        (full if is_full else inc[bin_of(poses, edges)]).append(seconds * 1e3)
    cells = []
    for b in inc:
        if b:
            cells.append(f"{len(b)}: {percentile(b, 50):.2f} / {percentile(b, 99):.2f}")
        else:
            cells.append("–")
    if full:
        cells.append(f"{len(full)}: {percentile(full, 50):.1f} / {max(full):.1f}")
    else:
        cells.append("0")
    max_poses = max((p for p, _, _ in rows), default=0)
    return f"| {name} | {max_poses} | " + " | ".join(cells) + " |"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", help="results folders of `vinebench bench`")
    ap.add_argument("--bins", default="100,300", help="graph-size bin edges in poses")
    ap.add_argument("--per-scenario", action="store_true", help="one profile row per run")
    args = ap.parse_args()
    edges = [int(e) for e in args.bins.split(",")]
    labels, scenarios, runs = load(args.folders)

    out = [f"Results: {', '.join(args.folders)}", ""]
    out += matrix("ATE RMSE (m)", labels, scenarios, runs, lambda r: fmt(r.get("rmse")))
    out += matrix(
        "Loops accepted / false",
        labels,
        scenarios,
        runs,
        lambda r: f"{r.get('loops_accepted', 0)} / {r.get('loops_false', 0)}",
    )

    def speed(rec):
        t = read_timing(rec["dir"]) or {}
        rtf = rec.get("realtime_factor", t.get("realtime_factor"))
        plug = t.get("realtime_factor_plugin")
        return f"{fmt(rtf, 1)} ({fmt(plug, 1)})"

    out += matrix(
        "Real-time factor, whole run (plugin callbacks only)", labels, scenarios, runs, speed
    )

    names = bin_names(edges)
    out.append(
        "**Graph updates** (updates.csv): incremental updates by graph size — "
        "count: p50 / p99 ms; full updates — count: p50 / max ms"
    )
    out.append("")
    first = "run" if args.per_scenario else "label (S0–S3 pooled)"
    out.append(f"| {first} | poses | " + " | ".join(f"inc. {n}" for n in names) + " | full |")
    out.append("|---|---|" + "---|" * (len(names) + 1))
    for label in labels:
        pooled = []
        missing = []
        for s in scenarios:
            rec = runs[label].get(s)
            if not ok(rec):
                continue
            rows = read_updates(rec["dir"])
            if rows is None:
                missing.append(s)
                continue
            if args.per_scenario:
                out.append(profile_row(f"{label} {s.upper()}", rows, edges))
            pooled += rows
        if not args.per_scenario and pooled:
            out.append(profile_row(label, pooled, edges))
        if missing:
            out.append(f"| {label}: no updates.csv in {', '.join(missing)} | | |")
    out.append("")

    failures = []
    for label in labels:
        for s in scenarios:
            rec = runs[label].get(s)
            if rec is not None and not ok(rec):
                line = f"- {s.upper()} {label}: {rec.get('status')}"
                err = worker_error(rec["dir"])
                if err and err not in rec.get("status", ""):
                    line += f" (worker.log: `{err}`)"
                failures.append(line)
    if failures:
        out += ["**Failed runs**", ""] + failures + [""]
    sys.stdout.write("\n".join(out))


if __name__ == "__main__":
    main()
