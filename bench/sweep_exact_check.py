"""The signed distance of `umbra sweep` against an exact Euclidean distance, by distance from
the surface (docs/accuracy.md, "On real, noisy and anisotropic volumes").

    python3 bench/sweep_exact_check.py VOLUME.nrrd ISO [--fine F] [--umbra BIN]

VOLUME is an NRRD as `umbra convert` writes it (bench/nrrd_io.py). The reference is the exact
distance (the `edt` package) of the mask `value >= ISO` of the trilinear field supersampled F
times per axis (default 4), less half a fine voxel; its own error is about 1 / (2 F) voxel.
Each method (`--distance closest-point` and `sweeping`) is run with `--sdf-only`; errors are in
voxels of the smallest spacing, for voxels whose reference distance is under 1, 1-3 and over 3
of them: mean and maximum; with --worst N, each method's N worst voxels."""
import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import nrrd_io  # noqa: E402


def reference(v, iso, spacing_zyx, fine):
    import edt
    from scipy.ndimage import map_coordinates
    if fine > 1:
        axes = [np.arange(0, n - 1 + 1e-9, 1.0 / fine) for n in v.shape]
        grid = np.meshgrid(*axes, indexing="ij")
        f = map_coordinates(v.astype(np.float64), grid, order=1, mode="nearest")
    else:
        f = v.astype(np.float64)
    m = np.isfinite(f) & (f >= iso)
    p = max(fine // 2, 1)
    m = np.pad(m, p, constant_values=False)
    h = tuple(s / fine for s in spacing_zyx)
    inside = edt.edt(m, anisotropy=h, black_border=False, parallel=2)
    outside = edt.edt(~m, anisotropy=h, black_border=False, parallel=2)
    half = np.mean(h) / 2
    s = np.where(m, -(inside - half), outside - half)[p:-p, p:-p, p:-p]
    return s[::fine, ::fine, ::fine]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("volume")
    ap.add_argument("iso", type=float)
    ap.add_argument("--fine", type=int, default=4)
    ap.add_argument("--worst", type=int, default=0,
                    help="also print each method's N worst voxels: (x, y, z), error, umbra's "
                         "distance and the reference, in voxels")
    ap.add_argument("--umbra", default=str(Path(__file__).resolve().parents[1]
                                           / "target/release/umbra"))
    a = ap.parse_args()
    v, sp = nrrd_io.read(a.volume, scalar=True)
    sp_zyx = sp[::-1]
    vox = min(sp)
    ref = reference(v, a.iso, sp_zyx, a.fine)
    print(f"{Path(a.volume).name} iso {a.iso} dims (x, y, z) {v.shape[::-1]} spacing {sp}, "
          f"errors in voxels of {vox}")
    with tempfile.TemporaryDirectory() as tmp:
        for method in ["closest-point", "sweeping"]:
            out = Path(tmp) / "d.nrrd"
            r = subprocess.run([a.umbra, "sweep", a.volume, "--iso", repr(a.iso), "-o", str(out),
                                "--sdf-only", "--json", "--distance", method],
                               capture_output=True, text=True)
            if r.returncode:
                raise SystemExit(f"umbra sweep ({method}) failed: {r.stderr.strip()}")
            json.loads(r.stdout)
            d, _ = nrrd_io.read(out, scalar=True)
            err = np.abs(d - ref) / vox
            far = np.abs(ref) / vox
            parts = []
            for lo, hi in [(0, 1), (1, 3), (3, np.inf)]:
                sel = (far >= lo) & (far < hi)
                if sel.any():
                    parts.append(f"{lo}-{hi}: mean {err[sel].mean():.3f} max {err[sel].max():.2f}")
            print(f"  {method}: " + "; ".join(parts))
            for i in np.argsort(err.ravel())[::-1][:a.worst]:
                z, y, x = np.unravel_index(i, err.shape)
                print(f"    ({x}, {y}, {z}): error {err.ravel()[i]:.2f}, umbra "
                      f"{d.ravel()[i] / vox:.2f}, reference {ref.ravel()[i] / vox:.2f}")


if __name__ == "__main__":
    main()
