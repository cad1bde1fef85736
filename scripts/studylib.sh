# What the sweep-based study scripts (study-realism.sh, study-gnss.sh) share; sourced.

# keep_sweep_runs RESULTS KEPT: copies the small files (cell.json, metrics.json,
# timing.json) of every finished run of the sweeps under RESULTS/<world>/runs/<key>/ to
# KEPT/<world>/<key>/, the runs kept already left as they are, and a run of a cell kept
# already (by another build) left out (scripts/studylib.py keep_runs).
keep_sweep_runs() {
    python3 "$(dirname "${BASH_SOURCE[0]}")/studylib.py" keep "$1" "$2"
}
