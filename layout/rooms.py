"""Synthetic Manhattan rooms: templates of arbitrary shape and the paper's
perturbation (Sec. 5, synthetic data).

Templates (corner counts): ``rectangle`` (4), ``L`` (6), ``T`` (8), ``U`` (8),
``plus`` (12), ``notched`` (rectangle with 1-3 notches or alcoves: 8, 12,
16), ``corridor`` (long and thin, optionally with a side room: 4, 6, 8).
Sizes are drawn per template (bounding boxes 2.5-8 m per side, corridors
4.5-9 m long; corridors, arms and bars at least 1.8 m wide in the template,
so at least 1.2 m after the offsets; walls at least 0.4 m long),
then the template is turned by a random multiple of 90 degrees and
possibly mirrored.

The paper's perturbation, exactly:

* wall height ``ceiling_z ~ N(2.7, 0.2)`` m (not truncated);
* every wall whose TEMPLATE length exceeds 0.7 m gets an offset
  ``delta ~ U[-0.3, 0.3]`` m added to its length.

How an offset is applied (a Manhattan polygon cannot change one wall length
alone and stay closed): walls are visited in order; for wall i, running
along axis a, we pick a cut inside its extent, between two consecutive
distinct vertex coordinates along a, and move every vertex beyond the cut by
``delta`` along a (a "strip stretch"). Wall i gets exactly ``delta`` longer;
the other walls parallel to it that span the same cut change by the same
``delta`` (for a rectangle the width becomes ``W + delta_0 + delta_2``);
all other walls keep their length. The map is strictly increasing along a,
so the polygon stays closed, Manhattan and simple. Among the possible cuts
we skip those spanned by a wall of template length <= 0.7 m (such walls
keep their template length exactly) and take the widest strip; if no cut
keeps every strip >= ``min_wall`` the room is drawn again. The sampled
offsets are recorded in :attr:`Room.offsets`.

Convention:
    World frame x, y (metres), z up, floor at z = 0. ``Room.floor`` is CCW
    seen from above, no repeated closing vertex, consecutive edges
    orthogonal and axis-aligned; its bounding box is centred on the origin
    (the generator does not know the camera; see
    :meth:`Room.translated`). Wall i runs from vertex i to vertex i + 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .polygon import Walls, as_ccw, polygon_problems, signed_area, validate_floor_polygon, wall_segments

__all__ = [
    "TEMPLATE_NAMES",
    "Room",
    "as_generator",
    "make_template",
    "perturb_walls",
    "generate_room",
    "generate_rooms",
]

FloatArray = NDArray[np.float64]

TEMPLATE_NAMES: tuple[str, ...] = ("rectangle", "L", "T", "U", "plus", "notched", "corridor")


def as_generator(rng: int | np.random.Generator | None) -> np.random.Generator:
    """A numpy Generator from a seed, a Generator (returned as is) or None
    (fresh entropy).

    >>> int(as_generator(3).integers(100)) == int(as_generator(3).integers(100))
    True
    """
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, (int, np.integer)) and not isinstance(rng, bool)):
        return np.random.default_rng(rng)
    raise ValueError(f"expected an int seed, a numpy Generator or None, got {type(rng).__name__}")


def _ro(a: ArrayLike, dtype: type = np.float64) -> NDArray:
    arr = np.array(a, dtype=dtype)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Room:
    """A generated room.

    Attributes
    ----------
    floor : (N, 2) float
        Floor polygon, metres, CCW seen from above, Manhattan, no repeated
        closing vertex.
    ceiling_z : float
        Wall height in metres (floor at z = 0).
    template : str
        One of :data:`TEMPLATE_NAMES`.
    template_floor : (N, 2) float
        The polygon before the wall-length offsets (same vertex order,
        same centring shift as ``floor``).
    offsets : (N,) float
        Sampled length offset of each wall (0 where none was applied).
    offset_applied : (N,) bool
        True where the template wall was longer than the threshold (0.7 m).

    Convention:
        World x, y, z (z up), metres; wall i runs from vertex i to i + 1.
    """

    floor: FloatArray
    ceiling_z: float
    template: str
    template_floor: FloatArray
    offsets: FloatArray
    offset_applied: NDArray[np.bool_]
    _walls: Walls | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        floor = validate_floor_polygon(self.floor)
        n = len(floor)
        tf = np.asarray(self.template_floor, dtype=np.float64)
        off = np.asarray(self.offsets, dtype=np.float64)
        app = np.asarray(self.offset_applied, dtype=bool)
        if tf.shape != floor.shape or off.shape != (n,) or app.shape != (n,):
            raise ValueError(
                f"expected template_floor {floor.shape}, offsets ({n},), offset_applied ({n},), "
                f"got {tf.shape}, {off.shape}, {app.shape}"
            )
        if not (np.isfinite(self.ceiling_z) and self.ceiling_z > 0):
            raise ValueError(f"expected a positive ceiling_z, got {self.ceiling_z}")
        object.__setattr__(self, "floor", _ro(floor))
        object.__setattr__(self, "template_floor", _ro(tf))
        object.__setattr__(self, "offsets", _ro(off))
        object.__setattr__(self, "offset_applied", _ro(app, bool))
        object.__setattr__(self, "ceiling_z", float(self.ceiling_z))
        object.__setattr__(self, "_walls", wall_segments(floor))

    @property
    def walls(self) -> Walls:
        """Wall segments with inward normals (see :func:`layout.polygon.wall_segments`)."""
        assert self._walls is not None
        return self._walls

    @property
    def n_corners(self) -> int:
        return int(len(self.floor))

    @property
    def wall_lengths(self) -> FloatArray:
        """(N,) wall lengths in metres."""
        return self.walls.length

    @property
    def area(self) -> float:
        """Floor area in square metres."""
        return float(signed_area(self.floor))

    def translated(self, shift: ArrayLike) -> "Room":
        """The same room moved by ``shift`` (2,) metres in x, y (e.g.
        ``-camera_xy`` to put the origin below the camera)."""
        s = np.asarray(shift, dtype=np.float64)
        if s.shape != (2,) or not np.all(np.isfinite(s)):
            raise ValueError(f"expected a finite shift of shape (2,), got {s.shape}")
        return Room(
            floor=self.floor + s,
            ceiling_z=self.ceiling_z,
            template=self.template,
            template_floor=self.template_floor + s,
            offsets=self.offsets,
            offset_applied=self.offset_applied,
        )


# --------------------------------------------------------------------------- templates


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, max(lo, hi)))


def _rectangle(rng: np.random.Generator) -> FloatArray:
    w, d = _u(rng, 2.5, 8.0), _u(rng, 2.5, 8.0)
    return np.array([[0, 0], [w, 0], [w, d], [0, d]], float)


def _l_shape(rng: np.random.Generator) -> FloatArray:
    w, d = _u(rng, 3.5, 8.0), _u(rng, 3.5, 8.0)
    cw, cd = _u(rng, 1.2, w - 2.0), _u(rng, 1.2, d - 2.0)
    return np.array([[0, 0], [w, 0], [w, d - cd], [w - cw, d - cd], [w - cw, d], [0, d]], float)


def _t_shape(rng: np.random.Generator) -> FloatArray:
    w, d = _u(rng, 4.5, 8.0), _u(rng, 4.0, 8.0)
    bd = _u(rng, 1.8, d - 2.0)  # depth of the bar
    sw = _u(rng, 1.8, w - 2.4)  # stem width
    x0 = _u(rng, 1.2, w - 1.2 - sw)
    x1 = x0 + sw
    return np.array(
        [[x0, 0], [x1, 0], [x1, d - bd], [w, d - bd], [w, d], [0, d], [0, d - bd], [x0, d - bd]], float
    )


def _u_shape(rng: np.random.Generator) -> FloatArray:
    w, d = _u(rng, 5.4, 8.0), _u(rng, 3.5, 8.0)
    bd = _u(rng, 1.8, d - 1.6)  # depth of the base
    a1 = _u(rng, 1.8, (w - 1.8) / 2)  # arm widths; the gap between the arms is >= 1.8 m
    a2 = _u(rng, 1.8, (w - 1.8) / 2)
    return np.array([[0, 0], [w, 0], [w, d], [w - a2, d], [w - a2, bd], [a1, bd], [a1, d], [0, d]], float)


def _plus_shape(rng: np.random.Generator) -> FloatArray:
    w, d = _u(rng, 5.0, 8.0), _u(rng, 5.0, 8.0)
    bw = _u(rng, 1.8, w - 2.8)  # vertical bar width
    x0 = _u(rng, 1.2, w - 1.2 - bw)
    x1 = x0 + bw
    bh = _u(rng, 1.8, d - 2.8)
    y0 = _u(rng, 1.2, d - 1.2 - bh)
    y1 = y0 + bh
    return np.array(
        [
            [x0, 0], [x1, 0], [x1, y0], [w, y0], [w, y1], [x1, y1],
            [x1, d], [x0, d], [x0, y1], [0, y1], [0, y0], [x0, y0],
        ],
        float,
    )


def _notched(rng: np.random.Generator) -> FloatArray:
    while True:  # until at least one notch fits
        poly = _notched_draw(rng)
        if len(poly) > 4:
            return poly


def _notched_draw(rng: np.random.Generator) -> FloatArray:
    w, d = _u(rng, 3.6, 8.0), _u(rng, 3.6, 8.0)
    corners = np.array([[0, 0], [w, 0], [w, d], [0, d]], float)
    k = int(rng.choice([1, 2, 3], p=[0.5, 0.35, 0.15]))
    chosen = set(int(s) for s in rng.choice(4, size=k, replace=False))
    # depth: shallow (<= 0.7 m, no offset, keeps its length) or deep (>= 1.0 m,
    # so that the offsets of both its side walls leave >= 0.4 m)
    depth = {s: (_u(rng, 0.4, 0.7) if rng.uniform() < 0.5 else _u(rng, 1.0, 1.4)) for s in sorted(chosen)}
    sign = {s: (1.0 if rng.uniform() < 0.5 else -1.0) for s in sorted(chosen)}  # +1 closet, -1 alcove

    def intrusion(s: int) -> float:
        return depth[s] if s in chosen and sign[s] > 0 else 0.0

    verts: list[FloatArray] = []
    for s in range(4):
        p, q = corners[s], corners[(s + 1) % 4]
        verts.append(p)
        if s not in chosen:
            continue
        side = float(np.linalg.norm(q - p))
        # keep >= 0.8 m of wall beyond a closet on the neighbouring side
        m0 = max(1.2, intrusion((s - 1) % 4) + 0.8)
        m1 = max(1.2, intrusion((s + 1) % 4) + 0.8)
        if side - m0 - m1 < 1.0:
            continue
        u = (q - p) / side
        n = np.array([-u[1], u[0]])  # inward for a CCW rectangle
        nw = _u(rng, 1.0, min(2.2, side - m0 - m1))  # notch width
        a = _u(rng, m0, side - m1 - nw)
        dn = sign[s] * depth[s] * n
        verts += [p + a * u, p + a * u + dn, p + (a + nw) * u + dn, p + (a + nw) * u]
    return np.array(verts, float)


def _corridor(rng: np.random.Generator) -> FloatArray:
    cw, cl = _u(rng, 1.8, 2.4), _u(rng, 4.5, 9.0)
    kind = int(rng.choice([0, 1, 2], p=[0.4, 0.3, 0.3]))  # plain, side room at an end, in the middle
    if kind == 0:
        return np.array([[0, 0], [cl, 0], [cl, cw], [0, cw]], float)
    sw, sd = _u(rng, 2.2, min(4.0, cl - 2.4)), _u(rng, 2.0, 3.5)
    if kind == 1:
        return np.array([[0, 0], [cl, 0], [cl, cw + sd], [cl - sw, cw + sd], [cl - sw, cw], [0, cw]], float)
    x0 = _u(rng, 1.2, cl - 1.2 - sw)
    x1 = x0 + sw
    return np.array(
        [[0, 0], [cl, 0], [cl, cw], [x1, cw], [x1, cw + sd], [x0, cw + sd], [x0, cw], [0, cw]], float
    )


_TEMPLATES: dict[str, Callable[[np.random.Generator], FloatArray]] = {
    "rectangle": _rectangle,
    "L": _l_shape,
    "T": _t_shape,
    "U": _u_shape,
    "plus": _plus_shape,
    "notched": _notched,
    "corridor": _corridor,
}


def make_template(name: str, rng: int | np.random.Generator | None = None, *, turn: bool = True) -> FloatArray:
    """Draw the sizes of one room template (no wall-length offsets).

    Parameters
    ----------
    name : str
        One of :data:`TEMPLATE_NAMES`.
    rng : int, numpy Generator or None
    turn : bool
        Rotate by a random multiple of 90 degrees and mirror with
        probability 1/2 (then re-ordered to stay CCW).

    Returns
    -------
    (N, 2) float
        CCW, axis-aligned Manhattan polygon, bounding box centred on the origin.

    Convention:
        World x, y in metres seen from above.

    >>> p = make_template("L", 0)
    >>> p.shape
    (6, 2)
    """
    if name not in _TEMPLATES:
        raise ValueError(f"expected a template name in {TEMPLATE_NAMES}, got {name!r}")
    g = as_generator(rng)
    poly = _TEMPLATES[name](g)
    if turn:
        k = int(g.integers(4))
        rot = np.array([[0.0, -1.0], [1.0, 0.0]])
        poly = poly @ np.linalg.matrix_power(rot, k).T
        if g.uniform() < 0.5:
            poly = poly * np.array([-1.0, 1.0])
        poly = as_ccw(poly)
        start = int(g.integers(len(poly)))
        poly = np.roll(poly, -start, axis=0)
    poly = poly - 0.5 * (poly.min(axis=0) + poly.max(axis=0))
    return np.round(poly, 12) + 0.0


# --------------------------------------------------------------------------- perturbation


def _axis_of_edges(poly: FloatArray) -> NDArray[np.intp]:
    e = np.roll(poly, -1, axis=0) - poly
    return np.where(np.abs(e[:, 0]) >= np.abs(e[:, 1]), 0, 1)


def _choose_cut(
    poly: FloatArray, wall: int, axis: NDArray[np.intp], frozen: NDArray[np.bool_], delta: float, min_wall: float
) -> float | None:
    """Coordinate c along the wall's axis: vertices with coordinate >= c move."""
    a = int(axis[wall])
    q = np.roll(poly, -1, axis=0)
    lo_all = np.minimum(poly[:, a], q[:, a])
    hi_all = np.maximum(poly[:, a], q[:, a])
    lo, hi = lo_all[wall], hi_all[wall]
    coords = np.unique(poly[:, a])
    inside = coords[(coords >= lo - 1e-9) & (coords <= hi + 1e-9)]
    best: tuple[float, float] | None = None
    parallel = axis == a
    for g0, g1 in zip(inside[:-1], inside[1:]):
        width = g1 - g0
        if width + delta < min_wall:
            continue
        mid = 0.5 * (g0 + g1)
        spanning = parallel & (lo_all < mid) & (hi_all > mid)
        if np.any(spanning & frozen):
            continue
        if best is None or width > best[0] + 1e-12:
            best = (width, float(g1))
    return None if best is None else best[1]


