#!/usr/bin/env bash
# The fast-sweeping benchmark of docs/benchmarks.md, with its peers in the same run:
# umbra's distance + eight octants (compute seconds, median of 5), the distance alone, a plain
# copy of the same bytes, the `edt` package's exact SDF (median of 3), scikit-fmm orders 1 and 2
# (one run each; slow), all on the three-solids scene at N^3 (default 256), then umbra at the
# paper's Table 2 grid sizes. Needs: pip install edt scikit-fmm numpy.
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-256}
cargo build --release -q -p volume --example sweep_bench
echo "# machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo "# date: $(date -u +%Y-%m-%dT%H:%MZ)"
target/release/examples/sweep_bench "$N" 5
python3 bench/peers_sdf.py --n "$N" --methods edt --repeat 3
target/release/examples/sweep_bench "$N" 5
python3 bench/peers_sdf.py --n "$N" --methods fmm1,fmm2 --repeat 1
target/release/examples/sweep_bench "$N" 3 table2
