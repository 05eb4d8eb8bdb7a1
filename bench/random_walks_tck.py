#!/usr/bin/env python3
"""Short random walks as a .tck: many tiny rough streamlines, for the memory of `umbra tubes`
to OBJ (README, `umbra tubes`, "Memory") and the tube benchmarks' worst case.

    python3 bench/random_walks_tck.py OUT.tck [--n N] [--points P] [--seed S]

N streamlines (default 1,000,000) of P points (default 3), each starting uniformly in
[-50, 50]^3 mm and moving by normal steps of 1 mm per axis (numpy's default generator, seed S,
default 1). Needs: numpy, nibabel."""
import argparse

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("output")
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--points", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    if a.n < 1 or a.points < 2:
        raise SystemExit("--n must be at least 1 and --points at least 2")
    import nibabel as nib
    rng = np.random.default_rng(a.seed)
    base = rng.uniform(-50, 50, (a.n, 1, 3)).astype(np.float32)
    steps = np.cumsum(rng.normal(0, 1, (a.n, a.points, 3)).astype(np.float32), axis=1)
    t = nib.streamlines.Tractogram(list(base + steps), affine_to_rasmm=np.eye(4))
    nib.streamlines.save(t, a.output)
    print(f"wrote {a.output}: {a.n} streamlines of {a.points} points")


if __name__ == "__main__":
    main()
