#!/usr/bin/env bash
# Issue 46's localisation study (docs/localization/): on the paper's world under the
# `typical` profile, a map built on S3 at growth stage 2; each system localises on S1 at
# stages 0, 2 and 4, plant variation 0 and 1, seeds 0-2 (one map per variation and seed),
# and once kidnapped (S1, stage 2, variation 0, seed 0: carried 30 s ahead at 60 s).
# Systems: lio-sam in its own saved keyframes; rtabmap in its saved locations (its
# localisation mode); staticmapping in its saved submaps; orbslam2 in its keyframes and map
# points (ORB-SLAM2's localisation mode); amcl in the world's surveyed grid of the block at stage 2 (what a lab
# surveys once), globally and (amcl-guess) told its start. lio-sam-gnss (issue 47): lio-sam
# mapping with `[gps] enabled` (LIO-SAM's defaults: the map georeferenced, no GPS factor on
# these routes) in the same worlds with an RTK receiver and the IMU's orientation (an
# AHRS's error), localising with each fix as a prior for its global search; not in the
# default list (run it by name).
#   bash scripts/study-localization.sh [SYSTEM...]   run (or resume) the runs, all by default
#   bash scripts/study-localization.sh --save        keep the finished runs' small files in git
#   bash scripts/study-localization.sh --table       write docs/localization/study.md
#   PROFILE=field bash scripts/study-localization.sh ...   the same under `field` (its own
#                                                    folders, study-field.md)
# A run whose folder holds metrics.json (or whose kept copy exists) is not run again; the
# study spreads over sessions. VINEBENCH: another build's vinebench, used as it is (its
# plugins beside it), so that a study left running keeps its binary while the tree is
# rebuilt.
set -euo pipefail
cd "$(dirname "$0")/.."
# PROFILE=field: the same study under the `field` profile, in its own folders.
profile=${PROFILE:-typical}
case $profile in
    typical) results=results/localization; kept=docs/localization/runs ;;
    *) results=results/localization-$profile; kept=docs/localization/runs-$profile ;;
esac
vb=${VINEBENCH:-target/release/vinebench}
all=(lio-sam amcl amcl-guess rtabmap staticmapping orbslam2)

world() { # world STAGE VARIATION [gnss] -> the path of the paper's world at that stage and
           # variation (with `gnss`: an RTK receiver and the IMU's orientation, Xsens MTi-30)
    local file="$results/worlds/stage$1-var$2${3:+-$3}.toml"
    if [ ! -f "$file" ]; then
        mkdir -p "$results/worlds"
        python3 - "$1" "$2" "$file" "${3:-}" <<'EOF'
import re, sys
stage, var, out, gnss = sys.argv[1:]
text = open("configs/paper-world.toml").read()
text = re.sub(r"(?m)^growth_stage = .*$", f"growth_stage = {float(stage)}", text)
text = re.sub(r"(?m)^plant_variation = .*$", f"plant_variation = {float(var)}", text)
if gnss:
    text = text.replace("[sensors.imu]", "[sensors.imu]\nreports_orientation = true\n"
                        "orientation_roll_pitch_sigma_rad = 0.0087\n"
                        "orientation_yaw_sigma_rad = 0.0175", 1)
    text += '\n[sensors.gnss]\nprofile = "rtk"\n'
open(out, "w").write(text)
EOF
    fi
    echo "$file"
}

# A system of the study: its plugin, its parameters, its worlds' extra.
plugin_of() { case $1 in lio-sam-gnss) echo lio-sam ;; *) echo "$1" ;; esac; }
extra_of() { case $1 in lio-sam-gnss) echo gnss ;; *) echo "" ;; esac; }
params_of() { # SYSTEM -> its --plugin-config arguments
    case $1 in
        lio-sam-gnss)
            local f="$results/lio-sam-gnss.toml"
            mkdir -p "$results"
            printf '[gps]\nenabled = true\n' > "$f"
            echo "--plugin-config $f" ;;
        *) echo "" ;;
    esac
}

done_run() { [ -f "$1/metrics.json" ] || [ -f "$kept/${1#"$results"/}/metrics.json" ]; }

