#!/usr/bin/env bash
# Issue 47's GNSS study (docs/gnss/): each system with its GNSS on, on S0-S3 under `typical`
# and `field`, three seeds, with no receiver, a consumer one, RTK under the block's sky and
# RTK under an open sky (configs/study/gnss/<world>.toml). Each route of a (profile, seed)
# is recorded once, without GNSS, and replayed to every system under every receiver, each
# run simulating its own receiver (runner::record). Hours on two cores; spread it over
# sessions:
#   bash scripts/study-gnss.sh [WORLD...]   run (or resume) the named worlds' sweeps
#                                           (our-world by default)
#   bash scripts/study-gnss.sh --save       keep the finished runs' small files in git
#   bash scripts/study-gnss.sh --table      write docs/gnss/study.md from what is kept
# What --save keeps in docs/gnss/runs/<world>/<key>/ (cell.json, metrics.json, timing.json)
# is what counts: a sweep runs only the cells not kept yet, in the order `typical` before
# `field`, then seed, every receiver of a seed in one sweep (scripts/study-gnss.py
# --resume), on any machine and after any rebuild.
set -euo pipefail
cd "$(dirname "$0")/.."
results=results/gnss
kept=docs/gnss/runs
# VINEBENCH: another build's vinebench (its plugins beside it), used as it is, not rebuilt.
vb=${VINEBENCH:-target/release/vinebench}

source scripts/studylib.sh
save() { keep_sweep_runs "$results" "$kept"; }

case "${1:-}" in
--save) save; exit 0 ;;
--table) python3 scripts/study-gnss.py --kept "$kept" --out docs/gnss/study.md; exit 0 ;;
esac

source scripts/setup.sh
[ -n "${VINEBENCH:-}" ] || cargo build --release

worlds=("$@")
[ ${#worlds[@]} -gt 0 ] || worlds=(our-world)
for world in "${worlds[@]}"; do
    file="configs/study/gnss/$world.toml"
    resumes=$(python3 scripts/study-gnss.py --resume "$file" --kept "$kept/$world")
    [ -n "$resumes" ] || { echo "$world: every run kept"; continue; }
    for resume in $resumes; do
        "$vb" sweep "$resume" --out "$results/$world" --allow-failures || true
        rm -f "$resume"
        save
    done
done
python3 scripts/study-gnss.py --kept "$kept" --out docs/gnss/study.md