def perturb_walls(
    polygon: ArrayLike,
    rng: int | np.random.Generator | None = None,
    *,
    offset_max: float = 0.3,
    min_length: float = 0.7,
    min_wall: float = 0.4,
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]] | None:
    """Add a length offset ``U[-offset_max, offset_max]`` to every wall longer
    than ``min_length`` by strip stretches (see the module docstring).

    Parameters
    ----------
    polygon : (N, 2) float
        Axis-aligned Manhattan polygon, CCW.
    rng : int, numpy Generator or None
    offset_max, min_length, min_wall : float
        Metres; ``min_wall`` is the smallest strip width (hence wall length)
        a stretch may leave.

    Returns
    -------
    (floor, offsets, applied), or None when an offset cannot be applied
    without a strip narrower than ``min_wall`` (the caller draws again).
    ``floor (N, 2)`` keeps the vertex order; ``offsets (N,)`` are the
    sampled offsets (0 where not applied); ``applied (N,)`` bool.

    Convention:
        World x, y in metres, axis-aligned walls.

    >>> floor, off, app = perturb_walls([[0, 0], [4, 0], [4, 3], [0, 3]], 0)
    >>> bool(np.isclose(floor[1, 0] - floor[0, 0], 4 + off[0] + off[2]))
    True
    """
    p = validate_floor_polygon(polygon)
    if not (0 <= offset_max and 0 <= min_length and 0 < min_wall):
        raise ValueError(
            f"expected offset_max >= 0, min_length >= 0, min_wall > 0, got {offset_max}, {min_length}, {min_wall}"
        )
    axis = _axis_of_edges(p)
    e = np.roll(p, -1, axis=0) - p
    if np.any(np.min(np.abs(e), axis=1) > 1e-9):
        raise ValueError("expected an axis-aligned Manhattan polygon, got an edge that is not parallel to x or y")
    g = as_generator(rng)
    lengths = np.abs(e).max(axis=1)
    applied = lengths > min_length
    offsets = np.where(applied, g.uniform(-offset_max, offset_max, size=len(p)), 0.0)
    frozen = ~applied
    cur = p.copy()
    for i in np.flatnonzero(applied):
        cut = _choose_cut(cur, int(i), axis, frozen, float(offsets[i]), min_wall)
        if cut is None:
            return None
        a = int(axis[i])
        move = cur[:, a] >= cut - 1e-9
        cur[move, a] += offsets[i]
    return cur, offsets, applied


