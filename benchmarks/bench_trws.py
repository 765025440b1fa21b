"""Benchmark of posecrf.trws on the paper's pose CRF size.

Problem (Sec. 3.2 / 4 of the paper): 400 nodes, 360 labels = 72 yaw x 5 pitch
bins (yaw cyclic, 5 and 11.25 degree steps), truncated L1 pose distance with
gamma = 20 degrees, edges to the k = 6 nearest neighbours of random points,
random unaries and edge weights, 100 TRW-S iterations (no early stop).

Printed: first-call times (compile with an empty numba cache, and load from
the cache), the 100-iteration time of ``trws`` (single thread; min and
median of the repeats), and the peer ``trws_naive`` (dense O(L^2) messages,
plain numpy) timed on fewer iterations and extrapolated per iteration, with
the ratio. Also checks that the two agree. The machine's load average is
printed: on a shared machine the times grow with it.

Run:  .venv/bin/python benchmarks/bench_trws.py [--repeat 5] [--peer-iters 2]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from posecrf.mrf import LabelGrid, PairwiseMRF, knn_edges  # noqa: E402
from posecrf.trws import backend, trws, trws_naive  # noqa: E402

N_NODES, K, ITERS = 400, 6, 100


def build(seed: int = 0) -> PairwiseMRF:
    rng = np.random.default_rng(seed)
    grid = LabelGrid((72, 5), (np.deg2rad(5.0), np.deg2rad(11.25)), (True, False))
    mrf = PairwiseMRF(rng.uniform(0.0, 1.0, (N_NODES, grid.size)))
    pairs = knn_edges(rng.uniform(0.0, 1.0, (N_NODES, 2)), K)
    mrf.add_grid_edges(pairs, grid, rng.uniform(0.0, 1.0, len(pairs)), gamma=np.deg2rad(20.0))
    return mrf


def first_call_seconds(cold: bool) -> tuple[float, float]:
    """Wall and CPU seconds of the first trws call in a fresh interpreter (cold: empty numba cache)."""
    code = (
        "import time, sys; sys.path.insert(0, %r)\n"
        "from benchmarks.bench_trws import build\n"
        "from posecrf.trws import trws\n"
        "m = build(); t, c = time.perf_counter(), time.process_time(); trws(m, max_iter=1)\n"
        "print(time.perf_counter() - t, time.process_time() - c)\n"
    ) % ROOT
    env = dict(os.environ)
    with tempfile.TemporaryDirectory() as tmp:
        if cold:
            env["NUMBA_CACHE_DIR"] = tmp
        out = subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True, text=True)
    wall, cpu = out.stdout.strip().splitlines()[-1].split()
    return float(wall), float(cpu)


def timed(fn, repeat: int) -> tuple[list[float], list[float]]:  # type: ignore[no-untyped-def]
    """Wall-clock and CPU seconds of each of ``repeat`` calls."""
    wall, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed repeats of the 100-iteration run")
    ap.add_argument("--peer-iters", type=int, default=2, help="iterations of the O(L^2) peer (extrapolated)")
    args = ap.parse_args(argv)

    mrf = build()
    print(f"problem: {mrf.n_nodes} nodes, {mrf.n_edges} edges, 360 labels (72 yaw x 5 pitch), "
          f"kNN k={K}, gamma=20 deg, {ITERS} iterations")
    print(f"machine: {os.cpu_count()} cores, load average before {os.getloadavg()[0]:.2f}; backend {backend()}")

    cold = first_call_seconds(cold=True)
    trws(mrf, max_iter=1)  # fills the regular cache for this process
    warm = first_call_seconds(cold=False)
    print(f"first call (1 iteration): {cold[0]:.2f} s wall / {cold[1]:.2f} s CPU with an empty numba cache "
          f"(compile), {warm[0]:.2f} s wall / {warm[1]:.2f} s CPU with the cache (load)")

    ref = trws(mrf, max_iter=ITERS, tol=None)
    t1, c1 = timed(lambda: trws(mrf, max_iter=ITERS, tol=None), args.repeat)
    print(f"trws: {ITERS} iterations in {min(t1):.3f} s wall (min of {args.repeat}; median {np.median(t1):.3f} s), "
          f"{1e3 * min(t1) / ITERS:.2f} ms/iteration; CPU time min {min(c1):.3f} s")
    print(f"  energy {ref.energy:.6f}, lower bound {ref.lower_bound:.6f}, gap {ref.gap:.6f} "
          f"({100 * ref.gap / abs(ref.energy):.2f} %)")

    t, c = time.perf_counter(), time.process_time()
    peer = trws_naive(mrf, max_iter=args.peer_iters, tol=None)
    tp, cp = time.perf_counter() - t, time.process_time() - c
    per_iter, per_iter_cpu = tp / args.peer_iters, cp / args.peer_iters
    agree = np.allclose(peer.lower_bounds, ref.lower_bounds[: args.peer_iters], rtol=1e-10, atol=1e-9)
    print(f"peer trws_naive (dense O(L^2) messages, numpy): {tp:.2f} s wall, {cp:.2f} s CPU for {args.peer_iters} "
          f"iterations -> extrapolated to {ITERS}: {per_iter * ITERS:.1f} s wall, {per_iter_cpu * ITERS:.1f} s CPU")
    print(f"  peer bounds equal trws's over those iterations: {agree}")
    best = min(t1)
    print(f"speed-up vs peer (extrapolated per iteration): {per_iter * ITERS / best:.0f}x wall, "
          f"{per_iter_cpu * ITERS / min(c1):.0f}x CPU")
    print(f"target < 1 s for {ITERS} iterations: {'met' if best < 1.0 else 'NOT met'} ({best:.3f} s wall, "
          f"{min(c1):.3f} s CPU); load average after {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