map_run() { # map_run SYSTEM VAR SEED -> the mapping run's folder
    local dir="$results/map/$1/var$2-seed$3"
    if ! [ -f "$dir/s3/$1/metrics.json" ]; then
        rm -rf "$dir"
        # Every system with its defaults, as the paper bench runs it (configs/paper.toml).
        # shellcheck disable=SC2046
        nice -n 19 "$vb" run --world "$(world 2 "$2" "$(extra_of "$1")")" --profile "$profile" \
            --scenario s3 --seed "$3" --plugin "$(plugin_of "$1")" $(params_of "$1") \
            --label "$1" --out "$dir" >&2
    fi
    echo "$dir/s3/$1"
}

localize() { # localize SYSTEM VAR SEED STAGE NAME [ARGS...]
    local system=$1 var=$2 seed=$3 stage=$4 name=$5
    shift 5
    local out="$results/loc/$system/$name"
    done_run "$out/s1/$system" && return 0
    rm -rf "$out"
    local map
    case $system in
        amcl) map=(--surveyed --survey-world "$(world 2 "$var")" --plugin amcl) ;;
        # AMCL as a Thorvald's navigation starts it: told its start within AMCL's default
        # initial spread (0.5 m, 15 deg), the start read off the global run's ground truth.
        amcl-guess)
            local gt="$results/loc/amcl/$name/s1/amcl/groundtruth.tum"
            [ -f "$gt" ] || localize amcl "$var" "$seed" "$stage" "$name" "$@"
            local guess
            guess=$(python3 -c 'import math,sys
line = next(l for l in open(sys.argv[1]) if l.strip() and not l.startswith("#"))
t,x,y,z,qx,qy,qz,qw = map(float, line.split())
print(f"{x},{y},{math.atan2(2*(qw*qz+qx*qy), 1-2*(qy*qy+qz*qz))},0.5,0.26")' "$gt")
            map=(--surveyed --survey-world "$(world 2 "$var")" --plugin amcl "--initial-guess=$guess") ;;
        *) map=(--map "$(map_run "$system" "$var" "$seed")") ;;
    esac
    echo "localize $system $name" >&2
    nice -n 19 "$vb" localize "${map[@]}" --world "$(world "$stage" "$var" "$(extra_of "$system")")" \
        --profile "$profile" \
        --scenario s1 --seed "$seed" --label "$system" --out "$out" --allow-failures "$@" >&2
    printf '{"system": "%s", "variation": %s, "seed": %s, "stage": %s, "kidnap": %s}\n' \
        "$system" "$var" "$seed" "$stage" "$([ $# -gt 0 ] && echo true || echo false)" \
        > "$out/s1/$system/cell.json"
}

save() {
    for dir in "$results"/map/*/*/s3/*/; do
        case $dir in */latest/*) continue ;; esac  # vinebench's link to the newest folder
        [ -f "$dir/metrics.json" ] || continue
        key=$(basename "$(dirname "$(dirname "$dir")")")
        system=$(basename "$dir")
        mkdir -p "$kept/map/$system/$key"
        cp "$dir/metrics.json" "$kept/map/$system/$key/"
    done
    for dir in "$results"/loc/*/*/s1/*/; do
        case $dir in */latest/*) continue ;; esac
        [ -f "$dir/metrics.json" ] || continue
        rel=${dir#"$results"/}
        dest="$kept/$rel"
        [ -f "$dest/metrics.json" ] && continue
        mkdir -p "$dest"
        for f in cell.json metrics.json localization.toml run.toml; do
            [ -f "$dir/$f" ] && cp "$dir/$f" "$dest/"
        done
    done
    echo "kept in $kept"
}

case "${1:-}" in
    --save) save; exit 0 ;;
    --table) table=docs/localization/study.md
             [ "$profile" = typical ] || table=docs/localization/study-$profile.md
             python3 scripts/study-localization.py "$kept" > "$table"
             echo "wrote $table"; exit 0 ;;
esac
systems=("$@")
[ ${#systems[@]} -gt 0 ] || systems=("${all[@]}")
for system in "${systems[@]}"; do
    for var in 0 1; do
        for seed in 0 1 2; do
            for stage in 0 2 4; do
                localize "$system" "$var" "$seed" "$stage" "var$var-stage$stage-seed$seed"
            done
        done
    done
    localize "$system" 0 0 2 kidnap-var0-stage2-seed0 --kidnap 60,30
    save
done
