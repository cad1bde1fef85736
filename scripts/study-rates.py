#!/usr/bin/env python3
"""The rates table of issue 43 (docs/hroob/rates.md) from the runs scripts/study-rates.sh
kept in docs/hroob/rates/runs/<sweep>/<key>/: per scenario, fence, plant variation and
system, the runs with a false accepted loop or a wrong join of the final map, k of n, with
the 95 % Wilson score interval (the formula of vinebench's eval::Rate: Wilson, JASA 1927),
and the ATE RMSE mean ± sample std. Then every false loop and wrong join, with its frames.

    python3 scripts/study-rates.py [--kept DIR] [--out FILE]
    python3 scripts/study-rates.py --resume configs/study/rates/X.toml --kept DIR/X
"""

import argparse
import json
import math
import statistics
from pathlib import Path

from studylib import toml_text, wilson

def fisher_two_sided(k1, n1, k2, n2):
    """Fisher's exact test of k1 of n1 against k2 of n2 (Fisher 1935): the probability,
    under the hypergeometric law with both margins fixed, of every table no likelier than the
    observed one (the usual two-sided rule, with a relative tolerance for ties)."""
    k, n = k1 + k2, n1 + n2
    total = math.comb(n, k)

    def p(a):
        return math.comb(n1, a) * math.comb(n2, k - a) / total

    observed = p(k1)
    lo, hi = max(0, k - n2), min(k, n1)
    return min(1.0, sum(p(a) for a in range(lo, hi + 1) if p(a) <= observed * (1 + 1e-9)))


