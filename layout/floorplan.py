"""Closing observed wall pieces into a Manhattan floor polygon.

Both routes to room geometry (panorama columns in :mod:`layout.roomgeom`,
per-view point clouds and greedy plane fitting in :mod:`layout.planefit`)
end with a list of :class:`WallObservation`: an axis-aligned wall line seen
over a range of viewing angles. :func:`close_manhattan_polygon` orders them
around the camera and closes them into a simple, counter-clockwise,
Manhattan polygon with any number of corners:

* two consecutive walls of different axes meet at the corner of their lines
  when that corner lies in the angular gap between them;
* otherwise the later wall is partly hidden behind the nearer one and the
  hidden walls are completed through the occluding end point: a single
  perpendicular wall between two parallel walls, two walls (through both
  end points) between perpendicular walls that do not meet;
* between two parallel walls on opposite sides of the camera (nothing seen
  in between: masked or unlabelled columns), the perpendicular wall goes
  through the farther of the two end points in the gap's direction, so both
  observed walls stay whole (:func:`_beyond_both`);
* walls shorter than ``min_wall`` (noise, or a corner a few columns off)
  are removed and their two parallel neighbours merged, keeping the better
  supported offset.
* a wall seen up to the ray through an occluding corner goes on behind it
  (generic viewpoint: a room does not turn exactly on that ray): the
  inferred line through its far end moves onto the nearest farther parallel
  wall line of the polygon, where the result is valid and every observed
  wall stays the first one its rays meet (:func:`_extend_far_ends`).

The result is validated (:func:`layout.polygon.polygon_problems` and the
camera strictly inside); if closing fails, the weakest walls are dropped
and, as a last resort, the bounding rectangle of the observed points is
returned with ``uncertain=True``. It is never self-intersecting.

Convention:
    World x, y in metres seen from above, the camera at the origin.
    ``axis = 0``: a wall ``x = offset`` (normal parallel to x, label 3);
    ``axis = 1``: a wall ``y = offset`` (label 4). Viewing angles are
    panorama longitudes: the column direction is
    ``(cos lon, -sin lon)`` (:mod:`panogeom.coords`), so increasing lon
    turns clockwise seen from above; the returned polygon is
    counter-clockwise, wall i from vertex i to vertex i + 1.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import lonlat_to_ray, ray_to_lonlat

from .polygon import points_in_polygon, polygon_problems, ray_hits

__all__ = ["WallObservation", "FloorPlan", "close_manhattan_polygon", "rectangle_around", "polygon_lines"]

FloatArray = NDArray[np.float64]
_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class WallObservation:
    """An axis-aligned wall line seen over a range of viewing angles.

    Attributes
    ----------
    axis : int
        0: the wall is ``x = offset`` (label 3); 1: ``y = offset`` (label 4).
    offset : float
        Line position, metres (camera at the origin).
    lon_start, lon_end : float
        Viewing angles (panorama longitude, radians) of its first and last
        observation in increasing lon; ``lon_end >= lon_start``, at most
        ``lon_start + 2*pi`` (unwrapped across the seam).
    support : int
        Number of observations (columns or points) behind it; 0 for a wall
        inferred by the closing step.
    spread : float
        Robust spread of the observations about the line, metres.

    Examples
    --------
    >>> WallObservation(axis=0, offset=2.0, lon_start=-0.5, lon_end=0.5, support=40, spread=0.01).offset
    2.0
    """

    axis: int
    offset: float
    lon_start: float
    lon_end: float
    support: int
    spread: float = 0.0

    def __post_init__(self) -> None:
        if self.axis not in (0, 1):
            raise ValueError(f"axis: expected 0 (x = offset) or 1 (y = offset), got {self.axis!r}")
        vals = (self.offset, self.lon_start, self.lon_end, self.spread)
        if not all(np.isfinite(v) for v in vals):
            raise ValueError(f"expected finite offset, angles and spread, got {vals}")
        if not 0.0 <= self.lon_end - self.lon_start <= _TWO_PI + 1e-9:
            raise ValueError(f"expected lon_start <= lon_end <= lon_start + 2*pi, got {self.lon_start}, {self.lon_end}")
        if self.support < 0:
            raise ValueError(f"support: expected >= 0, got {self.support}")

    def point_at(self, lon: float) -> FloatArray | None:
        """(x, y) where the column direction ``lon`` meets the wall line, or None if it never does."""
        return _line_point(self.axis, self.offset, lon)


def _line_point(axis: int, offset: float, lon: float) -> FloatArray | None:
    """Where the horizontal direction of longitude ``lon`` meets the line (axis, offset); None if it never does."""
    d = lonlat_to_ray([lon, 0.0])[:2]
    if abs(d[axis]) < 1e-9:
        return None
    t = offset / d[axis]
    if not (t > 1e-9 and np.isfinite(t)):
        return None
    return t * d


@dataclass(frozen=True)
class FloorPlan:
    """A closed Manhattan floor polygon and where each wall came from.

    Attributes
    ----------
    polygon : (N, 2) float
        Counter-clockwise, axis-aligned, simple; wall i from vertex i to i + 1.
    wall_axis : (N,) int
        0: wall ``x = const`` (label 3); 1: ``y = const`` (label 4).
    wall_support : (N,) int
        Observations behind each wall, 0 for walls completed behind occluders.
    uncertain : bool
        The polygon is a guess in part (see ``reasons``).
    reasons : tuple of str
        Why it is uncertain (empty when it is not).
    n_observed : int
        Wall observations given to the closing step.

    Convention: world x, y in metres, camera at the origin (module docstring).
    """

    polygon: FloatArray
    wall_axis: NDArray[np.intp]
    wall_support: NDArray[np.intp]
    uncertain: bool
    reasons: tuple[str, ...]
    n_observed: int

    @property
    def n_inferred(self) -> int:
        """Walls completed by the closing step (no observation behind them)."""
        return int(np.count_nonzero(self.wall_support == 0))


@dataclass
class _Line:
    axis: int
    offset: float
    support: int
    lon_start: float | None = None
    lon_end: float | None = None
    through_far_end: bool = False  # inferred through the far end of a wall seen up to an occluding corner


def _lon_of(p: FloatArray) -> float:
    return float(ray_to_lonlat([p[0], p[1], 0.0])[0])


def _wrap(a: float) -> float:
    return float((a + np.pi) % _TWO_PI - np.pi)


def polygon_lines(lines_axis: ArrayLike, lines_offset: ArrayLike) -> FloatArray:
    """Vertices of a cyclic sequence of alternating axis-aligned lines.

    Parameters
    ----------
    lines_axis : (N,) int
        0 for ``x = offset``, 1 for ``y = offset``; consecutive lines must
        alternate (N even).
    lines_offset : (N,) float

    Returns
    -------
    vertices : (N, 2) float
        Vertex k is where line k meets line k + 1.

    Examples
    --------
    >>> polygon_lines([0, 1, 0, 1], [2.0, 1.0, -1.0, -3.0]).tolist()
    [[2.0, 1.0], [-1.0, 1.0], [-1.0, -3.0], [2.0, -3.0]]
    """
    ax = np.asarray(lines_axis, dtype=np.intp)
    off = np.asarray(lines_offset, dtype=np.float64)
    if ax.ndim != 1 or ax.shape != off.shape or len(ax) < 4 or len(ax) % 2:
        raise ValueError(f"expected equal (N,) axes and offsets with N even and >= 4, got {ax.shape}, {off.shape}")
    nxt = np.roll(ax, -1)
    if np.any(ax == nxt):
        raise ValueError("expected alternating line axes (x, y, x, ...), got two consecutive lines on one axis")
    off_next = np.roll(off, -1)
    x = np.where(ax == 0, off, off_next)
    y = np.where(ax == 1, off, off_next)
    return np.stack([x, y], axis=-1)


def rectangle_around(points: ArrayLike) -> FloatArray:
    """Counter-clockwise axis-aligned bounding rectangle of 2D points.

    Examples
    --------
    >>> rectangle_around([[1.0, 2.0], [-1.0, 0.5], [0.0, -1.0]]).tolist()
    [[-1.0, -1.0], [1.0, -1.0], [1.0, 2.0], [-1.0, 2.0]]
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2 or not np.all(np.isfinite(p)):
        raise ValueError(f"points: expected finite (M, 2) with M >= 2, got {p.shape}")
    lo, hi = p.min(axis=0), p.max(axis=0)
    if np.any(hi - lo <= 0):
        raise ValueError(f"points: expected a non-degenerate spread in x and y, got extent {(hi - lo).tolist()}")
    return np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])


