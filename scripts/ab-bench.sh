#!/usr/bin/env bash
# Two builds of vinebench timed against each other on the same machine, alternated so that a
# drift of the machine's speed falls on both alike (issue 44's before/after figures):
#
#   bash scripts/ab-bench.sh [--rounds N] OLD_TREE NEW_TREE -- VINEBENCH_ARGS...
#
# OLD_TREE and NEW_TREE are checkouts with a release build (`target/release/vinebench`), for
# example `git worktree add /tmp/old REV && (cd /tmp/old && cargo build --release)` and this
# tree. Each command runs from its own tree, so that each build reads the configs/ it was
# made with. `{side}` in the arguments becomes `old` or `new` and `{round}` the round, for
# output folders that must not collide (`--out /tmp/ab/{side}-{round}`; the folder is
# removed before each run, so that a bench starts afresh). Prints one line a run (wall and
# user seconds from /usr/bin/time) and, at the end, each side's median and new/old.
# Measure on a quiet machine: nothing else running.
set -euo pipefail
rounds=2
if [ "${1:-}" = "--rounds" ]; then rounds=$2; shift 2; fi
[ $# -ge 3 ] && [ "$3" = "--" ] || {
    echo "usage: bash scripts/ab-bench.sh [--rounds N] OLD_TREE NEW_TREE -- VINEBENCH_ARGS..." >&2
    exit 2
}
old=$(cd "$1" && pwd); new=$(cd "$2" && pwd); shift 3
for tree in "$old" "$new"; do
    [ -x "$tree/target/release/vinebench" ] || {
        echo "ab-bench: $tree/target/release/vinebench missing: build it with cargo build --release" >&2
        exit 2
    }
done
log=$(mktemp)
trap 'rm -f "$log" "$log.t"' EXIT
printf 'round\tside\twall_s\tuser_s\n'
for round in $(seq 1 "$rounds"); do
    for side in old new; do
        tree=$old; [ $side = new ] && tree=$new
        args=()
        for a in "$@"; do
            a=${a//\{side\}/$side}
            args+=("${a//\{round\}/$round}")
        done
        # A results folder named by --out is removed first: each run starts afresh.
        for ((i = 0; i < ${#args[@]}; i++)); do
            if [ "${args[$i]}" = "--out" ] && [ $((i + 1)) -lt ${#args[@]} ]; then
                rm -rf "${args[$((i + 1))]}"
            fi
        done
        (cd "$tree" && /usr/bin/time -o "$log.t" -f '%e %U' target/release/vinebench "${args[@]}" \
            > /dev/null 2>&1) || { echo "ab-bench: the $side run of round $round failed" >&2; exit 1; }
        read -r wall user < "$log.t"
        printf '%s\t%s\t%s\t%s\n' "$round" "$side" "$wall" "$user"
        printf '%s %s %s\n' "$side" "$wall" "$user" >> "$log"
    done
done
python3 - "$log" <<'EOF'
import statistics, sys
runs = [l.split() for l in open(sys.argv[1])]
med = {s: [statistics.median(float(r[k]) for r in runs if r[0] == s) for k in (1, 2)]
       for s in ("old", "new")}
for s in ("old", "new"):
    print(f"{s}: median wall {med[s][0]:.2f} s, user {med[s][1]:.2f} s")
print(f"new/old: wall {med['new'][0] / med['old'][0]:.3f}, user {med['new'][1] / med['old'][1]:.3f}")
EOF
