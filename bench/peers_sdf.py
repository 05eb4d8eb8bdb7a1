#!/usr/bin/env python3
"""Peers for the signed-distance benchmark and accuracy table: scikit-fmm (orders 1 and 2)
and the `edt` package's exact Euclidean SDF of the binary mask, on umbra's three-solids scene
(volume::synthetic::three_solids: sphere, torus and box in the unit cube, n^3 voxel centres
spanning [0, 1]). Prints one JSON object per method: seconds (median of --repeat), and errors in
voxels against the analytic distance (near = |d| < 3 voxels).

Usage: python3 bench/peers_sdf.py --n 256 [--repeat 3] [--methods edt,fmm1,fmm2]
"""
import argparse
import json
import time

import numpy as np


def scene(n):
    x = np.linspace(0.0, 1.0, n)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")

    def sphere(c, r):
        return np.sqrt((X - c[0]) ** 2 + (Y - c[1]) ** 2 + (Z - c[2]) ** 2) - r

    def torus(c, R, r):
        dx, dy, dz = X - c[0], Y - c[1], Z - c[2]
        q = np.sqrt(dx * dx + dy * dy) - R
        return np.sqrt(q * q + dz * dz) - r

    def box(c, h):
        q = np.abs(np.stack([X - c[0], Y - c[1], Z - c[2]])) - np.array(h)[:, None, None, None]
        return np.linalg.norm(np.maximum(q, 0), axis=0) + np.minimum(q.max(axis=0), 0)

    return np.minimum(np.minimum(sphere((0.3, 0.3, 0.3), 0.2), torus((0.68, 0.68, 0.3), 0.17, 0.07)),
                      box((0.5, 0.55, 0.75), (0.3, 0.15, 0.12)))


def errors(d, exact, h):
    e = np.abs(d - exact) / h
    near = np.abs(exact) < 3 * h
    return {"near_mean": float(e[near].mean()), "near_max": float(e[near].max()), "all_max": float(e.max())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--methods", default="edt,fmm1,fmm2")
    a = ap.parse_args()
    n = a.n
    h = 1.0 / (n - 1)
    exact = scene(n)
    for m in a.methods.split(","):
        times = []
        for _ in range(a.repeat if m == "edt" else 1):
            if m == "edt":
                import edt
                inside = exact <= 0
                t0 = time.perf_counter()
                d = edt.sdf(inside, anisotropy=(h, h, h), parallel=1)
                times.append(time.perf_counter() - t0)
                # edt.sdf is positive inside: flip to umbra's sign (negative inside), and measure
                # to the voxel-centre boundary it represents.
                d = -d
            else:
                import skfmm
                phi = exact.copy()
                t0 = time.perf_counter()
                d = skfmm.distance(phi, dx=h, order=1 if m == "fmm1" else 2)
                times.append(time.perf_counter() - t0)
        out = {"method": m, "n": n, "seconds": float(np.median(times))}
        out.update(errors(np.asarray(d), exact, h))
        print(json.dumps(out))


if __name__ == "__main__":
    main()
