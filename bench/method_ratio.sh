#!/bin/bash
# method_ratio.sh SCENE [SIZES] [ROUNDS] [BIN] [SLICE_DISTANCE]: issue 14 item 3's ratio, measured
# in one run. For each size of SIZES (comma-separated, default 128,256,512,1024) it alternates
# `render.method = "ea"` and `"combined"` of one umbra binary BIN (default target/release/umbra)
# ROUNDS times (default 3) on SCENE at W x W pixels and render.slice_distance (default 0.5), 9
# frames a run, and prints per size the median over the rounds of each run's median frame (ms)
# and combined / ea. Alternating puts this shared machine's drift on both methods alike.
# From the repository root.
set -e
SCENE=$1; SIZES=${2:-128,256,512,1024}; N=${3:-3}; BIN=${4:-target/release/umbra}; D=${5:-0.5}
[ -n "$SCENE" ] || { echo "usage: bash bench/method_ratio.sh SCENE [SIZES] [ROUNDS] [BIN] [D]" >&2; exit 2; }
[ -f "$SCENE" ] || { echo "method_ratio.sh: no scene file $SCENE" >&2; exit 2; }
[[ "$N" =~ ^[1-9][0-9]*$ ]] || { echo "method_ratio.sh: ROUNDS must be a positive integer, got '$N'" >&2; exit 2; }
[[ "$SIZES" =~ ^[1-9][0-9]*(,[1-9][0-9]*)*$ ]] || { echo "method_ratio.sh: SIZES must be comma-separated pixel counts, got '$SIZES'" >&2; exit 2; }
[ -x "$BIN" ] || { echo "method_ratio.sh: no umbra binary at $BIN (cargo build --release)" >&2; exit 2; }
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
for w in ${SIZES//,/ }; do
  for i in $(seq "$N"); do
    for m in ea combined; do
      "$BIN" render "$SCENE" -o "$OUT/$m.png" --set render.method="$m" --set render.width="$w" \
        --set render.height="$w" --set render.slice_distance="$D" --frames 9 \
        --timings-json "$OUT/$w-$m-$i.json" > /dev/null 2> "$OUT/err" || {
        echo "method_ratio.sh: $BIN render $SCENE failed:" >&2; cat "$OUT/err" >&2; exit 1; }
    done
  done
done
python3 - "$OUT" "$SIZES" "$N" <<'PY'
import json, statistics as st, sys
out, sizes, n = sys.argv[1], sys.argv[2].split(","), int(sys.argv[3])
print("size  ea_ms  combined_ms  combined/ea")
for w in sizes:
    med = {}
    for m in ("ea", "combined"):
        runs = [sorted(json.load(open(f"{out}/{w}-{m}-{i}.json"))["frames_ms"]) for i in range(1, n + 1)]
        med[m] = st.median(r[len(r) // 2] for r in runs)
    print(f"{w}^2  {med['ea']:.1f}  {med['combined']:.1f}  {med['combined'] / med['ea']:.2f}")
PY
