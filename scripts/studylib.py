"""What the study scripts (study-rates.py, study-realism.py, study-gnss.py) share."""

import json
import re
import tomllib
from pathlib import Path


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


def resume_files(sweep_file, kept, write_dir, normal=dict):
    """One narrowed copy of `sweep_file` per (point, seed) some of whose systems have no
    kept run in `kept` (a world's folder of kept runs), with only those systems.
    `normal(point)` is the point as a dict, as the study compares points (a study whose
    baseline variant is the same run as another's drops it). Returns their paths.

    A run's key hashes the plugin library's bytes, which change with a rebuild; these
    narrowed files let a study spread over sessions (and rebuilds) run each cell once."""
    path = Path(sweep_file)
    text = path.read_text()
    cfg = tomllib.loads(text)
    have = set()
    for cell_path in Path(kept).glob("*/cell.json"):
        c = json.loads(cell_path.read_text())
        have.add((c["label"], bool(c.get("queue_size")), c["scenario"], c["seed"],
                  tuple(sorted(normal(c["point"]).items()))))
    head, *blocks = re.split(r"(?m)^(?=\[\[plugins\]\])", text)
    plugins = [tomllib.loads(b)["plugins"][0] for b in blocks]
    # A run with bounded queues (transport-*.toml) is another cell than the same system's
    # without.
    labels = [(p.get("label") or p["name"], "queue_size" in p) for p in plugins]
    written = []
    for i, point in enumerate(points_of(cfg)):
        key = tuple(sorted(normal(point).items()))
        for seed in cfg.get("seeds", [cfg.get("seed", 0)]):
            missing = [b for b, (label, queued) in zip(blocks, labels)
                       if not all((label, queued, s, seed, key) in have for s in cfg["scenarios"])]
            if not missing:
                continue
            # Only the routes some missing system lacks: a group cut short in its last route
            # does not run its first ones again.
            routes = [s for s in cfg["scenarios"]
                      if any((label, queued, s, seed, key) not in have
                             for label, queued in labels)]
            narrowed = re.sub(r"(?m)^seeds = .*$", f"seeds = [{seed}]", head)
            narrowed, n = re.subn(r"(?m)^scenarios = .*$",
                                  "scenarios = [" + ", ".join(f'"{s}"' for s in routes) + "]",
                                  narrowed)
            assert n == 1, f"{sweep_file}: scenarios not on a line of their own"
            for k, v in point:
                if k == "variant":
                    name = json.loads(v)
                    # Keep this variant's table, drop the others'.
                    narrowed = re.sub(r"(?ms)^\[variants\.([^\]]+)\]\n.*?(?=^\[|\Z)",
                                      lambda m: m.group(0) if m.group(1) == name else "",
                                      narrowed)
                else:
                    narrowed, n = re.subn(rf'(?m)^"{re.escape(k)}" = .*$', f'"{k}" = [{v}]',
                                          narrowed)
                    assert n == 1, f"{sweep_file}: axis {k} not on a line of its own"
            narrowed = narrowed.rstrip() + "\n\n" + "".join(missing)
            check = tomllib.loads(narrowed)
            assert check["seeds"] == [seed] and len(check["plugins"]) == len(missing)
            assert check["scenarios"] == routes
            assert points_of(check) == [point], (points_of(check), point)
            out = Path(write_dir) / f".{path.stem}.resume-{i}-{seed}.toml"
            out.write_text(narrowed)
            written.append(out)
    return written
