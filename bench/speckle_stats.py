"""Grain and black of a render's covered pixels (docs/accuracy.md, "Black speckle on dense tubes
is the sum"): for each PNG, over the pixels darker than 254 in grey (the white background left
out): the mean grey, the high-frequency part (mean absolute difference from a 3 x 3 box blur of
the grey image) and the share darker than 30 of 255.
usage: python3 bench/speckle_stats.py A.png [B.png ...]   (needs numpy, pillow, scipy)"""
import sys

import numpy as np
from PIL import Image
from scipy.ndimage import uniform_filter

for path in sys.argv[1:]:
    g = np.asarray(Image.open(path).convert("L")).astype(float)
    covered = g < 254
    hf = np.abs(g - uniform_filter(g, 3))[covered]
    print(f"{path}: covered {covered.sum()}, mean grey {g[covered].mean():.1f}, "
          f"high-frequency part {hf.mean():.2f}, darker than 30 {100 * (g[covered] < 30).mean():.1f}%")
