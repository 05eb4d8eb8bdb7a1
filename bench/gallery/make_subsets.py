"""Subsets of the HCP1065 bundles: every K-th streamline of each bundle, every S-th point of each
streamline (its last point kept), one TrackVis file with the bundles' own header (voxmm
coordinates copied unchanged, so the scenes' MNI transform (78, 76, -50) still applies).
usage: python3 make_subsets.py OUT.trk K S BUNDLE [BUNDLE ...]"""
import gzip, struct, sys
import numpy as np
import os
D = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', 'shared', 'data', 'tracts', 'hcp1065') + os.sep
def read(path):
    b = gzip.open(path).read()
    assert struct.unpack('<h', b[36:38])[0] == 0 and struct.unpack('<h', b[238:240])[0] == 0
    off, lines = 1000, []
    while off < len(b):
        m = struct.unpack_from('<i', b, off)[0]; off += 4
        lines.append(np.frombuffer(b, '<f4', 3 * m, off).reshape(m, 3)); off += 12 * m
    return b[:1000], lines
out, k, s = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
hdr, sel = None, []
for name in sys.argv[4:]:
    h, lines = read(D + name + '.trk.gz')
    if hdr is None: hdr = bytearray(h)
    assert h[:504] == bytes(hdr[:504]) and h[948:988] == bytes(hdr[948:988]), name + ': header differs'
    for l in lines[::k]:
        idx = list(range(0, len(l), s))
        if idx[-1] != len(l) - 1: idx.append(len(l) - 1)
        if len(idx) >= 2: sel.append(l[idx])
struct.pack_into('<i', hdr, 988, len(sel))
with open(out, 'wb') as f:
    f.write(hdr)
    for l in sel:
        f.write(struct.pack('<i', len(l))); f.write(np.ascontiguousarray(l, '<f4').tobytes())
print(out, len(sel), 'streamlines', sum(len(l) for l in sel), 'points')
