#!/usr/bin/env python3
"""Largest and mean absolute difference between two EXR images, per channel set they share
(e.g. RGBA and the AOVs of `umbra render ... -o X.exr`): what the docs quote where two renders
are "the same to float precision" (docs/accuracy.md, "Light below 1/1024 is not swept").

Usage: python3 bench/exr_diff.py A.exr B.exr
Needs numpy and OpenEXR (pip install numpy OpenEXR). Exits 1 on a missing or unreadable
file, on images of different sizes, or when the two share no channel set.
"""
import sys

import numpy as np
import OpenEXR


def channels(path):
    try:
        f = OpenEXR.File(path)
        return {k: np.asarray(v.pixels, dtype=np.float64) for k, v in f.channels().items()}
    except Exception as e:  # OpenEXR raises plain exceptions for missing or bad files
        sys.exit(f"{path}: cannot read as EXR: {e}")


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[3])
    a, b = channels(sys.argv[1]), channels(sys.argv[2])
    shared = sorted(set(a) & set(b))
    if not shared:
        sys.exit(f"{sys.argv[1]} and {sys.argv[2]} share no channel set")
    for name in shared:
        if a[name].shape != b[name].shape:
            sys.exit(f"{name}: {a[name].shape} against {b[name].shape}")
        d = np.abs(a[name] - b[name])
        # NaN in one image and not the other counts as a difference of infinity.
        d[np.isnan(a[name]) != np.isnan(b[name])] = np.inf
        d[np.isnan(d)] = 0.0
        print(f"{name}: max {d.max():.3g}, mean {d.mean():.3g} over {d.size} values")


if __name__ == "__main__":
    main()
