"""The context prior of the paper (Sec. 3.3), vectorised over hypotheses.

    E_ow = sum_j || p_j - p^w_{i*(j)} ||  +  nu_n * sum_j a(n_j, n^w_{i*(j)})
    E_oo = sum_{j < k} A(b_j & b_k)
    pi   = exp(-(E_ow + mu * E_oo)),       nu_n = 10, mu = 0.25 (Sec. 4)

How the paper's text is read here:

* Closest wall ``i*(j)`` and ``p^w`` (option ``wall_point``): by default
  (``"closest"``) ``i*`` is the wall SEGMENT at the smallest Euclidean
  distance from the object's centre ``p_j`` and ``p^w`` is the closest point
  on that segment, so the first term is the centre-to-wall distance. With
  ``"midpoint"`` the paper's ``p^w_i`` is taken literally as the wall centre
  position: ``i*`` is the nearest wall midpoint and the distance is to it
  (this drags objects towards the middle of walls). When several walls
  are nearest at the same distance (a point whose nearest boundary point
  is a reflex corner shared by two walls) ``i*`` is the one with the
  lower alignment cost, so the energy does not depend on the wall order.
* Alignment ``a`` (option ``alignment``), with ``c = n_j . n^w`` where
  ``n_j = (cos yaw, sin yaw)`` is the object's front and ``n^w`` the wall's
  inward unit normal:

  - ``"parallel"`` (default): ``a = 1 - |c|``. Zero when the object faces
    straight into the room or straight at the wall (a bed with its
    headboard against the wall, a TV on a wall, a desk chair), one when it
    stands sideways. This is the complement of the printed term.
  - ``"facing"``: ``a = 1 - c`` in [0, 2]: zero only when facing into the
    room (beds, TVs, sofas, wardrobes).
  - ``"axis"``: ``a = 1 - max(|c|, |s|)`` with ``s = n_j x n^w``: zero
    for any multiple of 90 degrees to the wall (tables).
  - ``"literal"``: ``a = |c|`` exactly as printed in Eq. (3). It penalises
    the most exactly the alignments the paper wants to favour (a bed with
    its headboard against the wall gets the maximum), which is why it is
    not the default.

  All modes agree to second order near their optimum (``~ theta^2 / 2``).
  ``alignment`` may be one mode for all objects or one per object, and
  ``alignment_weights`` (e.g. 0 for rotationally symmetric plants) scales
  each object's term.
* ``E_oo``: the printed double sum over ``j, k = 1..N_o`` would count each
  pair twice and add the constant self-overlaps; we sum unordered pairs
  ``j < k`` (the intended reading). Footprints ``b`` are the oriented
  rectangles ``length x width`` of the objects; areas are exact (convex
  clipping, :func:`layout.polygon.convex_intersection_area`).
* ``p_j`` is the object's centre (the paper). Option ``anchor_offsets``
  moves the point used for the wall term along the object's front, e.g.
  ``-length / 2`` = middle of the back edge: then "back against a wall"
  is the minimum (distance 0) for beds, TVs, wardrobes, instead of a bed
  whose centre sits near a wall's end point scoring as well as one with its
  headboard on the wall. Default 0 (the paper's reading).

Convention:
    World x, y in metres seen from above (z up); yaw in radians,
    counter-clockwise from +x to the object's front (shared/CONVENTIONS.md);
    object size (length along its x = front, width along its y).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .polygon import Walls, _rect_intersection_area, as_polygon, wall_segments

__all__ = [
    "Alignment",
    "ALIGNMENT_MODES",
    "ContextEnergy",
    "alignment_cost",
    "context_energy",
    "context_prior",
    "pair_overlap_areas",
]

FloatArray = NDArray[np.float64]
Alignment = Literal["parallel", "facing", "axis", "literal"]
ALIGNMENT_MODES: tuple[str, ...] = ("parallel", "facing", "axis", "literal")

NU_N = 10.0
MU = 0.25
_TIE_TOL = 1e-9  # metres: walls this close to the minimum distance count as tied


@dataclass(frozen=True)
class ContextEnergy:
    """Context prior terms for a batch of hypotheses (``...`` = batch axes).

    Attributes
    ----------
    total : (...) float
        ``E_ow + mu * E_oo``.
    prior : (...) float
        ``exp(-total)``.
    wall : (...) float
        ``E_ow`` (distance terms plus ``nu_n`` times the alignment terms).
    overlap : (...) float
        ``E_oo``, square metres (unordered pairs).
    distance : (..., N_o) float
        Distance of each object centre (or anchor point) to its wall
        point, metres.
    alignment : (..., N_o) float
        Alignment cost of each object, unweighted (before ``nu_n`` and
        ``alignment_weights``).
    pair_overlap : (..., N_o, N_o) float
        Symmetric matrix of footprint intersection areas, zero diagonal.
    per_object : (..., N_o) float
        ``distance + nu_n * weight * alignment + mu * 0.5 * sum_k
        pair_overlap[j, k]``; sums to ``total`` over objects.
    closest_wall : (..., N_o) int
        Index ``i*(j)`` of the wall used for each object.
    wall_point : (..., N_o, 2) float
        The point ``p^w`` on (or the midpoint of) that wall.
    """

    total: FloatArray
    prior: FloatArray
    wall: FloatArray
    overlap: FloatArray
    distance: FloatArray
    alignment: FloatArray
    pair_overlap: FloatArray
    per_object: FloatArray
    closest_wall: NDArray[np.intp]
    wall_point: FloatArray


def alignment_cost(object_dirs: ArrayLike, wall_normals: ArrayLike, mode: str = "parallel") -> FloatArray:
    """Alignment cost between object fronts and wall normals (see module doc).

    Parameters
    ----------
    object_dirs : (..., 2) float
        Unit front directions ``(cos yaw, sin yaw)``.
    wall_normals : (..., 2) float
        Unit inward wall normals, broadcast with ``object_dirs``.
    mode : {"parallel", "facing", "axis", "literal"}

    Returns
    -------
    (...) float

    Convention:
        Inward normals (pointing into the room).

    >>> into, side, at = [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]
    >>> n = [1.0, 0.0]  # wall at the left, room towards +x
    >>> [float(alignment_cost(d, n)) for d in (into, side, at)]
    [0.0, 1.0, 0.0]
    >>> [float(alignment_cost(d, n, "facing")) for d in (into, side, at)]
    [0.0, 1.0, 2.0]
    >>> [float(alignment_cost(d, n, "literal")) for d in (into, side, at)]
    [1.0, 0.0, 1.0]
    """
    if mode not in ALIGNMENT_MODES:
        raise ValueError(f"expected alignment mode in {ALIGNMENT_MODES}, got {mode!r}")
    d = np.asarray(object_dirs, dtype=np.float64)
    n = np.asarray(wall_normals, dtype=np.float64)
    if d.shape[-1:] != (2,) or n.shape[-1:] != (2,):
        raise ValueError(f"expected object_dirs and wall_normals of shape (..., 2), got {d.shape} and {n.shape}")
    c = d[..., 0] * n[..., 0] + d[..., 1] * n[..., 1]
    s = d[..., 0] * n[..., 1] - d[..., 1] * n[..., 0]
    return _alignment_from_cs(c, s, mode)


def _alignment_from_cs(c: FloatArray, s: FloatArray, mode: str) -> FloatArray:
    if mode == "parallel":
        return 1.0 - np.abs(c)
    if mode == "facing":
        return 1.0 - c
    if mode == "axis":
        return 1.0 - np.maximum(np.abs(c), np.abs(s))
    return np.abs(c)


def _alignment_by_mode(c: FloatArray, s: FloatArray, mode_index: NDArray[np.intp]) -> FloatArray:
    """Alignment cost with a mode per element (index into ALIGNMENT_MODES,
    broadcast against c and s)."""
    codes = np.unique(mode_index)
    shape = np.broadcast_shapes(c.shape, s.shape, mode_index.shape)
    if codes.size == 1:
        return np.broadcast_to(_alignment_from_cs(c, s, ALIGNMENT_MODES[int(codes[0])]), shape)
    out = np.zeros(shape)
    for code in codes:
        out = np.where(mode_index == code, _alignment_from_cs(c, s, ALIGNMENT_MODES[int(code)]), out)
    return out


def _pair_index(n_obj: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    i, j = np.triu_indices(n_obj, k=1)
    return i, j


def _pair_areas(centers: FloatArray, yaws: FloatArray, sizes: FloatArray) -> FloatArray:
    """(..., P) exact pair intersection areas (pairs j < k). Pairs are
    filtered by their axis-aligned bounding boxes, then by the exact
    separating-axis test; only pairs that truly overlap are clipped."""
    n_obj = centers.shape[-2]
    i, j = _pair_index(n_obj)
    lead = centers.shape[:-2]
    out = np.zeros(lead + (len(i),))
    if len(i) == 0:
        return out
    sizes_b = np.broadcast_to(sizes, lead + (n_obj, 2))
    ac, as_ = np.abs(np.cos(yaws)), np.abs(np.sin(yaws))
    hl, hw = 0.5 * sizes_b[..., 0], 0.5 * sizes_b[..., 1]
    hx = ac * hl + as_ * hw  # half extents of the axis-aligned bounding boxes
    hy = as_ * hl + ac * hw
    cx, cy = centers[..., 0], centers[..., 1]
    cand = (np.abs(cx[..., i] - cx[..., j]) < hx[..., i] + hx[..., j]) & (
        np.abs(cy[..., i] - cy[..., j]) < hy[..., i] + hy[..., j]
    )
    if not np.any(cand):
        return out
    idx = np.nonzero(cand)
    a = idx[:-1] + (i[idx[-1]],)
    b = idx[:-1] + (j[idx[-1]],)
    ca, ya, sa = centers[a], yaws[a], sizes_b[a]
    cb, yb, sb = centers[b], yaws[b], sizes_b[b]
    # exact separating-axis test on the four rectangle axes (touching = separated)
    d = cb - ca
    cos_a, sin_a, cos_b, sin_b = np.cos(ya), np.sin(ya), np.cos(yb), np.sin(yb)
    cd, sd = np.abs(np.cos(yb - ya)), np.abs(np.sin(yb - ya))
    hla, hwa, hlb, hwb = 0.5 * sa[:, 0], 0.5 * sa[:, 1], 0.5 * sb[:, 0], 0.5 * sb[:, 1]
    overlap = (
        (np.abs(d[:, 0] * cos_a + d[:, 1] * sin_a) < hla + cd * hlb + sd * hwb)
        & (np.abs(d[:, 1] * cos_a - d[:, 0] * sin_a) < hwa + sd * hlb + cd * hwb)
        & (np.abs(d[:, 0] * cos_b + d[:, 1] * sin_b) < hlb + cd * hla + sd * hwa)
        & (np.abs(d[:, 1] * cos_b - d[:, 0] * sin_b) < hwb + sd * hla + cd * hwa)
    )
    if not np.any(overlap):
        return out
    keep = tuple(k[overlap] for k in idx)
    out[keep] = _rect_intersection_area(
        ca[overlap], ya[overlap], sa[overlap], cb[overlap], yb[overlap], sb[overlap]
    )
    return out


def _check_objects(centers: ArrayLike, yaws: ArrayLike, sizes: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    c = np.asarray(centers, dtype=np.float64)
    y = np.asarray(yaws, dtype=np.float64)
    s = np.asarray(sizes, dtype=np.float64)
    if c.ndim < 2 or c.shape[-1] != 2:
        raise ValueError(f"expected centers of shape (..., N_o, 2), got {c.shape}")
    if y.shape != c.shape[:-1]:
        raise ValueError(f"expected yaws of shape {c.shape[:-1]} (centers without the last axis), got {y.shape}")
    n_obj = c.shape[-2]
    if s.ndim < 2 or s.shape[-2:] != (n_obj, 2):
        raise ValueError(f"expected sizes of shape ({n_obj}, 2) or (..., {n_obj}, 2), got {s.shape}")
    try:
        np.broadcast_shapes(s.shape, c.shape)
    except ValueError:
        raise ValueError(f"expected sizes broadcastable to {c.shape}, got {s.shape}") from None
    for name, a in (("centers", c), ("yaws", y), ("sizes", s)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"expected finite {name}, got NaN or inf")
    if np.any(s <= 0):
        raise ValueError("expected positive footprint sizes (length, width), got a value <= 0")
    return c, y, s


def pair_overlap_areas(centers: ArrayLike, yaws: ArrayLike, sizes: ArrayLike) -> FloatArray:
    """Footprint intersection areas of all object pairs, batched.

    Parameters
    ----------
    centers : (..., N_o, 2) float
    yaws : (..., N_o) float
        Radians, CCW from +x to the object's front.
    sizes : (N_o, 2) or (..., N_o, 2) float
        (length along the front, width), metres.

    Returns
    -------
    (..., N_o, N_o) float
        Symmetric, zero diagonal, square metres.

    Convention:
        World x, y seen from above; object yaw per shared/CONVENTIONS.md.

    >>> a = pair_overlap_areas([[0.0, 0.0], [1.0, 0.5]], [0.0, np.pi / 2], [[2.0, 2.0], [2.0, 1.0]])
    >>> a.round(6).tolist()
    [[0.0, 0.75], [0.75, 0.0]]
    """
    c, y, s = _check_objects(centers, yaws, sizes)
    areas = _pair_areas(c, y, s)
    return _pairs_to_matrix(areas, c.shape[-2])


def _pairs_to_matrix(areas: FloatArray, n_obj: int) -> FloatArray:
    i, j = _pair_index(n_obj)
    m = np.zeros(areas.shape[:-1] + (n_obj, n_obj))
    m[..., i, j] = areas
    m[..., j, i] = areas
    return m


def _nearest_walls(
    p_obj: FloatArray, y: FloatArray, walls: Walls, wall_point: str, modes: list[str], lead: tuple[int, ...]
) -> tuple[FloatArray, NDArray[np.intp], FloatArray, FloatArray, FloatArray]:
    """i*(j) for every object: (distance, wall index, wall point, wall normal x, y).

    Loops over the N walls with (..., N_o) arrays (a running minimum is
    faster in numpy than reducing a small trailing axis). Ties (several
    walls within _TIE_TOL of the minimum distance, e.g. a point nearest to
    a reflex corner) go to the wall with the lower alignment cost.
    """
    n_walls = walls.length.shape[-1]
    shape = lead + (p_obj.shape[-2],)
    px, py = p_obj[..., 0], p_obj[..., 1]

    def wall(v: FloatArray, w: int) -> FloatArray:  # (..., N) -> (..., 1) for wall w
        return v[..., w, None]

    d2 = np.empty((n_walls,) + shape)
    tt = np.empty((n_walls,) + shape) if wall_point == "closest" else None
    best = np.full(shape, np.inf)
    wi = np.zeros(shape, dtype=np.intp)
    for w in range(n_walls):
        if wall_point == "closest":
            ax, ay = wall(walls.start[..., 0], w), wall(walls.start[..., 1], w)
            dx = wall(walls.end[..., 0], w) - ax
            dy = wall(walls.end[..., 1], w) - ay
            rx, ry = px - ax, py - ay
            t = np.clip((rx * dx + ry * dy) / (dx * dx + dy * dy), 0.0, 1.0)
            ex, ey = rx - t * dx, ry - t * dy
            assert tt is not None
            tt[w] = t
        else:
            ex = px - wall(walls.midpoint[..., 0], w)
            ey = py - wall(walls.midpoint[..., 1], w)
        d2_w = ex * ex + ey * ey
        d2[w] = d2_w
        better = d2_w < best
        np.copyto(best, d2_w, where=better)
        np.copyto(wi, w, where=better)
    bound = (np.sqrt(best) + _TIE_TOL) ** 2
    n_tied = np.zeros(shape, dtype=np.intp)
    for w in range(n_walls):
        n_tied += d2[w] <= bound
    if np.any(n_tied > 1):
        sel = np.nonzero(n_tied > 1)
        obj = sel[-1]
        cy = np.broadcast_to(np.cos(y), shape)[sel]
        sy = np.broadcast_to(np.sin(y), shape)[sel]
        mode_of = np.array([ALIGNMENT_MODES.index(m) for m in modes])[obj]
        best_cost = np.full(len(obj), np.inf)
        choice = wi[sel].copy()
        for w in range(n_walls):
            nx = np.broadcast_to(wall(walls.normal[..., 0], w), shape)[sel]
            ny = np.broadcast_to(wall(walls.normal[..., 1], w), shape)[sel]
            cost = _alignment_by_mode(cy * nx + sy * ny, cy * ny - sy * nx, mode_of)
            cost = np.where(d2[w][sel] <= bound[sel], cost, np.inf)
            better = cost < best_cost
            best_cost = np.where(better, cost, best_cost)
            choice = np.where(better, w, choice)
        wi[sel] = choice

    def gather(v: FloatArray) -> FloatArray:  # (..., N) per-wall values -> (..., N_o) at wi
        full = np.broadcast_to(v[..., None, :], shape + (n_walls,))
        return np.take_along_axis(full, wi[..., None], axis=-1)[..., 0]

    dist = np.sqrt(np.take_along_axis(d2, wi[None], axis=0)[0])
    if wall_point == "closest":
        assert tt is not None
        t_j = np.take_along_axis(tt, wi[None], axis=0)[0]
        sx, sy_ = gather(walls.start[..., 0]), gather(walls.start[..., 1])
        point = np.stack(
            [sx + t_j * (gather(walls.end[..., 0]) - sx), sy_ + t_j * (gather(walls.end[..., 1]) - sy_)], axis=-1
        )
    else:
        point = np.stack([gather(walls.midpoint[..., 0]), gather(walls.midpoint[..., 1])], axis=-1)
    return dist, wi, point, gather(walls.normal[..., 0]), gather(walls.normal[..., 1])


def context_energy(
    centers: ArrayLike,
    yaws: ArrayLike,
    sizes: ArrayLike,
    floor: ArrayLike,
    *,
    nu_n: float = NU_N,
    mu: float = MU,
    alignment: Alignment | Sequence[str] = "parallel",
    alignment_weights: ArrayLike | None = None,
    wall_point: Literal["closest", "midpoint"] = "closest",
    anchor_offsets: ArrayLike | None = None,
) -> ContextEnergy:
    """Context prior energy ``E_ow + mu * E_oo`` for a batch of hypotheses.

    Parameters
    ----------
    centers : (..., N_o, 2) float
        Object centres projected on the floor, metres; ``...`` are batch
        axes (e.g. ``B = 3000`` hypotheses).
    yaws : (..., N_o) float
        Radians, counter-clockwise from +x to each object's front.
    sizes : (N_o, 2) or (..., N_o, 2) float
        Footprint (length along the front, width), metres.
    floor : (N, 2) or (..., N, 2) float
        Floor polygon(s), CCW; one for all hypotheses or one per hypothesis
        (e.g. when the room scale is sampled).
    nu_n, mu : float
        Weights (paper: 10 and 0.25), >= 0.
    alignment : str or sequence of N_o str
        Alignment cost mode(s), see the module docstring; default
        ``"parallel"`` (``1 - |n_o . n_w|``).
    alignment_weights : (N_o,) float, optional
        Per-object factor on the alignment term (0 for symmetric objects);
        default all ones.
    wall_point : {"closest", "midpoint"}
        ``p^w``: closest point on the closest wall segment (default) or the
        nearest wall's midpoint (the paper's ``p^w_i`` read literally).
    anchor_offsets : (N_o,) float, optional
        Signed distance along each object's front from its centre to the
        point used for the wall term (``-length / 2``: middle of the back
        edge); default zeros (the centre, as in the paper).

    Returns
    -------
    ContextEnergy

    Convention:
        World x, y in metres seen from above, inward wall normals, yaw
        CCW from +x (shared/CONVENTIONS.md).

    A 4 m x 3 m room, a 2 m x 1.6 m bed with its head against the wall
    x = 0 (facing +x), and the same bed turned sideways:

    >>> floor = [[0, 0], [4, 0], [4, 3], [0, 3]]
    >>> e = context_energy([[[1.0, 1.5]], [[1.0, 1.5]]], [[0.0], [np.pi / 2]], [[2.0, 1.6]], floor)
    >>> e.distance.tolist(), e.alignment.round(6).tolist()
    ([[1.0], [1.0]], [[0.0], [1.0]])
    >>> e.total.round(6).tolist()  # 1 m + 10 * misalignment
    [1.0, 11.0]
    """
    c, y, s = _check_objects(centers, yaws, sizes)
    poly = as_polygon(floor, name="floor")
    n_obj = c.shape[-2]
    if not (np.isfinite(nu_n) and nu_n >= 0 and np.isfinite(mu) and mu >= 0):
        raise ValueError(f"expected nu_n >= 0 and mu >= 0, got {nu_n} and {mu}")
    if wall_point not in ("closest", "midpoint"):
        raise ValueError(f"expected wall_point 'closest' or 'midpoint', got {wall_point!r}")
    if isinstance(alignment, str):
        modes = [alignment] * n_obj
    else:
        modes = list(alignment)
        if len(modes) != n_obj:
            raise ValueError(f"expected one alignment mode or {n_obj} of them, got {len(modes)}")
    bad = [m for m in modes if m not in ALIGNMENT_MODES]
    if bad:
        raise ValueError(f"expected alignment modes in {ALIGNMENT_MODES}, got {bad[0]!r}")
    if alignment_weights is None:
        weights = np.ones(n_obj)
    else:
        weights = np.asarray(alignment_weights, dtype=np.float64)
        if weights.shape != (n_obj,) or not np.all(np.isfinite(weights)) or np.any(weights < 0):
            raise ValueError(f"expected alignment_weights of shape ({n_obj},) with values >= 0, got {weights.shape}")
    try:
        np.broadcast_shapes(poly.shape[:-2], c.shape[:-2])
    except ValueError:
        raise ValueError(f"expected floor batch axes {poly.shape[:-2]} broadcastable to {c.shape[:-2]}") from None

    if anchor_offsets is not None:
        anchors = np.asarray(anchor_offsets, dtype=np.float64)
        if anchors.shape != (n_obj,) or not np.all(np.isfinite(anchors)):
            raise ValueError(f"expected finite anchor_offsets of shape ({n_obj},), got {anchors.shape}")
        cos_y, sin_y = np.cos(y), np.sin(y)
        p_obj = np.stack([c[..., 0] + anchors * cos_y, c[..., 1] + anchors * sin_y], axis=-1)
    else:
        p_obj = c

    walls = wall_segments(poly)
    lead = np.broadcast_shapes(poly.shape[:-2], c.shape[:-2])
    dist, wi, point, nx_j, ny_j = _nearest_walls(p_obj, y, walls, wall_point, modes, lead)
    cos_y, sin_y = np.cos(y), np.sin(y)
    mode_of = np.array([ALIGNMENT_MODES.index(m) for m in modes])
    align = _alignment_by_mode(cos_y * nx_j + sin_y * ny_j, cos_y * ny_j - sin_y * nx_j, mode_of)

    areas = _pair_areas(c, y, s)
    pair_m = _pairs_to_matrix(areas, n_obj)
    pair_m = np.broadcast_to(pair_m, lead + (n_obj, n_obj))
    dist = np.broadcast_to(dist, lead + (n_obj,))
    align = np.broadcast_to(align, lead + (n_obj,))
    per_wall = dist + nu_n * weights * align
    e_ow = per_wall.sum(axis=-1)
    e_oo = np.broadcast_to(areas.sum(axis=-1), lead)
    per_object = per_wall + mu * 0.5 * pair_m.sum(axis=-1)
    total = e_ow + mu * e_oo
    return ContextEnergy(
        total=total,
        prior=np.exp(-total),
        wall=e_ow,
        overlap=np.asarray(e_oo),
        distance=np.asarray(dist),
        alignment=np.asarray(align),
        pair_overlap=np.asarray(pair_m),
        per_object=per_object,
        closest_wall=np.broadcast_to(wi, lead + (n_obj,)),
        wall_point=np.broadcast_to(point, lead + (n_obj, 2)),
    )


def context_prior(
    centers: ArrayLike,
    yaws: ArrayLike,
    sizes: ArrayLike,
    floor: ArrayLike,
    **options: object,
) -> FloatArray:
    """``pi = exp(-(E_ow + mu * E_oo))`` for a batch of hypotheses.

    Same parameters and options as :func:`context_energy`; returns
    ``(...)`` float in (0, 1]. For comparing hypotheses prefer the energy
    (``exp`` underflows to 0 beyond an energy of about 745).

    >>> floor = [[0, 0], [4, 0], [4, 3], [0, 3]]
    >>> float(context_prior([[0.5, 1.5]], [0.0], [[1.0, 1.0]], floor))  # doctest: +ELLIPSIS
    0.606...
    """
    return context_energy(centers, yaws, sizes, floor, **options).prior  # type: ignore[arg-type]
