#!/usr/bin/env bash
# The study "why our figures differ from the paper's" (docs/hroob/README.md): every bench and
# sweep of configs/study/, then its tables (docs/hroob/tables.md). About two and a half hours
# on two cores; started again, each sweep runs only what is missing (a bench that finished
# is skipped by its folder). ORB-SLAM3 runs at real-time pace: keep the machine otherwise
# idle while it runs.
#   bash scripts/study.sh [RESULTS]      (default: results)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
results="${1:-results}"
cargo build --release
vb=target/release/vinebench
[ -f target/orbslam3-vocabulary.txt ] || target/release/orbslam2-vocabulary \
    --export-dbow2-text plugins/orbslam2/vocabulary/vineyard-k10l6.dbow target/orbslam3-vocabulary.txt

sweep() { "$vb" sweep "configs/study/$1.toml" --out "$results/study/$1" --jobs 2; }
bench() { # a bench runs once: its folder is its mark
    [ -f "$results/study/$2/table.json" ] || "$vb" bench "configs/study/$1.toml" --jobs 1 --out "$results/study/$2"
}

sweep paper-world-seeds
for a in ablate-per-point-time ablate-lio-sam-defaults ablate-imu-noise ablate-fence ablate-fence-relief ablate-depth-registered \
         ablate-colour-unclipped ablate-rtabmap-visual-odometry finding-ablations lio-sam-lidar-only-paper-world \
         lio-sam-lidar-only-our-world; do
    sweep "$a"
done
for k in 1 2 3; do bench orbslam3-s3 "orbslam3-s3-run$k"; done
bench orbslam3-s3-free orbslam3-s3-free
for a in plant-variation-paper-world growth-stage-paper-world kiss-icp-instant-sweeps-our-world \
         ablate-fence-orbslam2 plant-variation-our-world lio-sam-seeds-our-world; do
    sweep "$a"
done
# Our world's paper bench, seed 0 (configs/vinebench.toml), if not run yet.
[ -f "$results/vinebench/table.json" ] || "$vb" bench configs/vinebench.toml --out "$results/vinebench"
# The peers on both worlds at plant variation 0 (configs/peers*.toml), if not run yet.
[ -f "$results/peers/table.json" ] || VINEBENCH_PEERS=configs/peers.toml bash scripts/peers.sh --out "$results/peers"
[ -f "$results/peers-paper-world/table.json" ] || VINEBENCH_PEERS=configs/peers-paper-world.toml \
    bash scripts/peers.sh --out "$results/peers-paper-world"
python3 scripts/study-tables.py --results "$results" --out docs/hroob/tables.md
