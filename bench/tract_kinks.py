"""Sharp turns (more than 100 degrees at a point, as `tubes::tube_mesh` calls them) in a
tractogram: how many, on how many lines, how far from a line's end, and the hooks - a line's
first or last segment doubling back - with their lengths (docs/benchmarks.md, "A fit weighed
against its polyline's rings").

    python3 bench/tract_kinks.py FILE.trk.gz   (nibabel reads .trk, .tck, .trx)"""
import sys

import numpy as np


def main():
    import nibabel as nib
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    lines = nib.streamlines.load(sys.argv[1]).streamlines
    turns, with_turn, ends, hooked, hook_len = 0, 0, [], 0, []
    for line in lines:
        p = np.asarray(line, float)
        keep = np.r_[True, np.linalg.norm(np.diff(p, axis=0), axis=1) > 1e-9]
        p = p[keep]
        if len(p) < 3:
            continue
        a, b = p[1:-1] - p[:-2], p[2:] - p[1:-1]
        cos = (a * b).sum(1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        at = np.nonzero(cos < -0.17)[0] + 1
        turns += len(at)
        with_turn += len(at) > 0
        ends += [min(i, len(p) - 1 - i) for i in at]
        hooks = [np.linalg.norm(p[1] - p[0])] if cos[0] < -0.17 else []
        hooks += [np.linalg.norm(p[-1] - p[-2])] if cos[-1] < -0.17 else []
        hooked += len(hooks) > 0
        hook_len += hooks
    print(f"{len(lines)} lines; {turns} sharp turns on {with_turn} of them, "
          f"median {np.median(ends) if ends else 0:g} points from the nearest end")
    if hook_len:
        print(f"{hooked} lines end in a hook, {min(hook_len):.2f}-{max(hook_len):.2f} long")


if __name__ == "__main__":
    main()
