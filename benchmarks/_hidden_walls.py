"""Which walls of a synthetic room its panorama shows, and whether the view shows the room's corner count.

Used by ``eval_layout_labels.py --hidden``. The synthetic engine writes, beside each room's ``labels.png``, a
``depth.png`` (millimetres along each pixel's ray). Lifted with it, every floor, ceiling, wall and object pixel is a
3D point of the room; a wall of the true polygon is *seen* when wall pixels of its orientation lie on it in at least
``min_columns`` image columns (:func:`seen_walls`).

A run of two or more consecutive walls that no pixel shows is a part of the room the camera does not see (an arm of
a U behind a wall, a recess behind a wardrobe). The view then may not decide how many corners the room has:
:func:`fewer_wall_polygons` replaces the run with fewer walls (two perpendicular neighbours extended to meet, two
parallel ones joined by one wall, or a run of four by two), the new walls at the coordinates of the run's corners or
midway between them, and :func:`explains_view` tests whether such a polygon accounts for every pixel as well as the
true one does: every point inside it, every wall point on its boundary, every point reached from the camera without
crossing one of its walls. Where one does, no method that reads the image alone can know the corner count
(:func:`corner_count_shown` is False). The candidates are a finite set, so the rooms found are a lower bound of
those whose view leaves the count open.

Convention: world frame of shared/CONVENTIONS.md, camera at (0, 0, camera_height); polygons (K, 2) counter-
clockwise without a repeated closing vertex, wall ``i`` from vertex ``i`` to ``i + 1``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Iterator

import numpy as np
from numpy.typing import ArrayLike, NDArray

from layout.labelmap import WALL_X, WALL_Y
from layout.polygon import distance_to_boundary, is_simple, points_in_polygon, signed_area
from panogeom.coords import pixel_grid_rays

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ViewPoints:
    """Pixels of a panorama lifted to the floor plan (x, y in metres, camera at the origin).

    Attributes
    ----------
    inside : (N, 2) float
        Every floor, ceiling, wall and object pixel: all lie inside the room.
    wall : (M, 2) float
        The wall pixels (labels 3 and 4), a subset of ``inside``.
    wall_label : (M,) uint8
        3 (wall facing +-x) or 4 (facing +-y).
    wall_column : (M,) int
        Image column of each wall pixel.
    """

    inside: FloatArray
    wall: FloatArray
    wall_label: NDArray[np.uint8]
    wall_column: NDArray[np.intp]


def lift_view(labels: ArrayLike, depth_mm: ArrayLike, *, step: int = 2) -> ViewPoints:
    """Lift every ``step``-th pixel of an (H, W) label map with its depth (mm along the ray) to the floor plan."""
    lab = np.asarray(labels)
    h, w = lab.shape
    rays = pixel_grid_rays(w, h).reshape(h, w, 3)[::step, ::step]
    lab = lab[::step, ::step]
    pts = (rays * (np.asarray(depth_mm, float)[::step, ::step, None] / 1000.0))[..., :2]
    cols = np.broadcast_to(np.arange(0, w, step), lab.shape)
    room = (lab >= 1) & (lab <= 5)
    wall = (lab == WALL_X) | (lab == WALL_Y)
    return ViewPoints(inside=pts[room], wall=pts[wall], wall_label=lab[wall].astype(np.uint8),
                      wall_column=cols[wall].astype(np.intp))


def seen_walls(polygon: ArrayLike, view: ViewPoints, *, tol: float = 0.05, min_columns: int = 2) -> NDArray[np.bool_]:
    """(K,) True for each wall of ``polygon`` on which wall pixels of its orientation lie (within ``tol`` metres)
    in at least ``min_columns`` image columns."""
    p = np.asarray(polygon, float)
    q = np.roll(p, -1, axis=0)
    out = np.zeros(len(p), bool)
    for i, (a, b) in enumerate(zip(p, q)):
        along = 0 if abs(b[0] - a[0]) > abs(b[1] - a[1]) else 1  # the coordinate that runs along the wall
        label = WALL_Y if along == 0 else WALL_X  # a wall along x faces +-y
        lo, hi = sorted((a[along], b[along]))
        pt = view.wall
        on = ((view.wall_label == label) & (np.abs(pt[:, 1 - along] - a[1 - along]) < tol)
              & (pt[:, along] > lo - tol) & (pt[:, along] < hi + tol))
        out[i] = len(np.unique(view.wall_column[on])) >= min_columns
    return out


def hidden_runs(seen: ArrayLike) -> list[tuple[int, int]]:
    """Maximal circular runs of unseen walls as ``(first wall, number of walls)``; none when all or none are seen.

    >>> hidden_runs([True, False, False, True, False])
    [(1, 2), (4, 1)]
    """
    s = np.asarray(seen, bool)
    k = len(s)
    if s.all() or not s.any():
        return []
    start = int(np.argmax(s))
    runs, j = [], 0
    while j < k:
        e = (start + j) % k
        if s[e]:
            j += 1
            continue
        n = 0
        while not s[(e + n) % k]:
            n += 1
        runs.append((e, n))
        j += n
    return sorted(runs)


def _axis_line(p: FloatArray, q: FloatArray) -> tuple[int, float]:
    """The line of wall p -> q as (fixed coordinate, value): a wall along x has y fixed (1)."""
    fixed = 1 if abs(q[0] - p[0]) > abs(q[1] - p[1]) else 0
    return fixed, float(p[fixed])


def fewer_wall_polygons(polygon: ArrayLike, first: int, count: int, *, max_walls: int = 2) -> Iterator[FloatArray]:
    """Polygons with walls ``first .. first + count - 1`` of ``polygon`` replaced by ``m < count`` walls.

    ``m`` has the parity of ``count`` (a Manhattan chain between the same two neighbours) and is at most
    ``max_walls``; each new wall lies at one of the replaced corners' coordinates or midway between two of them.
    The polygons yielded are not checked: see :func:`explains_view`.
    """
    p = np.asarray(polygon, float)
    k = len(p)
    before = _axis_line(p[(first - 1) % k], p[first % k])
    after = _axis_line(p[(first + count) % k], p[(first + count + 1) % k])
    kept = [p[(first + count + 1 + j) % k] for j in range(k - count - 1)]  # after's end round to before's start
    replaced = p[[(first + j) % k for j in range(count + 1)]]
    cand = {}
    for ax in (0, 1):
        v = sorted(set(replaced[:, ax].tolist()))
        cand[ax] = v + [0.5 * (a + b) for a, b in zip(v[:-1], v[1:])]
    for m in range(count - 2, -1, -2):
        if m > max_walls:
            continue
        axes = [(before[0] + 1 + j) % 2 for j in range(m)]  # the first new wall is perpendicular to ``before``
        for values in itertools.product(*[cand[a] for a in axes]):
            lines = [before, *zip(axes, values), after]
            if any(l1[0] == l2[0] for l1, l2 in zip(lines[:-1], lines[1:])):
                continue
            corners = []
            for l1, l2 in zip(lines[:-1], lines[1:]):
                c = np.zeros(2)
                c[l1[0]], c[l2[0]] = l1[1], l2[1]
                corners.append(c)
            yield np.array(kept + corners)


def explains_view(polygon: ArrayLike, view: ViewPoints, *, tol: float = 0.03, ray_step: int = 4) -> bool:
    """True when a room of this floor polygon would show the same pixels: the polygon is simple, counter-clockwise
    and holds the camera; every point of ``view.inside`` lies inside it (within ``tol`` metres), every wall point
    within ``tol`` of its boundary, and every ``ray_step``-th point is reached from the camera without crossing a
    wall."""
    p = np.asarray(polygon, float)
    if len(p) < 4 or not is_simple(p) or signed_area(p) <= 0:
        return False
    if not points_in_polygon(np.zeros((1, 2)), p, margin=tol).all():
        return False
    if not points_in_polygon(view.inside, p, margin=-tol).all():
        return False
    if len(view.wall) and not (distance_to_boundary(view.wall, p) < tol).all():
        return False
    pts = view.inside[::ray_step]
    r = np.linalg.norm(pts, axis=1)
    keep = r > 2 * tol
    pts, r = pts[keep], r[keep]
    frac = np.linspace(0.05, 1.0, 20)[:, None, None]
    along = frac * ((1.0 - 2.0 * tol / r)[None, :, None] * pts[None])  # stop short of the surface seen
    return bool(points_in_polygon(along.reshape(-1, 2), p, margin=-tol / 2).all())


def fewer_corner_explanations(polygon: ArrayLike, view: ViewPoints, *, max_walls: int = 2) -> list[FloatArray]:
    """Polygons with fewer corners than ``polygon`` (counter-clockwise), each made by replacing one run of two or
    more unseen walls (:func:`fewer_wall_polygons`), that explain ``view`` as well (:func:`explains_view`)."""
    p = np.asarray(polygon, float)
    out = []
    for first, count in hidden_runs(seen_walls(p, view)):
        if count >= 2:
            out += [q for q in fewer_wall_polygons(p, first, count, max_walls=max_walls)
                    if len(q) < len(p) and explains_view(q, view)]
    return out


def corner_count_shown(polygon: ArrayLike, view: ViewPoints, *, max_walls: int = 2) -> bool:
    """False when a polygon with fewer corners explains ``view`` as well (:func:`fewer_corner_explanations`)."""
    return not fewer_corner_explanations(polygon, view, max_walls=max_walls)
