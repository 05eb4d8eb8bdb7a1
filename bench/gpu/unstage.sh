#!/bin/bash
# bench/gpu/unstage.sh: on the GPU machine, from the repository root, unpacks .gpu/ (bench/gpu/stage.sh)
# into target/release/umbra and ../shared/data (the .trk files gzipped again, as the scenes name them).
set -e
mkdir -p target/release ../shared
xz -dc .gpu/umbra.xz > target/release/umbra
chmod +x target/release/umbra
xz -dc .gpu/shared.tar.xz | tar -C ../shared -xf -
for f in ../shared/data/tracts/hcp1065/*.trk; do gzip -1 "$f" & done
wait
