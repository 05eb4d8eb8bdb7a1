#!/usr/bin/env python3
"""VTK peers of the stream-tube benchmark: vtkTubeFilter alone and vtkSplineFilter +
vtkTubeFilter on the same polylines (a .tck written by `cargo run --release -p umbra --example
tubes_bench -- 10000 3 lines.tck`), radius 0.2, 8 sides. Prints one JSON line per method:
seconds (median of --repeat; filter Update() only, the polydata is built beforehand) and
triangles. Needs: pip install vtk nibabel numpy.

Usage: python3 bench/peers_tubes.py lines.tck [--repeat 3]
"""
import argparse
import json
import time

import numpy as np

from tubes_peers import vtk_polydata


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("tck")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    import nibabel as nib
    import vtk
    from vtk.util import numpy_support as ns

    s = nib.streamlines.load(a.tck).streamlines
    poly = vtk_polydata([np.asarray(x, dtype=np.float32) for x in s])

    def tris(out):
        n = 0
        strips = out.GetStrips()
        if strips.GetNumberOfCells():
            o = ns.vtk_to_numpy(strips.GetOffsetsArray())
            n += int(np.sum(np.diff(o) - 2))
        n += out.GetPolys().GetNumberOfCells()
        return n

    for name in ["vtkTubeFilter", "vtkSplineFilter+vtkTubeFilter"]:
        times, ntri = [], 0
        for _ in range(a.repeat):
            tube = vtk.vtkTubeFilter()
            tube.SetRadius(0.2)
            tube.SetNumberOfSides(8)
            tube.CappingOff()
            if name == "vtkTubeFilter":
                tube.SetInputData(poly)
                t0 = time.perf_counter()
                tube.Update()
                times.append(time.perf_counter() - t0)
            else:
                spline = vtk.vtkSplineFilter()
                spline.SetInputData(poly)
                spline.SetSubdivideToSpecified()
                spline.SetNumberOfSubdivisions(199)
                tube.SetInputConnection(spline.GetOutputPort())
                t0 = time.perf_counter()
                tube.Update()
                times.append(time.perf_counter() - t0)
            ntri = tris(tube.GetOutput())
        print(json.dumps({"method": name, "seconds": float(np.median(times)), "triangles": ntri, "vtk": vtk.vtkVersion.GetVTKVersion()}))


if __name__ == "__main__":
    main()
