#!/usr/bin/env python3
"""`umbra tubes` against vtkTubeFilter on several tractograms in one run (issue 16).

For each input (a .tck or .trk, gzipped or not; another format umbra reads, such as TRX or VTK
polylines, is written as a .tck by `umbra tracts select` for VTK's side; .trk/.trk.gz bundles
can be merged into one .tck with --merge):
  * umbra: `seconds.compute` of `umbra tubes IN -o OUT.ply --radius R --sides 8 --tolerance T
    --stats-json S` (clean, fit, reduce, frames, mesh; no file I/O), with triangles, max
    deviation and how many pieces were meshed as polylines, one process per run;
  * VTK: `vtkTubeFilter` (radius R, 8 sides, no caps) `Update()` on the same polylines (the
    polydata is built beforehand), alternating with umbra's runs, --repeat of each.
Prints one JSON line per input and a Markdown table.
Needs: pip install vtk nibabel numpy; umbra built (target/release/umbra, or the binary the
environment variable UMBRA names). Seconds in the table to 4 significant digits; a failing
`umbra tubes` run stops the script with umbra's message.

Usage: python3 bench/tubes_peers.py [NAME=]FILE.tck [[NAME=]FILE ...] [--radius 0.2]
       [--tolerance 0.02] [--repeat 3] [--vtk-max-points P]
       (inputs of more than P points are timed with umbra alone: vtkTubeFilter's output for
       10^8 points, 1.6 G triangles, does not fit this machine's memory)
       python3 bench/tubes_peers.py --merge OUT.tck BUNDLE.trk.gz [...]   (merge bundles)
"""
import argparse
import gzip
import json
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
UMBRA = os.environ.get("UMBRA", str(ROOT / "target" / "release" / "umbra"))


def load_lines(path):
    import nibabel as nib
    p = str(path)
    low = p.lower()
    if not low.removesuffix(".gz").endswith((".trk", ".tck")):
        # A format nibabel does not read (TRX, VTK polylines): umbra writes the same points
        # as a .tck first (`umbra tracts select`), and VTK meshes those.
        with tempfile.TemporaryDirectory() as d:
            tck = os.path.join(d, "lines.tck")
            subprocess.run([UMBRA, "tracts", "select", p, "-o", tck], check=True,
                           stdout=subprocess.DEVNULL)
            return load_lines(tck)
    if p.endswith(".gz"):
        with gzip.open(p, "rb") as f, tempfile.NamedTemporaryFile(suffix=Path(p[:-3]).suffix) as t:
            t.write(f.read())
            t.flush()
            tg = nib.streamlines.load(t.name)
    else:
        tg = nib.streamlines.load(p)
    return [np.asarray(s, dtype=np.float32) for s in tg.streamlines]


def merge(out, inputs):
    import nibabel as nib
    lines = [l for p in inputs for l in load_lines(p)]
    tg = nib.streamlines.Tractogram(lines, affine_to_rasmm=np.eye(4))
    nib.streamlines.save(tg, out)
    print(f"wrote {out}: {len(lines)} streamlines, {sum(len(l) for l in lines)} points")


def vtk_polydata(lines):
    import vtk
    from vtk.util import numpy_support as ns
    pts = np.concatenate(lines).astype(np.float32)
    lens = np.array([len(x) for x in lines])
    poly = vtk.vtkPolyData()
    vp = vtk.vtkPoints()
    vp.SetData(ns.numpy_to_vtk(pts, deep=True))
    poly.SetPoints(vp)
    offsets = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    conn = np.arange(len(pts), dtype=np.int64)
    cells = vtk.vtkCellArray()
    cells.SetData(ns.numpy_to_vtkIdTypeArray(offsets, deep=True),
                  ns.numpy_to_vtkIdTypeArray(conn, deep=True))
    poly.SetLines(cells)
    return poly


