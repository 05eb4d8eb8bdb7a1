#!/usr/bin/env python3
"""`umbra resample` against VTK's vtkResampleToImage on the CFD grids of ../shared/data/cfd:
time (median of --repeat) and agreement of the sampled values.

Both sample the same regular grid (the input's bounding box, --dims samples, first and last
samples on the bounds). umbra is timed as the whole CLI process (read, resample, write NRRD);
VTK as reader Update() + vtkResampleToImage Update() in this process (no write), so the ratio is
conservative for umbra. Agreement: the fraction of samples both call inside the mesh, the
fraction where they disagree, and the largest difference where both have a value, relative to
the field's range. Prints one JSON line per grid. Needs: pip install vtk numpy, and a
release build (cargo build --release).

Usage: python3 bench/peers_resample.py [--data ../shared/data/cfd] [--repeat 5]
"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

import numpy as np

import nrrd_io

CASES = [
    # name, files, umbra --field, VTK array (None: velocity of PLOT3D), dims
    ("fire_ug.vtu", ["fire_ug.vtu"], "uvw", "uvw", (128, 54, 52)),
    ("cth.vtr", ["cth.vtr"], "Pressure", "Pressure", (128, 67, 67)),
    ("kitchen.vtk", ["kitchen.vtk"], "velocity", "velocity", (128, 92, 46)),
    ("office.binary.vtk", ["office.binary.vtk"], "vectors", "vectors", (128, 128, 72)),
    ("comb (PLOT3D)", ["combxyz.bin", "combq.bin"], "velocity", None, (128, 88, 100)),
]


def vtk_read(vtk, data, files):
    f0 = os.path.join(data, files[0])
    if f0.endswith(".vtu"):
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(f0)
    elif f0.endswith(".vtr"):
        r = vtk.vtkXMLRectilinearGridReader()
        r.SetFileName(f0)
    elif f0.endswith(".vtk"):
        r = vtk.vtkStructuredGridReader()
        r.SetFileName(f0)
        r.ReadAllScalarsOn()
        r.ReadAllVectorsOn()
    else:
        r = vtk.vtkMultiBlockPLOT3DReader()
        r.SetXYZFileName(f0)
        r.SetQFileName(os.path.join(data, files[1]))
        r.AutoDetectFormatOn()
        r.AddFunction(200)  # velocity
        r.Update()
        return r.GetOutput().GetBlock(0)
    r.Update()
    return r.GetOutput()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "cfd"))
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--umbra", default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "umbra"))
    a = ap.parse_args()
    import vtk
    from vtk.util import numpy_support as ns

    tmp = tempfile.mkdtemp()
    for name, files, ufield, vfield, dims in CASES:
        out = os.path.join(tmp, "r.nrrd")
        cmd = [a.umbra, "resample", os.path.join(a.data, files[0]), "--field", ufield,
               "--dims", ",".join(map(str, dims)), "-o", out]
        if len(files) > 1:
            cmd += ["--q", os.path.join(a.data, files[1])]
        tu = []
        for _ in range(a.repeat):
            t = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            tu.append(time.perf_counter() - t)
        u = nrrd_io.read(out)[0].astype(np.float64).reshape(dims[2], dims[1], dims[0], -1).transpose(2, 1, 0, 3)

        tv = []
        for _ in range(a.repeat):
            t = time.perf_counter()
            ds = vtk_read(vtk, a.data, files)
            rs = vtk.vtkResampleToImage()
            rs.SetInputDataObject(ds)
            rs.SetSamplingDimensions(*dims)
            rs.UseInputBoundsOn()
            rs.Update()
            tv.append(time.perf_counter() - t)
        img = rs.GetOutput()
        pd = img.GetPointData()
        arr = pd.GetArray(vfield if vfield else "Velocity")
        v = ns.vtk_to_numpy(arr).astype(np.float64)
        v = v.reshape(dims[2], dims[1], dims[0], -1).transpose(2, 1, 0, 3)
        mask = ns.vtk_to_numpy(pd.GetArray("vtkValidPointMask")).reshape(dims[2], dims[1], dims[0]).T != 0
        uin = ~np.isnan(u).any(axis=3)
        both = uin & mask
        rng = np.nanmax(v[mask]) - np.nanmin(v[mask]) if mask.any() else 1.0
        diff = np.abs(u[both] - v[both]).max() / rng if both.any() else float("nan")
        p99 = np.quantile(np.abs(u[both] - v[both]).max(axis=1), 0.99) / rng if both.any() else float("nan")
        print(json.dumps({
            "grid": name, "dims": dims,
            "umbra_s": round(statistics.median(tu), 4), "vtk_s": round(statistics.median(tv), 4),
            "ratio": round(statistics.median(tu) / statistics.median(tv), 3),
            "inside_both": round(float(both.mean()), 4),
            "inside_disagree": round(float((uin != mask).mean()), 5),
            "max_rel_diff": float(f"{diff:.3g}"), "p99_rel_diff": float(f"{p99:.3g}"),
        }), flush=True)


if __name__ == "__main__":
    main()
