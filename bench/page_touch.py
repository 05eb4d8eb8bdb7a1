#!/usr/bin/env python3
"""Cost of first-touching fresh anonymous memory, with and without transparent huge pages
(docs/benchmarks.md, the sweep's "Two more" paragraph).

Usage: python3 bench/page_touch.py PATTERN   (one letter a run: h = madvise(MADV_HUGEPAGE),
       4 = plain 4 KiB pages; e.g. `hhhh` or `4h4h`). Each run maps 1 GiB, writes one byte
       every 4 KiB and prints seconds and ns a byte. The first GiB a process touches also pays
       the host's backing of the memory (a VM), so compare the later runs.
"""
import mmap
import sys
import time

N = 1 << 30
for huge in [c == "h" for c in sys.argv[1]]:
    m = mmap.mmap(-1, N, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    if huge:
        m.madvise(mmap.MADV_HUGEPAGE)
    t = time.perf_counter()
    for off in range(0, N, 4096):
        m[off] = 1
    dt = time.perf_counter() - t
    print("huge" if huge else "4k  ", f"{dt:.3f} s  {dt / N * 1e9:.2f} ns/B")
    m.close()
