#!/usr/bin/env bash
# Times `vinebench eval` against `evo_ape` on the same 100k-pose pair (wall clock, best
# of RUNS) and prints both times and the ratio.
#
# Usage: tests/evo/bench_eval.sh PATH/TO/vinebench [N_POSES] [RUNS]
#   e.g. cargo build --release -p vinebench && tests/evo/bench_eval.sh target/release/vinebench
# Needs evo (python3 -m pip install -r tests/evo/requirements.txt) and numpy (comes with evo).
set -euo pipefail

vinebench=${1:?usage: bench_eval.sh PATH/TO/vinebench [N_POSES] [RUNS]}
n=${2:-100000}
runs=${3:-3}
here=$(cd "$(dirname "$0")" && pwd)
command -v evo_ape >/dev/null || { echo "evo_ape not found: python3 -m pip install -r $here/requirements.txt" >&2; exit 1; }

dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
python3 "$here/gen_pair.py" "$n" "$dir"

# Best wall-clock seconds of $runs runs of the given command (output discarded).
best_of() {
    local best=""
    for _ in $(seq "$runs"); do
        local start end elapsed
        start=$(date +%s.%N)
        "$@" >/dev/null
        end=$(date +%s.%N)
        elapsed=$(echo "$end - $start" | bc -l)
        if [[ -z $best ]] || (( $(echo "$elapsed < $best" | bc -l) )); then best=$elapsed; fi
    done
    echo "$best"
}

echo "pair: $n poses each ($dir)"
echo "vinebench: $("$vinebench" eval "$dir/gt.tum" "$dir/est.tum" --align se3 --json)"
echo "evo:       $(evo_ape tum "$dir/gt.tum" "$dir/est.tum" -a | grep -E 'rmse')"
ours=$(best_of "$vinebench" eval "$dir/gt.tum" "$dir/est.tum" --align se3 --json)
evo=$(best_of evo_ape tum "$dir/gt.tum" "$dir/est.tum" -a)
printf 'vinebench eval --align se3: %.3f s\n' "$ours"
printf 'evo_ape -a:                 %.3f s\n' "$evo"
printf 'speed-up:                   %.1fx\n' "$(echo "$evo / $ours" | bc -l)"
