#!/usr/bin/env python3
"""`umbra sweep` against the `edt` package's exact signed distance on scenes of different
character, in one run (issue 16). For each scene and size N^3:

  * umbra: `seconds.compute` of `umbra sweep --json` (initialisation + distance + the eight
    octant fields, no --sdf-only, file I/O excluded), median of --repeat processes, for each
    --distance method asked for (default closest-point, the default of `umbra sweep`), and the
    peak resident memory the command reports;
  * edt: `edt.sdf(mask, anisotropy=spacing, parallel=2)` on the same inside mask (values >= iso),
    median of --repeat calls, alternating with umbra's first method (this machine's speed drifts
    by tens of percent within minutes, so the pairs are taken side by side);
  * copy: a plain copy of the bytes the sweep reads and writes (4 in, 12 out per voxel: the
    float32 values, the float32 distance and the eight uint8 octants), numpy, median of --repeat.

Scenes (inside = values >= iso):
  three-solids  `umbra synth three-solids` (sphere, torus and box in the unit cube; smooth solids)
  gyroid        a gyroid sheet 0.5 thick, |sin x cos y + sin y cos z + sin z cos x| <= 0.25 over
                three periods (thin walls everywhere, one connected surface)
  mni-wm        the MNI ICBM152 2009a white-matter probability map (../shared/data/mri), resampled
                trilinearly to N^3 over its own extent (anisotropic spacing), iso 0.5 (a noisy
                real isosurface)

Prints one JSON line per measurement and a Markdown table at the end.
Needs: pip install edt numpy scipy nibabel; umbra built (target/release/umbra).

Your own volumes: `--volume PATH:ISO` (repeatable; any format `umbra info` reads, converted by
`umbra convert` to a raw NRRD that both sides read, at its own grid; inside = values >= ISO).
With --volume and no --scenes only those volumes run.

umbra is target/release/umbra, or the binary the environment variable UMBRA names. A failing
umbra run (an isovalue with every sample on one side, a NaN) stops the script with umbra's
message.

Usage: python3 bench/sweep_peers.py [--sizes 256,512] [--scenes three-solids,gyroid,mni-wm]
                                    [--volume PATH:ISO ...] [--repeat 5]
                                    [--methods closest-point,sweeping]
"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import nrrd_io

ROOT = Path(__file__).resolve().parent.parent
UMBRA = os.environ.get("UMBRA", str(ROOT / "target" / "release" / "umbra"))
SHARED = ROOT.parent / "shared" / "data"


TAKEN = set()


def own_volume(spec, tmp):
    """(name, path, iso, values [z, y, x], spacing xyz) of `--volume PATH:ISO`: the volume as
    `umbra convert` writes it (raw NRRD; what `umbra sweep` and edt both read)."""
    src, sep, iso = spec.rpartition(":")
    if not sep:
        raise SystemExit(f"--volume {spec}: PATH:ISO (the isovalue after the last colon)")
    try:
        iso = float(iso)
    except ValueError:
        raise SystemExit(f"--volume {spec}: the isovalue {iso!r} is not a number")
    name = Path(src).name.split(".")[0]
    while name in TAKEN:
        name += "_"
    TAKEN.add(name)
    path = Path(tmp) / f"own_{name}.nrrd"
    r = subprocess.run([UMBRA, "convert", src, "-o", str(path)], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"--volume {spec}: umbra convert failed:\n{r.stderr}")
    v, sp = nrrd_io.read(path, scalar=True)
    return name, path, iso, v, sp


def scene(name, n, tmp):
    """(path, iso, values [z, y, x], spacing xyz) of a scene at n^3."""
    path = Path(tmp) / f"{name}_{n}.nrrd"
    if name == "three-solids":
        subprocess.run([UMBRA, "synth", "three-solids", "--n", str(n), "-o", str(path)],
                       check=True, capture_output=True)
        v, sp = nrrd_io.read(path, scalar=True)
        return path, 0.0, v, sp
    if name == "gyroid":
        t = np.linspace(0.0, 6.0 * np.pi, n, dtype=np.float32)
        z, y, x = np.meshgrid(t, t, t, indexing="ij", sparse=True)
        g = np.sin(x) * np.cos(y) + np.sin(y) * np.cos(z) + np.sin(z) * np.cos(x)
        v = (0.25 - np.abs(g)).astype(np.float32)
        h = float(t[1] - t[0])
        sp = [h, h, h]
    elif name == "mni-wm":
        import nibabel as nib
        from scipy.ndimage import zoom
        img = nib.load(str(SHARED / "mri" / "mni_icbm152_wm_tal_nlin_sym_09a.nii.gz"))
        a = np.asarray(img.dataobj, dtype=np.float32)  # [x, y, z]
        zooms = img.header.get_zooms()[:3]
        f = [n / s for s in a.shape]
        r = zoom(a, f, order=1)
        v = np.ascontiguousarray(r.transpose(2, 1, 0))  # [z, y, x]
        sp = [float(zooms[i]) * a.shape[i] / r.shape[i] for i in range(3)]
        iso = 0.5
        nrrd_io.write(path, v, sp)
        return path, iso, v, sp
    else:
        raise SystemExit(f"unknown scene {name}")
    nrrd_io.write(path, v, sp)
    return path, 0.0, v, sp


def umbra_sweep(path, iso, method, tmp, repeat):
    out = []
    info = None
    for _ in range(repeat):
        r = subprocess.run(
            [UMBRA, "sweep", str(path), "--iso", repr(iso), "-o", str(Path(tmp) / "d.nrrd"),
             "--distance", method, "--json"],
            capture_output=True, text=True,
            env={**os.environ, "XDG_RUNTIME_DIR": os.environ.get("XDG_RUNTIME_DIR", "/tmp")})
        if r.returncode != 0:
            raise SystemExit(f"sweep_peers: umbra sweep {path} --iso {iso} failed:\n"
                             f"{r.stderr.strip()}")
        info = json.loads(r.stdout)
        out.append(info["seconds"]["compute"])
    return statistics.median(out), info


def edt_sdf(v, iso, spacing, repeat):
    import edt
    mask = v >= iso
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        d = edt.sdf(mask, anisotropy=(spacing[2], spacing[1], spacing[0]), parallel=2)
        ts.append(time.perf_counter() - t)
        del d
    return statistics.median(ts)


def copy_bytes(v, repeat):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        a = v.copy()
        o = np.empty(v.size * 12, dtype=np.uint8)
        o.fill(1)
        ts.append(time.perf_counter() - t)
        del a, o
    return statistics.median(ts)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="256,512")
    ap.add_argument("--scenes", default=None,
                    help="of three-solids, gyroid, mni-wm (default: all three, none with --volume)")
    ap.add_argument("--volume", action="append", default=[], metavar="PATH:ISO",
                    help="a volume of one's own (any format umbra reads) and its isovalue, at "
                         "its own grid; repeatable")
    ap.add_argument("--methods", default="closest-point")
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    rows = []
    print(f"# machine: {os.cpu_count()} cores; date {time.strftime('%Y-%m-%dT%H:%MZ', time.gmtime())}")
    if a.scenes is None:
        a.scenes = "" if a.volume else "three-solids,gyroid,mni-wm"
    cases = [(n, name) for n in [int(s) for s in a.sizes.split(",")]
             for name in a.scenes.split(",") if name]
    cases += [(None, spec) for spec in a.volume]
    with tempfile.TemporaryDirectory(dir=os.environ.get("TMPDIR", "/tmp")) as tmp:
        for n, name in cases:
            if n is None:
                name, path, iso, v, sp = own_volume(name, tmp)
            else:
                path, iso, v, sp = scene(name, n, tmp)
            rec = {"scene": name, "n": n, "dims": list(v.shape[::-1]), "voxels": int(v.size),
                   "spacing": sp, "inside_fraction": float((v >= iso).mean())}
            methods = a.methods.split(",")
            first, edt_t = [], []
            info = None
            for _ in range(a.repeat):
                s, info = umbra_sweep(path, iso, methods[0], tmp, 1)
                first.append(s)
                edt_t.append(edt_sdf(v, iso, sp, 1))
            rec[f"umbra_{methods[0]}_s"] = statistics.median(first)
            rec[f"umbra_{methods[0]}_all_s"] = first
            rec["band_voxels"] = info["band_voxels"]
            rec[f"umbra_{methods[0]}_peak_bytes"] = info["peak_bytes"]
            rec["edt_s"] = statistics.median(edt_t)
            rec["edt_all_s"] = edt_t
            for m in methods[1:]:
                s, info = umbra_sweep(path, iso, m, tmp, a.repeat)
                rec[f"umbra_{m}_s"] = s
                rec[f"umbra_{m}_peak_bytes"] = info["peak_bytes"]
            rec["copy_s"] = copy_bytes(v, a.repeat)
            print(json.dumps(rec), flush=True)
            rows.append(rec)
            os.remove(path)
    methods = a.methods.split(",")
    print()
    print("| scene | grid | " + " | ".join(f"umbra {m} s" for m in methods)
          + " | edt.sdf s | copy s | edt / umbra | umbra / copy | umbra peak bytes / voxel |")
    print("|---|---|" + "---|" * len(methods) + "---|---|---|---|---|")
    for r in rows:
        u = r[f"umbra_{methods[0]}_s"]
        grid = f"{r['n']}^3" if r["n"] else " x ".join(str(d) for d in r["dims"])
        print(f"| {r['scene']} | {grid} | "
              + " | ".join(f"{r[f'umbra_{m}_s']:.3f}" for m in methods)
              + f" | {r['edt_s']:.3f} | {r['copy_s']:.3f} | {r['edt_s'] / u:.2f} | {u / r['copy_s']:.2f} |"
              + f" {r[f'umbra_{methods[0]}_peak_bytes'] / r['voxels']:.1f} |")


if __name__ == "__main__":
    main()
