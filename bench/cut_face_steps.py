"""Lines a light step apart on a cut face (docs/accuracy.md, "Seams on cut faces").

    python3 bench/cut_face_steps.py VOLUME --normal X,Y,Z --offset D --azimuth A --elevation E
        [--distance 1.8] [--size 320] [--umbra BIN] [--set KEY=VALUE ...]

Renders VOLUME (any file `umbra convert` reads) cut by one clipping plane, `preset = "bone"`,
`range = "robust"`, on the CPU renderer, with `render.method = "ea"` (no light) and
`"combined"`, and over the cut face (the pixels whose first kept point lies on the plane, in
tissue, eroded by 3 pixels; a perspective camera of 35 degrees as umbra's orbit) prints:
the mean absolute second difference along rows of each image and their ratio, and the
step-locked profile - `combined - ea`, high-passed (less its Gaussian mean of 6 pixels), averaged
in 16 bins of where each pixel's cut depth lies within a light step (`light.step` slices of
`slice_distance` from `--json`) - and its peak to peak in levels of 255."""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def main():
    import nibabel as nib
    from PIL import Image
    from scipy import ndimage
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("volume")
    ap.add_argument("--normal", required=True)
    ap.add_argument("--offset", type=float, required=True)
    ap.add_argument("--azimuth", type=float, required=True)
    ap.add_argument("--elevation", type=float, required=True)
    ap.add_argument("--distance", type=float, default=1.8)
    ap.add_argument("--size", type=int, default=320)
    ap.add_argument("--umbra", default=str(Path(__file__).resolve().parents[1]
                                           / "target/release/umbra"))
    ap.add_argument("--set", action="append", default=[])
    a = ap.parse_args()
    n = np.array([float(x) for x in a.normal.split(",")])
    env = dict(os.environ, XDG_RUNTIME_DIR=os.environ.get("XDG_RUNTIME_DIR", "/tmp"))
    with tempfile.TemporaryDirectory() as tmp:
        nii = Path(tmp) / "v.nii.gz"
        subprocess.run([a.umbra, "convert", a.volume, "-o", str(nii)], check=True,
                       capture_output=True, env=env)
        img = nib.load(str(nii))
        vol = np.asanyarray(img.dataobj).astype(np.float32)
        aff = img.affine
        lo, hi = np.percentile(vol, [2, 98])
        scene = Path(tmp) / "s.toml"
        scene.write_text(
            f"background = [0, 0, 0]\n[camera]\nazimuth = {a.azimuth}\nelevation = {a.elevation}\n"
            f"distance = {a.distance}\n[volume]\npath = \"{Path(a.volume).resolve()}\"\n"
            "[volume.transfer]\npreset = \"bone\"\nrange = \"robust\"\n"
            f"[[clip]]\nnormal = [{n[0]}, {n[1]}, {n[2]}]\noffset = {a.offset}\n"
            f"[render]\ndevice = \"cpu\"\nwidth = {a.size}\nheight = {a.size}\n")
        out, js = {}, {}
        for m in ["ea", "combined"]:
            png = Path(tmp) / f"{m}.png"
            cmd = [a.umbra, "render", str(scene), "-o", str(png), "--json",
                   "--set", f"render.method=\"{m}\""]
            for s in a.set:
                cmd += ["--set", s]
            r = subprocess.run(cmd, capture_output=True, text=True, env=env)
            if r.returncode:
                raise SystemExit(f"umbra render failed: {r.stderr.strip()}")
            js[m] = json.loads(r.stdout[r.stdout.index("{"):])
            out[m] = np.asarray(Image.open(png).convert("L"), float)
    # The camera (umbra's orbit: azimuth 0 looks along +y, elevation 90 down from +z).
    sh = np.array(vol.shape[:3]) - 1
    corners = np.array([[i, j, k] for i in (0, sh[0]) for j in (0, sh[1]) for k in (0, sh[2])],
                       float) @ aff[:3, :3].T + aff[:3, 3]
    b0, b1 = corners.min(0), corners.max(0)
    az, el = np.radians(a.azimuth), np.radians(a.elevation)
    f = np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), -np.sin(el)])
    eye = (b0 + b1) / 2 - f * max(a.distance, 1.01) * np.linalg.norm((b1 - b0) / 2)
    up = np.array([0, 0, 1.0]) if np.linalg.norm(np.cross(f, [0, 0, 1])) > 1e-6 else np.array([0, 1.0, 0])
    right = np.cross(f, up)
    right /= np.linalg.norm(right)
    tu = np.cross(right, f)
    t = np.tan(np.radians(35.0) / 2)
    px = (np.arange(a.size) + 0.5) / a.size * 2 - 1
    x, y = np.meshgrid(px, -px)
    d = f + (x[..., None] * t * right + y[..., None] * t * tu)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    tt = (a.offset - eye @ n) / (d @ n)
    p = eye + d * tt[..., None]
    inv = np.linalg.inv(aff)
    ijk = p @ inv[:3, :3].T + inv[:3, 3]
    ok = (tt > 0) & np.all((ijk >= 0.5) & (ijk <= sh - 0.5), axis=-1) & ((eye @ n) > a.offset)
    v = ndimage.map_coordinates(vol, np.moveaxis(np.nan_to_num(ijk), -1, 0).reshape(3, -1),
                                order=1, mode="nearest").reshape(a.size, a.size)
    ok &= v > lo + 0.15 * (hi - lo)
    mask = ndimage.binary_erosion(ndimage.binary_opening(ok, iterations=1), iterations=3)
    depth = (p - eye) @ f

    def ripple(im):
        dd = np.abs(np.diff(im, 2, axis=1))
        mm = mask[:, 1:-1] & mask[:, :-2] & mask[:, 2:]
        return dd[mm].mean()

    ea, c = out["ea"], out["combined"]
    light = js["combined"].get("light") or {}
    period = light.get("step", 1) * js["combined"]["slice_distance"]
    z0 = ((corners - eye) @ f).min()
    lm = mask & (ea > 30)
    diff = c - ea
    hp = diff - ndimage.gaussian_filter(np.where(lm, diff, 0), 6) / np.maximum(
        ndimage.gaussian_filter(lm.astype(float), 6), 1e-3)
    ph = np.mod(depth - z0, period) / period
    idx = np.minimum((ph[lm] * 16).astype(int), 15)
    prof = np.array([hp[lm][idx == b].mean() for b in range(16)])
    re, rc = ripple(ea), ripple(c)
    print(f"face pixels {mask.sum()}, light step {period:.3f} deep")
    print(f"ripple along rows: ea {re:.3f}, combined {rc:.3f} ({rc / re:.2f}x)")
    print(f"step-locked profile (levels): {' '.join(f'{x:+.2f}' for x in prof)}; "
          f"peak to peak {prof.max() - prof.min():.2f}")


if __name__ == "__main__":
    sys.exit(main())
