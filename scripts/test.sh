#!/usr/bin/env bash
# The whole test suite: formatting, lints, unit and end-to-end tests (release mode, so the
# simulator-driven tests run at full speed). Installs what it needs when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo fmt --all -- --check
# Lints in the release profile, whose build scripts, proc macros and generated OpenCV
# bindings the release test build below reuses: on a fresh clone here, clippy 2 m 45 s and
# the test build 14 m 15 s, against 6 m 50 s + 15 m 52 s with clippy's dev profile (whose
# build scripts and proc macros compile at opt-level 3). The lints are the same: no code
# depends on debug_assertions.
cargo clippy --workspace --all-targets --release -- -D warnings
# A single-node Slurm on localhost for the Slurm sweep test, which then must not skip.
bash scripts/slurm-local.sh
export VINEBENCH_REQUIRE_SLURM=1
# scripts/setup.sh installed Chromium for the report's browser check, which then must not skip.
export VINEBENCH_REQUIRE_BROWSER=1
cargo test --workspace --release
