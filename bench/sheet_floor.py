#!/usr/bin/env python3
"""Writes the sheet-over-a-dense-floor scene of docs/accuracy.md ("The light at the sample's
depth") and of cli/tests/ea_cli.rs: a 32^3 grid of f32 samples one unit apart, a sheet one
voxel thick (value 1, extinction 0.6) at z = 17 over a floor three voxels thick (value 0.5,
extinction 2) at z = 2-4, seen from above with the head light (`dos`).

Usage: python3 bench/sheet_floor.py DIR   (writes DIR/sheet.nrrd and DIR/sheet.toml)
Then:  umbra bench accuracy DIR/sheet.toml --methods dos --reference-spp 256
       --set render.device=cpu --set render.width=128 --set render.height=128 -o OUT
"""
import struct
import sys
from pathlib import Path

N = 32


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    out.mkdir(parents=True, exist_ok=True)
    header = (
        f"NRRD0004\ntype: float\ndimension: 3\nsizes: {N} {N} {N}\nspacings: 1 1 1\n"
        "encoding: raw\nendian: little\n\n"
    ).encode()
    body = bytearray()
    for z in range(N):
        v = 1.0 if z == 17 else (0.5 if 2 <= z <= 4 else 0.0)
        body += struct.pack("<f", v) * (N * N)
    (out / "sheet.nrrd").write_bytes(header + bytes(body))
    (out / "sheet.toml").write_text(
        """background = [0.0, 0.0, 0.0]
[camera]
azimuth = 10.0
elevation = 75.0
[volume]
path = "sheet.nrrd"
[volume.transfer]
points = [
  { value = 0.0, color = [1.0, 1.0, 1.0], extinction = 0.0 },
  { value = 0.5, color = [1.0, 1.0, 1.0], extinction = 2.0 },
  { value = 1.0, color = [1.0, 1.0, 1.0], extinction = 0.6 },
]
[render]
method = "dos"
width = 48
height = 48
fxaa = false
slice_distance = 0.5
"""
    )


if __name__ == "__main__":
    main()
