#!/usr/bin/env bash
# Writes the seed corpus, fuzz/corpus/<target>/, from vinebench's own files and output
# (docs/fuzzing.md): the configs, tiny recordings of every sensor, one short run of
# staticmapping (trajectories, map, metrics, ape.csv, results.mcap), and what
# fuzz/targets/examples/seeds.rs derives from them. Needs the `vinebench` executable and the
# plugin beside it: `cargo build --profile suite` (VINEBENCH overrides the path).
set -euo pipefail
cd "$(dirname "$0")/.."
vinebench=${VINEBENCH:-target/suite/vinebench}
corpus=fuzz/corpus
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

seed() { # target, files...
    local target=$1
    shift
    mkdir -p "$corpus/$target"
    cp "$@" "$corpus/$target/"
}

seed world_toml configs/world.toml configs/paper-world.toml configs/peers-paper-world.toml
seed bench_toml configs/paper.toml configs/lio-sam.toml configs/backends.toml configs/peers.toml
seed sweep_toml configs/paper-sweep.toml configs/sweep-demo.toml configs/fidelity-subset.toml \
    configs/study/realism/factors-paper-world.toml
seed g2o plugins/slam-common/tests/fixtures/pose3example.txt
# A planar TORO graph and a City10000 one (GTSAM's layouts, docs of posegraph::parse).
cat > "$work/toro2d.graph" <<'EOF'
VERTEX2 0 0.0 0.0 0.0
VERTEX2 1 1.0 0.1 0.05
VERTEX2 2 2.0 0.1 1.57
EDGE2 0 1 1.0 0.1 0.05 1 0 1 1 0 0
EDGE2 1 2 1.0 0.0 1.52 1 0 1 1 0 0
EQUIV 1 2
EOF
cat > "$work/city10000.txt" <<'EOF'
EDGE2 0 0 1 0 1 1.0 0.0 0.01
EDGE2 1 0 2 0 2 0.9 0.1 0.02 1.1 0.0 0.0
EOF
seed g2o "$work/toro2d.graph" "$work/city10000.txt"

# The smallest sensors that still make every kind of message: 2 x 36 lidar points, 16-ray
# scans, an 8 x 6 camera.
cat > "$work/tiny.toml" <<'EOF'
[sensors.lidar]
rings = 2
columns = 36
[sensors.scan2d_front]
samples = 16
[sensors.scan2d_back]
samples = 16
[sensors.camera]
width = 8
height = 6
EOF
recordings=()
for sensors in gt,imu,odom scan2d lidar rgbd; do
    out="$work/${sensors//,/-}.mcap"
    "$vinebench" record --scenario s0 --world "$work/tiny.toml" --max-time 0.1 \
        --sensors "$sensors" -o "$out" > /dev/null
    recordings+=("$out")
done
seed mcap_dataset "${recordings[@]}"

"$vinebench" run --scenario s0 --plugin staticmapping --max-time 3 --out "$work/run" > /dev/null
run=$(dirname "$(find "$work/run" -name metrics.json | head -1)")
cp "$run/metrics.json" "$run/timing.json" "$work/"
seed run_json "$work/metrics.json" "$work/timing.json"
head -c 4000 "$run/ape.csv" | sed '$d' > "$work/ape.csv"
seed ape_csv "$work/ape.csv"
cp "$run/results.mcap" "$work/results.mcap"
seed mcap_dataset "$work/results.mcap"

cargo run --quiet --profile suite -p vinebench-fuzz-targets --example seeds -- \
    "$run" "$corpus" "${recordings[@]}"
du -sh "$corpus"