def _merge_parallel(lines: list[_Line], merge_tol: float) -> list[_Line]:
    """Merge consecutive (cyclic) lines of one axis whose offsets agree within merge_tol."""
    changed = True
    while changed and len(lines) > 1:
        changed = False
        for i in range(len(lines)):
            j = (i + 1) % len(lines)
            a, b = lines[i], lines[j]
            if a.axis == b.axis and abs(a.offset - b.offset) <= merge_tol:
                tot = a.support + b.support
                off = (a.offset * a.support + b.offset * b.support) / tot if tot > 0 else 0.5 * (a.offset + b.offset)
                merged = _Line(a.axis, off, tot, a.lon_start, b.lon_end)
                if j == 0:
                    lines = [merged] + lines[1:i]
                else:
                    lines = lines[:i] + [merged] + lines[j + 1:]
                changed = True
                break
    return lines


def _complete(walls: list[_Line], corner_tol: float) -> list[_Line]:
    """Insert the hidden walls between consecutive observed walls (angular order)."""
    out: list[_Line] = []
    n = len(walls)
    for i in range(n):
        a, b = walls[i], walls[(i + 1) % n]
        out.append(a)
        pa = _line_point(a.axis, a.offset, float(a.lon_end))
        pb = _line_point(b.axis, b.offset, float(b.lon_start))
        if pa is None or pb is None:
            # a line that its own end ray does not meet: keep the plain corner (validated later)
            if a.axis == b.axis:
                ref = pa if pa is not None else pb
                if ref is None:
                    continue
                out.append(_Line(1 - a.axis, float(ref[1 - a.axis]), 0))
            continue
        if a.axis != b.axis:
            corner = np.zeros(2)
            corner[a.axis], corner[b.axis] = a.offset, b.offset
            gap = _wrap(float(b.lon_start) - float(a.lon_end))
            rel = _wrap(_lon_of(corner) - float(a.lon_end)) if np.any(corner) else np.inf
            if min(gap, 0.0) - corner_tol <= rel <= max(gap, 0.0) + corner_tol:
                continue  # the two walls meet at their corner
            a_far = bool(np.hypot(*pa) > np.hypot(*pb))
            out.append(_Line(1 - a.axis, float(pa[1 - a.axis]), 0, through_far_end=a_far))
            out.append(_Line(1 - b.axis, float(pb[1 - b.axis]), 0, through_far_end=not a_far))
        elif np.sign(a.offset) != np.sign(b.offset):
            out.append(_Line(1 - a.axis, _beyond_both(a, b, pa, pb), 0))
        else:
            near = pa if np.hypot(*pa) <= np.hypot(*pb) else pb
            out.append(_Line(1 - a.axis, float(near[1 - a.axis]), 0))
    return out


