#!/usr/bin/env python3
"""A NIfTI volume upsampled by spline interpolation: a finer grid of the same content, for
bench/sweep_peers.py --volume on a real noisy surface at a larger size.

    python3 bench/upsample_nifti.py IN.nii[.gz] OUT.nii FACTOR [--order K]

scipy.ndimage.zoom by FACTOR along each axis (order K, default 3: cubic), float32, the affine's
axes divided by FACTOR (the origin kept). For example the FA map of ../shared/data/dti at 3x:
252 x 276 x 168 voxels of 0.73 mm. Needs: numpy, scipy, nibabel."""
import argparse

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("factor", type=float)
    ap.add_argument("--order", type=int, default=3)
    a = ap.parse_args()
    import nibabel as nib
    from scipy.ndimage import zoom
    img = nib.load(a.input)
    data = np.asarray(img.dataobj, dtype=np.float32)
    up = zoom(data, a.factor, order=a.order).astype(np.float32)
    aff = img.affine.copy()
    aff[:3, :3] /= a.factor
    nib.save(nib.Nifti1Image(up, aff), a.output)
    print(f"wrote {a.output}: {up.shape}")


if __name__ == "__main__":
    main()
