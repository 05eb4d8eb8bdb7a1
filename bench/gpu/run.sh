#!/bin/bash
# bench/gpu/run.sh OUT [DEADLINE_S]: the GPU measurements of docs/benchmarks.md ("On a data-centre
# GPU"), in one script for a lent GPU machine with no network. Run from the repository root with
#   UMBRA=path/to/umbra (default target/release/umbra) and the shared data at ../shared/data
#   (the ten HCP1065 bundles and cfd/office.binary.vtk; bench/gpu/stage.sh packs them).
# Everything measured goes to OUT/log.txt (each report's JSON, one per line, after a "== name"
# header) and OUT/results.tar (timings, CSVs, a few images). Steps run in order of priority and
# a step is skipped when fewer seconds than it needs are left before DEADLINE_S (default 480).
set -u
OUT=$1
DEADLINE=${2:-480}
U=$(realpath "${UMBRA:-target/release/umbra}")
SHARED=$(realpath ../shared)
W=/tmp/umbra_gpu
mkdir -p "$W" "$OUT"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
LOG=$OUT/log.txt
TAR=$OUT/results.tar
exec > >(tee -a "$LOG") 2>&1
. "$(dirname "$0")/../bundles_scene.sh"

say() { echo "== $(date -u +%T) t=${SECONDS}s $*"; }
# left N: true when at least N seconds are left before the deadline
left() { if (( SECONDS + $1 > DEADLINE )); then say "SKIP (needs $1 s, ${SECONDS}/${DEADLINE} used): $2"; return 1; fi; }
keep() { (cd "$W" && tar -rf "$TAR" "$@" 2>/dev/null) || true; }
# peak NAME TIMEOUT CMD...: runs CMD, prints its wall seconds, exit status and peak resident memory
peak() {
  local name=$1 t=$2; shift 2
  say "$name: $*"
  python3 - "$t" "$@" <<'PY'
import resource, subprocess, sys, time
t0 = time.time()
try:
    rc = subprocess.run(sys.argv[2:], timeout=float(sys.argv[1])).returncode
except subprocess.TimeoutExpired:
    rc = 'timeout'
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print(f'wall {time.time() - t0:.2f} s, rc {rc}, peak {r.ru_maxrss / 1024:.0f} MiB, cpu {r.ru_utime + r.ru_stime:.1f} s')
PY
}
# frame NAME SCENE ARGS...: umbra render with --frames 5 --timings-json, the JSON on one line
frame() {
  local name=$1 scene=$2; shift 2
  say "$name"
  timeout 120 "$U" render "$scene" -o "$W/$name.png" --frames 5 --timings-json "$W/$name.json" "$@" > "$W/$name.log" 2>&1
  local rc=$?
  if [ $rc -ne 0 ]; then echo "rc $rc"; tail -5 "$W/$name.log"; return; fi
  python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print(json.dumps({k: d[k] for k in ('adapter','width','height','method','total_ms','frames_ms','passes','pass_clock','triangles','slices') if k in d}))" "$W/$name.json"
  keep "$name.json"
}

say "machine"
nvidia-smi -L 2>&1 | head -3
nproc; free -g | head -2
"$U" info --gpu 2>&1
"$U" --version

# 1. Issue 14: the MNI T1 cost curves (emission-absorption and combined) on the GPU
if left 150 "curves mni"; then
  say "curves mni"
  timeout 150 "$U" bench curves datasets/scenes/mni_ea.toml -o "$W/curves_mni" --sizes 128,256,512,1024,2048 \
    --slices 163,325,650,1300,2600 --slice-size 512 --methods ea,combined --devices gpu --frames 3 \
    --set render.slice_distance=0.5 --set render.fxaa=false 2>&1 | tail -3
  cat "$W/curves_mni/curves.csv"; keep curves_mni/curves.csv
fi

# 2. LineAO (Eichelbaum et al. 2013, Table 1: GTX 480, 1280 x 1024): illuminated against LineAO
if left 100 "lineao table"; then
  for n in 1000 3600; do
    bundles_scene "$U" "$W" "syn_1000x$n" 1000 $n 2.0 1280 1024
  done
  for m in illuminated lineao; do
    frame "eich_hcp10_$m" bench/scenes/hcp1065_lineao.toml --method $m --width 1280 --height 1024
    frame "eich_cstl_$m" bench/scenes/hcp1065_cst_l_lineao.toml --method $m
    frame "eich_syn1000x1000_$m" "$W/syn_1000x1000.toml" --method $m
    frame "eich_syn1000x3600_$m" "$W/syn_1000x3600.toml" --method $m
  done
  keep eich_hcp10_lineao.png
fi

# 3. Anisotropic LineAO (Koehler et al., Table 1: GTX 980, 853 x 917 at 2x SSAA = 1706 x 1834)
if left 40 "koehler"; then
  for a in false true; do
    frame "koehler_cstl_aniso_$a" bench/scenes/hcp1065_cst_l_lineao.toml --width 1706 --height 1834 \
      --set render.lineao.anisotropic=$a
  done
fi

# 4. Depth-dependent halos (Everts et al. 2009, Table 1: 8800 GTX, 812 x 600): plain, halos, anaglyph
if left 150 "everts table"; then
  say "everts data"
  UMBRA_BIN="$U" bench/gallery/make_data.sh > /dev/null
  for c in knot_173k hcp_280k office_280k points_427k office_short_1600k office_long_2600k points_4400k hcp_7100k points_143k; do
    s=bench/scenes/gallery_t1_$c.toml
    if ! left 20 "everts $c"; then break; fi
    kind=$(grep -q '^\[\[points\]\]' $s && echo points || echo lines)
    n=$(grep -c "^\[\[$kind\]\]" $s)
    plain=(--set render.method=illuminated)
    for ((k = 0; k < n; k++)); do plain+=(--set "$kind.$k.halo.mode=none"); done
    frame "everts_${c}_plain" $s "${plain[@]}"
    frame "everts_${c}_halos" $s
    frame "everts_${c}_anaglyph" $s --set render.stereo=anaglyph
  done
  keep everts_hcp_7100k_halos.png
fi

# 5. Issue 18 at GPU scale: 10^8 points (10^6 streamlines x 100) as LineAO lines, 1024 x 768
if left 120 "lines 1e8"; then
  bundles_scene "$U" "$W" b1e8 1000000 100 1.0 1024 768
  peak "lines_1e8" 110 "$U" render "$W/b1e8.toml" -o "$W/b1e8.png" --frames 3 --timings-json "$W/b1e8.json"
  cat "$W/b1e8.json" | tr -d '\n '; echo
  keep b1e8.json
  rm -f "$W/b1e8.tck"
fi

# 6. Issue 18: volumes of 512^3 and 1024^3 f32 (0.5 and 4 GiB) by emission-absorption on the GPU
for n in 512 1024; do
  if ! left $((n / 8 + 30)) "solids $n"; then break; fi
  "$U" synth three-solids --n $n -o "$W/solids.nrrd" > /dev/null
  cp bench/scale/solids.toml "$W/solids.toml"
  peak "solids_$n" $((n / 8 + 20)) "$U" render "$W/solids.toml" -o "$W/solids_$n.png" --frames 3 --timings-json "$W/solids_$n.json"
  cat "$W/solids_$n.json" | tr -d '\n '; echo
  keep "solids_$n.json"
  rm -f "$W/solids.nrrd"
done
say "done"
