#!/bin/bash
# bench/viewer_cpu.sh SCENE OUT [rest|drag]: CPU seconds of `umbra view SCENE` (900 x 600 under
# Xvfb with lavapipe) per thread, and of the whole machine, over 5 s after its first full image:
# with the view at rest (default) or during a drag (3 pixels right, 1 down, every 50 ms, one
# xdotool process). Threads are named by /proc's comm: the window's and the renderer's lavapipe
# threads are `llvmpipe-N` (the window's device is made first), lavapipe's compute threads take
# the name of the thread that made the renderer's device (`umbra render`). docs/benchmarks.md
# ("Interactive viewer") quotes it. From the repository root after `cargo build --release`;
# UMBRA_BIN=PATH runs another build.
set -e
SCENE=$1; OUT=$2; MODE=${3:-rest}
U=${UMBRA_BIN:-$(pwd)/target/release/umbra}
mkdir -p "$OUT"; rm -f "$OUT/log.csv"
D=:$((90 + RANDOM % 100))
Xvfb $D -screen 0 1280x800x24 >/dev/null 2>&1 & XPID=$!
trap 'kill $VPID $XPID 2>/dev/null || true' EXIT
sleep 1
DISPLAY=$D XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp} WINIT_X11_SCALE_FACTOR=1 \
  "$U" view "$SCENE" --width 900 --height 600 --frame-log "$OUT/log.csv" 2>"$OUT/stderr.txt" & VPID=$!
for _ in $(seq 600); do grep -q ',image,full,' "$OUT/log.csv" 2>/dev/null && break; sleep 0.5; done
sleep 2
snap() {
  echo "machine $(awk '/^cpu /{print $2+$3+$4}' /proc/stat)"
  echo "Xvfb $(awk '{print $14+$15}' /proc/$XPID/stat)"
  for t in /proc/$VPID/task/*; do
    echo "$(tr ' ' _ < $t/comm)-$(basename $t) $(awk '{print $14+$15}' $t/stat)"
  done
}
snap > "$OUT/a.txt"
if [ "$MODE" = drag ]; then
  export DISPLAY=$D
  xdotool mousemove 600 300 mousedown 1
  xdotool $(for _ in $(seq 100); do printf 'mousemove_relative -- 3 1 sleep 0.05 '; done)
  xdotool mouseup 1
else
  sleep 5
fi
snap > "$OUT/b.txt"
join <(sort "$OUT/a.txt") <(sort "$OUT/b.txt") |
  awk '{d = ($3 - $2) / 100; if (d > 0) printf "%s %.2f s\n", $1, d}' | sort -k2 -n -r
