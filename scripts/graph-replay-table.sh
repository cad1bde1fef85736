#!/usr/bin/env bash
# The backends on GTSAM's public benchmark graphs: every backend (isam2, gtsam, factrs) on
# sphere2500, w10000 and City10000, replayed pose by pose (one update per pose) and solved
# in batch, each run one `graph-replay` process on this machine. Prints a markdown table
# and keeps every run's JSON line and per-update profile in OUT (default
# results/graph-replay).
#
#   bash scripts/graph-replay-table.sh [OUT]
#
# The graphs come with the gtsam wheel that scripts/setup.sh installs (target/gtsam-venv);
# graph-replay finds a bare file name there. Batch solves run to convergence (at most 100
# Gauss-Newton or Levenberg-Marquardt iterations) so their final errors compare optima.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
out="${1:-results/graph-replay}"
mkdir -p "$out"
cargo build --release -p vinebench-slam-common --bin graph-replay -p vinebench-gtsam
replay=target/release/graph-replay
runs="$out/runs.jsonl"
: >"$runs"
graphs=(
  "sphere2500.txt --groundtruth sphere2500_groundtruth.txt"
  "w10000.graph"
  "T1_city10000_04.txt --groundtruth ISAM2_GT_city10000.txt"
)
for graph in "${graphs[@]}"; do
  name=${graph%% *}
  for backend in isam2 gtsam factrs; do
    for mode in incremental batch; do
      extra=()
      [ "$mode" = batch ] && extra=(--batch --max-iterations 100)
      echo "graph-replay $graph --backend $backend ${extra[*]}" >&2
      # shellcheck disable=SC2086 # $graph is a file name and its options
      if ! line=$("$replay" $graph --backend "$backend" "${extra[@]}" --json \
        --profile "$out/${name%%.*}-$backend-$mode.csv" 2>"$out/${name%%.*}-$backend-$mode.log"); then
        line=$(printf '{"file":"%s","backend":"%s","mode":"%s","failed":"%s"}' "$name" "$backend" \
          "$mode" "$(head -c 200 "$out/${name%%.*}-$backend-$mode.log" | tr '\n"' ' ' )")
      fi
      echo "$line" >>"$runs"
    done
  done
done
python3 - "$runs" <<'EOF'
import json, os, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
for r in rows:
    r["file"] = os.path.basename(r["file"])
print("| graph | backend | mode | final error | vs gtsam | ATE (m) | total (s) | worst update (s) |")
print("|---|---|---|---|---|---|---|---|")
ref = {(r["file"], r["mode"]): r.get("final_error") for r in rows if r["backend"] == "gtsam"}
for r in rows:
    if "failed" in r:
        print(f"| {r['file']} | {r['backend']} | {r['mode']} | failed: {r['failed'][:80]} | | | | |")
        continue
    g = ref.get((r["file"], r["mode"]))
    rel = f"{100 * (r['final_error'] / g - 1):+.3f} %" if g else "–"
    ate = f"{r['ate_rmse_m']:.4f}" if "ate_rmse_m" in r else "–"
    print(f"| {r['file']} | {r['backend']} | {r['mode']} | {r['final_error']:.3f} | {rel} | {ate} "
          f"| {r['seconds']:.2f} | {r['max_update_s']:.3f} |")
EOF
