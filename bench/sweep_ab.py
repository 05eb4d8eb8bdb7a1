#!/usr/bin/env python3
"""Two `umbra` builds' `umbra sweep` against each other, in one run: `seconds.compute` of
`umbra sweep --json` (initialisation + distance + the eight octants; with `--sdf-only` the
distance alone), median of REPEAT runs each, the two builds alternating (first A then B, then B
then A: this machine's speed drifts by tens of percent within minutes), on the scenes of
bench/sweep_peers.py (three-solids, gyroid, mni-wm) at N^3.

    python3 bench/sweep_ab.py OLD_UMBRA NEW_UMBRA [--n 256] [--repeat 5] [--sdf-only]

Prints one line per scene: both medians and NEW / OLD. Needs what bench/sweep_peers.py needs
(numpy, scipy, nibabel for the MNI white matter)."""
import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import sweep_peers  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--n", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--sdf-only", action="store_true")
    ap.add_argument("--scenes", default="three-solids,gyroid,mni-wm")
    a = ap.parse_args()
    extra = ["--sdf-only"] if a.sdf_only else []
    with tempfile.TemporaryDirectory() as tmp:
        for name in a.scenes.split(","):
            path, iso, _, _ = sweep_peers.scene(name, a.n, tmp)
            times = {"old": [], "new": []}
            for r in range(a.repeat):
                for which in (["old", "new"] if r % 2 == 0 else ["new", "old"]):
                    out = subprocess.run(
                        [getattr(a, which), "sweep", str(path), "--iso", repr(iso), "-o",
                         str(Path(tmp) / "d.nrrd"), "--json"] + extra,
                        capture_output=True, text=True, check=True)
                    times[which].append(json.loads(out.stdout)["seconds"]["compute"])
            o, n = statistics.median(times["old"]), statistics.median(times["new"])
            print(f"{name} {a.n}^3{' sdf-only' if a.sdf_only else ''}: old {o:.3f} s, "
                  f"new {n:.3f} s, new/old {n / o:.3f}", flush=True)


if __name__ == "__main__":
    main()
