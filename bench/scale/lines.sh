#!/bin/bash
# lines.sh OUT N POINTS: writes N synthetic streamlines of POINTS points (umbra synth bundles)
# and renders them as 1-pixel LineAO lines at 1024 x 768 under an 8 GB address-space limit,
# with /usr/bin/time's peak and memwatch.sh's samples: OUT/render.log, OUT/render.log.out.
# From the repository root after `cargo build --release`; UMBRA_BIN=PATH runs another build.
set -e
OUT=$1; N=$2; P=$3
U=${UMBRA_BIN:-$(pwd)/target/release/umbra}
HERE=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT"
. "$HERE/../bundles_scene.sh"
bundles_scene "$U" "$OUT" bundles "$N" "$P" 1.0 1024 768
XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp} "$HERE/memwatch.sh" "$OUT/render.log" \
  /usr/bin/time -f "%e s %M KB" prlimit --as=8000000000 "$U" render "$OUT/bundles.toml" -o "$OUT/bundles.png"
tail -3 "$OUT/render.log.out"
