#!/usr/bin/env bash
# The whole test suite: formatting, lints, unit and end-to-end tests (release mode, so the
# simulator-driven tests run at full speed). Installs what it needs when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo fmt --all -- --check
# The study scripts' resume logic (what a study spread over sessions runs next).
python3 -m unittest discover -s scripts -p 'test_*.py'
# Everything below builds in the `suite` profile (Cargo.toml): release optimisation, so the
# simulator-driven tests run at full speed, without the cross-crate LTO and debug info that
# make each of the suite's test binaries and plugins slow to link.
#
# Lints and build in one pass: `cargo clippy --workspace --all-targets -- -D warnings` is
# `cargo check` with clippy-driver as the workspace's compiler; here clippy-driver compiles
# every workspace target of the test build itself, so its lints (the same passes, the same
# targets: --all-targets) fail the build, and the dependencies are compiled once instead of
# checked for clippy and then built for the tests (5.7 min of a 43-min CI run on 2 cores).
# CLIPPY_ARGS is how cargo-clippy hands `-- -D warnings` to clippy-driver.
clippy_driver="$(rustup which clippy-driver 2>/dev/null || command -v clippy-driver)"
export RUSTC_WORKSPACE_WRAPPER="$clippy_driver"
export CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
cargo test --workspace --all-targets --profile suite --no-run
# A single-node Slurm on localhost for the Slurm sweep test, which then must not skip.
bash scripts/slurm-local.sh
export VINEBENCH_REQUIRE_SLURM=1
# scripts/setup.sh installed Chromium for the report's browser check, which then must not skip.
export VINEBENCH_REQUIRE_BROWSER=1
cargo test --workspace --profile suite
