#!/usr/bin/env python3
"""Signed error of an image against a reference, both EXR: the mean of (image - reference)
over the pixels where the reference differs from the background (the channels' absolute
differences from it summing to more than 0.01), and its RMS there; then the same over the
interior, the pixels whose 5 x 5 neighbourhood is all off the background (the silhouette's
pixels left out: where the reference's rays, jittered within the pixel, partly meet the
volume and the image's centre ray misses it, the image shows the background there, and
such pixels are counted while the converse ones are not - a bias towards the background's
brightness that says nothing of the light). A positive mean: the image is brighter than the
reference.

Usage: python3 bench/exr_bias.py REFERENCE.exr IMAGE.exr [BACKGROUND]
  REFERENCE: e.g. the `reference/*.exr` an `umbra bench accuracy` run leaves (channel RGB);
  IMAGE: `umbra render SCENE -o IMAGE.exr` (channel RGBA); BACKGROUND: the scene's grey level
  (default 1, white). Needs numpy and OpenEXR (pip install numpy OpenEXR).
"""
import sys

import numpy as np
import OpenEXR


def rgb(path):
    try:
        channels = OpenEXR.File(path).parts[0].channels
    except Exception as e:  # OpenEXR raises plain exceptions for missing or bad files
        sys.exit(f"{path}: cannot read as EXR: {e}")
    for name in ("RGB", "RGBA"):
        if name in channels:
            return np.asarray(channels[name].pixels, dtype=float)[..., :3]
    sys.exit(f"{path}: no RGB or RGBA channel (has {sorted(channels)})")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    ref, img = rgb(sys.argv[1]), rgb(sys.argv[2])
    bg = float(sys.argv[3]) if len(sys.argv) > 3 else 1.0
    if ref.shape != img.shape:
        sys.exit(f"sizes differ: {ref.shape} against {img.shape}")
    mask = np.abs(ref - bg).sum(-1) > 0.01
    d = (img - ref)[mask]
    print(f"{mask.sum()} pixels off the background: signed mean {d.mean():+.4f}, "
          f"RMS {np.sqrt((d ** 2).mean()):.4f}")
    inner = mask.copy()
    h, w = mask.shape
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            shifted = np.zeros_like(mask)
            shifted[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] = \
                mask[max(-dy, 0):h + min(-dy, 0), max(-dx, 0):w + min(-dx, 0)]
            inner &= shifted
    d = (img - ref)[inner]
    if inner.any():
        print(f"{inner.sum()} of them inside (5 x 5 all off the background): signed mean "
              f"{d.mean():+.4f}, RMS {np.sqrt((d ** 2).mean()):.4f}")


if __name__ == "__main__":
    main()
