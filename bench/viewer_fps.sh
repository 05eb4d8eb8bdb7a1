#!/bin/bash
# bench/viewer_fps.sh SCENE OUT [DRAG_SECONDS]: the viewer's frame rate while orbiting, under
# Xvfb with lavapipe (docs/benchmarks.md, "Interactive viewer"). Starts `umbra view SCENE` in a
# 900 x 600 window with `--frame-log OUT/log.csv`, waits for its first full image, drags across
# the view with xdotool for DRAG_SECONDS (default 6: 3 pixels right, 1 down, every 50 ms), lets
# go, waits for the full image of the new view, and prints from the log: drafts shown a second
# and window frames a second while the drafts came, and the time from the last draft to the
# full image. From the repository root after `cargo build --release`; needs Xvfb and xdotool
# (scripts/setup.sh). UMBRA_BIN=PATH runs another build of umbra (A/B runs).
set -e
SCENE=$1; OUT=$2; DRAG=${3:-6}
U=${UMBRA_BIN:-$(pwd)/target/release/umbra}
mkdir -p "$OUT"
rm -f "$OUT/log.csv" "$OUT/stderr.txt"
D=:$((90 + RANDOM % 100))
Xvfb $D -screen 0 1280x800x24 >/dev/null 2>&1 & XPID=$!
trap 'kill $VPID $XPID 2>/dev/null || true' EXIT
sleep 1
DISPLAY=$D XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp} WINIT_X11_SCALE_FACTOR=1 \
  "$U" view "$SCENE" --width 900 --height 600 --frame-log "$OUT/log.csv" 2>"$OUT/stderr.txt" & VPID=$!
fulls() { local n; n=$(grep -c ',image,full,' "$OUT/log.csv" 2>/dev/null); echo "${n:-0}"; }
wait_full() { # wait_full N: until the log has more than N full images (at most 300 s)
  for _ in $(seq 600); do [ "$(fulls)" -gt "$1" ] && return 0; sleep 0.5; done
  echo "no full image in 300 s" >&2; return 1
}
wait_full 0
n=$(fulls)
export DISPLAY=$D
xdotool mousemove 600 300 mousedown 1
# One xdotool process for the whole drag (a process a step took about a third of the CPU).
xdotool $(for _ in $(seq $((DRAG * 20))); do printf 'mousemove_relative -- 3 1 sleep 0.05 '; done)
xdotool mouseup 1
wait_full "$n"
kill $VPID; wait $VPID 2>/dev/null || true
python3 - "$OUT/log.csv" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
# The drag's drafts: those after the first full image (the drag starts once it is shown).
t0 = min(float(r['seconds']) for r in rows if r['level'] == 'full')
drafts = [float(r['seconds']) for r in rows if r['level'] == 'draft' and float(r['seconds']) > t0]
if len(drafts) < 2:
    sys.exit('fewer than two drafts: did the drag reach the view?')
a, b = drafts[0], drafts[-1]
frames = [float(r['seconds']) for r in rows if r['event'] == 'frame' and a <= float(r['seconds']) <= b]
full = [float(r['seconds']) for r in rows if r['level'] == 'full' and float(r['seconds']) > b]
ms = sorted(float(r['total_ms']) for r in rows if r['level'] == 'draft' and float(r['seconds']) > t0)
print(f'drafts shown: {len(drafts)} in {b - a:.2f} s = {(len(drafts) - 1) / (b - a):.1f} a second '
      f'(render ms median {ms[len(ms) // 2]:.0f}, min {ms[0]:.0f}, max {ms[-1]:.0f})')
print(f'window frames while dragging: {len(frames)} = {len(frames) / (b - a):.1f} a second')
if full:
    print(f'full image {full[0] - b:.2f} s after the last draft')
PY
