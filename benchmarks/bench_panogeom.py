"""Benchmark panogeom's cubemap and perspective resampling against py360convert.

Both libraries run in the same process on the same 2048x1024 uint8 panorama,
with the same output sizes and bilinear interpolation:

- equirect -> cubemap, 6 faces of 512 x 512 ("list" layout);
- cubemap (512) -> equirect 2048 x 1024;
- equirect -> perspective, 1024 x 768, 90 degree horizontal FOV.

"cold" is the first call (it builds and caches the sampling maps; both
libraries cache them per geometry), "warm" the median of repeated calls. The
script also measures accuracy: the equirect -> cubemap -> equirect round trip
and the agreement of the two libraries' outputs (mean absolute difference in
grey levels, outside 10 degrees of the poles for whole panoramas).

Usage::

    python benchmarks/bench_panogeom.py [--repeat N] [--update-docs]

``--update-docs`` writes the figures into the section
"## panogeom: cubemap and perspective" of docs/BENCHMARKS.md (only that
section is replaced; the file is re-read just before writing).
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from panogeom.cubemap import cubemap_to_equirect, equirect_to_cubemap  # noqa: E402
from panogeom.perspective import PinholeView, equirect_to_perspective  # noqa: E402
from panogeom.rotation import ypr_to_matrix  # noqa: E402
from panogeom.transform import procedural_pano, rotate_pano  # noqa: E402

SECTION = "## panogeom: cubemap and perspective"
DOCS = ROOT / "docs" / "BENCHMARKS.md"


def _once(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def timed_pair(ours, peer, repeat):
    """Cold (first) call of each, then ``repeat`` warm calls alternating the two (fair under load)."""
    out_a, cold_a = _once(ours)
    out_b, cold_b = _once(peer)
    warm_a, warm_b = [], []
    for _ in range(repeat):
        warm_a.append(_once(ours)[1])
        warm_b.append(_once(peer)[1])
    return out_a, out_b, cold_a, statistics.median(warm_a), cold_b, statistics.median(warm_b)


def mad(a, b, rows=None):
    d = np.abs(np.asarray(a, float) - np.asarray(b, float))
    return float(d[rows].mean() if rows is not None else d.mean())


def run(repeat: int) -> tuple[list[tuple], list[tuple], dict]:
    try:
        import py360convert as p3
    except ImportError:  # the peer is a test extra
        sys.exit("bench_panogeom needs py360convert (pip install -e '.[test]')")
    import cv2

    H, S = 1024, 512
    pano = procedural_pano(H)
    lat = 90.0 - 180.0 * (np.arange(H) + 0.5) / H
    rows = np.abs(lat) < 80.0

    view = PinholeView(0.0, 0.0, 0.0, np.radians(90.0), 1024, 768)
    vfov_deg = float(np.degrees(2 * np.arctan(np.tan(view.fov / 2) * view.height / view.width)))

    timings = []
    ours_c, p3_c, *t = timed_pair(lambda: equirect_to_cubemap(pano, S),
                                  lambda: p3.e2c(pano, S, "bilinear", "list"), repeat)
    timings.append(("equirect -> cubemap (6 x 512^2)", *t))
    ours_e, p3_e, *t = timed_pair(lambda: cubemap_to_equirect(ours_c, H),
                                  lambda: p3.c2e(p3_c, H, 2 * H, "bilinear", "list"), repeat)
    timings.append(("cubemap (512) -> equirect 2048x1024", *t))
    ours_p, p3_p, *t = timed_pair(lambda: equirect_to_perspective(pano, view),
                                  lambda: p3.e2p(pano, (90.0, vfov_deg), 0.0, 0.0, (768, 1024)), repeat)
    timings.append(("equirect -> perspective 1024x768, 90 deg", *t))

    R = ypr_to_matrix(0.4, -0.2, 0.1)
    _, r_cold = _once(lambda: rotate_pano(pano, R))
    r_warm = statistics.median(_once(lambda: rotate_pano(pano, R))[1] for _ in range(max(1, repeat // 4)))
    timings.append(("rotate_pano 2048x1024 (no peer)", r_cold, r_warm, None, None))

    accuracy = [
        ("round trip equirect -> cubemap -> equirect, pano2cad", mad(ours_e, pano, rows)),
        ("round trip equirect -> cubemap -> equirect, py360convert", mad(p3_e, pano, rows)),
        ("cubemap faces, pano2cad vs py360convert",
         float(np.mean([mad(a, b) for a, b in zip(ours_c, p3_c)]))),
        ("perspective view, pano2cad vs py360convert", mad(ours_p, p3_p)),
    ]
    env = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
        "py360convert": getattr(p3, "__version__", "?"),
        "cpus": os.cpu_count(),
        "cv2_threads": cv2.getNumThreads(),
        "repeat": repeat,
        "load average (1 min) at the end": round(os.getloadavg()[0], 1),
    }
    return timings, accuracy, env


def render(timings, accuracy, env) -> str:
    lines = [
        SECTION,
        "",
        "`python benchmarks/bench_panogeom.py --update-docs` (this section is written by the script). "
        "Same process, same 2048x1024 uint8 procedural panorama, same output sizes, bilinear. "
        "Cold = first call (builds and caches the sampling maps, as both libraries do); "
        f"warm = median of {env['repeat']} calls, alternating the two libraries. Ratio = py360convert time / pano2cad time (> 1: pano2cad faster).",
        "",
        "| operation | pano2cad cold ms | pano2cad warm ms | py360convert cold ms | py360convert warm ms "
        "| ratio warm | ratio cold |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, oc, ow, pc, pw in timings:
        if pc is None:
            lines.append(f"| {name} | {oc * 1e3:.1f} | {ow * 1e3:.1f} | - | - | - | - |")
        else:
            lines.append(f"| {name} | {oc * 1e3:.1f} | {ow * 1e3:.1f} | {pc * 1e3:.1f} | {pw * 1e3:.1f} "
                         f"| {pw / ow:.2f} | {pc / oc:.2f} |")
    lines += ["", "| accuracy (mean absolute difference, grey levels; panoramas: outside 10 deg of the poles) | value |",
              "|---|---:|"]
    lines += [f"| {name} | {val:.3f} |" for name, val in accuracy]
    lines += ["", "Environment: " + ", ".join(f"{k} {v}" for k, v in env.items()) + ".", ""]
    return "\n".join(lines)


def update_docs(section: str) -> None:
    """Replace our section of docs/BENCHMARKS.md (benchmarks/_docs.py)."""
    replace_section(DOCS, section, SECTION)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--repeat", type=int, default=20, help="warm calls per operation")
    ap.add_argument("--update-docs", action="store_true", help=f"write the figures into {DOCS.relative_to(ROOT)}")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error(f"--repeat: expected a positive integer, got {args.repeat}")
    timings, accuracy, env = run(args.repeat)
    section = render(timings, accuracy, env)
    print(section)
    slower = [name for name, _, ow, _, pw in timings if pw is not None and ow > pw]
    if args.update_docs:
        update_docs(section)
        print(f"wrote section {SECTION!r} of {DOCS}")
    if slower:
        print("pano2cad is slower than py360convert on: " + "; ".join(slower), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
