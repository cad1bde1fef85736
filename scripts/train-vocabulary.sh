#!/usr/bin/env bash
# Trains the vocabulary of the ORB-SLAM2-style plugin (plugins/orbslam2/vocabulary/) on camera
# frames of a world that is NOT the benchmark's: another world seed, every plant unique
# (plant_variation = 1), growth stages 0, 2 and 4, along S3 (lanes, headlands and turns).
# Deterministic: the same commit gives the same file.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo build --release -p vinebench -p vinebench-orbslam2 --bins
work=target/vocabulary
mkdir -p "$work"
dirs=()
for stage in 0 2 4; do
  world="$work/world-stage$stage.toml"
  printf 'world_seed = 7\n[vineyard]\ngrowth_stage = %s.0\nplant_variation = 1.0\n' "$stage" >"$world"
  ./target/release/vinebench simulate --world "$world" --scenario s3 --sensors rgbd --seed 7 \
    --max-time "${VOCABULARY_MAX_TIME:-150}" --out "$work/frames-stage$stage"
  dirs+=("$work/frames-stage$stage")
done
./target/release/orbslam2-vocabulary --out plugins/orbslam2/vocabulary/vineyard-k10l6.dbow \
  --k 10 --levels 6 --seed 0 --every 10 "${dirs[@]}"
