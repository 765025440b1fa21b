"""Time the context prior (layout.context) on a batch of hypotheses.

Scene: a 10-wall room, 8 objects placed by layout.placement. Hypotheses:
B = 3000 draws from the paper's sampling distributions around that scene
(Sec. 4: position variance 0.1 x camera distance along the camera-object
direction and 0.005 x distance across it, yaw variance 0.1 rad^2), plus a
dense worst case (uniform positions and yaws: many overlapping pairs).

Prints: vectorised time per batch (median of repeats), the time of a
per-hypothesis Python loop over the same function, their ratio, and the
time of one place_objects call.

Run: ``.venv/bin/python benchmarks/bench_context.py [--batch 3000] [--repeats 30]``
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from layout.context import context_energy
from layout.placement import ObjectSpec, place_objects
from layout.polygon import validate_floor_polygon
from layout.rooms import Room

# 10 walls: an L-shaped room with a closet notch
FLOOR = np.array(
    [[0, 0], [6.2, 0], [6.2, 2.4], [4.0, 2.4], [4.0, 5.1], [2.3, 5.1], [2.3, 4.5], [1.1, 4.5], [1.1, 5.1], [0, 5.1]],
    float,
)
SPECS = [
    ObjectSpec("bed", (2.05, 1.6, 0.55), "bed"),
    ObjectSpec("wardrobe", (0.6, 1.5, 2.0), "wardrobe"),
    ObjectSpec("sofa", (0.9, 2.0, 0.85), "sofa"),
    ObjectSpec("tv", (0.25, 1.1, 0.7), "tv"),
    ObjectSpec("nightstand", (0.4, 0.45, 0.55), "nightstand"),
    ObjectSpec("chair", (0.5, 0.5, 0.9), "chair-0"),
    ObjectSpec("chair", (0.5, 0.5, 0.9), "chair-1"),
    ObjectSpec("plant", (0.4, 0.4, 0.9), "plant", symmetric=True),
]


def _median_time(fn, repeats: int) -> tuple[float, float]:
    """Median wall-clock and median process CPU time of ``fn()`` in seconds
    (CPU time is the fairer figure on a machine shared with other jobs)."""
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall)), float(np.median(cpu))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--batch", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    floor = validate_floor_polygon(FLOOR)
    room = Room(floor, 2.7, "bench", floor, np.zeros(len(floor)), np.zeros(len(floor), bool))
    t_place, cpu_place = _median_time(lambda: place_objects(room, SPECS, args.seed), 5)
    pl = place_objects(room, SPECS, args.seed)
    assert len(pl.objects) == 8, pl.dropped
    c0, y0 = pl.centers[:, :2], pl.yaws
    sizes = np.array([o.size[:2] for o in pl.objects])
    n_o, b = len(c0), args.batch
    rng = np.random.default_rng(args.seed)

    # the paper's proposal distributions around the placed scene
    ray = c0 - pl.camera_xy
    dist = np.linalg.norm(ray, axis=1)
    along = ray / dist[:, None]
    across = np.stack([-along[:, 1], along[:, 0]], axis=1)
    z_a = rng.normal(size=(b, n_o)) * np.sqrt(0.1 * dist)
    z_c = rng.normal(size=(b, n_o)) * np.sqrt(0.005 * dist)
    c_paper = c0 + z_a[..., None] * along + z_c[..., None] * across
    y_paper = y0 + rng.normal(size=(b, n_o)) * np.sqrt(0.1)
    # dense worst case
    lo, hi = floor.min(0), floor.max(0)
    c_dense = rng.uniform(lo, hi, size=(b, n_o, 2))
    y_dense = rng.uniform(0, 2 * np.pi, size=(b, n_o))

    modes = ["facing", "facing", "facing", "facing", "facing", "parallel", "parallel", "parallel"]
    opts = dict(alignment=modes, alignment_weights=[1, 1, 1, 1, 1, 1, 1, 0])

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# context prior benchmark: numpy {np.__version__}, python {platform.python_version()}, "
        f"{os.cpu_count()} CPU(s), {platform.machine()}, load average {load:.1f}"
    )
    print(f"room walls: {len(floor)}, objects: {n_o}, hypotheses: {b}, repeats: {args.repeats}")
    for name, c, y in (("paper proposals", c_paper, y_paper), ("dense uniform", c_dense, y_dense)):
        context_energy(c, y, sizes, floor, **opts)  # warm-up
        t_vec, cpu_vec = _median_time(lambda: context_energy(c, y, sizes, floor, **opts), args.repeats)
        e_vec = context_energy(c, y, sizes, floor, **opts).total
        t0, cpu0 = time.perf_counter(), time.process_time()
        e_loop = np.array([float(context_energy(c[i], y[i], sizes, floor, **opts).total) for i in range(b)])
        t_loop, cpu_loop = time.perf_counter() - t0, time.process_time() - cpu0
        assert np.allclose(e_vec, e_loop)
        overlap_frac = float(np.mean(context_energy(c, y, sizes, floor, **opts).overlap > 0))
        print(
            f"{name:16s}: vectorised {t_vec * 1e3:6.1f} ms wall / {cpu_vec * 1e3:6.1f} ms CPU per batch "
            f"({cpu_vec / b * 1e6:5.2f} us CPU / hypothesis); per-hypothesis loop {t_loop * 1e3:7.0f} ms wall / "
            f"{cpu_loop * 1e3:7.0f} ms CPU; speed-up x{cpu_loop / cpu_vec:5.1f} (CPU); "
            f"hypotheses with overlap {overlap_frac:.0%}"
        )
    print(
        f"place_objects (8 objects, 8 epochs x 25 samples, camera): {t_place * 1e3:.0f} ms wall / "
        f"{cpu_place * 1e3:.0f} ms CPU (median of 5)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
