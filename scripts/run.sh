#!/usr/bin/env bash
# The main job on the embedded defaults. Until the plugin host lands (the benchmark of
# SLAM plugins), this drives the four scenarios of the paper through the simulator with
# every sensor and writes each one's data and top view to out/<scenario>/.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo build --release -p vinebench
for scenario in s0 s1 s2 s3; do
  ./target/release/vinebench simulate --scenario "$scenario" --sensors all --out "out/$scenario"
done
