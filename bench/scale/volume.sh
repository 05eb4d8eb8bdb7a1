#!/bin/bash
# volume.sh OUT N [METHOD] [DEVICE] [WIDTH]: writes the 3-D Shepp-Logan phantom in uint16 on N^3
# samples (umbra synth phantom; 2 N^3 bytes stored) and a tiny one (8^3), renders each once
# under an 8 GB address-space limit (render.method METHOD, default ea; render.device DEVICE,
# default auto; WIDTH x WIDTH pixels, default 512) and prints /usr/bin/time's peak resident
# memory of both, and the large one's over the tiny one's as a multiple of the stored size
# (`volume.downsample = true`: the GPU passes halve what passes their bindings).
# From the repository root after `cargo build --release`; UMBRA_BIN=PATH runs another build
# (the phantom is written by this checkout's build).
set -e
OUT=$1; N=$2; METHOD=${3:-ea}; DEVICE=${4:-auto}; W=${5:-512}
U=${UMBRA_BIN:-$(pwd)/target/release/umbra}
SYNTH=$(pwd)/target/release/umbra
mkdir -p "$OUT"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
for n in 8 "$N"; do
  [ -f "$OUT/phantom$n.nrrd" ] || "$SYNTH" synth phantom --n "$n" -o "$OUT/phantom$n.nrrd" >/dev/null
  cat > "$OUT/phantom$n.toml" <<TOML
background = [1.0, 1.0, 1.0]
[camera]
azimuth = 30.0
elevation = 20.0
[volume]
path = "phantom$n.nrrd"
downsample = true
[volume.transfer]
points = [
  { value = 190.0, color = "#000000", extinction = 0.0 },
  { value = 215.0, color = "#d9a066", extinction = 0.4 },
  { value = 290.0, color = "#ff3030", extinction = 80.0 },
  { value = 600.0, color = "#ffffff", extinction = 1.0 },
  { value = 1010.0, color = "#ffffff", extinction = 1.0 },
]
[render]
method = "$METHOD"
device = "$DEVICE"
width = $W
height = $W
TOML
  /usr/bin/time -f "%e s %M KB" -o "$OUT/time$n.txt" prlimit --as=8000000000 \
    "$U" render "$OUT/phantom$n.toml" -o "$OUT/phantom$n.png" > "$OUT/render$n.log" 2>&1
  echo "$n^3: $(grep -o '[0-9.]* ms per frame' "$OUT/render$n.log") $(cat "$OUT/time$n.txt")"
done
small=$(awk '{print $3}' "$OUT/time8.txt"); big=$(awk '{print $3}' "$OUT/time$N.txt")
awk -v s="$small" -v b="$big" -v n="$N" 'BEGIN { stored = 2 * n * n * n / 1024;
  printf "peak over the 8^3 scene: %.0f MB = %.2f x the stored %.0f MB\n", (b - s) / 1024, (b - s) / stored, stored / 1024 }'
