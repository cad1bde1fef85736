#!/usr/bin/env bash
# Issue 45's sensitivity study (docs/realism/): every system on S3 of the paper's world under
# each rung of the realism ladder (ideal, paper, typical, field; three seeds), with each
# factor of `field` alone over `typical` (three seeds; ORB-SLAM3 one), and the cheap systems'
# breaks as a rate over ten seeds, the sweeps of configs/study/realism/.
# Each (rung or factor, seed) is recorded once and replayed to every system. Hours on two
# cores; spread it over sessions:
#   bash scripts/study-realism.sh [SWEEP...]   run (or resume) the named sweeps, all by default
#   bash scripts/study-realism.sh --save       keep the finished runs' small files in git
#   bash scripts/study-realism.sh --table      write docs/realism/sensitivity.md from what is kept
# What --save keeps in docs/realism/runs/<world>/<key>/ (cell.json, metrics.json,
# timing.json) is what counts: a sweep runs only the cells not kept yet, on any machine and
# after any rebuild (a run's key hashes the plugin's bytes), and a sweep stopped midway
# resumes from its folder (results/realism/<world>/, one folder for every sweep of a world,
# so that the ladder's `typical` rung at seed 0 and the factors' `typical` are one run).
set -euo pipefail
cd "$(dirname "$0")/.."
results=results/realism
kept=docs/realism/runs
# VINEBENCH: another build's vinebench (its plugins beside it), used as it is, not rebuilt.
vb=${VINEBENCH:-target/release/vinebench}
all=(ladder-paper-world factors-paper-world rates-paper-world ladder-paper-world-camera
     factors-paper-world-camera ladder-paper-world-orbslam3 factors-paper-world-orbslam3
     transport-paper-world)

source scripts/studylib.sh
save() { keep_sweep_runs "$results" "$kept"; }

table() {
    python3 scripts/study-realism.py --kept "$kept" --out docs/realism/sensitivity.md \
        --figure docs/realism/sensitivity.svg
}

case "${1:-}" in
--save) save; exit 0 ;;
--table) table; exit 0 ;;
esac

source scripts/setup.sh
[ -n "${VINEBENCH:-}" ] || cargo build --release
[ -f target/orbslam3-vocabulary.txt ] || "$(dirname "$vb")/orbslam2-vocabulary" \
    --export-dbow2-text plugins/orbslam2/vocabulary/vineyard-k10l6.dbow target/orbslam3-vocabulary.txt

sweeps=("$@")
[ ${#sweeps[@]} -gt 0 ] || sweeps=("${all[@]}")
for s in "${sweeps[@]}"; do
    file="configs/study/realism/$s.toml"
    world=${s#*-}
    world=${world%-orbslam3}
    world=${world%-camera}
    resumes=$(python3 scripts/study-realism.py --resume "$file" --kept "$kept/$world")
    [ -n "$resumes" ] || { echo "$s: every run kept"; continue; }
    for resume in $resumes; do
        # Jobs as the file says (ORB-SLAM3's: one, it runs threads of its own).
        "$vb" sweep "$resume" --out "$results/$world" --allow-failures || true
        rm -f "$resume"
        save
    done
done
table
