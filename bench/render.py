#!/usr/bin/env python3
"""The renderer benchmark of docs/benchmarks.md: every method on one scene at equal slices and
resolution, in one run, with the per-pass breakdown and the ratio to emission-absorption.

    python3 bench/render.py [--scene datasets/scenes/demo.toml] [--size 512x512] [--slices 512]
                            [--frames 5] [--cells 2,4] [--rounds 2]

Each configuration runs `umbra render --frames N --timings-json`; total_ms is the median frame
(submit to completion, scene loading and file output excluded). Methods are interleaved over
`--rounds` rounds (machines are shared and noisy) and each configuration's best round median is
reported with the spread of its round medians. Prints a markdown table.
"""
import argparse
import json
import os
import platform
import subprocess
import tempfile

ap = argparse.ArgumentParser()
ap.add_argument("--scene", default="datasets/scenes/demo.toml")
ap.add_argument("--size", default="512x512")
ap.add_argument("--slices", type=int, default=512)
ap.add_argument("--frames", type=int, default=5)
ap.add_argument("--cells", default="2,4")
ap.add_argument("--rounds", type=int, default=2)
ap.add_argument("--methods", default="ea,phong,vicinity,dos,combined")
ap.add_argument("--set", action="append", default=[], help="scene overrides for every run")
a = ap.parse_args()
root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
os.chdir(root)
subprocess.run(["cargo", "build", "--release", "-q"], check=True)
w, h = a.size.split("x")
configs = []
for m in a.methods.split(","):
    if m in ("dos", "combined"):
        configs += [(m, int(c)) for c in a.cells.split(",")]
    else:
        configs.append((m, None))
results = {c: [] for c in configs}
failed = {}
passes = {}
adapter = ""
with tempfile.TemporaryDirectory() as d:
    for _ in range(a.rounds):
        for m, cell in configs:
            t = os.path.join(d, "t.json")
            cmd = ["target/release/umbra", "render", a.scene, "-o", os.path.join(d, "o.png"),
                   "--width", w, "--height", h, "--method", m, "--frames", str(a.frames),
                   "--timings-json", t, "--set", f"render.slices={a.slices}"]
            if cell:
                cmd += ["--set", f"render.occlusion_cell={cell}"]
            for o in a.set:
                cmd += ["--set", o]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                failed[(m, cell)] = r.stderr.strip().splitlines()[-1]
                continue
            j = json.load(open(t))
            results[(m, cell)].append(j["total_ms"])
            if j["total_ms"] <= min(results[(m, cell)]):
                passes[(m, cell)] = j["passes"]
            adapter = j["adapter"]
cpu = ""
try:
    cpu = [l.split(":")[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")][0]
except Exception:
    pass
print(f"machine: {os.cpu_count()} cores, {cpu}; adapter: {adapter}; {platform.system()}")
print(f"scene: {a.scene}, {a.size}, {a.slices} slices, median of {a.frames} frames, "
      f"best of {a.rounds} rounds{', --set ' + ' '.join(a.set) if a.set else ''}\n")
ea = min(results[("ea", None)]) if ("ea", None) in results else None
print("| method | cell | total ms (best round median) | round medians | x E/A | passes (ms, by GPU timestamps where the adapter has them: the report's pass_clock) |")
print("|---|---|---|---|---|---|")
for c in configs:
    if not results[c]:
        print(f"| {c[0]} | {c[1] or '-'} | - | - | - | {failed.get(c, 'failed')} |")
        continue
    best = min(results[c])
    ratio = f"{best / ea:.2f}" if ea else "-"
    p = ", ".join(f"{k} {v:.0f}" for k, v in sorted(passes[c].items()))
    print(f"| {c[0]} | {c[1] or '-'} | {best:.0f} | {', '.join(f'{x:.0f}' for x in results[c])} | {ratio} | {p} |")
