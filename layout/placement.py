"""Object and camera placement in a room with the context prior (Sec. 5:
"Objects are placed at random, and their position and orientation are
updated by sampling from the context prior").

Algorithm of :func:`place_objects`:

1. Initial placement, largest footprint first: ``init_tries`` random
   draws, centre uniform in the room's bounding box, yaw uniform in
   [0, 2 pi); among the draws whose footprint lies inside the floor and
   overlaps no placed footprint, the one of lowest prior energy is kept
   (a second round tries yaws along the room axes if none fits). A spec
   that fits nowhere is dropped with the reason.
2. Sampling epochs (the paper's scheme: ``epochs`` x ``samples_per_epoch``,
   8 x 25 in Sec. 4): every sample perturbs every object of the seed
   configuration with Gaussian noise on position and yaw. Once overlaps
   are excluded the energy is a sum over objects, so the best combination
   of the samples is the per-object best: each object keeps its lowest
   energy pose among the seed and its in-room samples, then moved objects
   that now overlap are put back (smaller gain first) until no pair
   overlaps. The seed is kept, so the energy never increases. The
   proposal standard deviations shrink geometrically over the epochs from
   ``pos_sigma[0]``/``yaw_sigma[0]`` to ``pos_sigma[1]``/``yaw_sigma[1]``.
3. Camera: uniform among points of the floor at least
   ``camera_wall_clearance`` (0.5 m) from every wall and
   ``camera_object_clearance`` (0.3 m) from every footprint; height
   uniform in ``camera_height_range`` ([1.3, 1.8] m). If no such point
   exists the smallest object is removed (and reported) until one does.

Hard constraints of the result: every footprint inside the floor polygon
(up to ``wall_tol``), no two footprints sharing more than ``overlap_tol``
(1 cm^2), the camera as above.

Convention:
    World frame x, y, z up, metres (the room's frame; see
    :meth:`Placement.centered_on_camera` for the frame with the origin
    below the camera). Yaw in radians in [0, 2 pi), counter-clockwise from
    +x to the object's front; size = (length along the front, width,
    height); centre = centre of the 3D box, z = elevation + height / 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Collection, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .context import ALIGNMENT_MODES, MU, NU_N, context_energy
from .polygon import _convex_in_polygon, _convex_intersection_area, _rectangles, points_in_polygon
from .rooms import Room, as_generator

__all__ = [
    "ObjectSpec",
    "PlacedObject",
    "DroppedSpec",
    "Placement",
    "CLASS_ALIGNMENT",
    "BACK_TO_WALL",
    "BEDROOM_COUNTS",
    "CLUTTER_CLASSES",
    "sample_class_counts",
    "place_objects",
]

FloatArray = NDArray[np.float64]

#: Default alignment mode per class (see :mod:`layout.context`): furniture
#: with a back faces into the room, chairs may face a wall (desk) or the
#: room, tables align with the walls in any of the four directions.
CLASS_ALIGNMENT: dict[str, str] = {
    "bed": "facing",
    "tv": "facing",
    "sofa": "facing",
    "wardrobe": "facing",
    "nightstand": "facing",
    "chair": "parallel",
    "table": "axis",
}

#: Classes that stand with their back to a wall: their wall term is measured
#: from the middle of the back edge (``anchor_offsets = -length / 2`` in
#: :func:`layout.context.context_energy`) instead of the centre.
BACK_TO_WALL: frozenset[str] = frozenset({"bed", "tv", "sofa", "wardrobe", "nightstand"})

#: Default bedroom contents: class -> (min, max) count, inclusive.
BEDROOM_COUNTS: dict[str, tuple[int, int]] = {"bed": (1, 1), "chair": (1, 3), "tv": (1, 1), "plant": (0, 2)}
#: Clutter classes drawn by :func:`sample_class_counts`.
CLUTTER_CLASSES: tuple[str, ...] = ("sofa", "table", "nightstand", "wardrobe")


@dataclass(frozen=True)
class ObjectSpec:
    """What to place: a plain record the caller builds from its model library.

    Attributes
    ----------
    class_name : str
        Lowercase class (``bed``, ``chair``, ``tv``, ``plant``, ...).
    size : (3,) float
        (length along the front, width, height), metres, > 0.
    model_id : str
        Identifier of the 3D model, passed through.
    symmetric : bool
        Rotationally symmetric (plants): no alignment term.
    elevation : float
        Height of the object's base above the floor (0 for floor-standing).
    """

    class_name: str
    size: tuple[float, float, float]
    model_id: str = ""
    symmetric: bool = False
    elevation: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.class_name, str) or not self.class_name:
            raise ValueError(f"expected a non-empty class_name, got {self.class_name!r}")
        size = tuple(float(v) for v in np.asarray(self.size, dtype=np.float64).ravel())
        if len(size) != 3 or not all(math.isfinite(v) and v > 0 for v in size):
            raise ValueError(f"expected size (length, width, height) of 3 positive numbers, got {self.size!r}")
        if not (math.isfinite(self.elevation) and self.elevation >= 0):
            raise ValueError(f"expected elevation >= 0, got {self.elevation}")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "elevation", float(self.elevation))


@dataclass(frozen=True)
class PlacedObject:
    """A placed object.

    Attributes
    ----------
    class_name, model_id : str
    size : (3,) tuple of float
        (length, width, height) in metres.
    center : (3,) tuple of float
        Centre of the 3D box in the room frame; z = elevation + height / 2.
    yaw : float
        Radians in [0, 2 pi), counter-clockwise from +x to the front.
    symmetric : bool
    """

    class_name: str
    model_id: str
    size: tuple[float, float, float]
    center: tuple[float, float, float]
    yaw: float
    symmetric: bool = False

    @property
    def yaw_deg(self) -> float:
        """Yaw in degrees, [0, 360)."""
        return math.degrees(self.yaw) % 360.0

    @property
    def footprint(self) -> FloatArray:
        """(4, 2) floor footprint corners, counter-clockwise."""
        return _rectangles(np.array(self.center[:2]), np.array(self.yaw), np.array(self.size[:2]))


@dataclass(frozen=True)
class DroppedSpec:
    """A spec that could not be placed, and why."""

    spec: ObjectSpec
    reason: str


@dataclass(frozen=True, eq=False)
class Placement:
    """Result of :func:`place_objects`.

    Attributes
    ----------
    room : Room
    objects : tuple of PlacedObject
    camera_xy : (2,) float
        Camera position on the floor plane, room frame, metres.
    camera_height : float
        Camera centre height above the floor, metres.
    energy : float
        Context prior energy ``E_ow + mu * E_oo`` of the objects, with the
        options used for the placement (alignment modes, back anchors).
    dropped : tuple of DroppedSpec
    """

    room: Room
    objects: tuple[PlacedObject, ...]
    camera_xy: FloatArray
    camera_height: float
    energy: float
    dropped: tuple[DroppedSpec, ...]

    @property
    def prior(self) -> float:
        """``exp(-energy)``."""
        return math.exp(-self.energy)

    @property
    def centers(self) -> FloatArray:
        """(N_o, 3) object centres."""
        return np.array([o.center for o in self.objects], dtype=np.float64).reshape(-1, 3)

    @property
    def yaws(self) -> FloatArray:
        """(N_o,) yaws in radians."""
        return np.array([o.yaw for o in self.objects], dtype=np.float64)

    @property
    def footprints(self) -> FloatArray:
        """(N_o, 4, 2) footprint corners, counter-clockwise."""
        if not self.objects:
            return np.zeros((0, 4, 2))
        return np.stack([o.footprint for o in self.objects])

    def centered_on_camera(self) -> "Placement":
        """The same scene translated so that the camera is at x = y = 0
        (the world frame of shared/CONVENTIONS.md)."""
        shift = -np.asarray(self.camera_xy, dtype=np.float64)
        objs = tuple(
            PlacedObject(
                class_name=o.class_name,
                model_id=o.model_id,
                size=o.size,
                center=(o.center[0] + shift[0], o.center[1] + shift[1], o.center[2]),
                yaw=o.yaw,
                symmetric=o.symmetric,
            )
            for o in self.objects
        )
        return Placement(
            room=self.room.translated(shift),
            objects=objs,
            camera_xy=np.zeros(2),
            camera_height=self.camera_height,
            energy=self.energy,
            dropped=self.dropped,
        )


def sample_class_counts(
    rng: int | np.random.Generator | None = None,
    *,
    counts: Mapping[str, tuple[int, int]] = BEDROOM_COUNTS,
    clutter: Sequence[str] = CLUTTER_CLASSES,
    clutter_range: tuple[int, int] = (1, 3),
) -> dict[str, int]:
    """Draw how many objects of each class a room gets.

    Parameters
    ----------
    rng : int, numpy Generator or None
    counts : mapping class -> (min, max)
        Inclusive uniform ranges (default: one bed, 1-3 chairs, one TV,
        0-2 plants).
    clutter : sequence of str
        Classes drawn (with replacement) for the clutter.
    clutter_range : (min, max)
        How many clutter objects, inclusive.

    Returns
    -------
    dict class -> count (classes with count 0 included).

    >>> c = sample_class_counts(0)
    >>> c["bed"], c["tv"], 1 <= c["chair"] <= 3
    (1, 1, True)
    """
    g = as_generator(rng)
    out: dict[str, int] = {}
    for name, rng_pair in counts.items():
        lo, hi = (int(v) for v in rng_pair)
        if not 0 <= lo <= hi:
            raise ValueError(f"expected 0 <= min <= max for {name!r}, got {rng_pair}")
        out[name] = int(g.integers(lo, hi + 1))
    lo, hi = (int(v) for v in clutter_range)
    if not 0 <= lo <= hi:
        raise ValueError(f"expected 0 <= min <= max clutter_range, got {clutter_range}")
    n_clutter = int(g.integers(lo, hi + 1))
    if n_clutter and not clutter:
        raise ValueError("expected clutter classes when clutter_range allows clutter, got none")
    for c in clutter:
        out.setdefault(c, 0)
    for _ in range(n_clutter):
        out[clutter[int(g.integers(len(clutter)))]] += 1
    return out


# --------------------------------------------------------------------------- helpers


def _overlaps_with(rects: FloatArray, placed: list[FloatArray]) -> FloatArray:
    """Max overlap area of each candidate rect (T, 4, 2) with the placed ones."""
    if not placed:
        return np.zeros(len(rects))
    others = np.stack(placed)  # (P, 4, 2)
    a = np.broadcast_to(rects[:, None], (len(rects), len(others), 4, 2))
    b = np.broadcast_to(others[None], a.shape)
    return _convex_intersection_area(a, b).max(axis=1)


def _wrap_angle(yaw: float) -> float:
    """yaw in [0, 2 pi) (float rounding can give 2 pi from a tiny negative)."""
    w = math.fmod(yaw, 2 * math.pi)
    if w < 0:
        w += 2 * math.pi
    return 0.0 if w >= 2 * math.pi else w


def _point_rect_distance(points: FloatArray, centers: FloatArray, yaws: FloatArray, sizes: FloatArray) -> FloatArray:
    """Distance from points (T, 2) to filled rectangles (N_o) -> (T, N_o); 0 inside."""
    rel = points[:, None, :] - centers[None]
    cos, sin = np.cos(yaws), np.sin(yaws)
    lx = rel[..., 0] * cos + rel[..., 1] * sin
    ly = -rel[..., 0] * sin + rel[..., 1] * cos
    dx = np.maximum(np.abs(lx) - sizes[:, 0] / 2, 0.0)
    dy = np.maximum(np.abs(ly) - sizes[:, 1] / 2, 0.0)
    return np.sqrt(dx * dx + dy * dy)


def _pair_matrix(centers: FloatArray, yaws: FloatArray, sizes: FloatArray) -> FloatArray:
    n = len(centers)
    m = np.zeros((n, n))
    if n < 2:
        return m
    i, j = np.triu_indices(n, k=1)
    rects = _rectangles(centers, yaws, sizes)
    a = _convex_intersection_area(rects[i], rects[j])
    m[i, j] = a
    m[j, i] = a
    return m


def place_objects(
    room: Room,
    specs: Sequence[ObjectSpec],
    rng: int | np.random.Generator | None = None,
    *,
    epochs: int = 8,
    samples_per_epoch: int = 25,
    pos_sigma: tuple[float, float] = (0.5, 0.02),
    yaw_sigma: tuple[float, float] = (0.6, 0.02),
    init_tries: int = 400,
    alignment: Mapping[str, str] | None = None,
    back_to_wall: Collection[str] = BACK_TO_WALL,
    nu_n: float = NU_N,
    mu: float = MU,
    camera_wall_clearance: float = 0.5,
    camera_object_clearance: float = 0.3,
    camera_height_range: tuple[float, float] = (1.3, 1.8),
    overlap_tol: float = 1e-4,
    wall_tol: float = 1e-6,
) -> Placement:
    """Place objects and a camera in a room, refined with the context prior.

    Parameters
    ----------
    room : Room
        From :func:`layout.rooms.generate_room` (or built by hand).
    specs : sequence of ObjectSpec
        What to place (the caller converts from its model library).
    rng : int, numpy Generator or None
        The only source of randomness.
    epochs, samples_per_epoch : int
        Sampling scheme (paper: 8 x 25).
    pos_sigma, yaw_sigma : (first, last)
        Proposal standard deviations (metres, radians), shrinking
        geometrically over the epochs.
    init_tries : int
        Random draws per object for the initial placement.
    alignment : mapping class -> mode, optional
        Alignment mode per class for the prior (default
        :data:`CLASS_ALIGNMENT`, other classes ``"parallel"``); symmetric
        specs get no alignment term.
    back_to_wall : collection of str
        Classes whose wall term is measured from the middle of the back
        edge (default :data:`BACK_TO_WALL`): "against the wall" is their
        optimum. Other classes use the centre, as in the paper.
    nu_n, mu : float
        Prior weights (paper: 10, 0.25).
    camera_wall_clearance, camera_object_clearance : float
        Metres (0.5 and 0.3).
    camera_height_range : (low, high)
        Uniform camera height, metres ([1.3, 1.8]).
    overlap_tol : float
        Largest allowed footprint intersection, m^2 (1 cm^2).
    wall_tol : float
        Allowed footprint penetration into a wall, metres.

    Returns
    -------
    Placement
        Objects in the order of ``specs`` (dropped ones removed and listed
        in ``dropped``), camera, prior energy.

    Convention:
        Room frame x, y, z up, metres; yaw CCW from +x in [0, 2 pi).

    >>> from layout.rooms import generate_room
    >>> room = generate_room(0, template="rectangle")
    >>> specs = [ObjectSpec("bed", (2.0, 1.6, 0.5), "bed-0"), ObjectSpec("plant", (0.4, 0.4, 0.8), "p", True)]
    >>> pl = place_objects(room, specs, 0)
    >>> [o.class_name for o in pl.objects], len(pl.dropped)
    (['bed', 'plant'], 0)
    >>> 1.3 <= pl.camera_height <= 1.8
    True
    """
    if not isinstance(room, Room):
        raise ValueError(f"expected a layout.rooms.Room, got {type(room).__name__}")
    specs = list(specs)
    for s in specs:
        if not isinstance(s, ObjectSpec):
            raise ValueError(f"expected ObjectSpec items in specs, got {type(s).__name__}")
    for name, v in (("epochs", epochs), ("samples_per_epoch", samples_per_epoch), ("init_tries", init_tries)):
        if not isinstance(v, (int, np.integer)) or v < (0 if name == "epochs" else 1):
            raise ValueError(f"expected integer {name} >= {0 if name == 'epochs' else 1}, got {v!r}")
    pairs = (("pos_sigma", pos_sigma), ("yaw_sigma", yaw_sigma), ("camera_height_range", camera_height_range))
    for name, pair in pairs:
        if len(pair) != 2 or not all(math.isfinite(float(v)) and float(v) > 0 for v in pair):
            raise ValueError(f"expected {name} as two positive numbers, got {pair!r}")
    h_lo, h_hi = (float(v) for v in camera_height_range)
    if h_lo > h_hi or h_hi >= room.ceiling_z:
        raise ValueError(
            f"expected camera_height_range low <= high < ceiling ({room.ceiling_z:.3f} m), got {camera_height_range}"
        )
    if camera_wall_clearance < 0 or camera_object_clearance < 0 or overlap_tol < 0 or wall_tol < 0:
        raise ValueError("expected non-negative clearances and tolerances, got a negative value")
    align_map = dict(CLASS_ALIGNMENT if alignment is None else alignment)
    bad = [m for m in align_map.values() if m not in ALIGNMENT_MODES]
    if bad:
        raise ValueError(f"expected alignment modes in {ALIGNMENT_MODES}, got {bad[0]!r}")

    back = frozenset(back_to_wall)

    def anchor_of(spec: ObjectSpec) -> float:
        return -0.5 * spec.size[0] if spec.class_name in back else 0.0

    g = as_generator(rng)
    floor = room.floor
    lo, hi = floor.min(axis=0), floor.max(axis=0)
    dropped: list[DroppedSpec] = []

    # 1. initial random placement, largest footprint first ------------------------------
    order = sorted(range(len(specs)), key=lambda k: -specs[k].size[0] * specs[k].size[1])
    kept: list[int] = []
    centers: list[FloatArray] = []
    yaws: list[float] = []
    rects: list[FloatArray] = []
    for k in order:
        spec = specs[k]
        size2 = np.array(spec.size[:2])
        found = None
        for axis_yaws in (False, True):
            c = g.uniform(lo, hi, size=(init_tries, 2))
            if axis_yaws:
                y = g.integers(4, size=init_tries) * (np.pi / 2)
            else:
                y = g.uniform(0.0, 2 * np.pi, size=init_tries)
            r = _rectangles(c, y, np.broadcast_to(size2, (init_tries, 2)))
            ok = _convex_in_polygon(r, floor, wall_tol)
            if np.any(ok):
                ok &= _overlaps_with(r, rects) <= overlap_tol
            hits = np.flatnonzero(ok)
            if hits.size:
                # keep the feasible draw of lowest prior energy (its own terms)
                mode = "parallel" if spec.symmetric else align_map.get(spec.class_name, "parallel")
                e = context_energy(
                    c[hits, None],
                    y[hits, None],
                    size2[None],
                    floor,
                    nu_n=nu_n,
                    alignment=mode,
                    alignment_weights=[0.0 if spec.symmetric else 1.0],
                    anchor_offsets=[anchor_of(spec)],
                ).total
                h = hits[int(np.argmin(e))]
                found = (c[h], float(y[h]), r[h])
                break
        if found is None:
            dropped.append(
                DroppedSpec(
                    spec,
                    f"no free floor area for a {spec.size[0]:.2f} x {spec.size[1]:.2f} m footprint "
                    f"in {2 * init_tries} random tries (room area {room.area:.1f} m^2)",
                )
            )
            continue
        kept.append(k)
        centers.append(found[0])
        yaws.append(found[1])
        rects.append(found[2])

    # 2. sampling epochs ------------------------------------------------------------------
    kept_specs = [specs[k] for k in kept]
    n_obj = len(kept)
    c_cur = np.array(centers, dtype=np.float64).reshape(n_obj, 2)
    y_cur = np.array(yaws, dtype=np.float64)
    sizes = np.array([s.size[:2] for s in kept_specs], dtype=np.float64).reshape(n_obj, 2)
    modes = ["parallel" if s.symmetric else align_map.get(s.class_name, "parallel") for s in kept_specs]
    weights = np.array([0.0 if s.symmetric else 1.0 for s in kept_specs])
    anchors = np.array([anchor_of(s) for s in kept_specs])
    opts = dict(nu_n=nu_n, mu=0.0, alignment=modes, alignment_weights=weights, anchor_offsets=anchors)

    def per_object(c: FloatArray, y: FloatArray) -> FloatArray:
        return context_energy(c, y, sizes, floor, **opts).per_object  # type: ignore[arg-type]

    if n_obj and epochs > 0:
        e_cur = per_object(c_cur, y_cur)
        n_s = int(samples_per_epoch)
        for ep in range(int(epochs)):
            frac = ep / max(int(epochs) - 1, 1)
            sp = pos_sigma[0] * (pos_sigma[1] / pos_sigma[0]) ** frac
            sy = yaw_sigma[0] * (yaw_sigma[1] / yaw_sigma[0]) ** frac
            c_s = c_cur[None] + g.normal(0.0, sp, size=(n_s, n_obj, 2))
            y_s = y_cur[None] + g.normal(0.0, sy, size=(n_s, n_obj))
            inside = _convex_in_polygon(_rectangles(c_s, y_s, sizes), floor, wall_tol)
            e_s = np.where(inside, per_object(c_s, y_s), np.inf)
            best = np.argmin(e_s, axis=0)
            e_best = e_s[best, np.arange(n_obj)]
            moved = e_best < e_cur
            c_new = np.where(moved[:, None], c_s[best, np.arange(n_obj)], c_cur)
            y_new = np.where(moved, y_s[best, np.arange(n_obj)], y_cur)
            gain = np.where(moved, e_cur - e_best, 0.0)
            while True:
                over = _pair_matrix(c_new, y_new, sizes) > overlap_tol
                if not over.any():
                    break
                bad_obj = np.flatnonzero(over.any(axis=1) & moved)
                if not bad_obj.size:  # the seed is overlap-free, so a moved object is involved
                    raise RuntimeError("internal error: overlap between objects that did not move")
                # put back the moved object with the smallest gain among those in an overlap
                r = bad_obj[np.argmin(gain[bad_obj])]
                c_new[r], y_new[r], moved[r], gain[r] = c_cur[r], y_cur[r], False, 0.0
            e_cur = np.where(moved, e_best, e_cur)
            c_cur, y_cur = c_new, y_new

    # 3. camera -----------------------------------------------------------------------------
    alive = list(range(n_obj))
    cam = None
    while cam is None:
        cand = g.uniform(lo, hi, size=(4096, 2))
        ok = points_in_polygon(cand, floor, margin=max(camera_wall_clearance, 1e-9))
        if alive and np.any(ok):
            d = _point_rect_distance(cand, c_cur[alive], y_cur[alive], sizes[alive])
            ok &= np.all(d >= camera_object_clearance, axis=1)
        hits = np.flatnonzero(ok)
        if hits.size:
            cam = cand[hits[0]]
            break
        if not alive:
            raise ValueError(
                f"expected a room with floor at least {camera_wall_clearance} m from every wall for the camera, "
                f"got none in room {room.template!r} (area {room.area:.2f} m^2)"
            )
        # remove the smallest remaining object (last in placement order)
        victim = alive.pop()
        dropped.append(
            DroppedSpec(
                kept_specs[victim],
                f"removed: no camera position left at >= {camera_wall_clearance} m from walls and "
                f">= {camera_object_clearance} m from furniture",
            )
        )
    cam_h = float(g.uniform(h_lo, h_hi))

    # result, in the order of specs ------------------------------------------------------
    final = {kept[a]: a for a in alive}
    objs: list[PlacedObject] = []
    for k in range(len(specs)):
        if k not in final:
            continue
        a = final[k]
        s = specs[k]
        objs.append(
            PlacedObject(
                class_name=s.class_name,
                model_id=s.model_id,
                size=s.size,
                center=(float(c_cur[a, 0]), float(c_cur[a, 1]), s.elevation + s.size[2] / 2),
                yaw=_wrap_angle(float(y_cur[a])),
                symmetric=s.symmetric,
            )
        )
    if alive:
        idx = np.array([final[k] for k in range(len(specs)) if k in final])
        energy = float(
            context_energy(
                c_cur[idx],
                y_cur[idx],
                sizes[idx],
                floor,
                nu_n=nu_n,
                mu=mu,
                alignment=[modes[i] for i in idx],
                alignment_weights=weights[idx],
                anchor_offsets=anchors[idx],
            ).total
        )
    else:
        energy = 0.0
    return Placement(
        room=room,
        objects=tuple(objs),
        camera_xy=np.array(cam, dtype=np.float64),
        camera_height=cam_h,
        energy=energy,
        dropped=tuple(dropped),
    )
