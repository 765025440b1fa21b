"""Wall snap: the room step's walls and ceiling height moved onto the image's creases.

Not in the paper. The room step (:mod:`layout.roomgeom`) places every wall
where the surface labels put its ceiling-wall and floor-wall boundaries.
Where the labeller's ceiling boundary drifts (a pink wall under a pink
ceiling, a dark corner; on real photos more than on the synthetic rooms it
was trained on) the wall moves with it, by up to 31 % of its distance on the
two real panoramas of ../shared/data/real (docs/EVALUATION.md, "Session
26"). The image itself usually shows the crease where a wall meets the
ceiling as a grey-level step along the wall's whole width, and ceilings are
rarely hidden by furniture.

**Profiles.** Each wall ``k`` of the polygon (a Manhattan line ``x = c`` or
``y = c``) is tried at ``s * c`` for ``s`` on a log-spaced grid within
``1 / span .. span`` (the wall moves along its normal, its two neighbours
stretch or shrink). For each ``s`` the ceiling-wall curve of the moved wall
(:func:`layout.labelmap.room_boundaries`) is scored by the mean, over the
columns where the polygon shows the wall (``margin_deg`` from its corners,
columns whose ceiling boundary an object box covers left out), of the image
gradient across the curve:

    C_k(s) = mean_u | grad I(u, v_k(u; s)) . n_k(u; s) |

(``I`` the grey image blurred by ``sigma`` pixels at 1024 columns, ``n``
the curve's unit normal); ``F_k(s)`` the same along the floor-wall curve,
over the columns whose floor boundary no object box covers. An edge is
*clear* at ``s*`` when ``C(s*) >= min_peak * median_s C(s)`` (a peak, not
a textured wall).

**Ceiling height** (:func:`snap_walls`). A ceiling-wall curve fixes a
wall's distance in units of ``ceiling_z - camera_height``, a floor-wall
curve in units of ``camera_height``. Where a wall shows a clear ceiling
crease at ``s_c`` and a clear floor crease at ``s_f`` (both inside the
grid), the labels' ``ceiling_z - camera_height`` is ``s_c / s_f`` times
the true one. When two or more walls show both and agree within
:data:`RATIO_SPREAD` grid steps, the ceiling height moves by their median
factor and each wall's ceiling profile is read in the new units.

**Walls** (:func:`snap_walls`). A wall moves to its best ``s`` where the
ceiling edge there is clear and ``C(s*) >= min_gain * C(s_0)`` (``s_0`` its
place from the labels, in the ceiling height's units; the labels' place has
no edge of its own), unless its floor-wall boundary shows and vetoes the
move: ``F(s_0)`` clear and ``F(s*) < F(s_0) / min_gain`` (the labels' wall
stands on a floor crease and the new place has none: the ceiling edge was
most likely the top of a tall cupboard in front of the wall). An edge
beyond the span pulls its wall to the span's end (keeping such walls where
the labels put them scored worse on both tuning sets). The accepted moves
are applied strongest first, each kept only if the polygon stays simple,
Manhattan and around the camera.

**Room scale** (:func:`snap_ceiling_height`). Scaling the polygon and
``ceiling_z - camera_height`` by one factor leaves every ceiling curve
where it is and moves every floor curve: the factor whose floor curves of
all walls together lie on the clearest edge fixes the wall height where
single walls cannot.

Convention:
    World frame of shared/CONVENTIONS.md (metres, camera at
    ``(0, 0, camera_height)``, floor z = 0, walls of the polygon from vertex
    i to i + 1); panorama pixels as :mod:`panogeom.coords` (upright
    panorama, W == 2 * H, rows from the top).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_grid
from panogeom.sampling import EquirectSampler, pad_equirect, sample_equirect

from .labelmap import room_boundaries
from .polygon import is_manhattan, is_simple, points_in_polygon

__all__ = ["WallSnap", "HeightSnap", "RoomSnap", "snap_walls", "snap_ceiling_height", "snap_room",
           "DEFAULT_SPAN", "DEFAULT_MIN_PEAK", "DEFAULT_MIN_GAIN", "RATIO_SPREAD", "WALL_COLUMNS", "HEIGHT_COLUMNS"]

FloatArray = NDArray[np.float64]

#: Largest factor a wall's distance may move by (either way). Chosen on the tuning seeds 7000 / 8000 with the room
#: step at the true camera height (1.15, 1.25, 1.35; docs/EVALUATION.md, "Session 26").
DEFAULT_SPAN: float = 1.25
#: The best edge must be this many times the median of the wall's profile (a peak, not texture).
DEFAULT_MIN_PEAK: float = 2.0
#: ... and this many times the edge at the wall's place from the labels (and a floor crease this many times weaker
#: at the new place vetoes the move).
DEFAULT_MIN_GAIN: float = 1.5
#: Largest spread, in grid steps (0.74 % each with the defaults), of the walls' ceiling-over-floor crease factors
#: for the ceiling height to move by their median. Chosen on the tuning seeds 7000 / 8000 among 1, 6 and 12
#: (docs/EVALUATION.md, "Session 26").
RATIO_SPREAD: int = 6
#: Fewest scoring columns (of 1024) for a wall to be tried, and for all walls together to scale the room.
WALL_COLUMNS: int = 12
HEIGHT_COLUMNS: int = 30
_WORK_WIDTH = 1024  # columns the image is scored at (the room step's resolution)
#: u of each column's centre at that width (:func:`panogeom.coords.pixel_grid`), (1024,).
_COLUMN_U = pixel_grid(_WORK_WIDTH, 1)[0, :, 0]


@dataclass(frozen=True)
class WallSnap:
    """Result of :func:`snap_walls`.

    Attributes
    ----------
    floor : (K, 2) float
        The polygon with the snapped walls, metres, same vertex order.
    ceiling_z : float
        The ceiling height, metres: the input's unless walls with both
        creases moved it (``height_walls``).
    height_walls : int
        Walls whose ceiling and floor creases set ``ceiling_z`` (0: kept).
    factor : (K,) float
        Factor each wall's distance was multiplied by (1 where it stayed).
    moved : (K,) bool
        Walls that moved.
    peak : (K,) float
        ``C_k(s*) / median C_k`` of each scored wall; nan where a wall had
        too few columns to score.
    columns : (K,) int
        Columns (at 1024) that scored each wall.
    vetoed : (K,) bool
        Walls whose move the floor crease refused.
    """

    floor: FloatArray
    ceiling_z: float
    height_walls: int
    factor: FloatArray
    moved: NDArray[np.bool_]
    peak: FloatArray
    columns: NDArray[np.intp]
    vetoed: NDArray[np.bool_]


@dataclass(frozen=True)
class RoomSnap:
    """Result of :func:`snap_room`.

    Attributes
    ----------
    floor : (K, 2) float
        The snapped polygon, metres, same vertex order as the input.
    ceiling_z : float
        The snapped ceiling height, metres.
    walls : WallSnap
        The :func:`snap_walls` step.
    height : HeightSnap
        The :func:`snap_ceiling_height` step on its room.
    """

    floor: FloatArray
    ceiling_z: float
    walls: WallSnap
    height: "HeightSnap"


@dataclass(frozen=True)
class HeightSnap:
    """Result of :func:`snap_ceiling_height`.

    Attributes
    ----------
    floor : (K, 2) float
        The polygon scaled by ``factor`` about the camera, metres.
    ceiling_z : float
        ``camera_height + factor * (ceiling_z - camera_height)``, metres.
    factor : float
        1 where nothing moved.
    peak : float
        Best edge over the profile's median (nan without enough columns).
    columns : int
        Columns (at 1024) that scored it.
    """

    floor: FloatArray
    ceiling_z: float
    factor: float
    peak: float
    columns: int

    @property
    def moved(self) -> bool:
        return self.factor != 1.0


@dataclass(frozen=True)
class _Edges:
    """The image's x and y gradients at 1024 x 512, each padded once across the seam and the poles by the border
    :class:`panogeom.sampling.EquirectSampler` samples linearly with (its ``pad``)."""

    gx: NDArray[np.float32]
    gy: NDArray[np.float32]
    pad: int


def _gradients(image: ArrayLike, sigma: float) -> _Edges:
    """Sobel gradients of the blurred grey image at 1024 columns (blurred after padding across the seam and the
    poles, :func:`panogeom.sampling.pad_equirect`)."""
    import cv2

    img = np.asarray(image)
    if img.ndim == 3:
        img = img[..., :3].astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
    img = img.astype(np.float32)
    if img.shape[1] != _WORK_WIDTH:
        img = cv2.resize(img, (_WORK_WIDTH, _WORK_WIDTH // 2), interpolation=cv2.INTER_AREA)
    blur = 8
    img = cv2.GaussianBlur(pad_equirect(img, blur), (0, 0), sigma)
    pad = EquirectSampler.from_uv(np.zeros((1, 1, 2)), _WORK_WIDTH, _WORK_WIDTH // 2).pad
    crop = slice(blur - pad, -(blur - pad))
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)[crop, crop]
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)[crop, crop]
    return _Edges(np.ascontiguousarray(gx), np.ascontiguousarray(gy), pad)


def _edge_profile(edges: _Edges, rows: ArrayLike, columns: ArrayLike) -> FloatArray:
    """Mean image gradient across curves, (...,): ``|grad . n|`` averaged over ``columns`` (C,) at the curves
    ``rows`` (..., 1024) (continuous rows per column, pixel centres at integer + 0.5, :mod:`panogeom.coords`; the
    normal from the slope between neighbouring columns), sampled bilinearly with the maps of
    :class:`panogeom.sampling.EquirectSampler` on the gradients padded once."""
    import cv2

    v = np.asarray(rows, dtype=np.float64)
    cols = np.asarray(columns, dtype=np.intp)
    lead = v.shape[:-1]
    v2 = v.reshape(-1, v.shape[-1])
    slope = (np.roll(v2, -1, axis=1) - np.roll(v2, 1, axis=1)) / 2.0
    uv = np.stack(np.broadcast_arrays(_COLUMN_U[cols], v2[:, cols]), axis=-1)  # column centres on each curve
    at = EquirectSampler.from_uv(uv, _WORK_WIDTH, _WORK_WIDTH // 2)
    sx, sy = (cv2.remap(g, at.map_x, at.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
              for g in (edges.gx, edges.gy))
    d = slope[:, cols]
    across = np.abs(sy - d * sx) / np.sqrt(1.0 + d * d)
    return across.mean(axis=1).reshape(lead)


def _valid(floor: FloatArray) -> bool:
    return bool(is_simple(floor) and is_manhattan(floor, tol=1e-6, axis_aligned=True)
                and points_in_polygon(np.zeros((1, 2)), floor)[0])


def _inputs(image: ArrayLike, floor: ArrayLike, ceiling_z: float, camera_height: float, span: float, steps: int,
            object_mask: ArrayLike | None
            ) -> tuple[np.ndarray, FloatArray, float, float, FloatArray, np.ndarray | None]:
    """Checked inputs of :func:`snap_walls` and :func:`snap_ceiling_height`, and the factors tried."""
    img = np.asarray(image)
    if img.ndim not in (2, 3) or img.shape[1] != 2 * img.shape[0] or img.shape[0] < 16:
        raise ValueError(f"image: expected an (H, 2H[, C]) panorama, got shape {img.shape}")
    poly = np.asarray(floor, dtype=np.float64)
    if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 4 or not np.isfinite(poly).all():
        raise ValueError(f"floor: expected a (K >= 4, 2) finite polygon, got shape {poly.shape}")
    if not _valid(poly):
        raise ValueError("floor: expected a simple, axis-aligned Manhattan polygon around the camera (0, 0)")
    h, cz = float(camera_height), float(ceiling_z)
    if not (math.isfinite(h) and h > 0 and math.isfinite(cz) and cz > h):
        raise ValueError(f"ceiling_z, camera_height: expected 0 < camera_height < ceiling_z, got {cz!r}, {h!r}")
    if not (math.isfinite(span) and span > 1):
        raise ValueError(f"span: expected a factor > 1, got {span!r}")
    if int(steps) != steps or steps < 3 or steps % 2 == 0:
        raise ValueError(f"steps: expected an odd count >= 3, got {steps!r}")
    mask = None
    if object_mask is not None:
        mask = np.asarray(object_mask, dtype=bool)
        if mask.ndim != 2 or mask.shape[1] != 2 * mask.shape[0]:
            raise ValueError(f"object_mask: expected (H, 2H) bool, got shape {mask.shape}")
        mask = mask.astype(np.uint8)
    return img, poly, cz, h, np.geomspace(1.0 / span, span, int(steps)), mask


def _columns(wall: NDArray[np.intp], seen: NDArray[np.bool_], rows: FloatArray, margin_deg: float,
             mask: np.ndarray | None) -> NDArray[np.intp]:
    """Columns (of 1024) of ``seen`` at least ``margin_deg`` from a change of the wall seen ``wall`` (1024,)
    (wrapping around the seam) whose boundary row ``rows`` (1024,) the object mask (uint8, any panorama size)
    leaves free."""
    W = _WORK_WIDTH
    inner = seen & (wall >= 0)
    for dk in range(1, max(1, int(round(margin_deg / 360.0 * W))) + 1):
        inner &= (np.roll(wall, dk) == wall) & (np.roll(wall, -dk) == wall)
    cols = np.flatnonzero(inner)
    if mask is not None and len(cols):
        r = mask.shape[1] / W  # the mask's pixels per column of 1024
        uv = np.stack([_COLUMN_U[cols], rows[cols]], axis=-1)[None] * r
        cols = cols[sample_equirect(mask, uv, "nearest")[0] == 0]
    return cols


def _best(profile: FloatArray, min_peak: float, min_gain: float) -> tuple[int, float, float]:
    """Index of the profile's best factor, its ratio to the profile's median, and its gain over the middle factor
    (1) where it passes both tests, else 0."""
    i, one = int(np.argmax(profile)), len(profile) // 2
    med = float(np.median(profile))
    peak = float(profile[i] / med) if med > 0 else math.inf
    ok = i != one and profile[i] >= min_peak * med and profile[i] >= min_gain * profile[one]
    return i, peak, float(profile[i] / max(float(profile[one]), 1e-12)) if ok else 0.0


def snap_walls(image: ArrayLike, floor: ArrayLike, ceiling_z: float, camera_height: float, *,
               object_mask: ArrayLike | None = None, span: float = DEFAULT_SPAN, steps: int = 61,
               margin_deg: float = 2.1, min_columns: int = WALL_COLUMNS, sigma: float = 1.0,
               min_peak: float = DEFAULT_MIN_PEAK, min_gain: float = DEFAULT_MIN_GAIN) -> WallSnap:
    """Move each wall of ``floor`` onto the image's ceiling-wall edge where the image shows a clear one.

    The ceiling height first moves where two or more walls show both their
    creases and agree on the factor (module docstring, "Ceiling height");
    a wall's move is refused where its floor crease confirms the labels'
    place ("Walls").

    Parameters
    ----------
    image : (H, W, 3) or (H, W) array
        The upright panorama (W == 2 * H; any size, scored at 1024 x 512).
    floor : (K, 2) float
        Axis-aligned Manhattan floor polygon around the camera, metres
        (the room step's :attr:`layout.roomgeom.RoomGeometry.floor`).
    ceiling_z : float
        Ceiling height above the floor, metres (> ``camera_height``).
    camera_height : float
        Metres, in the polygon's units.
    object_mask : (H', W') bool, optional
        Pixels covered by objects (any size with W' == 2 * H'): columns whose
        ceiling (floor) boundary lies under the mask do not score the
        ceiling (floor) profile.
    span : float
        Largest factor (> 1) a wall's distance may move by, either way.
    steps : int
        Factors tried per wall (log-spaced, odd so that 1 is one of them).
    margin_deg : float
        Columns within this azimuth of a wall's ends do not score it.
    min_columns : int
        Fewest scoring columns (at 1024) for a wall to be tried.
    sigma : float
        Blur of the grey image, pixels at 1024 columns.
    min_peak, min_gain : float
        The acceptance tests of the module docstring.

    Returns
    -------
    WallSnap

    Raises
    ------
    ValueError
        For an image that is not a panorama, a polygon that is not a valid
        axis-aligned Manhattan polygon around the camera, or a ceiling not
        above the camera.

    Examples
    --------
    A 4 x 3 m room whose east wall the labels put at 1.8 m instead of 2.0 m,
    in an image that shows its ceiling crease:

    >>> from layout.labelmap import room_boundaries
    >>> true = np.array([[-2.0, -1.5], [2.0, -1.5], [2.0, 1.5], [-2.0, 1.5]])
    >>> b = room_boundaries(true, 2.6, [0.0, 0.0], 1.5, 1024)
    >>> img = np.where(np.arange(512)[:, None] + 0.5 < b.ceil_v[None, :], 220.0, 120.0)
    >>> guess = true.copy(); guess[1:3, 0] = 1.8
    >>> res = snap_walls(img, guess, 2.6, 1.5)
    >>> res.moved.tolist(), round(float(res.floor[1, 0]), 2)
    ([False, True, False, False], 2.0)
    """
    img, poly, cz, h, factors, mask = _inputs(image, floor, ceiling_z, camera_height, span, steps, object_mask)
    return _walls(_gradients(img, sigma), poly, cz, h, factors, mask, margin_deg, min_columns, min_peak, min_gain)


def _walls(grad: _Edges, poly: FloatArray, cz: float, h: float,
           factors: FloatArray, mask: np.ndarray | None, margin_deg: float, min_columns: int, min_peak: float,
           min_gain: float) -> WallSnap:
    """:func:`snap_walls` on checked inputs and the image's gradients."""
    W = _WORK_WIDTH
    K, n, one = len(poly), len(factors), len(factors) // 2
    b0 = room_boundaries(poly, cz, [0.0, 0.0], h, W)
    step = np.roll(poly, -1, axis=0) - poly
    axis = np.where(np.abs(step[:, 0]) < np.abs(step[:, 1]), 0, 1)  # wall k: x = c (0) or y = c (1)
    ceil_p: list[FloatArray | None] = [None] * K
    floor_p: list[FloatArray | None] = [None] * K
    peak = np.full(K, np.nan)
    n_cols = np.zeros(K, np.intp)
    shifts = []  # grid steps from each wall's clear floor crease to its clear ceiling crease
    for k in range(K):
        seen = b0.wall_index == k
        cols = _columns(b0.wall_index, seen, b0.ceil_v, margin_deg, mask)
        n_cols[k] = len(cols)
        if len(cols) < min_columns:
            continue
        polys = np.repeat(poly[None], n, axis=0)
        for j in (k, (k + 1) % K):
            polys[:, j, axis[k]] = poly[j, axis[k]] * factors
        b = room_boundaries(polys, np.full(n, cz), [0.0, 0.0], h, W)
        ceil_p[k] = c = _edge_profile(grad, b.ceil_v, cols)
        ic = int(np.argmax(c))
        peak[k] = c[ic] / max(float(np.median(c)), 1e-12)
        fcols = _columns(b0.wall_index, seen, b0.floor_v, margin_deg, mask)
        if len(fcols) >= min_columns:
            floor_p[k] = f = _edge_profile(grad, b.floor_v, fcols)
            i_f = int(np.argmax(f))
            if (peak[k] >= min_peak and f[i_f] >= min_peak * np.median(f) and 0 < ic < n - 1
                    and 0 < i_f < n - 1):
                shifts.append(ic - i_f)
    # the ceiling height from the walls that show both creases, when they agree
    shift, height_walls = 0, 0
    if len(shifts) >= 2 and max(shifts) - min(shifts) <= RATIO_SPREAD:
        shift = int(round(float(np.median(shifts))))
        height_walls = len(shifts) if shift else 0
    t = float(factors[one + shift] / factors[one]) if shift else 1.0  # (labels' cz - h) / (new cz - h)
    base = one + shift  # each wall's place from the labels on its ceiling profile, in the new ceiling's units
    best = np.ones(K)
    gain = np.zeros(K)
    vetoed = np.zeros(K, bool)
    for k in range(K):
        c = ceil_p[k]
        if c is None or not 0 <= base < n:
            continue
        i = int(np.argmax(c))
        med = float(np.median(c))
        if i == base or c[i] < min_peak * med or c[i] < min_gain * c[base]:
            continue
        f = floor_p[k]
        i_new = i - shift  # the new place on the floor profile (metric factors)
        if (f is not None and 0 <= i_new < n and f[one] >= min_peak * np.median(f)
                and f[i_new] < f[one] / min_gain):
            vetoed[k] = True  # the labels' wall stands on a floor crease, the new place has none
            continue
        best[k] = factors[i] / t
        gain[k] = c[i] / max(float(c[base]), 1e-12)
    out = poly.copy()
    factor = np.ones(K)
    for k in np.argsort(-gain, kind="stable"):
        if gain[k] <= 0:
            break
        trial = out.copy()
        for j in (k, (k + 1) % K):
            trial[j, axis[k]] = poly[j, axis[k]] * best[k]
        if _valid(trial):
            out, factor[k] = trial, best[k]
    return WallSnap(floor=out, ceiling_z=h + (cz - h) / t, height_walls=height_walls, factor=factor,
                    moved=factor != 1.0, peak=peak, columns=n_cols, vetoed=vetoed)


def snap_ceiling_height(image: ArrayLike, floor: ArrayLike, ceiling_z: float, camera_height: float, *,
                        object_mask: ArrayLike | None = None, span: float = DEFAULT_SPAN, steps: int = 61,
                        margin_deg: float = 2.1, min_columns: int = HEIGHT_COLUMNS, sigma: float = 1.0,
                        min_peak: float = DEFAULT_MIN_PEAK, min_gain: float = DEFAULT_MIN_GAIN) -> HeightSnap:
    """Scale the room about the camera, ceiling curves fixed, until its floor-wall curves lie on the image's edges.

    The ceiling-wall curves fix each wall's distance in units of
    ``ceiling_z - camera_height`` (what :func:`snap_walls` fits), the
    floor-wall curves in units of ``camera_height``. Scaling the polygon and
    ``ceiling_z - camera_height`` by one factor ``t`` leaves the ceiling
    curves where they are and moves every floor curve; ``t`` is chosen on a
    log grid within ``1 / span .. span`` by the mean image gradient across
    the floor curves of all walls (as for the walls), over the
    columns that show a wall (``margin_deg`` from its ends) and whose floor
    boundary the object mask leaves free, with the acceptance tests of
    :func:`snap_walls` (a clear peak, and a gain over ``t = 1``). The floor
    is often hidden by furniture; where it shows, its crease fixes the
    wall height (the room step's wall height in camera heights, which sets
    the object scale's prior, comes from the labels' ratio of the two
    boundaries).

    Parameters and errors as :func:`snap_walls` (``min_columns`` counts the
    columns of all walls together).

    Returns
    -------
    HeightSnap

    Examples
    --------
    The room of :func:`snap_walls`' example seen with its floor crease, its
    walls and ceiling given 10 % too far and too high (their ceiling curves
    are right):

    >>> from layout.labelmap import room_boundaries
    >>> true = np.array([[-2.0, -1.5], [2.0, -1.5], [2.0, 1.5], [-2.0, 1.5]])
    >>> b = room_boundaries(true, 2.6, [0.0, 0.0], 1.5, 1024)
    >>> rows = np.arange(512)[:, None] + 0.5
    >>> img = np.where(rows < b.ceil_v, 220.0, np.where(rows < b.floor_v, 120.0, 60.0))
    >>> res = snap_ceiling_height(img, true * 1.1, 1.5 + 1.1 * 1.1, 1.5)
    >>> round(res.factor * 1.1, 2), round(res.ceiling_z, 2)
    (1.0, 2.6)
    """
    img, poly, cz, h, factors, mask = _inputs(image, floor, ceiling_z, camera_height, span, steps, object_mask)
    return _height(_gradients(img, sigma), poly, cz, h, factors, mask, margin_deg, min_columns, min_peak, min_gain)


def _height(grad: _Edges, poly: FloatArray, cz: float, h: float,
            factors: FloatArray, mask: np.ndarray | None, margin_deg: float, min_columns: int, min_peak: float,
            min_gain: float) -> HeightSnap:
    """:func:`snap_ceiling_height` on checked inputs and the image's gradients."""
    W = _WORK_WIDTH
    b0 = room_boundaries(poly, cz, [0.0, 0.0], h, W)
    cols = _columns(b0.wall_index, np.ones(W, bool), b0.floor_v, margin_deg, mask)
    if len(cols) < min_columns:
        return HeightSnap(floor=poly, ceiling_z=cz, factor=1.0, peak=math.nan, columns=len(cols))
    b = room_boundaries(poly[None] * factors[:, None, None], h + (cz - h) * factors, [0.0, 0.0], h, W)
    i, peak, gain = _best(_edge_profile(grad, b.floor_v, cols), min_peak, min_gain)
    if gain <= 0:
        return HeightSnap(floor=poly, ceiling_z=cz, factor=1.0, peak=peak, columns=len(cols))
    t = float(factors[i])
    return HeightSnap(floor=poly * t, ceiling_z=h + (cz - h) * t, factor=t, peak=peak, columns=len(cols))


def snap_room(image: ArrayLike, floor: ArrayLike, ceiling_z: float, camera_height: float, *,
              object_mask: ArrayLike | None = None, span: float = DEFAULT_SPAN, steps: int = 61,
              margin_deg: float = 2.1, sigma: float = 1.0, min_peak: float = DEFAULT_MIN_PEAK,
              min_gain: float = DEFAULT_MIN_GAIN) -> RoomSnap:
    """:func:`snap_walls`, then :func:`snap_ceiling_height` on its room: what the pipeline runs after the room step
    (``pano2cad run --walls edges``). The image's gradients are computed once for both.

    Parameters, errors and defaults as :func:`snap_walls` (``min_columns``: :data:`WALL_COLUMNS` and
    :data:`HEIGHT_COLUMNS`).

    Returns
    -------
    RoomSnap
    """
    img, poly, cz, h, factors, mask = _inputs(image, floor, ceiling_z, camera_height, span, steps, object_mask)
    grad = _gradients(img, sigma)
    walls = _walls(grad, poly, cz, h, factors, mask, margin_deg, WALL_COLUMNS, min_peak, min_gain)
    height = _height(grad, walls.floor, walls.ceiling_z, h, factors, mask, margin_deg, HEIGHT_COLUMNS, min_peak,
                     min_gain)
    return RoomSnap(floor=height.floor, ceiling_z=height.ceiling_z, walls=walls, height=height)
