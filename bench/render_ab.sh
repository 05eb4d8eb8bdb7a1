#!/bin/bash
# render_ab.sh A B ROUNDS SCENE [ARGS...]: alternates two umbra binaries A and B (ROUNDS pairs) on
# `umbra render SCENE ARGS... --frames 5`, and prints per run the median frame (ms) and the
# passes' times (--timings-json; each pass re-run alone), then per binary the median frame over
# the rounds, and whether the two binaries' last images are the same bytes. Alternating puts
# this shared machine's drift on both builds alike. From the repository root; copy the "before"
# binary aside first (cp target/release/umbra A).
set -e
A=$1; B=$2; N=$3; SCENE=$4; shift 4
OUT=$(mktemp -d)
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
for i in $(seq "$N"); do
  for b in A B; do
    bin=$A; [ $b = B ] && bin=$B
    "$bin" render "$SCENE" -o "$OUT/$b.png" "$@" --frames 5 --timings-json "$OUT/$b$i.json" \
      > /dev/null 2> "$OUT/err" || {
      echo "render_ab.sh: $bin render $SCENE failed:" >&2; cat "$OUT/err" >&2; exit 1; }
    python3 -c "import json,sys; t=json.load(open(sys.argv[1])); \
print(sys.argv[2], '%.1f ms' % t['total_ms'], ', '.join('%s %.1f' % kv for kv in t['passes'].items()))" \
      "$OUT/$b$i.json" "$b$i"
  done
done
for b in A B; do
  python3 -c "import json,sys,statistics; \
print(sys.argv[1], 'median of the rounds: %.1f ms' % statistics.median(json.load(open(f))['total_ms'] for f in sys.argv[2:]))" \
    "$b" "$OUT"/$b[0-9]*.json
done
cmp -s "$OUT/A.png" "$OUT/B.png" && echo "images: identical" || echo "images: differ"
rm -rf "$OUT"
