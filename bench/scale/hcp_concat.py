# Usage: python3 bench/scale/hcp_concat.py [OUT.tck] [HCP1065_DIR] (from the repository root;
# bench/scale/hcp10x.toml reads bench/scale/hcp10x.tck).
# Concatenates the ten HCP1065 bundles (shifted into MNI space as demo_lines.toml does) ten
# times, each copy shifted by a different sub-millimetre offset, into one .tck.
import glob, sys, numpy as np, nibabel as nib
from nibabel.streamlines import Tractogram
lines = []
for f in sorted(glob.glob((sys.argv[2] if len(sys.argv) > 2 else '../shared/data/tracts/hcp1065') + '/*.trk.gz')):
    t = nib.streamlines.load(f)
    lines.extend(s + np.array([78, 76, -50], np.float32) for s in t.streamlines)
n0, p0 = len(lines), sum(len(s) for s in lines)
rng = np.random.default_rng(1)
out = []
for k in range(10):
    d = (rng.random(3).astype(np.float32) - 0.5) * 1.0
    out.extend(s + d for s in lines)
nib.streamlines.save(Tractogram(out, affine_to_rasmm=np.eye(4)), sys.argv[1] if len(sys.argv) > 1 else 'hcp10x.tck')
print(n0, p0, len(out), sum(len(s) for s in out))
