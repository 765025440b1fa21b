"""Seconds per generated room (room + placement + ray casting + shading + ground truth) at two sizes.

Prints per-room times at 1024x512 and 2048x1024 (single process) and the projected time of the
88-room set with one process per core. Usage: python benchmarks/bench_synth.py [--rooms 4]
"""

from __future__ import annotations

import argparse
import os
import time


def main() -> None:
    from apps.synth import make_room
    from posecrf.library import builtin_library

    ap = argparse.ArgumentParser()
    ap.add_argument("--rooms", type=int, default=4)
    args = ap.parse_args()
    lib = builtin_library()
    make_room(0, 99, 256, lib)  # warm-up: imports, Open3D
    cores = os.cpu_count() or 1
    for width in (1024, 2048):
        t = []
        for i in range(args.rooms):
            t0 = time.perf_counter()
            make_room(i, 0, width, lib)
            t.append(time.perf_counter() - t0)
        per = sum(t) / len(t)
        print(f"{width}x{width // 2}: {per:.2f} s per room (min {min(t):.2f}, max {max(t):.2f}, {len(t)} rooms); "
              f"88 rooms on {cores} cores ~ {88 * per / cores / 60:.1f} min")


if __name__ == "__main__":
    main()