def _beyond_both(a: _Line, b: _Line, pa: FloatArray, pb: FloatArray) -> float:
    """Offset of the hidden wall between parallel walls ``a`` and ``b`` on opposite sides of the camera.

    ``pa``, ``pb`` (2,) are where ``a`` was last seen and ``b`` first seen. The
    wall joining them lies in the direction of the unseen gap between them
    (angular order), and no nearer than either end point: a line through the
    nearer one would cut the other wall's observed part off the room.
    """
    k = 1 - a.axis
    gap = float((float(b.lon_start) - float(a.lon_end)) % _TWO_PI)
    mid = lonlat_to_ray([float(a.lon_end) + 0.5 * gap, 0.0])[:2]
    side = np.sign(mid[k]) or np.sign(pa[k] + pb[k]) or 1.0
    return float(side * max(side * pa[k], side * pb[k]))


def _drop_short(lines: list[_Line], min_wall: float) -> list[_Line]:
    """Remove walls shorter than min_wall, merging their parallel neighbours."""
    while len(lines) > 4:
        verts = polygon_lines([ln.axis for ln in lines], [ln.offset for ln in lines])
        length = np.sqrt(np.sum((verts - np.roll(verts, 1, axis=0)) ** 2, axis=-1))  # line k: vertex k-1 to k
        short = np.flatnonzero(length < min_wall)
        if short.size == 0:
            break
        k = int(min(short, key=lambda i: (lines[i].support, length[i])))
        n = len(lines)
        p, q = lines[(k - 1) % n], lines[(k + 1) % n]
        if p.support > q.support:
            off = p.offset
        elif q.support > p.support:
            off = q.offset
        else:
            off = 0.5 * (p.offset + q.offset)
        merged = _Line(p.axis, off, p.support + q.support, p.lon_start, q.lon_end)
        # the cycle continues after q and ends with the merged line where p, k, q were
        start = (k + 2) % n
        order = [(start + m) % n for m in range(n - 3)]
        keep = [lines[i] for i in order]
        lines = keep + [merged]
    return lines


