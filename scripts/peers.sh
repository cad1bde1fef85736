#!/usr/bin/env bash
# The real ORB-SLAM3 and KISS-ICP beside orbslam2 and lio-sam (configs/peers.toml): installs
# their venvs (scripts/setup.sh), builds, exports ORB-SLAM3's vocabulary from ours when missing,
# and runs the bench. Extra arguments go to `vinebench bench` (e.g. --max-time 30).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo build --release
vocabulary=target/orbslam3-vocabulary.txt
if [ ! -f "$vocabulary" ]; then
  ./target/release/orbslam2-vocabulary --export-dbow2-text \
    plugins/orbslam2/vocabulary/vineyard-k10l6.dbow "$vocabulary"
fi
./target/release/vinebench bench "${VINEBENCH_PEERS:-configs/peers.toml}" "$@"