def generate_room(
    rng: int | np.random.Generator | None = None,
    *,
    template: str | None = None,
    templates: Sequence[str] = TEMPLATE_NAMES,
    height_mean: float = 2.7,
    height_std: float = 0.2,
    offset_max: float = 0.3,
    offset_min_length: float = 0.7,
    min_wall: float = 0.4,
    max_attempts: int = 100,
) -> Room:
    """Draw one synthetic room: template, sizes, wall height and wall offsets.

    Parameters
    ----------
    rng : int, numpy Generator or None
        The only source of randomness: a seed gives the same room.
    template : str, optional
        Force one template; otherwise drawn uniformly from ``templates``.
    height_mean, height_std : float
        Wall height distribution, metres (paper: 2.7, 0.2).
    offset_max, offset_min_length : float
        Wall-length offsets ``U[-offset_max, offset_max]`` on walls longer
        than ``offset_min_length`` (paper: 0.3, 0.7).
    min_wall : float
        No wall shorter than this (metres).
    max_attempts : int
        Redraws of the template when an offset would break ``min_wall``.

    Returns
    -------
    Room

    Convention:
        World frame x, y, z up, metres; floor CCW, bounding box centred on
        the origin.

    >>> room = generate_room(7, template="U")
    >>> room.n_corners, room.template
    (8, 'U')
    >>> generate_room(7).floor.tolist() == generate_room(7).floor.tolist()
    True
    """
    names = tuple(templates)
    if not names or any(t not in _TEMPLATES for t in names):
        raise ValueError(f"expected templates from {TEMPLATE_NAMES}, got {names}")
    if template is not None and template not in _TEMPLATES:
        raise ValueError(f"expected a template name in {TEMPLATE_NAMES}, got {template!r}")
    if not (height_std >= 0 and height_mean > 0):
        raise ValueError(f"expected height_mean > 0 and height_std >= 0, got {height_mean}, {height_std}")
    if max_attempts < 1:
        raise ValueError(f"expected max_attempts >= 1, got {max_attempts}")
    g = as_generator(rng)
    name = template if template is not None else names[int(g.integers(len(names)))]
    height = float(g.normal(height_mean, height_std))
    for _ in range(max_attempts):
        base = make_template(name, g)
        out = perturb_walls(base, g, offset_max=offset_max, min_length=offset_min_length, min_wall=min_wall)
        if out is None:
            continue
        floor, offsets, applied = out
        shift = -0.5 * (floor.min(axis=0) + floor.max(axis=0))
        floor = floor + shift
        if polygon_problems(floor, min_edge=min_wall):
            continue
        return Room(
            floor=floor,
            ceiling_z=height,
            template=name,
            template_floor=base + shift,
            offsets=offsets,
            offset_applied=applied,
        )
    raise ValueError(
        f"expected a {name!r} room to be drawable with min_wall={min_wall} and offset_max={offset_max}, "
        f"got no valid draw in {max_attempts} attempts"
    )


def generate_rooms(n: int, rng: int | np.random.Generator | None = None, **kwargs: object) -> list[Room]:
    """``n`` rooms from one Generator (see :func:`generate_room` for options).

    >>> [r.template for r in generate_rooms(3, 0)] == [r.template for r in generate_rooms(3, 0)]
    True
    """
    if not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"expected a non-negative int n, got {n!r}")
    g = as_generator(rng)
    return [generate_room(g, **kwargs) for _ in range(int(n))]  # type: ignore[arg-type]
