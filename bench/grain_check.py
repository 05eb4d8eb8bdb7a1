#!/usr/bin/env python3
"""Where a volume's fine horizontal "wood grain" comes from: the same scene rendered from the
volume as it is, from it upsampled 2x by cubic splines (clipped to its range: a smoother
reconstruction of the same samples), and from it smoothed by Gaussians of SIGMA voxels; each
image high-passed (minus a Gaussian blur of 2 px, x 12 about grey) and cropped, side by side.

    python3 bench/grain_check.py SCENE.toml -o OUT.png [--crop X0,Y0,X1,Y1] [--sigma 0.5,0.8]
        [--set KEY=VALUE ...] [--umbra BIN]

The scene's volume must be NIfTI (`volume.path`); the variants are written beside OUT as
NIfTI and rendered with `--set volume.path=...`. Prints, per variant, the mean |second
difference| down the columns and along the rows of the crop (terraces along the rows raise the
first). Needs: numpy, scipy, nibabel, pillow."""
import argparse
import subprocess
import tomllib
from pathlib import Path

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--crop", default="150,170,350,370")
    ap.add_argument("--sigma", default="0.5,0.8")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--umbra", default=str(Path(__file__).resolve().parents[1]
                                           / "target/release/umbra"))
    a = ap.parse_args()
    import nibabel as nib
    from PIL import Image
    from scipy.ndimage import gaussian_filter, zoom

    scene = Path(a.scene)
    with open(scene, "rb") as f:
        vol = (scene.parent / tomllib.load(f)["volume"]["path"]).resolve()
    out = Path(a.out)
    work = out.parent
    img = nib.load(str(vol))
    data = np.asarray(img.dataobj, dtype=np.float32)
    lo, hi = float(np.nanmin(data)), float(np.nanmax(data))
    variants = [("as stored", vol)]
    up = np.clip(zoom(data, 2, order=3, grid_mode=False), lo, hi)
    aff = img.affine.copy()
    aff[:3, :3] /= 2
    p = work / "grain_cubic2x.nii.gz"
    nib.save(nib.Nifti1Image(up, aff), str(p))
    variants.append(("cubic 2x", p))
    for s in [float(x) for x in a.sigma.split(",") if x]:
        p = work / f"grain_gauss{s}.nii.gz"
        nib.save(nib.Nifti1Image(gaussian_filter(data, s), img.affine), str(p))
        variants.append((f"Gaussian {s} voxel", p))
    x0, y0, x1, y1 = [int(v) for v in a.crop.split(",")]
    tiles = []
    for name, path in variants:
        png = work / f"grain_{len(tiles)}.png"
        cmd = [a.umbra, "render", str(scene), "-o", str(png), "--set", f"volume.path={path}"]
        for s in a.set:
            cmd += ["--set", s]
        subprocess.run(cmd, check=True, capture_output=True)
        g = np.asarray(Image.open(png).convert("L"), dtype=np.float64)
        hp = (g - gaussian_filter(g, 2))[y0:y1, x0:x1]
        c = g[y0:y1, x0:x1]
        down = np.abs(np.diff(c, 2, axis=0)).mean()
        along = np.abs(np.diff(c, 2, axis=1)).mean()
        print(f"{name}: |second difference| down the columns {down:.3f}, along the rows "
              f"{along:.3f}")
        tiles.append(np.clip(128 + hp * 12, 0, 255).astype(np.uint8))
    h, w = tiles[0].shape
    m = np.full((h, (w + 4) * len(tiles) - 4), 255, np.uint8)
    for i, t in enumerate(tiles):
        m[:, i * (w + 4):i * (w + 4) + w] = t
    Image.fromarray(m).resize((m.shape[1] * 2, h * 2), Image.NEAREST).save(out)
    print(f"wrote {out} ({', '.join(n for n, _ in variants)}, left to right)")


if __name__ == "__main__":
    main()
