#!/usr/bin/env bash
# Installs what vinebench needs beyond the Rust toolchain, on Debian bookworm, when missing.
# Sourced by scripts/test.sh and scripts/run.sh; safe to run again (it only installs what lacks).
set -euo pipefail

apt_missing=()
need_pkg() { dpkg -s "$1" >/dev/null 2>&1 || apt_missing+=("$1"); }
# A C toolchain for crates that build C (present on most Rust images).
command -v cc >/dev/null 2>&1 || need_pkg gcc
command -v python3 >/dev/null 2>&1 || { need_pkg python3; need_pkg python3-pip; need_pkg python3-venv; }
if ((${#apt_missing[@]})); then
  echo "setup: installing ${apt_missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${apt_missing[@]}"
fi

# evo (the reference trajectory evaluator) in its own virtual environment, for the
# cross-check tests and the evaluation benchmark. Debian's python forbids global pip installs.
vinebench_venv="${VINEBENCH_VENV:-$PWD/target/evo-venv}"
evo_pin=$(grep -v '^#' tests/evo/requirements.txt | head -n 1)
if ! "$vinebench_venv/bin/python" -m pip show evo 2>/dev/null | grep -qx "Version: ${evo_pin#evo==}"; then
  if ! python3 -m venv "$vinebench_venv" >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq --no-install-recommends python3-venv
    python3 -m venv "$vinebench_venv"
  fi
  echo "setup: installing $evo_pin into $vinebench_venv" >&2
  "$vinebench_venv/bin/python" -m pip install --quiet --disable-pip-version-check -r tests/evo/requirements.txt
fi
export PATH="$vinebench_venv/bin:$PATH"
