#!/bin/bash
# cpu_ab.sh A B W METHOD [ROUNDS] [SCENE] [SLICE_DISTANCE]: alternates two umbra binaries A and B
# (ROUNDS pairs, default 3) on SCENE (default datasets/scenes/mni_ea.toml) at W x W pixels with
# render.method = METHOD and render.slice_distance (default 0.5), 9 frames each, and prints per
# run the median frame (ms) and the passes' times from --timings-json (`light` and `raycast` on
# the CPU renderer), then per binary the medians of those over the rounds. Alternating puts
# this shared machine's drift on both builds alike.
# From the repository root; copy the "before" binary aside first (cp target/release/umbra A).
set -e
A=$1; B=$2; W=$3; M=$4; N=${5:-3}; SCENE=${6:-datasets/scenes/mni_ea.toml}; D=${7:-0.5}
OUT=$(mktemp -d)
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
for i in $(seq "$N"); do
  for b in A B; do
    bin=$A; [ $b = B ] && bin=$B
    "$bin" render "$SCENE" -o "$OUT/$b.png" --set render.method="$M" --set render.width="$W" \
      --set render.height="$W" --set render.slice_distance="$D" --frames 9 \
      --timings-json "$OUT/$b$i.json" > /dev/null 2> "$OUT/err" || {
      echo "cpu_ab.sh: $bin render $SCENE failed:" >&2; cat "$OUT/err" >&2; exit 1; }
    python3 -c "import json,sys; t=json.load(open(sys.argv[1])); f=sorted(t['frames_ms']); \
print(sys.argv[2], 'median %.1f ms' % f[len(f)//2], {k: round(v, 1) for k, v in t['passes'].items()})" \
      "$OUT/$b$i.json" $b
  done
done
# Over the rounds: the median of the runs' median frames and of each pass's time.
python3 - "$OUT" "$N" <<'PY'
import json, statistics as st, sys
out, n = sys.argv[1], int(sys.argv[2])
for b in "AB":
    runs = [json.load(open(f"{out}/{b}{i}.json")) for i in range(1, n + 1)]
    frame = st.median(st.median(r["frames_ms"]) for r in runs)
    passes = {k: round(st.median(r["passes"][k] for r in runs), 2) for k in runs[0]["passes"]}
    print(f"{b} over {n} runs: median frame {frame:.2f} ms, passes {passes}")
PY
cmp -s "$OUT/A.png" "$OUT/B.png" && echo "images identical" || echo "images differ"
rm -rf "$OUT"
