#!/usr/bin/env bash
# Issue 43's rates (docs/hroob/README.md §5): how often orbslam2 and the real ORB-SLAM3 close
# a false loop or wrongly join two places on the paper's world, per cell of S3 (the fence as
# is / none / every panel's wood different × plant variation 0 / 1) and on S1, with Wilson
# 95 % intervals. The sweeps of configs/study/rates/: orbslam2 two runs at a time, ORB-SLAM3
# one at a time at real-time pace (it runs threads of its own). Hours on two cores; spread
# it over sessions:
#   bash scripts/study-rates.sh [SWEEP...]   run (or resume) the named sweeps, all by default
#   bash scripts/study-rates.sh --save       keep the finished runs' small files in git
#   bash scripts/study-rates.sh --table      write docs/hroob/rates.md from what is kept
# What --save kept in docs/hroob/rates/runs/ (each run's cell.json, metrics.json,
# joins.json, judged events.json, frames.json, and for a run with a false loop or a wrong
# join its figures from `vinebench report --figures`: route.svg, error.svg and the pictures
# of those in frames/) is what counts: a sweep runs only the seeds not kept yet, on any machine, and a
# sweep stopped midway resumes from its folder (results/rates/<sweep>/).
set -euo pipefail
cd "$(dirname "$0")/.."
results=results/rates
kept=docs/hroob/rates/runs
# VINEBENCH: another build's vinebench (its plugins and orbslam2-vocabulary beside it), used
# as it is, not rebuilt: a study left running keeps its binary while the tree is rebuilt.
vb=${VINEBENCH:-target/release/vinebench}
all=(orbslam2-s3 orbslam2-s3-decide orbslam2-s3-nofence orbslam2-s3-nofence-decide orbslam2-s1
     orbslam3-s3 orbslam3-s3-decide orbslam3-s3-nofence orbslam3-s3-nofence-decide orbslam3-s1)

save() {
    for dir in "$results"/*/runs/*/; do
        [ -f "$dir/cell.json" ] || continue
        sweep=$(basename "$(dirname "$(dirname "$dir")")")
        key=$(basename "$dir")
        dest="$kept/$sweep/$key"
        [ -f "$dest/cell.json" ] && continue
        mkdir -p "$dest"
        for f in cell.json metrics.json joins.json events.json frames.json; do
            [ -f "$dir/$f" ] && cp "$dir/$f" "$dest/"
        done
        # A run with a false loop or a wrong join keeps its figures (route.svg, error.svg)
        # and, half size each way, the pictures of its first false loop (and its matches),
        # else of its first wrong join; the rest stay in the results folder.
        if python3 -c 'import json,sys; m=json.load(open(sys.argv[1])); sys.exit(0 if m["loops"]["accepted_false"] or (m.get("joins") or {}).get("wrong_joins") else 1)' "$dir/metrics.json" 2>/dev/null; then
            "$vb" report "$dir" --figures "$dest" --label "${sweep%%-*}" --frame-scale 2 > /dev/null
            first=$(cd "$dest/frames" 2>/dev/null && ls false-loop-*-later.png wrong-join-*-later.png 2>/dev/null | head -1 || true)
            if [ -n "$first" ]; then
                find "$dest/frames" -type f ! -name "${first%-later.png}-*" -delete
            fi
        fi
    done
    echo "kept: $(find "$kept" -name cell.json 2>/dev/null | wc -l) runs in $kept"
}

case "${1:-}" in
--save) save; exit 0 ;;
--table) python3 scripts/study-rates.py --kept "$kept" --out docs/hroob/rates.md; exit 0 ;;
esac

source scripts/setup.sh
[ -n "${VINEBENCH:-}" ] || cargo build --release
[ -f target/orbslam3-vocabulary.txt ] || "$(dirname "$vb")/orbslam2-vocabulary" \
    --export-dbow2-text plugins/orbslam2/vocabulary/vineyard-k10l6.dbow target/orbslam3-vocabulary.txt

sweeps=("$@")
[ ${#sweeps[@]} -gt 0 ] || sweeps=("${all[@]}")
# Keep first what a sweep stopped earlier filed, so that the seeds to run are counted from
# everything done (else a run filed but not yet kept is run a second time).
save
for s in "${sweeps[@]}"; do
    file="configs/study/rates/$s.toml"
    # Only the seeds not kept yet, point by point of the axes, whatever build ran the kept
    # ones: a sweep's own resume keys its runs on the plugin library's bytes, which change
    # with every rebuild.
    resumes=$(python3 scripts/study-rates.py --resume "$file" --kept "$kept/$s")
    [ -n "$resumes" ] || { echo "$s: every run kept"; continue; }
    jobs=2
    [[ $s == orbslam3-* ]] && jobs=1
    for resume in $resumes; do
        "$vb" sweep "$resume" --out "$results/$s" --jobs "$jobs" --allow-failures || true
        rm -f "$resume"
        save
    done
done
python3 scripts/study-rates.py --kept "$kept" --out docs/hroob/rates.md
