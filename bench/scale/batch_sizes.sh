#!/bin/bash
# batch_sizes.sh OUT: builds umbra with G-buffer batches of 2^16..2^20 triangles and none (2^62;
# engine/src/gpu.rs CPU_BATCH_TRIANGLES, restored afterwards), then renders OUT/b4/bundles.toml
# (10^6 points, from lines.sh) three times and OUT/b5/bundles.toml (10^7) twice with each,
# alternating, printing the frame time and the peak. From the repository root.
set -e
OUT=$1
F=engine/src/gpu.rs
orig=$(grep -o 'CPU_BATCH_TRIANGLES: u64 = 1 << [0-9]*' $F | grep -o '[0-9]*$')
for v in 16 17 18 19 20 62; do
  sed -i "s/CPU_BATCH_TRIANGLES: u64 = 1 << [0-9]*;/CPU_BATCH_TRIANGLES: u64 = 1 << $v;/" $F
  cargo build --release -q
  cp target/release/umbra "$OUT/umbra-b$v"
done
sed -i "s/CPU_BATCH_TRIANGLES: u64 = 1 << [0-9]*;/CPU_BATCH_TRIANGLES: u64 = 1 << $orig;/" $F
cargo build --release -q
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
for scene in b4 b4 b4 b5 b5; do
  for v in 16 17 18 19 20 62; do
    /usr/bin/time -f "$scene 2^$v %e s %M KB" "$OUT/umbra-b$v" render "$OUT/$scene/bundles.toml" \
      -o "$OUT/x.png" 2>&1 | grep -E "KB|per frame" | sed 's/.*: //' | tr '\n' ' '; echo
  done
done