def _polygon_from_lines(lines: list[_Line]) -> tuple[FloatArray, NDArray[np.intp], NDArray[np.intp]]:
    verts = polygon_lines([ln.axis for ln in lines], [ln.offset for ln in lines])  # clockwise
    n = len(lines)
    poly = verts[::-1].copy()
    # CCW wall j runs from poly[j] = verts[n-1-j] to poly[j+1] = verts[n-2-j]: on line n-1-j
    idx = [(n - 1 - j) % n for j in range(n)]
    axis = np.array([lines[i].axis for i in idx], dtype=np.intp)
    support = np.array([lines[i].support for i in idx], dtype=np.intp)
    return poly, axis, support


def _problems(poly: FloatArray, max_range: float | None = None) -> list[str]:
    probs = polygon_problems(poly, tol=1e-9)
    if not probs and not bool(points_in_polygon(np.zeros(2), poly, margin=1e-6)):
        probs.append("camera outside the polygon")
    if max_range is not None and float(np.max(np.hypot(poly[:, 0], poly[:, 1]))) > max_range:
        probs.append(f"a corner farther than {max_range:.3g} from the camera")
    return probs


def close_manhattan_polygon(walls: Sequence[WallObservation], *, points: ArrayLike | None = None,
                            corner_tol: float = np.deg2rad(2.0), merge_tol: float = 0.12,
                            min_wall: float = 0.25, max_drops: int = 4,
                            max_range: float | None = None) -> FloorPlan:
    """Close observed wall pieces into a simple counter-clockwise Manhattan polygon.

    Parameters
    ----------
    walls : sequence of WallObservation
        Any order; sorted here by viewing angle.
    points : (M, 2) float, optional
        The observed wall points; their bounding rectangle is the last-resort
        answer when no valid polygon can be closed.
    corner_tol : float
        Radians by which a corner may lie outside the angular gap between
        two walls and still be taken as their meeting point.
    merge_tol : float
        Consecutive parallel walls closer than this (metres) are one wall.
    min_wall : float
        Walls shorter than this (metres) are removed.
    max_drops : int
        How many of the weakest walls may be dropped to obtain a valid
        polygon before falling back to the rectangle.
    max_range : float, optional
        A polygon with a corner farther than this from the camera is not
        valid (completions along nearly parallel rays run far away).

    Returns
    -------
    FloorPlan

    Raises
    ------
    ValueError
        With no wall and fewer than two points (nothing to build on).

    Convention: world x, y in metres, camera at the origin; see the module
    docstring for angles and axes.

    Examples
    --------
    A 4 m x 3 m room seen from (1, 0.5): four walls, four corners.

    >>> W = WallObservation
    >>> obs = [W(0, 3.0, -0.30, 0.57, 50), W(1, -2.0, 0.60, 2.0, 80), W(0, -1.0, 2.06, 3.9, 60),
    ...        W(1, 1.0, 3.95, 5.94, 70)]
    >>> plan = close_manhattan_polygon(obs)
    >>> plan.polygon.tolist(), plan.uncertain
    ([[-1.0, 1.0], [-1.0, -2.0], [3.0, -2.0], [3.0, 1.0]], False)

    An L-shaped room seen from its lower arm: the reflex corner (-1, 0.7)
    hides the far arm's inner wall and the end wall; both are completed
    through the occluding corner (two inferred walls, six corners).

    >>> obs = [W(0, 1.0, -0.60, 0.90, 50), W(1, -1.3, 0.93, 2.72, 90), W(0, -3.0, 2.74, 3.74, 30),
    ...        W(1, 0.7, 3.76, 5.66, 60)]
    >>> plan = close_manhattan_polygon(obs)
    >>> len(plan.polygon), plan.n_inferred, plan.uncertain
    (6, 2, False)
    >>> np.round(plan.polygon, 2).tolist()
    [[-0.98, 0.7], [-0.98, 2.05], [-3.0, 2.05], [-3.0, -1.3], [1.0, -1.3], [1.0, 0.7]]
    """
    ws = list(walls)
    pts = None if points is None else np.asarray(points, dtype=np.float64)
    if pts is not None and (pts.ndim != 2 or pts.shape[1] != 2):
        raise ValueError(f"points: expected shape (M, 2), got {pts.shape}")
    if not ws and (pts is None or len(pts) < 2):
        raise ValueError("expected at least one wall observation or two wall points, got none")
    for name, v in (("corner_tol", corner_tol), ("merge_tol", merge_tol), ("min_wall", min_wall)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name}: expected a finite value >= 0, got {v}")
    reasons: list[str] = []
    axes = {w.axis for w in ws}
    if len(ws) < 3:
        reasons.append(f"only {len(ws)} wall(s) observed")
    elif len(axes) < 2:
        reasons.append("walls of a single orientation observed")

    order = sorted(ws, key=lambda w: _wrap(w.lon_start))
    active = list(order)
    dropped = 0
    while True:
        result = _try_close(active, corner_tol, merge_tol, min_wall, max_range)
        if result is not None:
            poly, axis, support = result
            if dropped:
                reasons.append(f"{dropped} weak wall(s) dropped to close the polygon")
            return FloorPlan(polygon=poly, wall_axis=axis, wall_support=support, uncertain=bool(reasons),
                             reasons=tuple(reasons), n_observed=len(ws))
        if dropped >= max_drops or len(active) <= 2:
            break
        weakest = min(range(len(active)), key=lambda i: active[i].support)
        active = active[:weakest] + active[weakest + 1:]
        dropped += 1

    if pts is None or len(pts) < 2:
        pts = np.array([p for w in ws for p in (w.point_at(w.lon_start), w.point_at(w.lon_end)) if p is not None])
    pts = pts.reshape(-1, 2)
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    m = max(0.05, 0.05 * extent)  # keep the camera strictly inside
    rect = rectangle_around(np.concatenate([pts, [[-m, -m], [m, m]]], axis=0))
    reasons.append("no valid Manhattan polygon closes the observed walls: bounding rectangle of the observed points")
    return FloorPlan(polygon=rect, wall_axis=np.array([1, 0, 1, 0], dtype=np.intp),
                     wall_support=np.zeros(4, dtype=np.intp), uncertain=True, reasons=tuple(reasons),
                     n_observed=len(ws))


