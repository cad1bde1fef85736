#!/usr/bin/env bash
# The whole test suite: formatting, lints, unit and end-to-end tests (release mode, so the
# simulator-driven tests run at full speed). Installs what it needs when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo fmt --all -- --check
# Everything below builds in the `suite` profile (Cargo.toml): release optimisation, so the
# simulator-driven tests run at full speed, without the cross-crate LTO and debug info that
# make each of the suite's test binaries and plugins slow to link. Clippy runs in the same
# profile so that the build scripts, proc macros and generated OpenCV bindings it compiles
# serve the test build too. The lints are the same: no code depends on debug_assertions.
cargo clippy --workspace --all-targets --profile suite -- -D warnings
# A single-node Slurm on localhost for the Slurm sweep test, which then must not skip.
bash scripts/slurm-local.sh
export VINEBENCH_REQUIRE_SLURM=1
# scripts/setup.sh installed Chromium for the report's browser check, which then must not skip.
export VINEBENCH_REQUIRE_BROWSER=1
cargo test --workspace --profile suite
