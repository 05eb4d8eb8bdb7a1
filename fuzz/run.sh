#!/usr/bin/env bash
# Fuzzes every target (or those named) for RUNS executions each with libFuzzer, under the
# allocation limits docs/robustness.md states, and prints one line per target:
#   TARGET executions=N crashes=K corpus=FILES
# Usage: fuzz/run.sh [RUNS] [TARGET ...]   (RUNS default 1000000)
# Needs cargo-fuzz (cargo install cargo-fuzz) and a nightly toolchain, or RUSTC_BOOTSTRAP=1.
# New corpus entries go to fuzz/target/corpus/TARGET (not committed); crashes to
# fuzz/artifacts/TARGET; minimise one with `cargo fuzz tmin TARGET FILE` and keep it in
# fuzz/regressions/TARGET, where tests/tests/fuzz_corpora.rs replays it.
set -euo pipefail
cd "$(dirname "$0")"
runs=${1:-1000000}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=($(ls fuzz_targets | sed 's/\.rs$//'))
fi
toolchain=()
if rustup toolchain list | grep -q nightly; then toolchain=(+nightly); else export RUSTC_BOOTSTRAP=1; fi
cargo "${toolchain[@]}" fuzz build -O
for t in "${targets[@]}"; do
    work=target/corpus/$t
    mkdir -p "$work" "artifacts/$t"
    log=target/$t.log
    set +e
    cargo "${toolchain[@]}" fuzz run -O "$t" "$work" "corpus/$t" -- \
        -runs="$runs" -rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=20 \
        -dict="dict/$t.dict" -max_len=65536 -print_final_stats=1 \
        > "$log" 2>&1
    rc=$?
    set -e
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
    crashes=$(ls "artifacts/$t" | wc -l)
    echo "$t executions=${execs:-0} crashes=$crashes corpus=$(ls "$work" | wc -l) rc=$rc"
done