def _try_close(walls: Sequence[WallObservation], corner_tol: float, merge_tol: float, min_wall: float,
               max_range: float | None) -> tuple[FloatArray, NDArray[np.intp], NDArray[np.intp]] | None:
    if not walls:
        return None
    lines = [_Line(w.axis, w.offset, w.support, w.lon_start, w.lon_end) for w in walls]
    lines = _merge_parallel(lines, merge_tol)
    if len(lines) < 2:
        return None
    lines = _complete(lines, corner_tol)
    # completion can put parallel lines next to each other only through merges; re-merge equal ones
    lines = _merge_parallel(lines, 1e-9)
    if len(lines) < 4 or len(lines) % 2 or any(lines[i].axis == lines[(i + 1) % len(lines)].axis
                                                for i in range(len(lines))):
        return None
    lines = _drop_short(lines, min_wall)
    poly, axis, support = _polygon_from_lines(lines)
    if _problems(poly, max_range):
        return None
    if not any(ln.through_far_end for ln in lines):
        return poly, axis, support
    return _polygon_from_lines(_extend_far_ends(lines, walls, merge_tol, min_wall, max_range))


def _first_hits(poly: FloatArray, lons: FloatArray) -> tuple[NDArray[np.intp], FloatArray]:
    """The polygon wall each horizontal ray from the camera meets first.

    ``poly`` (N, 2) axis-aligned, ``lons`` (M,) viewing angles; returns the
    axis (M,) and offset (M,) of the first wall hit (axis -1 where none is).
    """
    d = lonlat_to_ray(np.stack([lons, np.zeros_like(lons)], axis=-1))[:, :2]  # (M, 2)
    dist, k = ray_hits(poly, d)
    e = np.roll(poly, -1, axis=0) - poly
    ax = np.where(np.abs(e[:, 0]) <= np.abs(e[:, 1]), 0, 1)  # x = const edges are axis 0
    c = poly[np.arange(len(poly)), ax]  # (N,) edge offsets
    hit = np.isfinite(dist)
    return np.where(hit, ax[k], -1), np.where(hit, c[k], np.nan)


