#!/bin/bash
# bench/gallery/make_data.sh: the derived data the gallery's scenes (bench/scenes/gallery_*.toml,
# docs/gallery.md) and the Everts et al. Table 1 timings (docs/benchmarks.md) read, written into
# bench/gallery/data/ (ignored by git): the HCP1065 subsets (every 3rd streamline, every 5th or
# 9th point), the trefoil-knot point cloud, and the office flow resampled and traced (the
# seeded 786 lines, and the short and long random-seeded sets). Needs ../shared/data beside the
# checkout, python3 with numpy (PYTHON, default python3), and the built umbra (UMBRA_BIN, default target/release/umbra).
# From the repository root; files already there are kept (delete one to make it again).
set -e
# UMBRA_BIN as given from where the script is run (the repository root), before the cd.
U=$(realpath "${UMBRA_BIN:-target/release/umbra}")
cd "$(dirname "$0")"
PY=${PYTHON:-python3}
mkdir -p data
B="AF_R CST_L CST_R FAT_R MCP OR_L SCP SLF1_R TR_S_R UF_L"
[ -s data/hcp10_k3s5.trk ] || "$PY" make_subsets.py data/hcp10_k3s5.trk 3 5 $B
[ -s data/hcp10_k3s9.trk ] || "$PY" make_subsets.py data/hcp10_k3s9.trk 3 9 $B
[ -s data/knot.csv ] || "$PY" make_knot.py data/knot.csv
[ -s data/office.nrrd ] || "$U" resample ../../../shared/data/cfd/office.binary.vtk --field vectors --size 128 -o data/office.nrrd
[ -s data/office_seeds.csv ] || "$PY" make_office_seeds.py data/office_seeds.csv 786
[ -s data/office.trk ] || "$U" trace data/office.nrrd -o data/office.trk --seeds data/office_seeds.csv --step 0.02 --max-length 4
[ -s data/office_short.trk ] || "$U" trace data/office.nrrd -o data/office_short.trk --seeds random:152000 --step 0.036 --max-length 0.17
[ -s data/office_long.trk ] || "$U" trace data/office.nrrd -o data/office_long.trk --seeds random:1428 --step 0.0088
ls -l data
