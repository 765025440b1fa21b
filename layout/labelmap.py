"""Surface-label maps of Manhattan rooms: analytic rendering and per-column boundaries.

A label map is an equirectangular ``(H, W) uint8`` image of surface labels
(shared/CONVENTIONS.md): 0 unknown / clutter, 1 floor, 2 ceiling, 3 wall
facing +-x (normal parallel to x), 4 wall facing +-y, 5 object (masked).

Walls are full height, so in every panorama column the camera sees, from the
top: ceiling, ONE wall (the nearest along the column's horizontal
direction), floor. A room seen from a camera is therefore fully described by
three numbers per column: the ceiling-wall boundary row, the floor-wall
boundary row and the wall label. :func:`room_boundaries` computes them
analytically (vectorised over columns and, optionally, over a batch of
hypotheses) and :func:`labels_from_boundaries` fills the image;
:func:`render_room_labels` does both. :func:`observe_boundaries` goes the
other way, reading the boundaries back from a (possibly noisy) label map.

Convention:
    Panorama pixels and world frame as in :mod:`panogeom.coords`: ``u`` to
    the right, ``v`` down, pixel centres at integer + 0.5, ``W == 2*H``;
    world x, y in metres, z up, floor at z = 0, the camera centre at
    ``(camera_xy, camera_height)``. Column ``j`` is rendered along the
    direction of its pixel centre ``u = j + 0.5``; a pixel of row ``i`` is
    floor when its centre ``i + 0.5`` lies below the floor boundary row,
    ceiling when above the ceiling boundary row, wall otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import lonlat_to_pixel, lonlat_to_ray, pixel_to_lonlat, ray_to_pixel

from .polygon import as_polygon, points_in_polygon, ray_hits

__all__ = [
    "UNKNOWN",
    "FLOOR",
    "CEILING",
    "WALL_X",
    "WALL_Y",
    "OBJECT",
    "RoomBoundaries",
    "ObservedBoundaries",
    "column_directions",
    "room_boundaries",
    "labels_from_boundaries",
    "render_room_labels",
    "observe_boundaries",
    "check_label_map",
    "LabelCounts",
    "sample_camera_xy",
    "visible_floor_fraction",
    "perturb_labels",
    "shade_labels",
]

#: Surface label ids (shared/CONVENTIONS.md, "Surface labels").
UNKNOWN, FLOOR, CEILING, WALL_X, WALL_Y, OBJECT = 0, 1, 2, 3, 4, 5

FloatArray = NDArray[np.float64]


def _check_width(width: int) -> tuple[int, int]:
    try:
        w = int(width)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"width: expected a positive even integer, got {width!r}") from exc
    if w != width or w <= 0 or w % 2:
        raise ValueError(f"width: expected a positive even integer (height = width / 2), got {width!r}")
    return w, w // 2


def column_directions(width: int) -> tuple[FloatArray, FloatArray]:
    """Longitude and horizontal unit direction of every panorama column.

    Parameters
    ----------
    width : int
        Panorama width W (even; H = W / 2).

    Returns
    -------
    lon : (W,) float
        Longitude of the pixel centre ``u = j + 0.5``, radians.
    direction : (W, 2) float
        World (x, y) unit vector of the column's horizontal direction.

    Convention: lon = 0 at the centre column looks along +x; lon = -pi/2
    (a quarter width left of centre) along +y (:mod:`panogeom.coords`).

    Examples
    --------
    >>> lon, d = column_directions(4)
    >>> np.round(lon, 4).tolist()
    [-2.3562, -0.7854, 0.7854, 2.3562]
    >>> np.round(d[1], 4).tolist()
    [0.7071, 0.7071]
    """
    w, h = _check_width(width)
    uv = np.stack([np.arange(w) + 0.5, np.full(w, 0.5 * h)], axis=-1)
    lon = pixel_to_lonlat(uv, w, h)[:, 0]
    direction = lonlat_to_ray(np.stack([lon, np.zeros(w)], axis=-1))[:, :2]
    return lon, direction


@dataclass(frozen=True)
class RoomBoundaries:
    """Per-column boundaries of a room seen from a camera (result of :func:`room_boundaries`).

    Attributes (``...`` = batch axes of the hypotheses, W = panorama width)
    ----------
    floor_v : (..., W) float
        Continuous row of the floor-wall boundary (below the horizon).
    ceil_v : (..., W) float
        Continuous row of the ceiling-wall boundary (above the horizon when
        the ceiling is above the camera).
    wall_label : (..., W) uint8
        3 (wall facing +-x) or 4 (wall facing +-y) of the wall seen; 0 where
        the column hits no wall.
    wall_index : (..., W) int
        Index i of the floor-polygon edge seen (edge from vertex i to i + 1),
        -1 where none.
    distance : (..., W) float
        Horizontal distance from the camera to the wall seen, metres (inf
        where none).
    valid : (...) bool
        Every column hits a wall (the camera is inside the room).
    width, height : int
        Panorama size.

    Convention: rows are continuous pixel coordinates (``v`` down, pixel
    centres at integer + 0.5).
    """

    floor_v: FloatArray
    ceil_v: FloatArray
    wall_label: NDArray[np.uint8]
    wall_index: NDArray[np.intp]
    distance: FloatArray
    valid: NDArray[np.bool_]
    width: int
    height: int


def _batch_float(x: ArrayLike, name: str, positive: bool = True) -> FloatArray:
    a = np.asarray(x, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got NaN or inf")
    if positive and np.any(a <= 0):
        raise ValueError(f"{name}: expected values > 0, got min {float(np.min(a))}")
    return a


def room_boundaries(floor: ArrayLike, ceiling_z: ArrayLike, camera_xy: ArrayLike, camera_height: ArrayLike,
                    width: int, *, scale: ArrayLike = 1.0) -> RoomBoundaries:
    """Analytic per-column floor/ceiling boundaries and wall labels, batched.

    Each column's horizontal direction is intersected with every polygon
    edge (2D ray against segments, vectorised); the nearest hit is the wall
    seen, since walls are full height. Its distance d gives the boundary
    latitudes ``-atan(camera_height / d)`` (floor) and
    ``atan((ceiling_z - camera_height) / d)`` (ceiling), turned into rows
    with :func:`panogeom.coords.lonlat_to_pixel`.

    Parameters
    ----------
    floor : (..., N, 2) float
        Floor polygon(s), metres, either orientation, no repeated closing
        vertex.
    ceiling_z : (...) float
        Ceiling height above the floor, metres.
    camera_xy : (..., 2) float
        Camera position on the floor plane, metres.
    camera_height : (...) float
        Camera centre above the floor, metres.
    width : int
        Panorama width W (even); H = W / 2.
    scale : (...) float
        Room scale: the hypothesis uses ``scale * floor`` and
        ``scale * ceiling_z`` (camera position and height unchanged).

    All leading axes broadcast against each other (a batch of hypotheses
    over scale, camera position or polygon).

    Returns
    -------
    RoomBoundaries
        Columns that hit no wall (camera outside the room) get
        ``wall_label`` 0, ``distance`` inf and both boundaries at the
        horizon; ``valid`` is False for that hypothesis.

    Convention: edge axis decides the label: an edge running along y is a
    wall ``x = const`` (normal parallel to x) -> 3; along x -> 4; a skew edge
    takes the label of its dominant normal component.

    Examples
    --------
    >>> sq = [[-2, -2], [2, -2], [2, 2], [-2, 2]]
    >>> b = room_boundaries(sq, 2.6, [0, 0], 1.6, 8)
    >>> b.wall_label.tolist()
    [3, 4, 4, 3, 3, 4, 4, 3]
    >>> bool(b.valid), round(float(b.distance[0]), 4)
    (True, 2.1648)
    >>> hyp = room_boundaries(sq, 2.6, [0, 0], 1.6, 8, scale=[1.0, 2.0])  # two scale hypotheses
    >>> hyp.distance.shape, bool(np.allclose(hyp.distance[1], 2 * hyp.distance[0]))
    ((2, 8), True)
    """
    w, h = _check_width(width)
    poly = as_polygon(floor, name="floor")
    ceil = _batch_float(ceiling_z, "ceiling_z")
    cam_h = _batch_float(camera_height, "camera_height")
    s = _batch_float(scale, "scale")
    cam = np.asarray(camera_xy, dtype=np.float64)
    if cam.ndim < 1 or cam.shape[-1] != 2 or not np.all(np.isfinite(cam)):
        raise ValueError(f"camera_xy: expected finite values of shape (..., 2), got {cam.shape}")
    lead = np.broadcast_shapes(poly.shape[:-2], ceil.shape, cam_h.shape, s.shape, cam.shape[:-1])
    lon, direction = column_directions(w)

    # polygon relative to the camera, (..., N, 2); the first edge each column's ray meets
    a = poly * s[..., None, None] - cam[..., None, :]
    dist, idx = ray_hits(a, direction)
    e = (np.roll(a, -1, axis=-2) - a)[..., None, :, :]  # (..., 1, N, 2)
    dist = np.broadcast_to(dist, lead + (w,))
    idx = np.broadcast_to(idx, lead + (w,))
    seen = np.isfinite(dist)
    edge_label = np.where(np.abs(e[..., 0]) <= np.abs(e[..., 1]), WALL_X, WALL_Y).astype(np.uint8)  # (..., 1, N)
    edge_label = np.broadcast_to(edge_label[..., 0, :], lead + edge_label.shape[-1:])
    label = np.take_along_axis(edge_label, idx, axis=-1)
    label = np.where(seen, label, UNKNOWN).astype(np.uint8)
    index = np.where(seen, idx, -1).astype(np.intp)

    d_safe = np.where(seen, dist, 1.0)
    cam_hb = np.broadcast_to(cam_h, lead)[..., None]
    ceil_b = (np.broadcast_to(ceil, lead) * np.broadcast_to(s, lead))[..., None]
    lat_f = np.where(seen, -np.arctan2(cam_hb, d_safe), 0.0)
    lat_c = np.where(seen, np.arctan2(ceil_b - cam_hb, d_safe), 0.0)
    lon_b = np.broadcast_to(lon, lead + (w,))
    floor_v = lonlat_to_pixel(np.stack([lon_b, lat_f], axis=-1), w, h)[..., 1]
    ceil_v = lonlat_to_pixel(np.stack([lon_b, lat_c], axis=-1), w, h)[..., 1]
    return RoomBoundaries(floor_v=floor_v, ceil_v=ceil_v, wall_label=label, wall_index=index,
                          distance=np.where(seen, dist, np.inf), valid=np.all(seen, axis=-1),
                          width=w, height=h)


def labels_from_boundaries(boundaries: RoomBoundaries) -> NDArray[np.uint8]:
    """Fill label images from per-column boundaries.

    Parameters
    ----------
    boundaries : RoomBoundaries
        With batch axes ``...``.

    Returns
    -------
    labels : (..., H, W) uint8
        1 where the pixel centre lies below the floor boundary, 2 above the
        ceiling boundary, the column's wall label in between (0 in columns
        that hit no wall).

    Examples
    --------
    >>> b = room_boundaries([[-2, -2], [2, -2], [2, 2], [-2, 2]], 2.6, [0, 0], 1.6, 8)
    >>> labels_from_boundaries(b)[:, 0].tolist()
    [2, 3, 3, 1]
    """
    h = boundaries.height
    rows = np.arange(h, dtype=np.float64)[:, None] + 0.5  # (H, 1)
    fv = boundaries.floor_v[..., None, :]
    cv = boundaries.ceil_v[..., None, :]
    lab = np.broadcast_to(boundaries.wall_label[..., None, :], fv.shape[:-2] + (h, boundaries.width))
    out = np.where(rows > fv, np.uint8(FLOOR), np.where(rows < cv, np.uint8(CEILING), lab))
    return out.astype(np.uint8)


def render_room_labels(floor: ArrayLike, ceiling_z: float, camera_xy: ArrayLike, camera_height: float,
                       width: int) -> NDArray[np.uint8]:
    """Analytic surface-label panorama of a room seen from a camera inside it.

    Parameters
    ----------
    floor : (N, 2) float
        Floor polygon, metres (Manhattan or not; labels 3/4 follow each
        edge's dominant normal axis).
    ceiling_z : float
        Ceiling height, metres, > camera_height.
    camera_xy : (2,) float
        Camera position, strictly inside the polygon.
    camera_height : float
        Camera centre above the floor, metres.
    width : int
        Panorama width W (even); the image is (W / 2, W).

    Returns
    -------
    labels : (H, W) uint8
        1 floor, 2 ceiling, 3 wall facing +-x, 4 wall facing +-y.

    Convention: see the module docstring (pixel centres, world frame).

    Examples
    --------
    >>> lab = render_room_labels([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 64)
    >>> lab.shape, sorted(np.unique(lab).tolist())
    ((32, 64), [1, 2, 3, 4])
    >>> int(lab[16, 32]), int(lab[16, 16])  # straight ahead (+x): wall x = 3; left (+y): wall y = 2
    (3, 4)
    """
    poly = as_polygon(floor, name="floor")
    cam = np.asarray(camera_xy, dtype=np.float64)
    if poly.ndim != 2:
        raise ValueError(f"floor: expected a single polygon (N, 2), got {poly.shape}")
    if cam.shape != (2,):
        raise ValueError(f"camera_xy: expected shape (2,), got {cam.shape}")
    if not float(ceiling_z) > float(camera_height) > 0:
        raise ValueError(f"expected 0 < camera_height < ceiling_z, got camera_height={camera_height}, "
                         f"ceiling_z={ceiling_z}")
    if not bool(points_in_polygon(cam, poly, margin=1e-9)):
        raise ValueError(f"camera_xy: expected a position strictly inside the floor polygon, got {cam.tolist()}")
    b = room_boundaries(poly, ceiling_z, cam, camera_height, width)
    if not bool(b.valid):
        raise ValueError(f"camera_xy: expected every column to see a wall, got columns without one at {cam.tolist()}")
    return labels_from_boundaries(b)


@dataclass(frozen=True)
class ObservedBoundaries:
    """Per-column boundaries read from a label map (result of :func:`observe_boundaries`).

    Attributes (W = panorama width)
    ----------
    floor_v : (W,) float
        Continuous row of the floor-wall boundary (NaN where no wall meets
        the floor visibly).
    ceil_v : (W,) float
        Continuous row of the ceiling-wall boundary (NaN where none).
    floor_contact, ceil_contact : (W,) bool
        A wall pixel run touches the floor (ceiling) directly, with no
        clutter or object between them: the boundary is trustworthy.
    wall_label : (W,) uint8
        Majority wall label of the column (3 or 4), 0 without wall pixels.
    wall_purity : (W,) float
        Fraction of the column's wall pixels carrying ``wall_label``.
    width, height : int

    Convention: rows are continuous pixel coordinates (``v`` down); a
    boundary between pixel rows ``k - 1`` and ``k`` is at ``v = k``.
    """

    floor_v: FloatArray
    ceil_v: FloatArray
    floor_contact: NDArray[np.bool_]
    ceil_contact: NDArray[np.bool_]
    wall_label: NDArray[np.uint8]
    wall_purity: FloatArray
    width: int
    height: int


def check_label_map(labels: ArrayLike, name: str = "labels") -> NDArray[np.uint8]:
    """Return ``labels`` as an (H, W) uint8 array with W == 2*H and values 0..5, or raise ValueError."""
    lab = np.asarray(labels)
    if lab.ndim != 2 or lab.shape[0] == 0 or lab.shape[1] != 2 * lab.shape[0]:
        raise ValueError(f"{name}: expected an (H, W) label map with W == 2*H, got shape {lab.shape}")
    if lab.dtype.kind not in "ui":
        raise ValueError(f"{name}: expected integer surface labels 0..5, got dtype {lab.dtype}")
    if lab.size and (lab.min() < 0 or lab.max() > OBJECT):
        raise ValueError(f"{name}: expected surface labels 0..5, got values in [{lab.min()}, {lab.max()}]")
    return lab.astype(np.uint8, copy=False)


def _column_cumsum(lab: NDArray[np.uint8]) -> NDArray[np.int32]:
    """(4, W, H + 1) counts of labels 1..4 in rows < i of each column (column-major: fast cumsum)."""
    lt = np.ascontiguousarray(lab.T)
    w, h = lt.shape
    cum = np.zeros((4, w, h + 1), np.int32)
    for k in range(4):
        np.cumsum(lt == k + 1, axis=1, dtype=np.int32, out=cum[k, :, 1:])
    return cum


def _split(pos: NDArray[np.int32], neg: NDArray[np.int32], lo: int, hi: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """First and last row k in [lo, hi] maximising #pos in [lo, k) + #neg in [k, hi), per column.

    pos, neg : (W, H + 1) cumulative counts. Rows neither pos nor neg are
    neutral, so a neutral band between the two regions gives a range of
    splits.
    """
    c = (pos[:, lo:hi + 1] - pos[:, lo:lo + 1]) - (neg[:, lo:hi + 1] - neg[:, lo:lo + 1])
    first = lo + np.argmax(c, axis=1)
    last = hi - np.argmax(c[:, ::-1], axis=1)
    return first, last


def _fraction(cum: NDArray[np.int32], start: NDArray[np.intp], stop: NDArray[np.intp], lo: int,
              hi: int) -> FloatArray:
    """Fraction of counted pixels in rows [start, stop) clipped to [lo, hi), per column (0 when empty)."""
    cols = np.arange(cum.shape[0])
    a = np.clip(start, lo, hi)
    b = np.clip(stop, lo, hi)
    n = b - a
    return np.where(n > 0, (cum[cols, b] - cum[cols, a]) / np.maximum(n, 1), 0.0)


def observe_boundaries(labels: ArrayLike, object_mask: ArrayLike | None = None, *, window: int | None = None,
                       min_fraction: float = 0.6, max_gap: int | None = None,
                       horizon: int | None = None) -> ObservedBoundaries:
    """Read the floor-wall and ceiling-wall boundary of every column from a label map.

    In the lower half of each column the split row maximising (wall pixels
    above) + (floor pixels below) is found with a cumulative sum; clutter
    (0) and object (5) pixels are neutral. The boundary is a *contact* only
    when the ``window`` rows above it are mostly wall and the rows below
    mostly floor, with at most ``max_gap`` neutral rows between: a wall
    whose bottom is hidden by furniture gives no floor contact. The upper
    half is read the same way (ceiling above, wall below).

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels 0..5, W == 2*H.
    object_mask : (H, W) bool, optional
        Pixels to ignore (treated as label 5).
    window : int, optional
        Rows checked on each side of a boundary (default ``max(2, H // 128)``).
    min_fraction : float
        Required fraction of the expected label in each window.
    max_gap : int, optional
        Largest neutral band allowed inside a contact (default ``max(1, H // 256)``).
    horizon : int, optional
        Row of the horizon. Default: a panorama (W == 2*H required) with the
        horizon at H // 2. Given, any (h, w) label image whose columns are
        vertical world lines is accepted - e.g. a pitch-0 perspective view
        with ``horizon = h // 2``.

    Returns
    -------
    ObservedBoundaries

    Convention: continuous rows; see :class:`ObservedBoundaries`.

    Examples
    --------
    >>> lab = render_room_labels([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 256)
    >>> ob = observe_boundaries(lab)
    >>> bool(ob.floor_contact.all()), bool(ob.ceil_contact.all())
    (True, True)
    >>> b = room_boundaries([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 256)
    >>> bool(np.all(np.abs(ob.floor_v - b.floor_v) <= 0.5))
    True
    """
    if horizon is None:
        lab = check_label_map(labels)
        half = lab.shape[0] // 2
    else:
        lab = np.asarray(labels)
        if lab.ndim != 2 or lab.dtype.kind not in "ui" or min(lab.shape) == 0:
            raise ValueError(f"labels: expected a non-empty (h, w) integer label image, got {lab.shape} {lab.dtype}")
        half = int(horizon)
        if not 0 < half < lab.shape[0]:
            raise ValueError(f"horizon: expected a row in (0, {lab.shape[0]}), got {horizon!r}")
        lab = lab.astype(np.uint8, copy=False)
    h, w = lab.shape
    if object_mask is not None:
        m = np.asarray(object_mask)
        if m.shape != lab.shape:
            raise ValueError(f"object_mask: expected shape {lab.shape}, got {m.shape}")
        lab = np.where(m.astype(bool), np.uint8(OBJECT), lab)
    win = max(2, h // 128) if window is None else int(window)
    gap = max(1, h // 256) if max_gap is None else int(max_gap)
    if win < 1 or gap < 0 or not 0.0 < min_fraction <= 1.0:
        raise ValueError(f"expected window >= 1, max_gap >= 0, 0 < min_fraction <= 1, got {win}, {gap}, {min_fraction}")
    cum = _column_cumsum(lab)
    cf, cc = cum[FLOOR - 1], cum[CEILING - 1]
    cw = cum[WALL_X - 1] + cum[WALL_Y - 1]

    # floor: rows [half, H), wall above the split, floor below
    k1, k2 = _split(cw, cf, half, h)
    above = _fraction(cw, k1 - win, k1, half, h)
    below = _fraction(cf, k2, k2 + win, half, h)
    floor_contact = (above >= min_fraction) & (below >= min_fraction) & (k2 - k1 <= gap) & (k1 > half) & (k2 < h)
    floor_v = np.where(floor_contact, 0.5 * (k1 + k2), np.nan)

    # ceiling: rows [0, half), ceiling above the split, wall below
    c1, c2 = _split(cc, cw, 0, half)
    above_c = _fraction(cc, c1 - win, c1, 0, half)
    below_w = _fraction(cw, c2, c2 + win, 0, half)
    ceil_contact = (above_c >= min_fraction) & (below_w >= min_fraction) & (c2 - c1 <= gap) & (c1 > 0) & (c2 < half)
    ceil_v = np.where(ceil_contact, 0.5 * (c1 + c2), np.nan)

    n3 = cum[WALL_X - 1][:, h]
    n4 = cum[WALL_Y - 1][:, h]
    n = n3 + n4
    wall_label = np.where(n == 0, UNKNOWN, np.where(n3 >= n4, WALL_X, WALL_Y)).astype(np.uint8)
    purity = np.where(n > 0, np.maximum(n3, n4) / np.maximum(n, 1), 0.0)
    return ObservedBoundaries(floor_v=floor_v, ceil_v=ceil_v, floor_contact=floor_contact, ceil_contact=ceil_contact,
                              wall_label=wall_label, wall_purity=purity, width=w, height=h)


@dataclass(frozen=True)
class LabelCounts:
    """Column-wise cumulative label counts of an observed label map, for fast agreement scores.

    ``cumulative[k, j, i]`` is the number of pixels of label ``k + 1``
    (floor, ceiling, wall x, wall y) in rows ``< i`` of column ``j``
    (column-major, so that the sums run along contiguous memory). With it
    the number of pixels on which a room hypothesis agrees with the
    observation (the paper's N_c of E_s) costs O(W) per hypothesis instead
    of rendering and comparing H x W pixels.

    Attributes
    ----------
    cumulative : (4, W, H + 1) int32
    comparable : int
        Pixels with a label 1..4 (clutter 0, objects 5 and masked pixels are
        not compared).

    Examples
    --------
    >>> sq = [[-2, -1], [3, -1], [3, 2], [-2, 2]]
    >>> lab = render_room_labels(sq, 2.7, [0, 0], 1.6, 128)
    >>> counts = LabelCounts.from_labels(lab)
    >>> b = room_boundaries(sq, 2.7, [0, 0], 1.6, 128, scale=[1.0, 1.3])
    >>> counts.agreement(b).tolist()[0] == lab.size, bool(counts.cost(b)[1] > 0.02)
    (True, True)
    """

    cumulative: NDArray[np.int32]
    comparable: int

    @classmethod
    def from_labels(cls, labels: ArrayLike, object_mask: ArrayLike | None = None) -> "LabelCounts":
        """Counts of an (H, W) label map; ``object_mask`` (H, W) bool pixels are left out."""
        lab = check_label_map(labels)
        if object_mask is not None:
            m = np.asarray(object_mask)
            if m.shape != lab.shape:
                raise ValueError(f"object_mask: expected shape {lab.shape}, got {m.shape}")
            lab = np.where(m.astype(bool), np.uint8(OBJECT), lab)
        cum = _column_cumsum(lab)
        return cls(cumulative=cum, comparable=int(cum[:, :, -1].sum()))

    def agreement(self, boundaries: RoomBoundaries) -> NDArray[np.int64]:
        """Pixels whose label the hypothesis reproduces (N_c), shape ``(...)`` of the batch."""
        cum = self.cumulative
        w, h = cum.shape[1], cum.shape[2] - 1
        if (boundaries.height, boundaries.width) != (h, w):
            raise ValueError(f"boundaries: expected a {w}x{h} panorama, got {boundaries.width}x{boundaries.height}")
        rc = np.clip(np.ceil(boundaries.ceil_v - 0.5), 0, h).astype(np.intp)
        rf = np.clip(np.floor(boundaries.floor_v - 0.5) + 1, 0, h).astype(np.intp)
        rf = np.maximum(rf, rc)
        cols = np.broadcast_to(np.arange(w), rc.shape)
        ceil = cum[CEILING - 1][cols, rc]
        floor = cum[FLOOR - 1][cols, h] - cum[FLOOR - 1][cols, rf]
        lab = boundaries.wall_label.astype(np.intp)
        k = np.clip(lab - 1, 0, 3)
        wall = np.where(lab >= WALL_X, cum[k, cols, rf] - cum[k, cols, rc], 0)
        return np.sum(ceil + floor + wall, axis=-1, dtype=np.int64)

    def cost(self, boundaries: RoomBoundaries) -> FloatArray:
        """The paper's E_s = 1 - N_c / N_pix over the comparable pixels, shape ``(...)``."""
        return 1.0 - self.agreement(boundaries) / max(self.comparable, 1)


def visible_floor_fraction(floor: ArrayLike, camera_xy: ArrayLike, *, width: int = 1024,
                           cells: int = 200) -> float:
    """Fraction of the floor area seen from a camera (walls are full height, so what is seen of the floor).

    Parameters
    ----------
    floor : (N, 2) float
        Floor polygon, metres.
    camera_xy : (2,) float
        Camera position inside it.
    width : int
        Panorama width whose columns sample the viewing directions.
    cells : int
        Grid cells along the longer side of the bounding box.

    Returns
    -------
    float in [0, 1]

    Examples
    --------
    >>> visible_floor_fraction([[0, 0], [4, 0], [4, 3], [0, 3]], [1.0, 1.0])
    1.0
    >>> L = [[0, 0], [4, 0], [4, 1], [1, 1], [1, 4], [0, 4]]
    >>> round(visible_floor_fraction(L, [3.5, 0.5]), 2)  # exact: (4 + 0.1) / 7 = 0.586
    0.59
    """
    poly = as_polygon(floor, name="floor")
    cam = np.asarray(camera_xy, dtype=np.float64)
    if poly.ndim != 2 or cam.shape != (2,):
        raise ValueError(f"expected floor (N, 2) and camera_xy (2,), got {poly.shape} and {cam.shape}")
    w, h = _check_width(width)
    b = room_boundaries(poly, 1.0, cam, 0.5, w)
    if not bool(b.valid):
        raise ValueError(f"camera_xy: expected a position inside the floor polygon, got {cam.tolist()}")
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    step = float(np.max(hi - lo)) / int(cells)
    xs = np.arange(lo[0] + step / 2, hi[0], step)
    ys = np.arange(lo[1] + step / 2, hi[1], step)
    g = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    g = g[points_in_polygon(g, poly)]
    if len(g) == 0:
        return 0.0
    rel = g - cam
    r = np.hypot(rel[:, 0], rel[:, 1])
    rays = np.concatenate([rel, np.zeros((len(g), 1))], axis=1)
    rays[r == 0, 0] = 1.0
    u = ray_to_pixel(rays, w, h)[:, 0]
    col = np.clip(np.floor(u).astype(np.intp), 0, w - 1)
    return float(np.mean(r <= b.distance[col] + 1e-9))


def sample_camera_xy(floor: ArrayLike, rng: int | np.random.Generator | None = None, *, margin: float = 0.5,
                     candidates: int = 1, max_tries: int = 10000) -> FloatArray:
    """Draw a camera position uniformly inside a floor polygon, at least ``margin`` from every wall.

    With ``candidates > 1``, that many positions are drawn and the one that
    sees the largest part of the floor (:func:`visible_floor_fraction`) is
    returned - the way a photographer puts the tripod where most of the room
    is in view.

    Parameters
    ----------
    floor : (N, 2) float
        Floor polygon, metres.
    rng : int, numpy Generator or None
    margin : float
        Minimum distance to the boundary, metres (>= 0).
    candidates : int
        Positions drawn; the most-seeing one wins (>= 1).
    max_tries : int
        Rejection-sampling attempts before giving up.

    Returns
    -------
    camera_xy : (2,) float

    Raises
    ------
    ValueError
        When no position ``margin`` away from the walls was found.

    Examples
    --------
    >>> xy = sample_camera_xy([[0, 0], [4, 0], [4, 3], [0, 3]], 0, margin=0.5)
    >>> bool(0.5 <= xy[0] <= 3.5 and 0.5 <= xy[1] <= 2.5)
    True
    """
    poly = as_polygon(floor, name="floor")
    if poly.ndim != 2:
        raise ValueError(f"floor: expected a single polygon (N, 2), got {poly.shape}")
    if not (np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin: expected a finite value >= 0, got {margin}")
    if int(candidates) < 1:
        raise ValueError(f"candidates: expected an integer >= 1, got {candidates!r}")
    g = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    if int(candidates) > 1:
        pts = [sample_camera_xy(poly, g, margin=margin, max_tries=max_tries) for _ in range(int(candidates))]
        seen = [visible_floor_fraction(poly, p, width=512, cells=80) for p in pts]
        return pts[int(np.argmax(seen))]
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    for _ in range(max(1, int(max_tries) // 256)):
        pts = g.uniform(lo, hi, size=(256, 2))
        ok = points_in_polygon(pts, poly, margin=margin) if margin > 0 else points_in_polygon(pts, poly)
        if np.any(ok):
            return pts[int(np.argmax(ok))].copy()
    raise ValueError(f"expected a floor polygon with room for a camera {margin} m from every wall, "
                     f"got none in {max_tries} tries")


def perturb_labels(labels: ArrayLike, rng: int | np.random.Generator | None = None, *, n_blobs: int = 12,
                   blob_radius: float = 0.03, n_clutter: int = 6, clutter_height: float = 0.06,
                   n_objects: int = 3, object_size: float = 0.08,
                   boundary_jitter: float = 0.004) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Corrupt a clean label map the way an estimated one goes wrong (for evaluation).

    Four kinds of damage, sizes as fractions of the panorama height H:

    * the lower and upper halves of every column shifted vertically by
      smooth random offsets of standard deviation ``boundary_jitter * H``
      (wobbly floor and ceiling boundaries);
    * ``n_blobs`` elliptic blobs of radius up to ``blob_radius * H`` filled
      with a random wrong label from 0..4;
    * ``n_clutter`` bands of clutter (label 0) sitting on the floor-wall
      boundary, ``clutter_height * H`` tall and 2-8 % of W wide (furniture
      hiding the bottom of walls);
    * ``n_objects`` object boxes (label 5, also returned as a mask) of side
      up to ``object_size * H`` standing on the floor below the horizon.

    Parameters
    ----------
    labels : (H, W) uint8
    rng : int, numpy Generator or None

    Returns
    -------
    noisy : (H, W) uint8
    object_mask : (H, W) bool
        Pixels of the object boxes.

    Examples
    --------
    >>> lab = render_room_labels([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 128)
    >>> noisy, mask = perturb_labels(lab, 0)
    >>> noisy.shape == lab.shape, bool(np.all(noisy[mask] == 5)), bool((noisy != lab).mean() < 0.2)
    (True, True, True)
    """
    lab = check_label_map(labels).copy()
    h, w = lab.shape
    g = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    rows = np.arange(h)[:, None]
    cols = np.arange(w)[None, :]
    if boundary_jitter > 0:
        half = h // 2
        for lo, hi in ((0, half), (half, h)):
            # smooth circular noise: a few random Fourier modes, unit variance
            k = np.arange(1, 9)
            phase = g.uniform(0, 2 * np.pi, size=(len(k), 1))
            amp = g.normal(size=(len(k), 1)) / k[:, None]
            x = 2 * np.pi * np.arange(w)[None, :] / w
            noise = np.sum(amp * np.sin(k[:, None] * x + phase), axis=0)
            noise = noise / max(float(np.std(noise)), 1e-9) * boundary_jitter * h
            shift = np.round(noise).astype(np.intp)
            src = np.clip(rows[lo:hi] - shift[None, :], lo, hi - 1)
            lab[lo:hi] = lab[src, np.broadcast_to(cols, src.shape)]

    def circular_dx(c0: float) -> FloatArray:
        return (cols - c0 + w / 2) % w - w / 2

    for _ in range(int(n_blobs)):
        r0, c0 = g.uniform(0, h), g.uniform(0, w)
        ry, rx = g.uniform(0.3, 1.0, size=2) * blob_radius * h
        inside = (((rows - r0) / ry) ** 2 + (circular_dx(c0) / rx) ** 2) <= 1.0
        lab[inside] = np.uint8(g.integers(0, 5))
    obs = observe_boundaries(labels)
    fv = np.where(np.isfinite(obs.floor_v), obs.floor_v, 0.75 * h)
    for _ in range(int(n_clutter)):
        c0 = g.uniform(0, w)
        half_w = g.uniform(0.01, 0.04) * w
        sel = np.abs(circular_dx(c0)[0]) <= half_w
        top = fv[sel] - clutter_height * h * g.uniform(0.5, 1.0)
        bottom = fv[sel] + clutter_height * h * g.uniform(0.1, 0.4)
        band = (rows >= top[None, :]) & (rows < bottom[None, :])
        sub = lab[:, sel]
        sub[band] = UNKNOWN
        lab[:, sel] = sub
    mask = np.zeros((h, w), bool)
    for _ in range(int(n_objects)):
        c0 = g.uniform(0, w)
        sx, sy = g.uniform(0.4, 1.0, size=2) * object_size * h
        v1 = g.uniform(0.62, 0.85) * h
        box = (rows >= v1 - sy) & (rows < v1) & (np.abs(circular_dx(c0)) <= sx)
        mask |= box
    lab[mask] = OBJECT
    return lab, mask


#: Grey level of each surface label in :func:`shade_labels` (unknown, floor, ceiling, wall x, wall y, object).
SHADES = (128.0, 80.0, 215.0, 150.0, 130.0, 128.0)


def shade_labels(labels: ArrayLike, rng: int | np.random.Generator | None = None, *,
                 noise: float = 6.0) -> FloatArray:
    """A grey panorama painted from a label map: each label one grey level (:data:`SHADES`) plus Gaussian noise.

    Stands in for a photo where a check needs the image's creases without a renderer (the wall snap of
    :mod:`layout.wallsnap` on analytic labels).

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels 0..5.
    rng : int, numpy Generator or None
    noise : float
        Standard deviation of the noise, grey levels.

    Returns
    -------
    (H, W) float

    >>> shade_labels(np.array([[2, 1]], np.uint8), noise=0.0).tolist()  # ceiling, floor
    [[215.0, 80.0]]
    """
    lab = check_label_map(labels)
    grey = np.asarray(SHADES, dtype=np.float64)[lab]
    if noise > 0:
        grey = grey + np.random.default_rng(rng).normal(0.0, float(noise), grey.shape)
    return grey
