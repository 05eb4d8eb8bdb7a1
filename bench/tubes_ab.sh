#!/bin/bash
# tubes_ab.sh A B ROUNDS FILE: alternates two umbra binaries A and B (ROUNDS pairs) on
# `umbra tubes FILE -o OUT.ply --radius 0.2 --sides 8 --tolerance 0.02 --stats-json S` and
# prints each binary's `seconds.compute` / `seconds.total` per run, sorted. The PLY goes to
# /dev/shm (memory) when there is one, so that the disk's write-back does not spill into the
# next run; alternating puts this shared machine's drift on both builds alike.
# From the repository root; copy the "before" binary aside first (cp target/release/umbra A).
set -e
A=$1; B=$2; N=${3:-3}; F=${4:?FILE}
D=/dev/shm; [ -d $D ] && [ -w $D ] || D=${TMPDIR:-/tmp}
OUT=$(mktemp -d "$D/tubes_ab.XXXXXX")
trap 'rm -rf "$OUT"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
for i in $(seq "$N"); do
  for b in A B; do
    bin=$A; [ $b = B ] && bin=$B
    rm -f "$OUT/t.ply"
    "$bin" tubes "$F" -o "$OUT/t.ply" --radius 0.2 --sides 8 --tolerance 0.02 \
      --stats-json "$OUT/s.json" > /dev/null 2>&1
    python3 -c "import json,sys; s=json.load(open(sys.argv[1]))['seconds']; \
print(sys.argv[2], '%.4f/%.4f' % (s['compute'], s['total']))" "$OUT/s.json" $b
  done
done | sort | awk '{a[$1]=a[$1]" "$2} END {for (k in a) print k":"a[k]}' | sort
