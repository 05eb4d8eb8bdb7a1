"""Compare PNG images as the docs quote them (docs/gallery.md, README).

  python3 bench/image_compare.py diff A.png B.png
      mean and 99th percentile of the per-pixel mean absolute RGB difference, in 8-bit levels,
      and how many pixels differ by more than 8 levels.
  python3 bench/image_compare.py channels REF.png IMG.png [--background 255,255,255]
      per pixel the largest absolute difference over R, G and B, in 8-bit levels: its mean over
      all pixels, its mean, 99th percentile and maximum over the pixels where REF is not the
      background colour (the volume's pixels), and the share of pixels that differ at all.
  python3 bench/image_compare.py darkened REF.png IMG.png [--background 250]
      the pixels of REF darker than BACKGROUND in grey (what is drawn on a white background),
      and how many of them IMG draws at less than half REF's grey level (darkened).
  python3 bench/image_compare.py ink A.png B.png
      the ink of a dark drawing on white: the sum over pixels of (255 - grey) / 255, in pixels
      of full coverage (a 2-pixel line n pixels long holds about 2n), of A and of B, and B / A."""
import argparse
import numpy as np
from PIL import Image


def load(path, mode):
    return np.asarray(Image.open(path).convert(mode), dtype=float)


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest='what', required=True)
    d = sub.add_parser('diff')
    d.add_argument('a')
    d.add_argument('b')
    c = sub.add_parser('channels')
    c.add_argument('ref')
    c.add_argument('img')
    c.add_argument('--background', default='255,255,255')
    k = sub.add_parser('darkened')
    k.add_argument('ref')
    k.add_argument('img')
    k.add_argument('--background', type=float, default=250.0)
    i = sub.add_parser('ink')
    i.add_argument('a')
    i.add_argument('b')
    a = p.parse_args()
    if a.what == 'ink':
        x, y = ((255.0 - load(f, 'L')).sum() / 255.0 for f in (a.a, a.b))
        ratio = f'{y / x:.3f}' if x > 0 else 'undefined (A is blank)'
        print(f'ink {x:.1f} and {y:.1f} pixels; B / A = {ratio}')
        return
    if a.what == 'diff':
        x, y = load(a.a, 'RGB'), load(a.b, 'RGB')
        if x.shape != y.shape:
            raise SystemExit(f'{a.a} is {x.shape[1]} x {x.shape[0]}, {a.b} {y.shape[1]} x {y.shape[0]}')
        e = np.abs(x - y).mean(axis=2)
        print(f'mean {e.mean():.2f} levels, 99th percentile {np.percentile(e, 99):.1f}, '
              f'{int((e > 8).sum())} of {e.size} pixels differ by more than 8')
    elif a.what == 'channels':
        x, y = load(a.ref, 'RGB'), load(a.img, 'RGB')
        if x.shape != y.shape:
            raise SystemExit(f'{a.ref} and {a.img} differ in size')
        try:
            bg = np.array([float(v) for v in a.background.split(',')])
        except ValueError:
            bg = np.zeros(0)
        if bg.shape != (3,) or not np.isfinite(bg).all():
            raise SystemExit(f'--background {a.background}: three 8-bit values, R,G,B')
        e = np.abs(x - y).max(axis=2)
        vol = np.abs(x - bg).max(axis=2) > 0
        if not vol.any():
            raise SystemExit(f'{a.ref} is all background')
        print(f'mean {e.mean():.3f} levels over all pixels; over the {int(vol.sum())} volume pixels '
              f'mean {e[vol].mean():.3f}, 99th percentile {np.percentile(e[vol], 99):.0f}, '
              f'max {e.max():.0f}; {100.0 * (e > 0).mean():.1f}% of the pixels differ')
    else:
        ref, img = load(a.ref, 'L'), load(a.img, 'L')
        if ref.shape != img.shape:
            raise SystemExit(f'{a.ref} and {a.img} differ in size')
        drawn = ref < a.background
        dark = (img < 0.5 * ref) & drawn
        print(f'{int(dark.sum())} of {int(drawn.sum())} drawn pixels darkened below half')


if __name__ == '__main__':
    main()
