#!/usr/bin/env python3
"""Charts of issue 16's cost curves from the JSON lines the peer scripts print.

  python3 bench/plot_cost_curves.py sweep SWEEP.jsonl OUT.png
      sweep time against N^3 (log-log), umbra (closest-point) and edt per scene, from the lines
      of `bench/sweep_peers.py`;
  python3 bench/plot_cost_curves.py tubes TUBES.jsonl OUT.png
      tube time against streamline count (log-log), umbra and vtkTubeFilter, from the lines of
      `bench/tubes_peers.py`.

Needs: pip install matplotlib."""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def records(path):
    with open(path) as f:
        return [json.loads(l) for l in f if l.startswith("{")]


def sweep(rows, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for i, scene in enumerate(dict.fromkeys(r["scene"] for r in rows)):
        rs = sorted((r for r in rows if r["scene"] == scene), key=lambda r: r["n"])
        vox = [r["n"] ** 3 for r in rs]
        c = f"C{i}"
        ax.plot(vox, [r["umbra_closest-point_s"] for r in rs], "o-", color=c, label=f"umbra, {scene}")
        ax.plot(vox, [r["edt_s"] for r in rs], "s--", color=c, label=f"edt, {scene}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("voxels (N^3)")
    ax.set_ylabel("compute s (median)")
    ax.set_title("umbra sweep against edt.sdf, 2 threads")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def tubes(rows, out):
    rows = sorted(rows, key=lambda r: r["streamlines"])
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot([r["streamlines"] for r in rows], [r["umbra_s"] for r in rows], "o-", label="umbra tubes")
    v = [r for r in rows if r.get("vtk_s") is not None]
    ax.plot([r["streamlines"] for r in v], [r["vtk_s"] for r in v], "s--", label="vtkTubeFilter")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("streamlines (100 points each)")
    ax.set_ylabel("compute s (median)")
    ax.set_title("tubes against vtkTubeFilter (8 sides)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main():
    if len(sys.argv) != 4 or sys.argv[1] not in ("sweep", "tubes"):
        sys.exit(__doc__)
    what, src, out = sys.argv[1:]
    (sweep if what == "sweep" else tubes)(records(src), out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
