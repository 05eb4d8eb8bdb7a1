#!/usr/bin/env bash
# The turntable benchmark of docs/benchmarks.md ("Frames in one process"): the demo scene at
# 128 x 128 as one 8-frame `--orbit` process (A) and as eight separate `umbra render` processes
# at the same cameras (B), each timed as a whole; UMBRA=path/to/umbra picks the binary
# (default target/release/umbra). Prints the wall seconds of A and B and their ratio.
set -euo pipefail
cd "$(dirname "$0")/.."
UMBRA=${UMBRA:-target/release/umbra}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
t0=$(date +%s.%N)
"$UMBRA" render datasets/scenes/demo.toml --orbit 8 --width 128 --height 128 -o "$out/orbit/f_#.png" >/dev/null 2>&1
t1=$(date +%s.%N)
for k in 0 1 2 3 4 5 6 7; do
  "$UMBRA" render datasets/scenes/demo.toml --width 128 --height 128 \
    --set camera.azimuth=$((115 + 45 * k)) -o "$out/eight/f_$k.png" >/dev/null 2>&1
done
t2=$(date +%s.%N)
python3 - "$t0" "$t1" "$t2" <<'PY'
import sys
t0, t1, t2 = map(float, sys.argv[1:])
a, b = t1 - t0, t2 - t1
print(f"A one process, 8 frames: {a:.2f} s; B 8 processes: {b:.2f} s; A/B {a / b:.3f}")
PY
