"""How well an outline predicts a library model's image extent: the convex hull against the mesh outline.

Run::

    .venv/bin/python benchmarks/eval_outline.py [--views 200] [--points 100]

For every model of the builtin library, the image extent (leftmost, rightmost, highest and lowest pixel of a
1024x512 panorama) of its convex hull's points (:func:`layout.sampler.hull_outline`, 400 points as in the box fits
and ``--points`` as in the model choice) and of its mesh outline (:func:`layout.sampler.mesh_outline`,
``--points`` points) is compared with
that of the whole surface (the mesh's edges sampled every centimetre: a face's extreme point from a camera lies on
its boundary), from ``--views`` random viewpoints: camera 0.9-2.4 m above the floor, 0.2-5 m outside the
footprint's bounding circle, any azimuth. Printed per class: the mean and the largest pixel error over the models
and views, and the seconds :func:`~layout.sampler.mesh_outline` takes per model (the pipeline stores each
model's outline in the model-library cache folder, so a run computes it once per machine).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import numpy as np

from layout.sampler import _outline_frame, _points_along, _triangle_edges, _wrap, hull_outline, mesh_outline
from panogeom.coords import world_to_pixel, xy_to_lon
from posecrf.library import builtin_library

W, H = 1024, 512


def _surface(vertices: np.ndarray, faces: np.ndarray, spacing: float = 0.01) -> np.ndarray:
    """The mesh's vertices and its edges sampled every ``spacing`` metres, in the outline's frame."""
    v = _outline_frame(np.asarray(vertices, dtype=np.float64))
    e = _triangle_edges(np.asarray(faces))
    a, b = v[e[:, 0]], v[e[:, 1]]
    return np.concatenate([v, _points_along(a, b, np.ceil(np.linalg.norm(b - a, axis=1) / spacing).astype(int))])


def _extent(points: np.ndarray, offset: np.ndarray, cam: float) -> np.ndarray:
    """(4,) left, top, right, bottom pixel of ``points`` moved by ``offset``, seen from ``cam`` m up."""
    p = points + offset
    uv = world_to_pixel(p, W, H, camera_height=cam)
    # columns relative to the object's direction (no seam inside an object's extent)
    u = _wrap(xy_to_lon(p[:, :2]) - xy_to_lon(offset[:2])) * W / (2 * np.pi)
    return np.array([u.min(), uv[:, 1].min(), u.max(), uv[:, 1].max()])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--views", type=int, default=200, help="random viewpoints per model")
    ap.add_argument("--points", type=int, default=100, help="mesh outline budget (the model choice's is 100)")
    args = ap.parse_args(argv)

    rng = np.random.default_rng(0)
    err: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    seconds: dict[str, list[float]] = defaultdict(list)
    for m in builtin_library():
        t0 = time.perf_counter()
        mesh = mesh_outline(m.vertices, m.faces, max_points=args.points)
        seconds[m.cls].append(time.perf_counter() - t0)
        hull, hull_small = hull_outline(m.vertices), hull_outline(m.vertices, max_points=args.points)
        surf = _surface(m.vertices, m.faces)
        reach = 0.5 * float(np.hypot(*m.size[:2]))
        for _ in range(args.views):
            cam = rng.uniform(0.9, 2.4)
            d, az = reach + rng.uniform(0.2, 5.0), rng.uniform(0.0, 2 * np.pi)
            off = np.array([d * np.cos(az), d * np.sin(az), 0.0])
            ref = _extent(surf, off, cam)
            for name, pts in (("hull", hull), ("hull_small", hull_small), ("mesh", mesh)):
                err[m.cls][name].append(float(np.abs(_extent(pts, off, cam) - ref).max()))
    print(f"{args.views} random views per model, {W}x{H}; largest of the four edges' errors, pixels, mean / max")
    print(f"| class | models | hull, 400 points | hull, {args.points} points | mesh outline, {args.points} points "
          "| mesh outline s per model |")
    print("|---|---:|---:|---:|---:|---:|")
    names = ("hull", "hull_small", "mesh")
    for c in sorted(err):
        cells = " | ".join(f"{np.mean(err[c][k]):.2f} / {np.max(err[c][k]):.1f}" for k in names)
        print(f"| {c} | {len(seconds[c])} | {cells} | {np.mean(seconds[c]):.3f} |")
    cells = " | ".join(f"{np.mean(np.concatenate([e[k] for e in err.values()])):.2f} / "
                       f"{np.max(np.concatenate([e[k] for e in err.values()])):.1f}" for k in names)
    print(f"| all | {sum(len(s) for s in seconds.values())} | {cells} | "
          f"{np.mean(np.concatenate(list(seconds.values()))):.3f} |")


if __name__ == "__main__":
    main()
