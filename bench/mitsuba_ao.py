#!/usr/bin/env python3
"""Cross-check of umbra's Monte Carlo reference against an independent renderer, Mitsuba 3
(issue 6): hemisphere ambient occlusion of tubes.

    pip install mitsuba
    target/release/umbra bench ao bench/scenes/ao_tracks.toml --spp 1024 -o DIR
    python3 bench/mitsuba_ao.py DIR [--spp 1024]

Mitsuba has no `ao` plugin, so the same quantity is rendered as what it is physically: a white
diffuse surface (reflectance 1) under a constant white environment, the `path` integrator with
`max_depth` 2 (one bounce: the environment seen directly or through one diffuse reflection),
which makes a pixel's radiance the cosine-weighted visible fraction of the sky (1 where the
ray misses the tubes). Box pixel filter, as umbra's reference jitters within the pixel.
Variant `scalar_rgb` (LLVM 15 crashes `llvm_ad_rgb`). Prints, over the pixels where the tubes are,
the mean difference, the RMSE, and the fraction of pixels within three combined standard errors (umbra's per-pixel error and
Mitsuba's, estimated from two independent half-sample renders), and writes DIR/mitsuba.csv.
"""
import argparse
import json
import math
import os

import mitsuba as mi
import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("dir")
ap.add_argument("--spp", type=int, default=1024)
a = ap.parse_args()
mi.set_variant("scalar_rgb")
cam = json.load(open(os.path.join(a.dir, "camera.json")))
w, h = cam["width"], cam["height"]


def render(seed, spp):
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 2},
        "sensor": {
            "type": "perspective",
            "fov": cam["fov_y"],
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=cam["eye"], target=cam["target"], up=cam["up"]),
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
            "film": {"type": "hdrfilm", "width": w, "height": h,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
        "tubes": {
            "type": "ply",
            "filename": os.path.join(a.dir, "tubes.ply"),
            "face_normals": False,
            "bsdf": {"type": "twosided", "bsdf": {
                "type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}}},
        },
    })
    img = mi.render(scene)
    return np.array(img)[:, :, 0]


half = max(1, a.spp // 2)
m1, m2 = render(1, half), render(2, half)
ours = np.array(mi.Bitmap(os.path.join(a.dir, "ao.exr")))  # channels Y, stderr
oy = ours[:, :, 0].astype(float)
ose = ours[:, :, 1].astype(float)
mit = (np.array(m1) + np.array(m2)) / 2
# Mitsuba's standard error from the two halves: |m1 - m2| / 2 estimates it per pixel (noisy);
# its mean over the image is used.
mse_m = float(np.mean(((np.array(m1) - np.array(m2)) / 2) ** 2))
d = mit - oy
sig = np.sqrt(ose ** 2 + mse_m)
# Over the pixels where the tubes are (either renderer sees less than open sky).
mask = (oy < 0.999) | (mit < 0.999)
d = d[mask]
sig = sig[mask]
within = float(np.mean(np.abs(d) <= 3 * sig))
rmse = float(np.sqrt(np.mean(d ** 2)))
oy, mit, ose = oy[mask], mit[mask], ose[mask]
print(f"{int(mask.sum())} tube pixels of {w}x{h}: mean umbra {oy.mean():.5f}, mean mitsuba {mit.mean():.5f}, "
      f"mean difference {d.mean():+.5f}, RMSE {rmse:.5f}, within 3 sigma {within:.3f}, "
      f"umbra stderr {ose.mean():.5f}, mitsuba stderr {math.sqrt(mse_m):.5f}")
with open(os.path.join(a.dir, "mitsuba.csv"), "w") as f:
    f.write("mean_umbra,mean_mitsuba,mean_difference,rmse,within_3_sigma,umbra_stderr,mitsuba_stderr\n")
    f.write(f"{oy.mean():.6f},{mit.mean():.6f},{d.mean():.6f},{rmse:.6f},{within:.4f},"
            f"{ose.mean():.6f},{math.sqrt(mse_m):.6f}\n")