def rates_svg(rows):
    """A figure of the rates: per cell a dot at k/n and a bar over its Wilson interval,
    orbslam2 and ORB-SLAM3 side by side. `rows`: [(label, system, k, n)]."""
    labels = list(dict.fromkeys(label for label, *_ in rows))
    systems = {"orbslam2": ("#1f77b4", -5), "ORB-SLAM3": ("#d62728", 5)}
    left, top, row_h, width = 290, 30, 26, 380
    height = top + row_h * len(labels) + 40
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{left + width + 45}" height="{height}" '
           'font-family="sans-serif" font-size="12">',
           f'<rect width="100%" height="100%" fill="white"/>']
    for i in range(11):
        x = left + width * i / 10
        out.append(f'<line x1="{x:.1f}" y1="{top - 8}" x2="{x:.1f}" y2="{height - 32}" stroke="#ddd"/>')
        if i % 2 == 0:
            out.append(f'<text x="{x:.1f}" y="{height - 18}" text-anchor="middle">{i / 10:.1f}</text>')
    out.append(f'<text x="{left + width / 2}" y="{height - 3}" text-anchor="middle">'
               'runs with a false loop or a wrong join (rate, Wilson 95 % interval)</text>')
    for j, (name, (colour, _)) in enumerate(systems.items()):
        out.append(f'<circle cx="{left + 10 + 110 * j}" cy="12" r="4" fill="{colour}"/>'
                   f'<text x="{left + 18 + 110 * j}" y="16">{name}</text>')
    for i, label in enumerate(labels):
        y = top + row_h * i + row_h / 2
        out.append(f'<text x="{left - 8}" y="{y + 4:.1f}" text-anchor="end">{label}</text>')
        for lab, system, k, n in rows:
            if lab != label:
                continue
            colour, dy = systems[system]
            lo, hi = wilson(k, n)
            x = lambda v: left + width * v  # noqa: E731
            out.append(f'<line x1="{x(lo):.1f}" y1="{y + dy:.1f}" x2="{x(hi):.1f}" y2="{y + dy:.1f}" '
                       f'stroke="{colour}" stroke-width="2"/>')
            out.append(f'<circle cx="{x(k / n):.1f}" cy="{y + dy:.1f}" r="4" fill="{colour}">'
                       f'<title>{system}: {k} of {n}</title></circle>')
            out.append(f'<text x="{left + width + 4}" y="{y + dy + 4:.1f}" font-size="10" '
                       f'fill="{colour}">{k}/{n}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def cell_of(sweep, cell):
    """(scenario, fence, variation, system) of a kept run."""
    point = dict(cell["point"])
    if "nofence" in sweep:
        fence = "none"
    elif point.get("fence.distinct_panels") == "true":
        fence = "every panel different"
    else:
        fence = "as is"
    variation = float(point.get("vineyard.plant_variation", "0.0"))
    system = "orbslam2" if sweep.startswith("orbslam2") else "ORB-SLAM3"
    return (cell["scenario"].upper(), fence, variation, system)


def points_of(cfg):
    """Every point of a sweep file's axes as [(key, value)], the last axis fastest."""
    points = [[]]
    for key, values in cfg.get("axes", {}).items():
        points = [p + [(key, v)] for p in points for v in values]
    return points


def same_point(kept_point, point):
    """Whether a kept run's point is this point: equal on every key the kept run names (a
    key the sweep pins later, with one value, is absent from runs kept before it)."""
    kept = dict(kept_point)
    wanted = {k: toml_text(v) for k, v in point}
    return all(wanted.get(k) == v for k, v in kept.items())


def resume_files(sweep_file, kept, write_dir):
    """For every point of `sweep_file`'s axes with seeds not kept yet in `kept` (any
    status, whatever build made them: a sweep's own resume keys on the plugin's bytes,
    which change with every rebuild), a copy of the sweep narrowed to that point and those
    seeds, written beside it in `write_dir` (so that its relative paths still hold).
    Returns their paths."""
    import re
    import tomllib

    path = Path(sweep_file)
    text = path.read_text()
    cfg = tomllib.loads(text)
    runs = [json.loads(c.read_text()) for c in Path(kept).glob("*/cell.json")]
    plugins = len(cfg.get("plugins", [])) * len(cfg.get("scenarios", []))
    written = []
    for i, point in enumerate(points_of(cfg)):
        have = {}
        for run in runs:
            if same_point(run["point"], point):
                have[run["seed"]] = have.get(run["seed"], 0) + 1
        missing = [s for s in cfg["seeds"] if have.get(s, 0) < plugins]
        if not missing:
            continue
        narrowed = re.sub(r"(?m)^seeds = .*$", f"seeds = {toml_text(missing)}", text)
        for key, value in point:
            narrowed, n = re.subn(rf'(?m)^"{re.escape(key)}" = .*$',
                                  f'"{key}" = [{toml_text(value)}]', narrowed)
            assert n == 1, f"{sweep_file}: axis {key} not found on a line of its own"
        assert tomllib.loads(narrowed)["seeds"] == missing
        out = Path(write_dir) / f".{path.stem}.resume-{i}.toml"
        out.write_text(narrowed)
        written.append(out)
    kept_points = [r["point"] for r in runs]
    stray = [p for p in kept_points if not any(same_point(p, q) for q in points_of(cfg))]
    assert not stray, f"{kept}: kept runs at points the sweep no longer has: {stray}"
    return written


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--kept", default="docs/hroob/rates/runs")
    ap.add_argument("--out", default="docs/hroob/rates.md")
    ap.add_argument("--resume", metavar="SWEEP.toml",
                    help="write beside it one sweep file per point of its axes with seeds not yet "
                         "kept in --kept (its folder), print their paths and stop")
    args = ap.parse_args()
    if args.resume:
        for f in resume_files(args.resume, args.kept, Path(args.resume).parent):
            print(f)
        return
    kept, out = Path(args.kept), Path(args.out)
    cells, failed, events = {}, {}, []
    for cell_json in sorted(kept.glob("*/*/cell.json")):
        run = cell_json.parent
        sweep = run.parent.name
        cell = json.loads(cell_json.read_text())
        key = cell_of(sweep, cell)
        if cell["status"] != "ok":
            failed.setdefault(key, []).append(f"seed {cell['seed']}: {cell['status']}")
            continue
        metrics = json.loads((run / "metrics.json").read_text())
        joins = metrics.get("joins")
        if joins is None:
            failed.setdefault(key, []).append(f"seed {cell['seed']}: evaluated without joins")
            continue
        false_loops = metrics["loops"]["accepted_false"]
        wrong = joins["wrong_joins"]
        cells.setdefault(key, []).append((false_loops > 0 or wrong > 0, metrics["ape"]["rmse"]))
        frames = {}
        if (run / "frames.json").exists():
            for pair in json.loads((run / "frames.json").read_text())["pairs"]:
                rel = lambda f: (run / f).relative_to(out.parent).as_posix()  # noqa: E731
                links = [f"[{w}]({rel(f)})" for w, f in zip(("later", "earlier"), pair.get("files", []))]
                if pair.get("matches"):
                    links.append(f"[matches]({rel(pair['matches'])})")
                for w, f in zip(("sweeps at the estimate", "sweeps at the truth"), pair.get("scans", [])):
                    links.append(f"[{w}]({rel(f)})")
                if all((run / f).exists() for f in pair.get("files", [])):
                    frames[(pair["kind"], pair["index"])] = links
        for figure in ("route", "error"):
            if (run / f"{figure}.svg").exists():
                figures = frames.setdefault("figures", [])
                figures.append(f"[{figure}]({(run / f'{figure}.svg').relative_to(out.parent).as_posix()})")
        judged = json.loads((run / "events.json").read_text())
        for i, e in enumerate(judged):
            if e.get("kind") == "loop_closure_accepted" and e.get("true_loop") is False:
                events.append((key, cell["seed"], "false loop", e["stamp_ns"] * 1e-9,
                               e.get("judged_by", ""),
                               frames.get(("false_loop", i), []) + frames.get("figures", [])))
        if (run / "joins.json").exists():
            j = json.loads((run / "joins.json").read_text())
            for i, w in enumerate(j["wrong_joins"]):
                what = "silent wrong join" if i in j["silent"] else "wrong join"
                detail = (f"{w['later_s'][0]:.1f}–{w['later_s'][1]:.1f} s onto "
                          f"{w['earlier_s'][0]:.1f}–{w['earlier_s'][1]:.1f} s, "
                          f"{w['truth_distance_m']:.2f} m apart in truth")
                events.append((key, cell["seed"], what, w["pair_s"][0], detail,
                               frames.get(("wrong_join", i), []) + frames.get("figures", [])))
    lines = [
        "# The central finding as rates (issue 43)",
        "",
        "Made by `bash scripts/study-rates.sh --table` from the runs kept in",
        "`docs/hroob/rates/runs/` (the sweeps of `configs/study/rates/`, paper's world). A run",
        "counts when it accepted a loop that ground truth shows false or its final trajectory",
        "wrongly joins two places (`docs/runs.md`). Interval: 95 % Wilson. Ten runs tell only",
        "large differences apart (0 of 10 is [0, 0.28], 5 of 10 [0.24, 0.76]). The same cells",
        "at cluster size (S1-S3, growth stages 1 and 4, 50 seeds: 3,600 runs) are",
        "`configs/study/rates/cluster.toml` and `cluster-nofence.toml`.",
        "",
        "| scenario | fence | plant variation | system | runs | with a false loop or join | rate [95 % CI] | ATE RMSE (m) |",
        "|---|---|---:|---|---:|---:|---|---|",
    ]
    for key in sorted(set(cells) | set(failed)):
        runs = cells.get(key, [])
        n, k = len(runs), sum(1 for bad, _ in runs if bad)
        if n:
            lo, hi = wilson(k, n)
            rate = f"{k / n:.2f} [{lo:.2f}, {hi:.2f}]"
            ates = [a for _, a in runs]
            ate = f"{statistics.mean(ates):.3f}" + (f" ± {statistics.stdev(ates):.3f}" if n > 1 else "")
        else:
            rate = ate = "–"
        scenario, fence, variation, system = key
        extra = f" ({len(failed[key])} failed)" if key in failed else ""
        lines.append(f"| {scenario} | {fence} | {variation:g} | {system} | {n}{extra} | {k} | {rate} | {ate} |")
    lines += ["", "![the rates, Wilson 95 % intervals](rates.svg)", ""]
    figure_rows = []
    for key in sorted(cells):
        scenario, fence, variation, system = key
        runs = cells[key]
        figure_rows.append((f"{scenario}, fence {fence}, variation {variation:g}", system,
                             sum(1 for bad, _ in runs if bad), len(runs)))
    (out.parent / "rates.svg").write_text(rates_svg(figure_rows))
    lines += ["## Whether the fence decides", "",
              "Per system and plant variation, S3 with the fence as is against each other",
              "fence, by Fisher's exact test (two-sided; the probability of so large a",
              "difference if the fence changed nothing):", ""]
    for (scenario, fence, variation, system) in sorted(cells):
        if scenario != "S3" or fence == "as is":
            continue
        base = cells.get(("S3", "as is", variation, system))
        if not base:
            continue
        other = cells[("S3", fence, variation, system)]
        k1, n1 = sum(1 for bad, _ in base if bad), len(base)
        k2, n2 = sum(1 for bad, _ in other if bad), len(other)
        p = fisher_two_sided(k1, n1, k2, n2)
        lines.append(f"- {system}, variation {variation:g}: as is {k1} of {n1} against {fence} "
                     f"{k2} of {n2}: p = {p:.2g}")
    lines += ["", "## Every false loop and wrong join", ""]
    if not events:
        lines.append("None in the runs kept so far.")
    for key, seed, what, t, detail, files in sorted(events, key=lambda e: (e[0], e[1], e[3])):
        scenario, fence, variation, system = key
        text = f"- {scenario}, fence {fence}, variation {variation:g}, {system}, seed {seed}: {what} at {t:.1f} s"
        if detail:
            text += f" ({detail})"
        if files:
            text += ": " + ", ".join(files)
        lines.append(text)
    fails = [f"- {' / '.join(map(str, k))}: {r}" for k, rs in sorted(failed.items()) for r in rs]
    if fails:
        lines += ["", "## Failed runs", ""] + fails
    out.write_text("\n".join(lines) + "\n")
    print(f"{out}: {sum(len(r) for r in cells.values())} runs in {len(cells)} cells")


if __name__ == "__main__":
    main()
