"""Subsets of the HCP1065 tract atlas (Yeh 2022, CC BY-SA 4.0) for umbra's demo scene.

Reads ../shared/data/tracts/hcp1065/{CST_L,CST_R,AF_R}.trk.gz and keeps every n-th streamline
(about 250 per bundle) unchanged, header included; writes <name>_demo.trk.gz here. The files
keep the atlas's coordinates: the demo scene applies the shift to MNI space (78, 76, -50) mm
documented in ../shared/data/README.md. Run from this directory:
    python3 make_demo_tracts.py ../../../shared/data/tracts/hcp1065
"""
import gzip
import sys

import nibabel as nib

src = sys.argv[1] if len(sys.argv) > 1 else "../../../shared/data/tracts/hcp1065"
for name in ["CST_L", "CST_R", "AF_R"]:
    trk = nib.streamlines.load(f"{src}/{name}.trk.gz")
    n = len(trk.streamlines)
    step = max(1, n // 250)
    kept = trk.tractogram[::step]
    out = nib.streamlines.TrkFile(kept, header=trk.header)
    tmp = f"{name}_demo.trk"
    out.save(tmp)
    with open(tmp, "rb") as f, open(f"{name}_demo.trk.gz", "wb") as raw:
        with gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as g:
            g.write(f.read())
    import os
    os.remove(tmp)
    print(name, n, "->", len(kept))
