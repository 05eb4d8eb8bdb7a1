#!/bin/bash
# bench/gpu/stage.sh: packs what bench/gpu/run.sh needs on a GPU machine with no network into .gpu/
# (git-ignored through .git/info/exclude): the release binary and the shared data it reads, xz'd to
# fit the device tool's 64 MiB; bench/gpu/unstage.sh unpacks them there. From the repository root
# after `cargo build --release`.
set -e
mkdir -p .gpu
xz -T0 -6 -c target/release/umbra > .gpu/umbra.xz
tmp=$(mktemp -d)
mkdir -p "$tmp/data/tracts/hcp1065" "$tmp/data/cfd"
for f in ../shared/data/tracts/hcp1065/*.trk.gz; do gzip -dc "$f" > "$tmp/data/tracts/hcp1065/$(basename "$f" .gz)"; done
cp ../shared/data/tracts/hcp1065/*.md "$tmp/data/tracts/hcp1065/"
cp ../shared/data/cfd/office.binary.vtk ../shared/data/cfd/*LICENSE* "$tmp/data/cfd/"
tar -C "$tmp" -cf - data | xz -T0 -6 > .gpu/shared.tar.xz
rm -rf "$tmp"
ls -la .gpu
