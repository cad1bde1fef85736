#!/usr/bin/env bash
# The whole test suite: formatting, lints, unit and end-to-end tests (release mode, so the
# simulator-driven tests run at full speed). Installs what it needs when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
cargo test --workspace --release
