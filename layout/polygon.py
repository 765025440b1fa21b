"""2D polygon helpers for floor plans: area, orientation, containment,
wall segments, point-to-segment distances, convex clipping and validity.

Convention:
    Polygons are ``(N, 2)`` float arrays of world ``(x, y)`` in metres, seen
    from above (z up), with NO repeated closing vertex: edge ``i`` runs from
    vertex ``i`` to vertex ``(i + 1) % N``. Floor polygons are
    counter-clockwise (positive signed area) and Manhattan (consecutive edges
    orthogonal), see shared/CONVENTIONS.md. Functions marked "batched" accept
    any leading axes ``(..., N, 2)`` and vectorise over them.

Everything here is pure numpy; no other pano2cad package is imported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Walls",
    "SegmentProjection",
    "as_polygon",
    "signed_area",
    "is_ccw",
    "as_ccw",
    "points_in_polygon",
    "ray_hits",
    "distance_to_boundary",
    "wall_segments",
    "project_to_segments",
    "closest_segment",
    "oriented_rectangles",
    "convex_intersection_area",
    "convex_in_polygon",
    "outside_fraction",
    "has_repeated_vertex",
    "is_manhattan",
    "wall_direction",
    "is_simple",
    "polygon_problems",
    "validate_floor_polygon",
]

FloatArray = NDArray[np.float64]


def _readonly(*arrays: np.ndarray) -> None:
    for a in arrays:
        a.setflags(write=False)


def as_polygon(polygon: ArrayLike, *, name: str = "polygon") -> FloatArray:
    """Check and convert a (batched) polygon to a float64 array.

    Parameters
    ----------
    polygon : (..., N, 2) array_like
        Vertices, N >= 3, finite.
    name : str
        Used in error messages.

    Returns
    -------
    (..., N, 2) float64 array (a copy only when a conversion was needed).

    Convention:
        Vertices without a repeated closing vertex; this function does not
        check orientation (see :func:`is_ccw`).

    >>> as_polygon([[0, 0], [1, 0], [1, 1]]).dtype
    dtype('float64')
    """
    arr = np.asarray(polygon, dtype=np.float64)
    if arr.ndim < 2 or arr.shape[-1] != 2 or arr.shape[-2] < 3:
        raise ValueError(f"expected {name} of shape (..., N, 2) with N >= 3, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"expected finite {name} coordinates, got NaN or inf")
    return arr


def _as_points(points: ArrayLike, name: str = "points") -> FloatArray:
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim < 1 or arr.shape[-1] != 2:
        raise ValueError(f"expected {name} of shape (..., 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"expected finite {name}, got NaN or inf")
    return arr


def signed_area(polygon: ArrayLike) -> FloatArray:
    """Signed area (shoelace formula), batched.

    Parameters
    ----------
    polygon : (..., N, 2) float

    Returns
    -------
    (...) float
        Positive for counter-clockwise polygons, negative for clockwise.

    Convention:
        x, y in metres seen from above (z up): CCW means positive area.

    >>> float(signed_area([[0, 0], [2, 0], [2, 1], [0, 1]]))
    2.0
    >>> float(signed_area([[0, 0], [0, 1], [2, 1], [2, 0]]))
    -2.0
    """
    p = as_polygon(polygon)
    # shift to the first vertex for precision with far-away coordinates
    q = p - p[..., :1, :]
    x, y = q[..., 0], q[..., 1]
    return 0.5 * np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)


def is_ccw(polygon: ArrayLike) -> NDArray[np.bool_]:
    """True where the (batched) polygon is counter-clockwise seen from above.

    >>> bool(is_ccw([[0, 0], [1, 0], [1, 1], [0, 1]]))
    True
    """
    return np.asarray(signed_area(polygon) > 0.0)


def as_ccw(polygon: ArrayLike) -> FloatArray:
    """Return a single polygon in counter-clockwise order (reversed if needed).

    Parameters
    ----------
    polygon : (N, 2) float

    Returns
    -------
    (N, 2) float
        Same vertices; when the input is clockwise the order is reversed
        keeping vertex 0 first.

    >>> as_ccw([[0, 0], [0, 1], [1, 1], [1, 0]]).tolist()
    [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    """
    p = as_polygon(polygon)
    if p.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {p.shape}")
    if signed_area(p) < 0:
        p = np.concatenate([p[:1], p[1:][::-1]], axis=0)
    return p.copy()


def points_in_polygon(points: ArrayLike, polygon: ArrayLike, *, margin: float = 0.0) -> NDArray[np.bool_]:
    """Vectorised point-in-polygon test (crossing number, any simple polygon).

    Parameters
    ----------
    points : (..., 2) float
    polygon : (N, 2) float
        Either orientation.
    margin : float
        0 (default): the plain crossing test; points exactly on the boundary
        may go either way. ``margin > 0``: a point counts as inside only if
        it is inside AND at least ``margin`` away from the boundary.
        ``margin < 0``: points outside but within ``|margin|`` of the
        boundary count as inside too.

    Returns
    -------
    (...) bool

    Convention:
        World x, y in metres, seen from above.

    >>> sq = [[0, 0], [2, 0], [2, 2], [0, 2]]
    >>> points_in_polygon([[1, 1], [3, 1], [0.1, 1]], sq).tolist()
    [True, False, True]
    >>> points_in_polygon([[1, 1], [0.1, 1]], sq, margin=0.5).tolist()
    [True, False]
    """
    pts = _as_points(points)
    poly = as_polygon(polygon)
    if poly.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {poly.shape}")
    if not np.isfinite(margin):
        raise ValueError(f"expected a finite margin, got {margin}")
    a = poly
    b = np.roll(poly, -1, axis=0)
    px = pts[..., 0, None]
    py = pts[..., 1, None]
    ay, by = a[:, 1], b[:, 1]
    ax, bx = a[:, 0], b[:, 0]
    straddle = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = ax + (py - ay) * (bx - ax) / (by - ay)
    crossings = np.sum(straddle & (px < x_cross), axis=-1)
    inside = (crossings % 2) == 1
    if margin != 0.0:
        d = distance_to_boundary(pts, poly)
        if margin > 0:
            inside = inside & (d >= margin)
        else:
            inside = inside | (d <= -margin)
    return np.asarray(inside)


@dataclass(frozen=True)
class SegmentProjection:
    """Projection of points onto segments (result of :func:`project_to_segments`).

    Attributes
    ----------
    distance : (..., S) float
        Euclidean distance from each point to each segment, metres.
    closest : (..., S, 2) float
        Closest point on each segment.
    t : (..., S) float
        Parameter of the closest point in [0, 1] (0 = start, 1 = end).
    """

    distance: FloatArray
    closest: FloatArray
    t: FloatArray



def ray_hits(polygon: ArrayLike, directions: ArrayLike) -> tuple[FloatArray, NDArray[np.intp]]:
    """The first edge of a polygon that each ray from the origin meets, and how far away (batched).

    Parameters
    ----------
    polygon : (..., N, 2) float
        Vertices relative to the rays' origin (e.g. the camera), either
        orientation, no repeated closing vertex.
    directions : (W, 2) float
        Unit directions of the rays.

    Returns
    -------
    distance : (..., W) float
        Distance along each ray to the first edge it meets (inf where none).
    index : (..., W) int
        That edge, ``i`` = from vertex ``i`` to ``i + 1``; meaningless where
        ``distance`` is inf.

    Examples
    --------
    >>> d, i = ray_hits([[-1, -1], [2, -1], [2, 1], [-1, 1]], [[1.0, 0.0], [0.0, 1.0]])
    >>> d.tolist(), i.tolist()
    ([2.0, 1.0], [1, 2])
    """
    a = np.asarray(polygon, dtype=np.float64)
    direction = np.asarray(directions, dtype=np.float64).reshape(-1, 2)
    e = np.roll(a, -1, axis=-2) - a
    a, e = a[..., None, :, :], e[..., None, :, :]  # (..., 1, N, 2)
    dx, dy = direction[:, None, 0], direction[:, None, 1]  # (W, 1)
    denom = dx * e[..., 1] - dy * e[..., 0]  # cross(dir, e): (..., W, N)
    num_t = a[..., 0] * e[..., 1] - a[..., 1] * e[..., 0]  # cross(a, e): (..., 1, N)
    num_s = a[..., 0] * dy - a[..., 1] * dx  # cross(a, dir): (..., W, N)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num_t / denom
        sp = num_s / denom
    elen = np.sqrt(np.sum(e * e, axis=-1))
    eps = 1e-12 * np.maximum(elen, 1.0)
    hit = (np.abs(denom) > eps) & (t > 1e-9) & (sp >= -1e-12) & (sp <= 1.0 + 1e-12)
    t = np.where(hit, t, np.inf)
    idx = np.argmin(t, axis=-1)
    return np.take_along_axis(t, idx[..., None], axis=-1)[..., 0], idx


def project_to_segments(points: ArrayLike, starts: ArrayLike, ends: ArrayLike) -> SegmentProjection:
    """Distance and closest point from every point to every segment, vectorised.

    Parameters
    ----------
    points : (..., 2) float
    starts, ends : (S, 2) float, or broadcastable against ``points[..., None, :]``
        e.g. ``(B, 1, S, 2)`` for per-batch walls with points ``(B, M, 2)``.

    Returns
    -------
    SegmentProjection
        ``distance (..., S)``, ``closest (..., S, 2)``, ``t (..., S)``.
        Degenerate (zero-length) segments project onto their start.

    Convention:
        World x, y in metres.

    >>> r = project_to_segments([[1.0, 1.0]], [[0, 0], [0, 0]], [[2, 0], [0, 0.5]])
    >>> r.distance.round(3).tolist(), r.closest[0, 0].tolist()
    ([[1.0, 1.118]], [1.0, 0.0])
    """
    pts = _as_points(points)
    a = _as_points(starts, "starts")
    b = _as_points(ends, "ends")
    if a.ndim < 2 or a.shape != b.shape:
        raise ValueError(f"expected starts and ends of equal shape (..., S, 2), got {a.shape} and {b.shape}")
    return _project(pts, a, b)


def _project(pts: FloatArray, a: FloatArray, b: FloatArray) -> SegmentProjection:
    ax, ay = a[..., 0], a[..., 1]
    dx, dy = b[..., 0] - ax, b[..., 1] - ay
    rx = pts[..., 0, None] - ax
    ry = pts[..., 1, None] - ay
    dd = dx * dx + dy * dy
    degenerate = dd <= 0
    t = np.clip((rx * dx + ry * dy) / np.where(degenerate, 1.0, dd), 0.0, 1.0)
    if np.any(degenerate):
        t = np.where(degenerate, 0.0, t)
    ex, ey = rx - t * dx, ry - t * dy
    dist = np.sqrt(ex * ex + ey * ey)
    closest = np.stack([ax + t * dx, ay + t * dy], axis=-1)
    return SegmentProjection(distance=dist, closest=closest, t=t)


def _nearest_segment(pts: FloatArray, a: FloatArray, b: FloatArray) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
    """Nearest of S segments for every point: ``pts (..., 2)``, ``a, b``
    broadcastable against ``pts[..., None, :]`` -> (index (...), distance
    (...), closest point (..., 2)). Only the winner's point is formed."""
    ax, ay = a[..., 0], a[..., 1]
    dx, dy = b[..., 0] - ax, b[..., 1] - ay
    rx = pts[..., 0, None] - ax
    ry = pts[..., 1, None] - ay
    dd = dx * dx + dy * dy
    t = np.clip((rx * dx + ry * dy) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    ex, ey = rx - t * dx, ry - t * dy
    d2 = ex * ex + ey * ey
    idx = np.argmin(d2, axis=-1)
    pick = idx[..., None]
    dist = np.sqrt(np.take_along_axis(d2, pick, axis=-1)[..., 0])
    shape = d2.shape

    def sel(v: FloatArray) -> FloatArray:
        return np.take_along_axis(np.broadcast_to(v, shape), pick, axis=-1)[..., 0]

    tt = sel(t)
    closest = np.stack([sel(ax) + tt * sel(dx), sel(ay) + tt * sel(dy)], axis=-1)
    return idx, dist, closest


def distance_to_boundary(points: ArrayLike, polygon: ArrayLike) -> FloatArray:
    """Unsigned distance from points to the polygon boundary.

    Parameters
    ----------
    points : (..., 2) float
    polygon : (N, 2) float

    Returns
    -------
    (...) float, metres.

    >>> float(distance_to_boundary([0.5, 0.25], [[0, 0], [1, 0], [1, 1], [0, 1]]))
    0.25
    """
    poly = as_polygon(polygon)
    if poly.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {poly.shape}")
    proj = project_to_segments(points, poly, np.roll(poly, -1, axis=0))
    return proj.distance.min(axis=-1)


@dataclass(frozen=True)
class Walls:
    """The edges of a floor polygon as wall segments.

    Attributes (``...`` = batch axes of the polygon, N = number of walls)
    ----------
    start, end : (..., N, 2) float
        Wall i runs from vertex i to vertex (i + 1) % N.
    direction : (..., N, 2) float
        Unit vector from start to end.
    normal : (..., N, 2) float
        Unit normal pointing INTO the room (left of the direction for a CCW
        polygon, right of it for a clockwise one).
    length : (..., N) float
    midpoint : (..., N, 2) float

    Convention:
        World x, y in metres, seen from above; normals point inward.
    """

    start: FloatArray
    end: FloatArray
    direction: FloatArray
    normal: FloatArray
    length: FloatArray
    midpoint: FloatArray

    def __len__(self) -> int:
        return int(self.length.shape[-1])


def wall_segments(polygon: ArrayLike) -> Walls:
    """Wall segments with inward normals, batched.

    Parameters
    ----------
    polygon : (..., N, 2) float
        Simple polygon, either orientation, no zero-length edge.

    Returns
    -------
    Walls

    Convention:
        Edge i runs from vertex i to vertex (i + 1) % N; the normal points
        into the polygon whatever its orientation.

    >>> w = wall_segments([[0, 0], [4, 0], [4, 3], [0, 3]])
    >>> w.normal.tolist()
    [[0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]]
    >>> w.length.tolist()
    [4.0, 3.0, 4.0, 3.0]
    """
    p = as_polygon(polygon)
    start = p
    end = np.roll(p, -1, axis=-2)
    vec = end - start
    length = np.sqrt(np.sum(vec * vec, axis=-1))
    if np.any(length <= 0):
        raise ValueError("expected polygon without zero-length edges (repeated consecutive vertices), got one")
    direction = vec / length[..., None]
    sign = np.where(signed_area(p) >= 0, 1.0, -1.0)[..., None, None]
    left = np.stack([-direction[..., 1], direction[..., 0]], axis=-1)
    normal = sign * left + 0.0  # + 0.0 turns -0.0 into 0.0
    midpoint = 0.5 * (start + end)
    out = Walls(start=start.copy(), end=end, direction=direction, normal=normal, length=length, midpoint=midpoint)
    _readonly(out.start, out.end, out.direction, out.normal, out.length, out.midpoint)
    return out


def closest_segment(points: ArrayLike, polygon: ArrayLike) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
    """Index of, distance to and closest point on the nearest polygon edge.

    Parameters
    ----------
    points : (..., 2) float
    polygon : (N, 2) float

    Returns
    -------
    index : (...) int
        Edge index i (edge from vertex i to vertex i + 1); ties go to the
        lower index.
    distance : (...) float
    closest : (..., 2) float

    >>> i, d, c = closest_segment([[3.5, 1.0]], [[0, 0], [4, 0], [4, 3], [0, 3]])
    >>> int(i[0]), float(d[0]), c[0].tolist()
    (1, 0.5, [4.0, 1.0])
    """
    poly = as_polygon(polygon)
    if poly.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {poly.shape}")
    return _nearest_segment(_as_points(points), poly, np.roll(poly, -1, axis=0))


def oriented_rectangles(centers: ArrayLike, yaws: ArrayLike, sizes: ArrayLike) -> FloatArray:
    """Corners of oriented rectangles (object footprints), batched.

    Parameters
    ----------
    centers : (..., 2) float
        Rectangle centres.
    yaws : (...) float
        Rotation in radians, counter-clockwise from world +x to the
        rectangle's local +x (the object's front).
    sizes : (..., 2) float
        (length along local x, width along local y), > 0; broadcast with
        the centres.

    Returns
    -------
    (..., 4, 2) float
        Corners in counter-clockwise order, starting at the front-right
        corner (local (+l/2, -w/2)).

    Convention:
        Object yaw as in shared/CONVENTIONS.md: the front direction is
        (cos yaw, sin yaw).

    >>> oriented_rectangles([0.0, 0.0], 0.0, [2.0, 1.0]).tolist()
    [[1.0, -0.5], [1.0, 0.5], [-1.0, 0.5], [-1.0, -0.5]]
    """
    c = _as_points(centers, "centers")
    yaw = np.asarray(yaws, dtype=np.float64)
    s = _as_points(sizes, "sizes")
    if np.any(s <= 0):
        raise ValueError("expected positive rectangle sizes (length, width), got a value <= 0")
    if not np.all(np.isfinite(yaw)):
        raise ValueError("expected finite yaws, got NaN or inf")
    return _rectangles(c, yaw, s)


_UNIT_CORNERS = np.array([[0.5, -0.5], [0.5, 0.5], [-0.5, 0.5], [-0.5, -0.5]])


def _rectangles(c: FloatArray, yaw: FloatArray, s: FloatArray) -> FloatArray:
    cos, sin = np.cos(yaw), np.sin(yaw)
    local = _UNIT_CORNERS * s[..., None, :]  # (..., 4, 2)
    lx, ly = local[..., 0], local[..., 1]
    x = cos[..., None] * lx - sin[..., None] * ly + c[..., None, 0]
    y = sin[..., None] * lx + cos[..., None] * ly + c[..., None, 1]
    return np.stack([x, y], axis=-1)


def _clip_edges_contribution(
    px: FloatArray, py: FloatArray, qx: FloatArray, qy: FloatArray, eps: float, own: bool
) -> FloatArray:
    """Sum of 0.5*cross over the parts of the edges of p lying inside convex q.

    Batch-LAST layout for speed: ``px, py (K, L)`` and ``qx, qy (M, L)``
    are vertex coordinates (CCW, relative to a common origin) of L polygon
    pairs; every reduction runs over a leading axis. Coincident parallel
    edges: kept from p (own=True) only when the two outward normals agree;
    never kept when own=False. This counts a shared boundary piece exactly
    once and a touching contact (opposite normals) never. Returns (L,).
    """
    qex = np.roll(qx, -1, axis=0) - qx
    qey = np.roll(qy, -1, axis=0) - qy
    qlen = np.sqrt(qex * qex + qey * qey)
    qlen[qlen <= 0] = 1.0
    qnx, qny = qey / qlen, -qex / qlen  # outward unit normals of a CCW polygon (M, L)
    off = qnx * qx + qny * qy
    # f0[k, m] = n_m . p_k - off_m (<= 0: inside half-plane m); f1: same at the edge's end
    f0 = qnx[None] * px[:, None] + qny[None] * py[:, None] - off[None]  # (K, M, L)
    z0 = np.abs(f0) <= eps
    f0[z0] = 0.0
    f1 = np.roll(f0, -1, axis=0)
    z1 = np.roll(z0, -1, axis=0)
    in0 = f0 <= 0
    in1 = f1 <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        tstar = f0 / (f0 - f1)
    t_lo = np.max(np.where(~in0 & in1, tstar, 0.0), axis=1)  # (K, L)
    t_hi = np.min(np.where(in0 & ~in1, tstar, 1.0), axis=1)
    empty = ~in0 & ~in1
    coincident = z0 & z1
    pex = np.roll(px, -1, axis=0) - px
    pey = np.roll(py, -1, axis=0) - py
    if own:
        # p's outward normal (pey, -pex) along q's outward normal?
        same = (pey[:, None] * qnx[None] - pex[:, None] * qny[None]) > 0
        empty |= coincident & ~same
    else:
        empty |= coincident
    keep = ~np.any(empty, axis=1) & (t_hi > t_lo)
    ax, ay = px + t_lo * pex, py + t_lo * pey
    bx, by = px + t_hi * pex, py + t_hi * pey
    return 0.5 * np.sum(np.where(keep, ax * by - ay * bx, 0.0), axis=0)


def _convex_intersection_area(a: FloatArray, b: FloatArray, eps: float = 1e-9) -> FloatArray:
    """a (..., K, 2), b (..., M, 2) with equal leading axes -> (...)."""
    lead = a.shape[:-2]
    a2 = a.reshape(-1, a.shape[-2], 2)
    b2 = b.reshape(-1, b.shape[-2], 2)
    origin = a2.mean(axis=1, keepdims=True)
    ax = np.ascontiguousarray((a2[..., 0] - origin[..., 0]).T)
    ay = np.ascontiguousarray((a2[..., 1] - origin[..., 1]).T)
    bx = np.ascontiguousarray((b2[..., 0] - origin[..., 0]).T)
    by = np.ascontiguousarray((b2[..., 1] - origin[..., 1]).T)
    area = _clip_edges_contribution(ax, ay, bx, by, eps, own=True) + _clip_edges_contribution(
        bx, by, ax, ay, eps, own=False
    )
    return np.maximum(area, 0.0).reshape(lead)


def _rect_xy(
    cx: FloatArray, cy: FloatArray, yaw: FloatArray, l: FloatArray, w: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Corners of L rectangles in batch-last layout: x, y of shape (4, L), CCW."""
    cos, sin = np.cos(yaw), np.sin(yaw)
    lx = _UNIT_CORNERS[:, 0, None] * l
    ly = _UNIT_CORNERS[:, 1, None] * w
    return cos * lx - sin * ly + cx, sin * lx + cos * ly + cy


def _rect_intersection_area(
    ca: FloatArray, ya: FloatArray, sa: FloatArray, cb: FloatArray, yb: FloatArray, sb: FloatArray, eps: float = 1e-9
) -> FloatArray:
    """Exact intersection areas of L rectangle pairs given as centres (L, 2),
    yaws (L,) and sizes (L, 2); coordinates relative to the first centre."""
    zero = np.zeros(len(ca))
    ax, ay = _rect_xy(zero, zero, ya, sa[:, 0], sa[:, 1])
    d = cb - ca
    bx, by = _rect_xy(d[:, 0], d[:, 1], yb, sb[:, 0], sb[:, 1])
    area = _clip_edges_contribution(ax, ay, bx, by, eps, own=True) + _clip_edges_contribution(
        bx, by, ax, ay, eps, own=False
    )
    return np.maximum(area, 0.0)


def convex_intersection_area(a: ArrayLike, b: ArrayLike, *, eps: float = 1e-9) -> FloatArray:
    """Exact area of the intersection of two convex polygons, batched.

    The boundary of ``A & B`` is made of the parts of A's edges inside B and
    of B's edges inside A; each part is found by clipping the edge against
    the other polygon's half-planes (Cyrus-Beck) and the area follows from
    Green's theorem, so every shape is fixed and the whole batch is one
    vectorised pass. Shared edge pieces are counted once; touching
    polygons have area 0.

    Parameters
    ----------
    a : (..., K, 2) float
    b : (..., M, 2) float
        Convex, counter-clockwise, broadcastable leading axes.
    eps : float
        Distance under which an edge is taken to lie on the other
        polygon's edge line (metres).

    Returns
    -------
    (...) float, square metres.

    Convention:
        Both polygons CCW seen from above; not checked for convexity.

    >>> sq = oriented_rectangles([0.0, 0.0], 0.0, [2.0, 2.0])
    >>> float(convex_intersection_area(sq, sq + [1.0, 1.0]))
    1.0
    >>> diamond = oriented_rectangles([0.0, 0.0], np.pi / 4, [2.0, 2.0])
    >>> round(float(convex_intersection_area(sq, diamond)), 6)  # regular octagon
    3.313708
    """
    pa = as_polygon(a, name="a")
    pb = as_polygon(b, name="b")
    if np.any(signed_area(pa) <= 0) or np.any(signed_area(pb) <= 0):
        raise ValueError("expected counter-clockwise convex polygons a and b, got a clockwise or degenerate one")
    lead = np.broadcast_shapes(pa.shape[:-2], pb.shape[:-2])
    pa = np.broadcast_to(pa, lead + pa.shape[-2:])
    pb = np.broadcast_to(pb, lead + pb.shape[-2:])
    return _convex_intersection_area(pa, pb, eps)


def convex_in_polygon(convex: ArrayLike, polygon: ArrayLike, *, tol: float = 1e-6) -> NDArray[np.bool_]:
    """True where a convex polygon lies entirely inside a simple polygon, batched.

    Test: no edge of ``polygon`` passes through the interior of ``convex``
    (shrunk by ``tol``), and the centroid of ``convex`` is inside
    ``polygon``. Then the interior of ``convex`` cannot meet the boundary of
    ``polygon`` and is on its inner side. Touching the boundary (an object
    flush against a wall) counts as inside.

    Parameters
    ----------
    convex : (..., K, 2) float
        Convex, counter-clockwise (e.g. :func:`oriented_rectangles`).
    polygon : (N, 2) float
        Simple polygon (e.g. a floor), either orientation.
    tol : float
        Allowed penetration in metres, >= 0.

    Returns
    -------
    (...) bool

    Convention:
        World x, y in metres seen from above.

    >>> room = [[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]]  # L shape
    >>> boxes = oriented_rectangles([[1.0, 1.0], [3.0, 3.0], [2.5, 1.5]], 0.0, [1.0, 1.0])
    >>> convex_in_polygon(boxes, room).tolist()
    [True, False, True]
    """
    cv = as_polygon(convex, name="convex")
    poly = as_polygon(polygon)
    if poly.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {poly.shape}")
    if not (np.isfinite(tol) and tol >= 0):
        raise ValueError(f"expected tol >= 0, got {tol}")
    if np.any(signed_area(cv) <= 0):
        raise ValueError("expected counter-clockwise convex polygons, got a clockwise or degenerate one")
    return _convex_in_polygon(cv, poly, tol)


def _convex_in_polygon(cv: FloatArray, poly: FloatArray, tol: float) -> NDArray[np.bool_]:
    origin = cv.mean(axis=-2)
    c0 = cv - origin[..., None, :]
    ce = np.roll(c0, -1, axis=-2) - c0
    cn = np.stack([ce[..., 1], -ce[..., 0]], axis=-1)
    cn = cn / np.sqrt(np.sum(cn * cn, axis=-1))[..., None]
    off = np.sum(cn * c0, axis=-1)  # (..., K): x strictly inside iff n_k . x - off_k < 0 for all k
    rel0 = poly - origin[..., None, :]  # polygon edges relative to the convex's centroid (..., N, 2)
    rel1 = np.roll(rel0, -1, axis=-2)
    # f[..., n, k] = n_k . s_n - off_k + tol < 0: inside the convex shrunk by tol
    f0 = np.einsum("...nd,...kd->...nk", rel0, cn) - off[..., None, :] + tol
    f1 = np.einsum("...nd,...kd->...nk", rel1, cn) - off[..., None, :] + tol
    in0, in1 = f0 < 0, f1 < 0
    with np.errstate(divide="ignore", invalid="ignore"):
        tstar = f0 / (f0 - f1)
    t_enter = np.where(~in0 & in1, tstar, 0.0)
    t_exit = np.where(in0 & ~in1, tstar, 1.0)
    empty = np.any(~in0 & ~in1, axis=-1)
    t_lo = np.max(t_enter, axis=-1)
    t_hi = np.min(t_exit, axis=-1)
    seg_len = np.sqrt(np.sum((np.roll(poly, -1, axis=0) - poly) ** 2, axis=-1))
    crosses = (~empty) & ((t_hi - t_lo) * seg_len > 1e-12)
    centroid_in = points_in_polygon(origin, poly)
    return np.asarray(centroid_in & ~np.any(crosses, axis=-1))


def outside_fraction(quads: ArrayLike, polygon: ArrayLike, *, samples: int = 6, margin: float = 0.0) -> FloatArray:
    """Share of each convex quadrilateral's area (e.g. an object footprint) outside a polygon, batched.

    Estimated on a ``samples x samples`` grid of cell centres spanned
    bilinearly by the four corners (the cells the boundary crosses count
    wholly in or out).

    Parameters
    ----------
    quads : (..., 4, 2) float
        Corners in order around the quadrilateral (e.g.
        :func:`oriented_rectangles`).
    polygon : (N, 2) float
        Any simple polygon.
    samples : int
        Grid points per side.
    margin : float
        Points outside the polygon but within ``margin`` of its boundary
        count as inside (tolerance for a footprint touching a wall).

    Returns
    -------
    (...) float in [0, 1].

    >>> room = [[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]]
    >>> outside_fraction(oriented_rectangles([[1.0, 1.0], [4.0, 1.0]], [0.0, 0.0], [1.0, 1.0]), room).tolist()
    [0.0, 0.5]
    """
    q = np.asarray(quads, dtype=np.float64)
    if q.shape[-2:] != (4, 2):
        raise ValueError(f"quads: expected shape (..., 4, 2), got {q.shape}")
    n = int(samples)
    if n < 1:
        raise ValueError(f"samples: expected an integer >= 1, got {samples!r}")
    if not (np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin: expected a finite value >= 0, got {margin!r}")
    t = (np.arange(n) + 0.5) / n
    a, b = np.meshgrid(t, t, indexing="ij")
    a, b = a.reshape(-1, 1), b.reshape(-1, 1)  # (n*n, 1)
    p0, p1, p2, p3 = (q[..., None, k, :] for k in range(4))
    pts = (1 - a) * (1 - b) * p0 + a * (1 - b) * p1 + a * b * p2 + (1 - a) * b * p3  # (..., n*n, 2)
    inside = points_in_polygon(pts, polygon, margin=-float(margin))
    return 1.0 - inside.mean(axis=-1)


def has_repeated_vertex(polygon: ArrayLike, *, tol: float = 1e-9) -> bool:
    """True if two vertices coincide (within ``tol``), including a closing
    vertex equal to the first one.

    >>> has_repeated_vertex([[0, 0], [1, 0], [1, 1], [0, 0]])
    True
    """
    p = as_polygon(polygon)
    if p.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {p.shape}")
    d = np.sqrt(np.sum((p[:, None, :] - p[None, :, :]) ** 2, axis=-1))
    iu = np.triu_indices(len(p), k=1)
    return bool(np.any(d[iu] <= tol))


def wall_direction(polygon: ArrayLike) -> float:
    """The direction of a Manhattan polygon's walls, modulo 90 degrees.

    The length-weighted circular mean of the edge angles on the circle of
    period 90 degrees (edges along x and along y count alike), so a polygon
    whose walls are rotated by ``t`` from the axes gives ``t``.

    Parameters
    ----------
    polygon : (N, 2) float

    Returns
    -------
    float
        Radians in ``[-pi/4, pi/4)``; the walls run along this angle and the
        angle plus 90 degrees.

    >>> round(wall_direction([[0, 0], [2, 0], [2, 1], [0, 1]]), 6) + 0.0
    0.0
    >>> c, s = np.cos(0.2), np.sin(0.2)
    >>> round(wall_direction(np.array([[0, 0], [2, 0], [2, 1], [0, 1]]) @ [[c, s], [-s, c]]), 6)
    0.2
    """
    p = as_polygon(polygon)
    if p.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {p.shape}")
    e = np.roll(p, -1, axis=0) - p
    z = np.sum(np.hypot(e[:, 0], e[:, 1]) * np.exp(4j * np.arctan2(e[:, 1], e[:, 0])))
    t = float(np.angle(z)) / 4.0 if abs(z) > 0 else 0.0
    return float((t + np.pi / 4) % (np.pi / 2) - np.pi / 4)


def is_manhattan(polygon: ArrayLike, *, tol: float = 1e-6, axis_aligned: bool = False) -> bool:
    """True if consecutive edges are orthogonal (and, optionally, every edge
    is parallel to x or y).

    Parameters
    ----------
    polygon : (N, 2) float
    tol : float
        Maximum |cos| of the angle between consecutive edges (and, with
        ``axis_aligned``, maximum |sin| of an edge's angle to the nearest axis).
    axis_aligned : bool

    >>> is_manhattan([[0, 0], [2, 0], [2, 1], [0, 1]], axis_aligned=True)
    True
    >>> is_manhattan([[0, 0], [2, 0], [1, 1]])
    False
    """
    p = as_polygon(polygon)
    if p.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {p.shape}")
    if len(p) % 2:
        return False
    e = np.roll(p, -1, axis=0) - p
    n = np.sqrt(np.sum(e * e, axis=-1))
    if np.any(n <= 0):
        return False
    u = e / n[:, None]
    cos = np.abs(np.sum(u * np.roll(u, -1, axis=0), axis=-1))
    ok = bool(np.all(cos <= tol))
    if axis_aligned:
        ok = ok and bool(np.all(np.min(np.abs(u), axis=-1) <= tol))
    return ok


def _orient(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _intersecting_edge_pairs(p: FloatArray, tol: float) -> list[tuple[int, int]]:
    n = len(p)
    a, b = p, np.roll(p, -1, axis=0)
    i, j = np.triu_indices(n, k=1)
    adjacent = (j == i + 1) | ((i == 0) & (j == n - 1))
    a1, b1, a2, b2 = a[i], b[i], a[j], b[j]
    scale = max(float(np.ptp(p)), 1.0)
    eps = tol * scale
    o1 = _orient(a1, b1, a2)
    o2 = _orient(a1, b1, b2)
    o3 = _orient(a2, b2, a1)
    o4 = _orient(a2, b2, b1)
    proper = (((o1 > eps) & (o2 < -eps)) | ((o1 < -eps) & (o2 > eps))) & (
        ((o3 > eps) & (o4 < -eps)) | ((o3 < -eps) & (o4 > eps))
    )

    def on_seg(a_: FloatArray, b_: FloatArray, c: FloatArray, o: FloatArray) -> NDArray[np.bool_]:
        within = (
            (np.minimum(a_[:, 0], b_[:, 0]) - eps <= c[:, 0])
            & (c[:, 0] <= np.maximum(a_[:, 0], b_[:, 0]) + eps)
            & (np.minimum(a_[:, 1], b_[:, 1]) - eps <= c[:, 1])
            & (c[:, 1] <= np.maximum(a_[:, 1], b_[:, 1]) + eps)
        )
        return (np.abs(o) <= eps) & within

    touch = on_seg(a1, b1, a2, o1) | on_seg(a1, b1, b2, o2) | on_seg(a2, b2, a1, o3) | on_seg(a2, b2, b1, o4)
    bad = (proper | touch) & ~adjacent
    # adjacent edges share exactly one vertex; they are bad only if they fold
    # back onto each other (collinear with opposite directions)
    d1, d2 = b1 - a1, b2 - a2
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    dot = np.sum(d1 * d2, axis=-1)
    fold = adjacent & (np.abs(cross) <= eps * scale) & (dot < 0)
    bad = bad | fold
    return [(int(x), int(y)) for x, y in zip(i[bad], j[bad])]


def is_simple(polygon: ArrayLike, *, tol: float = 1e-9) -> bool:
    """True if no two non-adjacent edges touch or cross and no adjacent
    edges fold back onto each other.

    Parameters
    ----------
    polygon : (N, 2) float
    tol : float
        Relative tolerance (times the polygon's extent) for touching.

    >>> is_simple([[0, 0], [2, 0], [2, 2], [0, 2]])
    True
    >>> is_simple([[0, 0], [2, 2], [2, 0], [0, 2]])  # bow tie
    False
    """
    p = as_polygon(polygon)
    if p.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {p.shape}")
    return not _intersecting_edge_pairs(p, tol)


def polygon_problems(
    polygon: ArrayLike, *, manhattan: bool = True, ccw: bool = True, min_edge: float = 0.0, tol: float = 1e-6
) -> list[str]:
    """List what makes a polygon an invalid floor (empty list: valid).

    Checks: no repeated vertex, counter-clockwise (if ``ccw``), simple,
    consecutive edges orthogonal (if ``manhattan``), every edge at least
    ``min_edge`` long.

    Parameters
    ----------
    polygon : (N, 2) float

    Returns
    -------
    list of str, one human-readable problem each.

    >>> polygon_problems([[0, 0], [0, 1], [1, 1], [1, 0]])
    ['not counter-clockwise (signed area -1)']
    """
    p = as_polygon(polygon)
    if p.ndim != 2:
        raise ValueError(f"expected a single polygon (N, 2), got {p.shape}")
    problems: list[str] = []
    if has_repeated_vertex(p, tol=tol):
        d = np.sqrt(np.sum((p[:, None] - p[None]) ** 2, axis=-1))
        i, j = np.argwhere(np.triu(d <= tol, k=1))[0]
        problems.append(f"repeated vertex {i} == {j}")
        return problems
    area = float(signed_area(p))
    if ccw and area <= 0:
        problems.append(f"not counter-clockwise (signed area {area:.4g})")
    pairs = _intersecting_edge_pairs(p, 1e-9)
    if pairs:
        problems.append("not simple: edges " + ", ".join(f"{i}&{j}" for i, j in pairs[:5]) + " intersect")
    if manhattan:
        if len(p) % 2:
            problems.append(f"not Manhattan: odd number of corners ({len(p)})")
        else:
            e = np.roll(p, -1, axis=0) - p
            u = e / np.sqrt(np.sum(e * e, axis=-1))[:, None]
            cos = np.abs(np.sum(u * np.roll(u, -1, axis=0), axis=-1))
            bad = np.flatnonzero(cos > tol)
            if bad.size:
                problems.append(
                    "not Manhattan: edges " + ", ".join(f"{k}&{(k + 1) % len(p)}" for k in bad[:5]) + " not orthogonal"
                )
    if min_edge > 0:
        lengths = np.sqrt(np.sum((np.roll(p, -1, axis=0) - p) ** 2, axis=-1))
        short = np.flatnonzero(lengths < min_edge)
        if short.size:
            problems.append(
                f"edges shorter than {min_edge} m: "
                + ", ".join(f"{k} ({lengths[k]:.3f} m)" for k in short[:5])
            )
    return problems


def validate_floor_polygon(polygon: ArrayLike, *, manhattan: bool = True, min_edge: float = 0.0) -> FloatArray:
    """Return the floor polygon as a float (N, 2) array or raise ValueError
    naming every problem found by :func:`polygon_problems`.

    >>> validate_floor_polygon([[0, 0], [3, 0], [3, 2], [0, 2]]).shape
    (4, 2)
    >>> validate_floor_polygon([[0, 0], [3, 0], [1, 2]])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: expected a simple counter-clockwise Manhattan floor polygon, got one that is not Manhattan: odd ...
    """
    p = as_polygon(polygon, name="floor polygon")
    if p.ndim != 2:
        raise ValueError(f"expected a floor polygon (N, 2), got {p.shape}")
    problems = polygon_problems(p, manhattan=manhattan, min_edge=min_edge)
    if problems:
        raise ValueError(
            "expected a simple counter-clockwise Manhattan floor polygon, got one that is " + "; ".join(problems)
        )
    return p.copy()
