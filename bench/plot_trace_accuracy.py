#!/usr/bin/env python3
"""Chart of docs/accuracy.md: tracer error against step size, from the CSV that
`cargo run --release -p umbra --example trace_accuracy > docs/data/trace_accuracy.csv` writes.
Usage: python3 bench/plot_trace_accuracy.py docs/data/trace_accuracy.csv docs/images/trace_accuracy.png
Needs: pip install matplotlib."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

rows = list(csv.DictReader(open(sys.argv[1])))
fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))


def series(method, case):
    r = [x for x in rows if x["method"] == method and x["case"] == case]
    return [float(x["mean_step"]) for x in r], [float(x["error"]) for x in r]


for m, style in [("euler", "o-"), ("rk4", "s-")]:
    h, e = series(m, "rotation")
    ax[0].loglog(h, e, style, label="Euler" if m == "euler" else "RK4")
h, e = series("rk45", "rotation")
ax[0].loglog(h[:1], e[:1], "^", ms=9, label="RK45 (any tolerance 1e-2..1e-7, step cap 0.1)")
hs = [0.2, 0.00625]
ax[0].loglog(hs, [0.9 * x for x in hs], "k:", lw=0.8, label="slope 1")
ax[0].loglog(hs[:1] + [0.03], [1.3e-4, 1.3e-4 * (0.03 / 0.2) ** 4], "k--", lw=0.8, label="slope 4")
ax[0].set_title("Rigid rotation (linear field, exact interpolation):\nlargest radius error over one turn, r = 0.5")
ax[0].set_xlabel("mean step (world units)")
ax[0].set_ylabel("error")
ax[0].legend(fontsize=8)
for n, c in [(32, "C0"), (64, "C1"), (128, "C2")]:
    h, e = series("euler", f"abc{n}")
    ax[1].loglog(h, e, "o:", color=c, label=f"Euler, {n}^3 grid")
    h, e = series("rk4", f"abc{n}")
    ax[1].loglog(h, e, "s-", color=c, label=f"RK4, {n}^3 grid")
ax[1].set_title("ABC flow sampled on a grid: end-point error after\narc length 2.5 against the analytic field")
ax[1].set_xlabel("mean step (world units)")
ax[1].legend(fontsize=8)
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=110)
