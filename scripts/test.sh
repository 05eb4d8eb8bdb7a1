#!/usr/bin/env bash
# The whole test suite, as CI runs it: set-up, formatting, lints, then every test in release mode.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
rustup component add rustfmt clippy >/dev/null 2>&1 || true
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release -- -D warnings
cargo test --workspace --release
