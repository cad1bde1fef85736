"""What the study scripts (study-rates.py, study-realism.py, study-gnss.py) share."""

import json
import math
import re
import tomllib
from pathlib import Path


# The normal quantile of a two-sided 95 % interval.
Z = 1.959963984540054


def wilson(k, n):
    """The 95 % Wilson score interval of k of n (exactly 0 and 1 at k = 0 and k = n)."""
    p = k / n
    d = 1 + Z * Z / n
    centre = (p + Z * Z / (2 * n)) / d
    half = Z / d * math.sqrt(p * (1 - p) / n + Z * Z / (4 * n * n))
    return (0.0 if k == 0 else max(0.0, centre - half), 1.0 if k == n else min(1.0, centre + half))


def toml_text(v):
    """A TOML value as `vinebench sweep` prints it in a run's `point` (and as TOML reads it
    back): `2`, `0.5`, `"dense"`, `[3.0, 1.5]`, `true`."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(toml_text(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)


def load(kept):
    """Every kept run: its cell, metrics and timing, with the world folder's name."""
    runs = []
    for cell_path in sorted(Path(kept).glob("*/*/cell.json")):
        d = cell_path.parent
        run = {"world": d.parent.name, "cell": json.loads(cell_path.read_text())}
        for name in ["metrics", "timing"]:
            f = d / f"{name}.json"
            run[name] = json.loads(f.read_text()) if f.exists() else None
        runs.append(run)
    return runs


def points_of(cfg):
    """Every point of a sweep file as [(key, TOML text)], variants outermost, then the
    axes in file order, the last fastest (as `vinebench sweep` expands them)."""
    points = [[]]
    variants = sorted(cfg.get("variants", {}))
    if variants:
        points = [[("variant", toml_text(v))] for v in variants]
    for key, values in cfg.get("axes", {}).items():
        points = [p + [(key, toml_text(v))] for p in points for v in values]
    return points


def cell_id(c, normal=dict):
    """What makes a kept run the run of a cell, whatever build made it: its system (label,
    bounded queues or not), route, seed and point."""
    return (c["label"], bool(c.get("queue_size")), c["scenario"], c["seed"],
            tuple(sorted(normal(c["point"]).items())))


def resume_files(sweep_file, kept, write_dir, normal=dict, group_variants=False):
    """One narrowed copy of `sweep_file` per (point, seed) some of whose systems have no
    kept run in `kept` (a world's folder of kept runs), with only those systems.
    `normal(point)` is the point as a dict, as the study compares points (a study whose
    baseline variant is the same run as another's drops it). With `group_variants`, one
    copy per (point but its variant, seed), with every variant that lacks a run: with
    `record_once`, variants that differ only in their GNSS receiver then replay one
    recording per route (`runner::record`); the systems and routes are those any of its
    variants lacks. Returns their paths.

    A run's key hashes the plugin library's bytes, which change with a rebuild; these
    narrowed files let a study spread over sessions (and rebuilds) run each cell once."""
    path = Path(sweep_file)
    text = path.read_text()
    cfg = tomllib.loads(text)
    have = set()
    for cell_path in Path(kept).glob("*/cell.json"):
        have.add(cell_id(json.loads(cell_path.read_text()), normal))
    head, *blocks = re.split(r"(?m)^(?=\[\[plugins\]\])", text)
    plugins = [tomllib.loads(b)["plugins"][0] for b in blocks]
    # A run with bounded queues (transport-*.toml) is another cell than the same system's
    # without.
    labels = [(p.get("label") or p["name"], "queue_size" in p) for p in plugins]
    points = list(enumerate(points_of(cfg)))
    units = {}
    for i, point in points:
        rest = tuple(kv for kv in point if kv[0] != "variant") if group_variants else i
        units.setdefault(rest, []).append((i, point))
    written = []
    for unit in units.values():
        first = unit[0][0]
        for seed in cfg.get("seeds", [cfg.get("seed", 0)]):
            lacking = lambda point, label, queued, s: (
                (label, queued, s, seed, tuple(sorted(normal(point).items()))) not in have)
            todo = [point for _, point in unit
                    if any(lacking(point, label, queued, s)
                           for label, queued in labels for s in cfg["scenarios"])]
            if not todo:
                continue
            missing = [b for b, (label, queued) in zip(blocks, labels)
                       if any(lacking(p, label, queued, s)
                              for p in todo for s in cfg["scenarios"])]
            # Only the routes some system lacks: a group cut short in its last route does
            # not run its first ones again.
            routes = [s for s in cfg["scenarios"]
                      if any(lacking(p, label, queued, s)
                             for p in todo for label, queued in labels)]
            narrowed = re.sub(r"(?m)^seeds = .*$", f"seeds = [{seed}]", head)
            narrowed, n = re.subn(r"(?m)^scenarios = .*$",
                                  "scenarios = [" + ", ".join(f'"{s}"' for s in routes) + "]",
                                  narrowed)
            assert n == 1, f"{sweep_file}: scenarios not on a line of their own"
            variants = [json.loads(v) for p in todo for k, v in p if k == "variant"]
            if variants:
                # Keep these variants' tables, drop the others'.
                narrowed = re.sub(r"(?ms)^\[variants\.([^\]]+)\]\n.*?(?=^\[|\Z)",
                                  lambda m: m.group(0) if m.group(1) in variants else "",
                                  narrowed)
            for k, v in todo[0]:
                if k != "variant":
                    narrowed, n = re.subn(rf'(?m)^"{re.escape(k)}" = .*$', f'"{k}" = [{v}]',
                                          narrowed)
                    assert n == 1, f"{sweep_file}: axis {k} not on a line of its own"
            narrowed = narrowed.rstrip() + "\n\n" + "".join(missing)
            check = tomllib.loads(narrowed)
            assert check["seeds"] == [seed] and len(check["plugins"]) == len(missing)
            assert check["scenarios"] == routes
            assert points_of(check) == todo, (points_of(check), todo)
            out = Path(write_dir) / f".{path.stem}.resume-{first}-{seed}.toml"
            out.write_text(narrowed)
            written.append(out)
    return written


def keep_runs(results, kept):
    """Copies the small files (cell.json, metrics.json, timing.json) of every finished run
    of the sweeps under `results`/<world>/runs/<key>/ to `kept`/<world>/<key>/, but a run
    whose cell is kept already (under another key: the same cell run again by another
    build), which stays as it is. Returns how many runs are kept."""
    ids = {}
    for cell_path in Path(kept).glob("*/*/cell.json"):
        ids.setdefault(cell_path.parent.parent.name, set()).add(
            cell_id(json.loads(cell_path.read_text())))
    for cell_path in sorted(Path(results).glob("*/runs/*/cell.json")):
        run = cell_path.parent
        world = run.parent.parent.name
        dest = Path(kept) / world / run.name
        cell = json.loads(cell_path.read_text())
        if (dest / "cell.json").exists() or cell_id(cell) in ids.get(world, set()):
            continue
        dest.mkdir(parents=True, exist_ok=True)
        for name in ["cell.json", "metrics.json", "timing.json"]:
            if (run / name).exists():
                (dest / name).write_bytes((run / name).read_bytes())
        ids.setdefault(world, set()).add(cell_id(cell))
    return len(list(Path(kept).glob("*/*/cell.json")))


if __name__ == "__main__":
    import sys
    if len(sys.argv) == 4 and sys.argv[1] == "keep":
        print(f"kept: {keep_runs(sys.argv[2], sys.argv[3])} runs in {sys.argv[3]}")
    else:
        sys.exit("usage: studylib.py keep RESULTS KEPT")
