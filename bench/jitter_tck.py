#!/usr/bin/env python3
"""A tractogram's points moved by Gaussian noise: rough input for bench/tubes_peers.py.

    python3 bench/jitter_tck.py IN.tck OUT.tck SIGMA [--seed S]

Every point of every streamline moves by independent normal offsets of SIGMA (world units, mm)
along x, y and z (numpy's default generator, seed S, default 7). Reads and writes MRtrix .tck
with nibabel. For example, on `umbra synth bundles --n 20000 --points 100 --seed 7 -o b.tck`
(steps of about 1 mm), SIGMA 0.3 gives lines that turn sharply every few points."""
import argparse

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("sigma", type=float)
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    import nibabel as nib
    from nibabel.streamlines import Tractogram
    t = nib.streamlines.load(a.input)
    rng = np.random.default_rng(a.seed)
    lines = [s + rng.normal(0.0, a.sigma, s.shape).astype(s.dtype) for s in t.streamlines]
    out = Tractogram(lines, affine_to_rasmm=np.eye(4))
    nib.streamlines.save(out, a.output)
    print(f"wrote {a.output}: {len(lines)} streamlines, sigma {a.sigma}")


if __name__ == "__main__":
    main()
