#!/usr/bin/env bash
# The shard benchmark of docs/cluster.md: a turntable rendered by one `umbra render --orbit`
# process (A) and by N shards of it running at once on this machine (`--shard I/N`, N = 2
# and 4), each variant timed as a whole (wall seconds from the first start to the last exit),
# interleaved A, N=2, N=4 per repetition so that drift hits all alike. Prints each variant's
# median and its median ratio to A, pair by pair.
#   bench/shards.sh [REPS]          (default 5; UMBRA=path/to/umbra picks the binary)
# Cases: the MNI T1, `combined`, 512 x 512, 12 frames (the native CPU renderer on a machine
# without a GPU), and the demo scene (volume + 3 tube bundles, ~950k triangles), `combined`,
# 128 x 128, 4 frames (the GPU passes; lavapipe here).
set -euo pipefail
cd "$(dirname "$0")/.."
UMBRA=${UMBRA:-target/release/umbra}
REPS=${1:-5}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}

run_case() { # name frames scene args...
  local name=$1 frames=$2 scene=$3; shift 3
  local log="$out/$name.tsv"
  for rep in $(seq "$REPS"); do
    for n in 1 2 4; do
      rm -rf "$out/frames"
      local t0 t1
      t0=$(date +%s.%N)
      for i in $(seq 0 $((n - 1))); do
        "$UMBRA" render "$scene" "$@" --orbit "$frames" --shard "$i/$n" \
          -o "$out/frames/f_##.png" >/dev/null 2>&1 &
      done
      wait
      t1=$(date +%s.%N)
      [ "$(ls "$out/frames" | wc -l)" -eq "$frames" ] || { echo "$name: missing frames" >&2; exit 1; }
      echo -e "$rep\t$n\t$(python3 -c "print($t1 - $t0)")" >>"$log"
    done
  done
  python3 - "$name" "$log" <<'PY'
import sys, statistics as st
name, log = sys.argv[1], sys.argv[2]
rows = [l.split("\t") for l in open(log).read().split("\n") if l]
t = {}
for rep, n, s in rows:
    t.setdefault(int(n), {})[int(rep)] = float(s)
for n in sorted(t):
    ratio = st.median(t[n][r] / t[1][r] for r in t[n])
    print(f"{name}: {n} shard(s) at once: median {st.median(t[n].values()):.2f} s wall, "
          f"{ratio:.3f}x one process (min {min(t[n].values()):.2f}, max {max(t[n].values()):.2f}, {len(t[n])} runs)")
PY
}

run_case mni-combined-512 12 datasets/scenes/mni_ea.toml \
  --set 'render.method="combined"' --width 512 --height 512
run_case demo-combined-128 4 datasets/scenes/demo.toml --width 128 --height 128