def vtk_tube(poly, radius):
    import vtk
    from vtk.util import numpy_support as ns
    tube = vtk.vtkTubeFilter()
    tube.SetRadius(radius)
    tube.SetNumberOfSides(8)
    tube.CappingOff()
    tube.SetInputData(poly)
    t0 = time.perf_counter()
    tube.Update()
    dt = time.perf_counter() - t0
    out = tube.GetOutput()
    n = 0
    strips = out.GetStrips()
    if strips.GetNumberOfCells():
        n += int(np.sum(np.diff(ns.vtk_to_numpy(strips.GetOffsetsArray())) - 2))
    n += out.GetPolys().GetNumberOfCells()
    return dt, n


def umbra_tubes(path, radius, tol, tmp):
    s = Path(tmp) / "s.json"
    r = subprocess.run([UMBRA, "tubes", str(path), "-o", str(Path(tmp) / "t.ply"), "--radius",
                        repr(radius), "--sides", "8", "--tolerance", repr(tol), "--stats-json",
                        str(s)],
                       capture_output=True, text=True,
                       env={**os.environ,
                            "XDG_RUNTIME_DIR": os.environ.get("XDG_RUNTIME_DIR", "/tmp")})
    if r.returncode != 0:
        raise SystemExit(f"tubes_peers: umbra tubes {path} failed:\n{r.stderr.strip()}")
    return json.loads(s.read_text())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("inputs", nargs="*")
    ap.add_argument("--merge")
    ap.add_argument("--radius", type=float, default=0.2)
    ap.add_argument("--tolerance", type=float, default=0.02)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--vtk-max-points", type=int, default=None)
    a = ap.parse_args()
    if a.merge:
        merge(a.merge, a.inputs)
        return
    if not a.inputs:
        ap.error("no input: give one or more [NAME=]FILE")
    print(f"# machine: {os.cpu_count()} cores; date {time.strftime('%Y-%m-%dT%H:%MZ', time.gmtime())}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for item in a.inputs:
            # NAME=FILE, or FILE alone (named by its file name).
            if Path(item).is_file():
                name, path = Path(item).name, item
            else:
                name, sep, path = item.partition("=")
                if not sep or not name:
                    path = path or name
                    name = Path(path).name
            if not Path(path).is_file():
                raise SystemExit(f"tubes_peers: no such file: {path}")
            lines = load_lines(path)
            points = int(sum(len(l) for l in lines))
            if points == 0:
                raise SystemExit(f"tubes_peers: {path}: no streamline points to mesh")
            with_vtk = a.vtk_max_points is None or points <= a.vtk_max_points
            poly = vtk_polydata(lines) if with_vtk else None
            n_lines = len(lines)
            del lines
            ut, vt, st, ntri = [], [], None, None
            for _ in range(a.repeat):
                st = umbra_tubes(path, a.radius, a.tolerance, tmp)
                ut.append(st["seconds"]["compute"] if "seconds" in st else st["compute_s"])
                if with_vtk:
                    dt, ntri = vtk_tube(poly, a.radius)
                    vt.append(dt)
            rec = {"input": name, "streamlines": n_lines, "points": points,
                   "umbra_s": statistics.median(ut), "umbra_all_s": ut,
                   "vtk_s": statistics.median(vt) if vt else None,
                   "vtk_all_s": vt, "umbra_triangles": st["triangles"], "vtk_triangles": ntri,
                   "max_deviation": st["max_deviation"], "polyline_pieces": st.get("polyline_pieces"),
                   "control_points": st["control_points"]}
            print(json.dumps(rec), flush=True)
            rows.append(rec)
    print()
    print("| input | streamlines | points | umbra s | vtkTubeFilter s | ratio | umbra triangles | VTK triangles | max deviation | polyline pieces |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        vtk_s = f"{r['vtk_s']:.4g}" if r["vtk_s"] is not None else "-"
        ratio = f"{r['umbra_s'] / r['vtk_s']:.2f}" if r["vtk_s"] is not None else "-"
        print(f"| {r['input']} | {r['streamlines']} | {r['points']} | {r['umbra_s']:.4g} | {vtk_s} | "
              f"{ratio} | {r['umbra_triangles']} | {r['vtk_triangles'] or '-'} | "
              f"{r['max_deviation']:.4f} | {r['polyline_pieces']} |")


if __name__ == "__main__":
    main()
