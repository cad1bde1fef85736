#!/usr/bin/env bash
# The main job: the paper's benchmark (configs/paper.toml) on the embedded defaults. Builds
# the host and every plugin of the workspace, runs each (scenario, system) pair in its own
# process, prints the paper-style table and writes results/paper/ (results/latest links it).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo build --release
./target/release/vinebench bench configs/paper.toml "$@"
