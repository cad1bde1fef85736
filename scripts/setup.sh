#!/usr/bin/env bash
# Installs what vinebench needs beyond the Rust toolchain, on Debian bookworm, when missing.
# Sourced by scripts/test.sh and scripts/run.sh; safe to run again (it only installs what lacks).
set -euo pipefail

apt_missing=()
# Waits for another apt (the other README command started beside this one, say) instead of
# failing on its lock.
apt_get() { apt-get -o DPkg::Lock::Timeout=600 "$@"; }
need_pkg() { dpkg -s "$1" >/dev/null 2>&1 || apt_missing+=("$1"); }
# A C toolchain for crates that build C (present on most Rust images).
command -v cc >/dev/null 2>&1 || need_pkg gcc
command -v python3 >/dev/null 2>&1 || { need_pkg python3; need_pkg python3-pip; need_pkg python3-venv; }
# OpenCV for sim/tests/all/camera_features.rs: the opencv crate binds the system's library
# (found with pkg-config) and generates its bindings with libclang.
need_pkg libopencv-dev
need_pkg clang
need_pkg libclang-dev
# Embree 3 (libembree3 and its headers) for vinebench-sim's `embree` feature, on by default:
# sim/embree links it for `raycaster = "embree"`.
need_pkg libembree-dev
# libpython3.11 to link, for pyo3 in plugins/gtsam-backend (the "gtsam" backend's bridge),
# and Debian's venv module for its GTSAM environment below.
need_pkg python3-dev
need_pkg python3-venv
# Debian's Chromium for the report's browser test (tests/browser), run headless.
need_pkg chromium
# The OpenGL/X11 runtime the real ORB-SLAM3's wheel (pyorbslam3, the `orbslam3` adapter of
# the Python bridge) links, though it opens no window.
for pkg in libgl1 libegl1 libopengl0 libsm6 libice6 libx11-6 libxext6; do need_pkg "$pkg"; done
if ((${#apt_missing[@]})); then
  echo "setup: installing ${apt_missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt_get update -qq
  apt_get install -y -qq --no-install-recommends "${apt_missing[@]}"
fi

# Python tools of the tests in their own virtual environment (Debian's python forbids
# global pip installs): evo, the reference trajectory evaluator (tests/evo), mcap with
# mcap-ros2-support, the independent reader of `vinebench record`'s files (tests/mcap), and
# websocket-client, the DevTools client of the report's browser check (tests/browser).
vinebench_venv="${VINEBENCH_VENV:-$PWD/target/evo-venv}"
if [ ! -x "$vinebench_venv/bin/python" ]; then
  if ! python3 -m venv "$vinebench_venv" >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    apt_get update -qq && apt_get install -y -qq --no-install-recommends python3-venv
    python3 -m venv "$vinebench_venv"
  fi
fi
# Installs a pinned requirements file into a venv (default: the one above) unless every pin
# is already installed.
ensure_requirements() {
  local venv="${2:-$vinebench_venv}" installed pin
  installed=$("$venv/bin/python" -m pip freeze 2>/dev/null || true)
  for pin in $(grep -v '^#' "$1"); do
    if ! grep -qixF "$pin" <<<"$installed"; then
      echo "setup: installing $1 into $venv" >&2
      "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$1"
      return
    fi
  done
}
# The environments are independent: two at a time (pip is mostly one busy core), the
# tests' tools beside the others; a failure in either fails the setup.
(
ensure_requirements tests/evo/requirements.txt
ensure_requirements tests/mcap/requirements.txt
ensure_requirements tests/browser/requirements.txt
) &
tools_pid=$!
(
# GTSAM 4.3's wheel for the "gtsam" backend, in a venv of Debian's own interpreter: the
# bridge library embeds /usr/lib's libpython3.11, so the packages must be built for it
# (plugins/gtsam-backend finds this venv, or VINEBENCH_GTSAM_VENV).
gtsam_venv="${VINEBENCH_GTSAM_VENV:-$PWD/target/gtsam-venv}"
if [ ! -x "$gtsam_venv/bin/python" ]; then
  /usr/bin/python3 -m venv "$gtsam_venv"
fi
ensure_requirements tests/gtsam/requirements.txt "$gtsam_venv"
# The Python bridge's environments (plugins/python-bridge), each a venv of /usr/bin/python3
# for the libpython3.11 the bridge links: numpy alone for the bridge's own tests and
# benchmark, and one per real system it hosts (plugins/python-bridge/adapters/*.txt).
python_venv() {
  local venv="$PWD/target/$1"
  [ -x "$venv/bin/python" ] || /usr/bin/python3 -m venv "$venv"
  ensure_requirements "$2" "$venv"
}
python_venv python-bridge-venv tests/python-plugin/requirements.txt
python_venv kiss-icp-venv plugins/python-bridge/adapters/kiss_icp.txt
python_venv orbslam3-venv plugins/python-bridge/adapters/orbslam3.txt
)
wait "$tools_pid"
export PATH="$vinebench_venv/bin:$PATH"