def _visibility_misses(poly: FloatArray, walls: Sequence[WallObservation], tol: float, n: int = 12) -> int:
    """Rays of the observed walls (``n`` each) on which the polygon's first wall is not the observed one."""
    seen = [w for w in walls if w.support > 0]
    if not seen:
        return 0
    f = (np.arange(n) + 0.5) / n
    lons = np.concatenate([w.lon_start + f * (w.lon_end - w.lon_start) for w in seen])
    axis = np.repeat([w.axis for w in seen], n)
    off = np.repeat([w.offset for w in seen], n)
    hit_axis, hit_off = _first_hits(poly, lons)
    return int(np.count_nonzero((hit_axis != axis) | ~(np.abs(hit_off - off) <= tol)))


def _extend_far_ends(lines: list[_Line], walls: Sequence[WallObservation], merge_tol: float, min_wall: float,
                     max_range: float | None) -> list[_Line]:
    """Continue walls hidden behind an occluding corner to a wall line seen elsewhere (generic viewpoint).

    Completing two perpendicular walls that do not meet through both end points
    puts a corner exactly where the farther wall passes out of sight: the room
    would have to turn precisely on the viewing ray through the occluding
    corner. Rather, the farther wall goes on behind the occluder. The inferred
    line through its far end moves, farther from the camera, onto the nearest
    parallel line of an observed wall for which the polygon stays valid and
    every observed wall stays the first wall on its rays
    (:func:`_visibility_misses` no worse); with no such line it stays put.
    """
    tol = max(merge_tol, 1e-6)
    seen = [w for w in walls if w.support > 0]
    for k in range(len(lines)):
        ln = lines[k]
        if not ln.through_far_end:
            continue
        base = _polygon_from_lines(lines)[0]
        base_misses = _visibility_misses(base, walls, tol)
        sign = np.sign(ln.offset)
        offs = [w.offset for w in seen if w.axis == ln.axis] + [m.offset for m in lines if m.axis == ln.axis]
        cands = sorted({round(o, 9) for o in offs if np.sign(o) == sign and abs(o) > abs(ln.offset) + tol}, key=abs)
        for off in cands:
            trial = list(lines)
            trial[k] = replace(ln, offset=float(off), through_far_end=False)
            trial = _drop_short(trial, min_wall)
            if len(trial) < 4:
                continue
            poly = _polygon_from_lines(trial)[0]
            if _problems(poly, max_range) or _visibility_misses(poly, walls, tol) > base_misses:
                continue
            return _extend_far_ends(trial, walls, merge_tol, min_wall, max_range)
    return lines
