# What the sweep-based study scripts (study-realism.sh, study-gnss.sh) share; sourced.

# keep_sweep_runs RESULTS KEPT: copies the small files (cell.json, metrics.json,
# timing.json) of every finished run of the sweeps under RESULTS/<world>/runs/<key>/ to
# KEPT/<world>/<key>/, the runs kept already left as they are.
keep_sweep_runs() {
    local results=$1 kept=$2 dir world dest f
    for dir in "$results"/*/runs/*/; do
        [ -f "$dir/cell.json" ] || continue
        world=$(basename "$(dirname "$(dirname "$dir")")")
        dest="$kept/$world/$(basename "$dir")"
        [ -f "$dest/cell.json" ] && continue
        mkdir -p "$dest"
        for f in cell.json metrics.json timing.json; do
            if [ -f "$dir/$f" ]; then cp "$dir/$f" "$dest/"; fi
        done
    done
    echo "kept: $(find "$kept" -name cell.json 2>/dev/null | wc -l) runs in $kept"
}
