"""Room geometry from a surface-label panorama: Manhattan floor polygon, wall height, scale.

Two routes, one result (:class:`RoomGeometry`):

``method="columns"`` (default, fast and robust)
    Works on the panorama columns directly (the post-processing of
    LayoutNet / HorizonNet). The ceiling-wall boundary is rarely occluded,
    the floor-wall boundary often is (beds and desks, labelled floor or
    clutter). So the wall height comes first: where a column shows both
    boundaries, ``(ceiling_z - camera_height) / camera_height =
    tan(lat_c) / tan(-lat_f)``, and furniture labelled floor makes this
    ratio too large; the estimate is the lowest well-supported mode of the
    ratios.
    Each column's horizontal wall distance then comes from the ceiling
    boundary, ``d = (ceiling_z - camera_height) / tan(lat_c)``, averaged
    with the floor boundary's ``d = camera_height / tan(-lat_f)`` where the
    two agree; a floor boundary that disagrees is taken for furniture
    (unless the agreeing columns nearby side with it; optionally also where
    the two boundaries disagree along most of that wall and the floor
    boundary is the straighter wall there, :func:`_walls_off_ceiling`), and
    used alone only
    where the ceiling boundary is not seen (:func:`observe_columns`). The
    wall label (3 or 4) of the column says which coordinate of the point
    ``d * (cos lon, -sin lon)`` is the wall's offset, overridden where the
    shape of the distance curve on both sides of the column clearly says
    otherwise (:func:`_axis_from_shape`). Columns are cut into runs of one
    axis and one offset (robust medians), the runs become
    :class:`layout.floorplan.WallObservation` and
    :func:`layout.floorplan.close_manhattan_polygon` closes them. Weak runs
    (label noise) are then dropped or merged with their parallel neighbour
    while the closed polygon reproduces the labels at least as well
    (:func:`prune_walls`: the paper's E_s pixel agreement, computed per
    column with :class:`layout.labelmap.LabelCounts`, minus a price per
    corner). When that polygon still explains few columns (unreliable
    labels), a robust cost of the column distances with a price per corner
    chooses among it, its walls pruned again under that cost (tiny notches
    go) and a fitted rectangle, each with its wall lines refitted
    (:func:`_robust_selection`).

``method="pointcloud"`` (the paper's Sec. 3.1)
    Six perspective views (:func:`panogeom.perspective.layout_views`), one
    point cloud per view lifted through the floor contact with its own
    unknown scale (:mod:`layout.pointcloud`), Open3D alignment of the clouds
    (:mod:`layout.align`), greedy Manhattan plane fitting largest segment
    first (:mod:`layout.planefit`), then the same closing step.

In both, the ceiling height comes from the columns where the wall meets
both floor and ceiling (as above), and metric units from the camera height.

Convention:
    Input label maps follow shared/CONVENTIONS.md (0 unknown / clutter,
    1 floor, 2 ceiling, 3 wall facing +-x, 4 wall facing +-y, 5 object) in an
    upright (rectified) equirectangular frame, W == 2*H. Output in the world
    frame: metres (units of ``camera_height``), origin on the floor below the
    camera, z up; the floor polygon is counter-clockwise seen from above,
    Manhattan, no repeated closing vertex; floor at z = 0.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import DEFAULT_CAMERA_HEIGHT, pixel_to_lonlat
from panogeom.rotation import angle_difference

from .floorplan import FloorPlan, WallObservation, close_manhattan_polygon
from .polygon import points_in_polygon, polygon_problems
from .labelmap import (
    WALL_X,
    WALL_Y,
    LabelCounts,
    ObservedBoundaries,
    check_label_map,
    column_directions,
    observe_boundaries,
    room_boundaries,
)

__all__ = [
    "RoomGeometryError",
    "RoomGeometry",
    "ColumnObservations",
    "observe_columns",
    "column_wall_runs",
    "prune_walls",
    "estimate_room_geometry",
    "RELIABLE_INLIER_FRACTION",
]

FloatArray = NDArray[np.float64]
Method = Literal["columns", "pointcloud"]
Prefer = Literal["ceiling", "floor", "wall"]
CeilingEstimate = Literal["lowest_mode", "median"]

#: A polygon explaining fewer than this share of its observed wall columns (``RoomGeometry.inlier_fraction``) is
#: taken to rest on unreliable labels: :func:`estimate_room_geometry` then chooses it robustly (``robust_below``)
#: and flags the room uncertain.
RELIABLE_INLIER_FRACTION = 0.75

#: Walls are never closer than this to the camera, in camera heights (boundary at the horizon is no wall).
_MAX_DISTANCE = 40.0


class RoomGeometryError(RuntimeError):
    """No room geometry can be estimated from the labels (e.g. no wall meets the floor anywhere)."""


@dataclass(frozen=True)
class RoomGeometry:
    """A Manhattan room estimated from surface labels.

    Attributes
    ----------
    floor : (N, 2) float
        Floor polygon, metres, counter-clockwise, Manhattan, simple; wall i
        runs from vertex i to vertex i + 1.
    ceiling_z : float
        Ceiling height above the floor (= wall height), metres.
    camera_height : float
        Camera centre above the floor, metres (the scale reference).
    wall_axis : (N,) int
        0: wall ``x = const`` (label 3); 1: ``y = const`` (label 4).
    wall_support : (N,) int
        Columns (or points) supporting each wall; 0 for walls completed
        behind occluders.
    inlier_fraction : float
        Fraction of the observed wall columns whose distance the polygon
        reproduces within 8 % (how well the polygon explains the labels).
    ceiling_support : int
        Columns used for the ceiling height.
    uncertain : bool
        Part of the answer is a guess; ``reasons`` says which.
    reasons : tuple of str
    method : str
        ``"columns"`` or ``"pointcloud"``.
    timing_s : float
        Wall-clock seconds of the estimation.
    alignment : object or None
        The :class:`layout.align.CloudAlignment` of the point-cloud route.

    Convention: world frame of the module docstring (camera at
    ``(0, 0, camera_height)``, floor z = 0).
    """

    floor: FloatArray
    ceiling_z: float
    camera_height: float
    wall_axis: NDArray[np.intp]
    wall_support: NDArray[np.intp]
    inlier_fraction: float
    ceiling_support: int
    uncertain: bool
    reasons: tuple[str, ...]
    method: str
    timing_s: float
    alignment: Any = None

    @property
    def n_corners(self) -> int:
        return int(len(self.floor))

    @property
    def wall_labels(self) -> NDArray[np.uint8]:
        """(N,) surface label of each wall: 3 (x = const) or 4 (y = const)."""
        return np.where(self.wall_axis == 0, WALL_X, WALL_Y).astype(np.uint8)

    @property
    def wall_height(self) -> float:
        """Ceiling height minus floor height (floor at z = 0)."""
        return float(self.ceiling_z)

    def corners_px(self, width: int = 1024) -> FloatArray:
        """HorizonNet-style corner pixels ``[u_ceiling, v_ceiling, u_floor, v_floor]`` per floor vertex
        (gt.json's ``corners_px``, :func:`layout.corners.polygon_to_corners_px`) in a W x W/2 panorama."""
        from .corners import polygon_to_corners_px

        return polygon_to_corners_px(self.floor, self.ceiling_z, self.camera_height, width)

    def room_dict(self) -> dict[str, Any]:
        """The ``room`` entry of scene.json: floor, floor_z, ceiling_z (plain lists and floats)."""
        return {"floor": self.floor.tolist(), "floor_z": 0.0, "ceiling_z": float(self.ceiling_z)}


@dataclass(frozen=True)
class ColumnObservations:
    """Per-column wall points read from a label map (result of :func:`observe_columns`).

    Attributes (W = panorama width)
    ----------
    lon : (W,) float
        Column longitude, radians.
    distance : (W,) float
        Horizontal camera-to-wall distance, metres (NaN where unobserved).
    points : (W, 2) float
        ``distance * (cos lon, -sin lon)``: the wall point seen (NaN where
        unobserved).
    axis : (W,) int
        0 for label 3 (x = const), 1 for label 4, -1 where unobserved.
    from_floor : (W,) bool
        The column's distance uses its floor contact (averaged with the
        ceiling contact where both agree; with ``prefer="ceiling"`` or
        ``"wall"`` a floor contact that disagrees with the ceiling contact
        is taken for furniture and not used, unless its neighbours or its
        wall side with it).
    pixel_sigma : (W,) float
        How far, in metres, the wall offset read from the column moves when
        its boundary row moves by one pixel (``d(offset)/d(row)``).
    ceiling_z : float
        Ceiling height estimate, metres.
    ceiling_support : int
        Columns with both contacts whose height ratio agrees with ``ceiling_z``.
    boundaries : ObservedBoundaries
    distance_sigma : (W,) float
        How far, in metres, ``distance`` moves when its boundary row moves
        by one pixel (NaN where unobserved).
    weight : (W,) float
        Trust in the column: 1 where floor and ceiling contacts agree, 0.5
        with one contact, 0.25 where they disagree (0 where unobserved).
    """

    lon: FloatArray
    distance: FloatArray
    points: FloatArray
    axis: NDArray[np.intp]
    from_floor: NDArray[np.bool_]
    pixel_sigma: FloatArray
    ceiling_z: float
    ceiling_support: int
    boundaries: ObservedBoundaries
    distance_sigma: FloatArray | None = None
    weight: FloatArray | None = None

    @property
    def observed(self) -> NDArray[np.bool_]:
        return self.axis >= 0


def _row_lat(v: FloatArray, w: int, h: int) -> FloatArray:
    uv = np.stack([np.full_like(v, 0.5 * w), np.nan_to_num(v, nan=0.5 * h)], axis=-1)
    return pixel_to_lonlat(uv, w, h)[:, 1]


def observe_columns(labels: ArrayLike, camera_height: float = DEFAULT_CAMERA_HEIGHT, *,
                    object_mask: ArrayLike | None = None, min_purity: float = 0.6,
                    prefer: Prefer = "ceiling", shape_axis: bool = True,
                    ceiling_estimate: CeilingEstimate = "lowest_mode") -> ColumnObservations:
    """Wall distance, wall point and wall axis of every panorama column.

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels, W == 2*H.
    camera_height : float
        Camera centre above the floor, metres (sets the units).
    object_mask : (H, W) bool, optional
        Pixels to ignore (detected objects).
    min_purity : float
        Columns whose wall pixels are less than this fraction of one label
        are left unobserved.
    prefer : {"wall", "ceiling", "floor"}
        Which contact gives the distance where both are seen but disagree.
        ``"ceiling"`` (default): furniture hides or fakes the floor-wall
        boundary far more often than anything hides the ceiling-wall one.
        ``"wall"``: the same, except on walls where the two contacts
        disagree along most of the wall and the floor contact gives the
        straighter wall (:func:`_walls_off_ceiling`: an estimated ceiling
        label creeping down a shadowed wall), whose floor contacts are
        trusted; better on the estimated labels of both tuning sets, but not
        in the whole pipeline on both (docs/EVALUATION.md, session 15), so
        not the default. ``"floor"``: the floor contact wherever it is seen.
    ceiling_estimate : {"lowest_mode", "median"}
        How the per-column wall-height ratios are combined:
        :func:`_ratio_mode` (default) or their plain median.
    shape_axis : bool
        Let the shape of the boundary curve decide a column's wall axis
        where it is unambiguous (:func:`_axis_from_shape`), overriding the
        wall label (3 or 4), which estimated labels often get wrong.

    Returns
    -------
    ColumnObservations

    Raises
    ------
    RoomGeometryError
        When no column shows a wall meeting the floor, or none shows both
        contacts (no scale for the ceiling).

    The wall height comes first: every column with both contacts gives
    ``(ceiling_z - camera_height) / camera_height = tan(lat_c) / tan(-lat_f)``;
    the estimate is the lowest well-supported mode of these ratios
    (:func:`_ratio_mode`). Then each column's distance comes from the
    ceiling contact, ``d = (ceiling_z - camera_height) / tan(lat_c)``,
    averaged with the floor contact ``d = camera_height / tan(-lat_f)``
    where the two agree within a few pixel rows; a disagreeing floor
    contact is used only where the ceiling contact is missing, the
    agreeing columns nearby (``W / 64`` each side) side with it or (with
    ``prefer="wall"``) most of its wall disagrees and the floor contacts
    give the straighter wall.

    Convention: world frame of the module docstring, latitudes of
    :mod:`panogeom.coords`.

    Examples
    --------
    >>> from layout.labelmap import render_room_labels
    >>> lab = render_room_labels([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 512)
    >>> obs = observe_columns(lab, 1.6)
    >>> round(obs.ceiling_z, 2), bool(obs.observed.all())
    (2.7, True)
    """
    h_cam = float(camera_height)
    if not (np.isfinite(h_cam) and h_cam > 0):
        raise ValueError(f"camera_height: expected a positive finite height, got {camera_height!r}")
    if prefer not in ("ceiling", "floor", "wall"):
        raise ValueError(f"prefer: expected 'ceiling', 'floor' or 'wall', got {prefer!r}")
    if ceiling_estimate not in ("lowest_mode", "median"):
        raise ValueError(f"ceiling_estimate: expected 'lowest_mode' or 'median', got {ceiling_estimate!r}")
    lab = check_label_map(labels)
    h, w = lab.shape
    ob = observe_boundaries(lab, object_mask)
    lon, direction = column_directions(w)
    lat_f = _row_lat(ob.floor_v, w, h)
    lat_c = _row_lat(ob.ceil_v, w, h)
    min_lat = np.deg2rad(0.5)
    floor_ok = ob.floor_contact & (lat_f < -min_lat)
    with np.errstate(divide="ignore", invalid="ignore"):
        d_f = np.where(floor_ok, h_cam / np.tan(-lat_f), np.nan)
    floor_ok &= d_f < _MAX_DISTANCE * h_cam
    if not np.any(floor_ok):
        raise RoomGeometryError("no column shows a wall meeting the floor: the floor-wall boundary is hidden "
                                "everywhere, so the room has no scale")
    both = floor_ok & ob.ceil_contact & (lat_c > min_lat)
    if not np.any(both):
        raise RoomGeometryError("no column shows a wall meeting both floor and ceiling: the wall height cannot be "
                                "measured")
    # wall height above the camera in camera heights, per column: tan(lat_c) / tan(-lat_f)
    ratio = np.tan(lat_c[both]) / np.tan(-lat_f[both])
    if ceiling_estimate == "median":
        ratio_hat, used = float(np.median(ratio)), int(ratio.size)
    else:
        ratio_hat, used = _ratio_mode(ratio)
    ceiling_z = float(h_cam * (1.0 + ratio_hat))
    hc = ceiling_z - h_cam
    ceil_ok = ob.ceil_contact & (lat_c > min_lat) & (hc > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        d_c = np.where(ceil_ok, hc / np.tan(lat_c), np.nan)
    ceil_ok &= d_c < _MAX_DISTANCE * h_cam
    # d = h_eff / tan(|lat|): |dd/dlat| = (d^2 + h_eff^2) / h_eff; one row is pi / H radians
    row = np.pi / h
    s_f = (d_f ** 2 + h_cam ** 2) / h_cam * row
    s_c = (d_c ** 2 + hc ** 2) / max(hc, 1e-9) * row
    # both contacts and consistent within a few rows: inverse-variance average of the two distances
    agree = floor_ok & ceil_ok & (np.abs(d_f - d_c) <= 4.0 * np.hypot(s_f, s_c))
    w_f, w_c = 1.0 / s_f ** 2, 1.0 / s_c ** 2
    with np.errstate(invalid="ignore"):
        d_both = (w_f * d_f + w_c * d_c) / (w_f + w_c)
        s_both = 1.0 / np.sqrt(w_f + w_c)
    if prefer in ("ceiling", "wall"):
        # the ceiling contact is rarely occluded: a floor contact that disagrees with it is taken for furniture,
        # unless the columns nearby where both contacts agree side with the floor contact (a label blob on the
        # ceiling boundary)
        half = max(2, w // 64)
        trusted = np.where(agree, d_both, np.nan)
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            ref = np.nanmedian(np.stack([np.roll(trusted, k) for k in range(-half, half + 1)]), axis=0)
            floor_side = np.isfinite(ref) & (np.abs(np.log(d_f / ref)) < np.abs(np.log(d_c / ref)))
        if prefer == "wall":
            # (leaving such walls out of the wall height too was measured and not kept: no better on the tuning sets)
            floor_side |= _walls_off_ceiling(ob.wall_label, direction, d_f, d_c, floor_ok & ceil_ok, agree,
                                             max(4, w // 128))
        use_f = floor_ok & ~agree & (~ceil_ok | floor_side)
        dist = np.where(agree, d_both, np.where(use_f, d_f, np.where(ceil_ok, d_c, np.nan)))
        sig = np.where(agree, s_both, np.where(use_f, s_f, s_c))
        uses_floor = agree | use_f
    else:
        dist = np.where(agree, d_both, np.where(floor_ok, d_f, np.where(ceil_ok, d_c, np.nan)))
        sig = np.where(agree, s_both, np.where(floor_ok, s_f, s_c))
        uses_floor = floor_ok
    # how much a column is trusted: both contacts agree 1, one contact only 0.5, contacts disagree 0.25
    weight = np.where(agree, 1.0, np.where(floor_ok & ceil_ok, 0.25, 0.5))
    axis = np.where(ob.wall_label == WALL_X, 0, np.where(ob.wall_label == WALL_Y, 1, -1)).astype(np.intp)
    axis = np.where(np.isfinite(dist) & (ob.wall_purity >= min_purity), axis, -1)
    if shape_axis:
        shaped = _axis_from_shape(dist, _boundary_noise_px(ob) * sig, direction, max(4, w // 64))
        axis = np.where(np.isfinite(dist) & (shaped >= 0), shaped, axis)
    dist = np.where(axis >= 0, dist, np.nan)
    comp = np.abs(np.take_along_axis(direction, np.clip(axis, 0, 1)[:, None], axis=1)[:, 0])
    sigma = np.where(axis >= 0, sig * comp, np.nan)
    return ColumnObservations(lon=lon, distance=dist, points=dist[:, None] * direction, axis=axis,
                              from_floor=uses_floor & (axis >= 0), pixel_sigma=sigma, ceiling_z=ceiling_z,
                              ceiling_support=int(used), boundaries=ob,
                              distance_sigma=np.where(axis >= 0, sig, np.nan),
                              weight=np.where(axis >= 0, weight, 0.0))


def _circular_runs(key: NDArray[np.integer]) -> list[NDArray[np.intp]]:
    """Index runs of equal values along a circular array, without the runs of negative values."""
    n = key.size
    start = np.flatnonzero(key != np.roll(key, 1))
    if start.size == 0:
        return [np.arange(n, dtype=np.intp)] if n and key[0] >= 0 else []
    ends = np.roll(start, -1)
    return [np.arange(a, b if b > a else b + n, dtype=np.intp) % n for a, b in zip(start, ends) if key[a] >= 0]


def _walls_off_ceiling(wall_label: NDArray[np.uint8], direction: FloatArray, d_f: FloatArray, d_c: FloatArray,
                       both: NDArray[np.bool_], agree: NDArray[np.bool_], min_columns: int,
                       share: float = 0.5) -> NDArray[np.bool_]:
    """Columns of walls whose floor contact is the straighter wall where it disagrees with the ceiling contact.

    A wall is a circular run of one wall label (3 or 4; ``direction`` (W, 2)
    the columns' horizontal ray directions). Where at least ``min_columns``
    of its columns show both contacts (``both``) and more than ``share`` of
    those disagree, the wall offsets read from the two contacts
    (``|d * direction[axis]|``) are compared: a contact that follows the
    wall gives one offset along it, a label edge that has left the wall
    (a ceiling label creeping down a shadowed wall, a wall label climbing a
    dark ceiling, furniture labelled floor) does not. Where the floor
    contact's offsets spread less (median absolute deviation relative to
    the median), the floor contacts of the wall are trusted over its
    ceiling contacts.
    """
    out = np.zeros(wall_label.shape, dtype=bool)
    key = np.where(np.isin(wall_label, (WALL_X, WALL_Y)), wall_label.astype(np.intp), -1)
    for run in _circular_runs(key):
        seen = run[both[run]]
        if seen.size < min_columns or np.mean(~agree[seen]) <= share:
            continue
        comp = np.abs(direction[seen, 0 if key[run[0]] == WALL_X else 1])
        spread = []
        for d in (d_f[seen], d_c[seen]):
            off = d * comp
            med = np.median(off)
            spread.append(np.median(np.abs(off - med)) / max(med, 1e-9))
        if spread[0] < spread[1]:
            out[run] = True
    return out


def _ratio_mode(ratio: FloatArray, bandwidth: float = 0.08, min_share: float = 0.1) -> tuple[float, int]:
    """Lowest well-supported mode of positive ratios on a log scale, refined by the median near it.

    Furniture in front of a wall bottom that the labeller calls floor (the
    common failure: beds, desks) raises the observed floor-wall boundary and
    makes the per-column ratio ``tan(lat_c) / tan(-lat_f)`` too large; the
    clean columns pile up at the true ratio. So the answer is the lowest local
    maximum of a Gaussian kernel density whose neighbourhood (two bandwidths)
    holds at least ``min_share`` of the ratios (and at least 3), else the
    global mode.

    Returns the estimate and how many ratios lie within two bandwidths of it.
    """
    x = np.log(ratio[np.isfinite(ratio) & (ratio > 0)])
    if x.size == 0:
        raise RoomGeometryError("no column gives a positive wall height above the camera")
    grid = np.arange(x.min() - 2 * bandwidth, x.max() + 2 * bandwidth + 1e-12, bandwidth / 4)
    dens = np.zeros_like(grid)
    for chunk in np.array_split(x, max(1, x.size // 256)):
        dens += np.exp(-0.5 * ((grid[:, None] - chunk[None, :]) / bandwidth) ** 2).sum(axis=1)
    xs = np.sort(x)
    mass = (np.searchsorted(xs, grid + 2 * bandwidth, side="right") - np.searchsorted(xs, grid - 2 * bandwidth))
    left = np.concatenate([[-np.inf], dens[:-1]])
    right = np.concatenate([dens[1:], [-np.inf]])
    peaks = np.flatnonzero((dens >= left) & (dens >= right) & (mass >= max(3, min_share * x.size)))
    peak = grid[int(peaks[0])] if peaks.size else grid[int(np.argmax(dens))]
    near = np.abs(x - peak) <= 2 * bandwidth
    return float(np.exp(np.median(x[near]))), int(np.count_nonzero(near))


def _boundary_noise_px(ob: ObservedBoundaries) -> float:
    """Row noise of the observed boundaries, pixels: robust spread of their second differences / sqrt(6).

    At least 0.5 (the quantisation of a clean label map), at most 5.
    """
    diffs = []
    for v in (ob.floor_v, ob.ceil_v):
        d2 = v[2:] - 2.0 * v[1:-1] + v[:-2]
        diffs.append(d2[np.isfinite(d2)])
    d2 = np.concatenate(diffs)
    if d2.size < 8:
        return 2.0
    return float(np.clip(1.4826 * np.median(np.abs(d2)) / np.sqrt(6.0), 0.5, 5.0))


def _axis_from_shape(dist: FloatArray, sigma: FloatArray, direction: FloatArray, half: int,
                     ratio: float = 20.0, min_chi2: float = 16.0) -> NDArray[np.intp]:
    """Wall axis of each column from the shape of the wall-distance curve around it; -1 where unclear.

    Along a wall ``x = X`` the points ``d * (cos lon, -sin lon)`` keep their
    x and their y runs as ``X tan``: in an upright panorama the boundary of
    a straight wall is a fixed curve of its normal and distance. On each
    side of a column (``half`` columns, the column included) the points are
    fitted with ``x = const`` and with ``y = const``; a side decides for the
    axis whose mean squared residual (in units of ``sigma`` times the
    direction component) is ``ratio`` times lower than the other's, the other
    being clearly wrong (``> min_chi2``). Only both sides deciding alike
    give the axis, and only in runs of five or more columns decided alike;
    near a corner (sides that disagree or one undecided) the column keeps
    its label.
    """
    w = len(dist)
    ok = np.isfinite(dist) & np.isfinite(sigma)
    side_axis = []
    chi = []
    for a in (0, 1):
        c = np.where(ok, dist * direction[:, a], 0.0)
        sa = np.where(ok, sigma * np.abs(direction[:, a]), 1.0) + 0.005 * np.where(ok, dist, 1.0)
        om = np.where(ok, 1.0 / sa ** 2, 0.0)
        cums = []
        for arr in (ok.astype(float), om, om * c, om * c * c):
            ext = np.concatenate([arr[-half:], arr, arr[:half]])
            cums.append(np.concatenate([[0.0], np.cumsum(ext)]))
        i = np.arange(w) + half  # index of column i in the padded array
        sides = []
        for lo, hi in ((i - half + 1, i + 1), (i, i + half)):
            n, s0, s1, s2 = (cs[hi] - cs[lo] for cs in cums)
            with np.errstate(divide="ignore", invalid="ignore"):
                sse = s2 - s1 * s1 / s0
                sides.append(np.where(n >= max(3, half // 2), np.maximum(sse, 0.0) / np.maximum(n, 1), np.nan))
        chi.append(sides)
    for side in range(2):
        c0, c1 = chi[0][side], chi[1][side]
        dec = np.full(w, -1, np.intp)
        with np.errstate(invalid="ignore"):
            dec[(c0 * ratio < c1) & (c1 > min_chi2)] = 0
            dec[(c1 * ratio < c0) & (c0 > min_chi2)] = 1
        side_axis.append(dec)
    left, right = side_axis
    out = np.where(ok & (left == right), left, -1)
    # isolated decisions (a column or two next to a corner) are not trusted: keep runs of >= 5 alike
    alike = np.all(np.stack([np.roll(out, k) == out for k in range(-2, 3)]), axis=0)
    return np.where(alike, out, -1).astype(np.intp)


def _circular_median(values: FloatArray, same: NDArray[np.bool_], half: int) -> FloatArray:
    """Median over a circular window of +-half entries, counting only entries flagged ``same`` to the centre."""
    n = len(values)
    stack = []
    for k in range(-half, half + 1):
        rolled = np.roll(values, -k)
        stack.append(np.where(same[k], rolled, np.nan))
    return np.nanmedian(np.stack(stack), axis=0) if n else values


def column_wall_runs(obs: ColumnObservations, camera_height: float, *, min_columns: int | None = None,
                     jump_abs: float = 0.06, jump_px: float = 3.0,
                     split_steps: bool = True) -> list[WallObservation]:
    """Cut the observed columns into runs of one wall: same axis, continuous offset.

    Parameters
    ----------
    obs : ColumnObservations
    camera_height : float
        Metres; absolute tolerances are multiples of it.
    min_columns : int, optional
        Shorter runs are dropped as spurious (default ``max(3, W // 256)``).
    jump_abs, jump_px : float
        Two neighbouring columns belong to different walls when their
        (locally median-filtered) offsets differ by more than
        ``jump_abs * camera_height`` plus what a boundary error of
        ``jump_px`` rows does to the offset (``obs.pixel_sigma``).
    split_steps : bool
        Also cut a run where its offset steps by more than twice that
        tolerance between two flat parts (:func:`_split_steps`): a wall seen
        edge-on between two parallel walls (the side of an alcove, in line
        with the camera) shows as a ramp of small steps that the
        neighbour test above does not see.

    Returns
    -------
    list of WallObservation
        In increasing longitude; offset = median of the run, spread =
        1.4826 * MAD.

    Convention: axis 0 = wall ``x = offset`` (label 3), 1 = ``y = offset``.
    """
    w = len(obs.lon)
    min_cols = max(3, w // 256) if min_columns is None else int(min_columns)
    idx = np.flatnonzero(obs.observed)
    if idx.size == 0:
        return []
    ax = obs.axis[idx]
    coord = np.where(ax == 0, obs.points[idx, 0], obs.points[idx, 1])
    sig = obs.pixel_sigma[idx]
    n = idx.size
    half = 3
    same = {k: np.roll(ax, -k) == ax for k in range(-half, half + 1)}
    smooth = _circular_median(coord, same, half)
    nxt = (np.arange(n) + 1) % n
    tol = jump_abs * camera_height + jump_px * np.minimum(sig, sig[nxt])
    brk = (ax != ax[nxt]) | (np.abs(smooth - smooth[nxt]) > tol)
    starts = np.sort((np.flatnonzero(brk) + 1) % n) if np.any(brk) else np.array([0])
    runs = []
    for s_i, s in enumerate(starts):
        e = starts[(s_i + 1) % len(starts)]  # a single start: the run goes once around
        members = np.arange(s, e) if e > s else np.concatenate([np.arange(s, n), np.arange(0, e)])
        if members.size >= min_cols:
            runs.extend(_split_steps(members, coord, tol, min_cols) if split_steps else [members])
    walls: list[WallObservation] = []
    two_pi = 2.0 * np.pi
    for members in runs:
        c = coord[members]
        med = float(np.median(c))
        mad = float(np.median(np.abs(c - med)))
        lon0 = float(obs.lon[idx[members[0]]])
        ext = float((obs.lon[idx[members[-1]]] - lon0) % two_pi)
        walls.append(WallObservation(axis=int(ax[members[0]]), offset=med, lon_start=lon0, lon_end=lon0 + ext,
                                     support=int(members.size), spread=1.4826 * mad))
    return walls


def _split_steps(members: NDArray[np.intp], coord: FloatArray, tol: FloatArray, min_cols: int,
                 depth: int = 3) -> list[NDArray[np.intp]]:
    """Cut a run of columns into flat parts where its offset steps (recursive two-piece L1 fit).

    A cut is made at the split that minimises the summed absolute deviation
    of the two parts from their medians, when both parts have ``min_cols``
    columns or more, their medians differ by more than twice the run's
    median tolerance ``tol`` (metres, per column) and by more than 8 times
    either part's median absolute deviation (two flat walls, not a noisy
    one), and the split halves the run's absolute deviation or better.

    Parameters
    ----------
    members : (M,) int
        Indices (into ``coord`` and ``tol``) of the run's columns, in order.
    coord : (N,) float
        Wall offset read from each observed column.
    tol : (N,) float
    min_cols, depth : int

    Returns
    -------
    list of (M_i,) int arrays, in order, concatenating to ``members``.

    Examples
    --------
    >>> c = np.r_[np.full(20, 2.2), np.linspace(2.2, 1.6, 4), np.full(20, 1.6)]
    >>> [len(p) for p in _split_steps(np.arange(44), c, np.full(44, 0.1), 4)]
    [22, 22]
    """
    m = members.size
    if depth <= 0 or m < 2 * min_cols:
        return [members]
    c = coord[members]
    tol_run = float(np.median(tol[members]))
    if float(np.ptp(c)) <= 2.0 * tol_run:  # no two medians of parts can differ by more
        return [members]
    whole = float(np.abs(c - np.median(c)).sum())
    ks = np.arange(min_cols, m - min_cols + 1)
    left = np.arange(m)[None, :] < ks[:, None]  # (K, M): column i in the first part of split k
    costs = np.zeros(len(ks))
    for part in (left, ~left):  # every split's two medians at once
        vals = np.where(part, c[None, :], np.nan)
        costs += np.nansum(np.abs(vals - np.nanmedian(vals, axis=1, keepdims=True)), axis=1)
    k = int(ks[int(np.argmin(costs))])
    a, b = c[:k], c[k:]
    ma, mb = float(np.median(a)), float(np.median(b))
    step = abs(ma - mb)
    flat = max(float(np.median(np.abs(a - ma))), float(np.median(np.abs(b - mb))))
    if step <= 2.0 * tol_run or step <= 8.0 * flat or float(costs.min()) > 0.5 * whole:
        return [members]
    return (_split_steps(members[:k], coord, tol, min_cols, depth - 1)
            + _split_steps(members[k:], coord, tol, min_cols, depth - 1))


def _inlier_fraction(floor: FloatArray, ceiling_z: float, camera_height: float, obs: ColumnObservations,
                     rel_tol: float = 0.08) -> float:
    m = obs.observed
    if not np.any(m):
        return 0.0
    b = room_boundaries(floor, ceiling_z, [0.0, 0.0], camera_height, len(obs.lon))
    if not bool(b.valid):
        return 0.0
    err = np.abs(b.distance[m] - obs.distance[m]) / obs.distance[m]
    return float(np.mean(err <= rel_tol))


def _merged(a: WallObservation, b: WallObservation) -> WallObservation:
    tot = a.support + b.support
    off = (a.offset * a.support + b.offset * b.support) / tot if tot > 0 else 0.5 * (a.offset + b.offset)
    ext = (b.lon_end - a.lon_start) % (2.0 * np.pi)
    return WallObservation(axis=a.axis, offset=float(off), lon_start=a.lon_start, lon_end=a.lon_start + ext,
                           support=tot, spread=max(a.spread, b.spread, abs(a.offset - b.offset) / 2))


def prune_walls(walls: list[WallObservation], close: Callable[[list[WallObservation]], FloorPlan],
                score: Callable[[FloorPlan], float], *, max_support: int,
                max_evaluations: int = 200) -> tuple[FloorPlan, list[WallObservation]]:
    """Simplify the wall list while the closed polygon explains the labels at least as well.

    Greedy model selection by local search, first improvement: the moves
    are (a) dropping a wall with support below ``max_support``, weakest
    first, and (b) merging two consecutive parallel walls into one,
    closest offsets first. A move is kept when ``score`` of the re-closed
    polygon (e.g. label pixels reproduced minus a price per corner) does not
    decrease. Stops when no move is kept or after ``max_evaluations``
    closings.

    Returns
    -------
    (plan, walls) : the best FloorPlan and the walls it was closed from.
    """
    current = sorted(walls, key=lambda w: (w.lon_start + np.pi) % (2.0 * np.pi))
    plan = close(current)
    best = score(plan)
    evaluations = 1
    improved = True
    while improved and len(current) > 2 and evaluations < max_evaluations:
        improved = False
        n = len(current)
        moves: list[list[WallObservation]] = []
        for k in sorted(range(n), key=lambda i: current[i].support):
            if current[k].support < max_support:
                moves.append(current[:k] + current[k + 1:])
        pairs = [i for i in range(n) if current[i].axis == current[(i + 1) % n].axis]
        for i in sorted(pairs, key=lambda i: abs(current[i].offset - current[(i + 1) % n].offset)):
            j = (i + 1) % n
            m = _merged(current[i], current[j])
            moves.append(current[:i] + [m] + current[i + 2:] if j else [m] + current[1:n - 1])
        for cand in moves:
            if evaluations >= max_evaluations:
                break
            p = close(cand)
            evaluations += 1
            sc = score(p)
            if sc >= best and not (p.uncertain and not plan.uncertain):
                current, plan, best, improved = cand, p, sc, True
                break
    return plan, current


def _offsets_to_polygon(axis: NDArray[np.intp], offsets: FloatArray) -> FloatArray:
    """Vertices of a Manhattan polygon whose wall i (vertex i to i + 1) is the line ``xy[axis[i]] = offsets[i]``."""
    n = len(axis)
    prev = np.roll(np.arange(n), 1)
    v = np.empty((n, 2))
    v[np.arange(n), axis] = offsets
    v[np.arange(n), axis[prev]] = offsets[prev]
    return v


def _polygon_ok(poly: FloatArray) -> bool:
    return not polygon_problems(poly, tol=1e-9) and bool(points_in_polygon(np.zeros(2), poly, margin=1e-6))


@dataclass(frozen=True)
class _Residuals:
    """Robust fit of a polygon to the per-column wall distances (see :func:`_column_fit`)."""

    weight: FloatArray
    distance: FloatArray
    sigma: FloatArray
    cap: float
    columns: NDArray[np.intp]

    def normalised(self, poly: FloatArray, ceiling_z: float, camera_height: float, width: int) -> FloatArray:
        b = room_boundaries(poly, ceiling_z, [0.0, 0.0], camera_height, width)
        model = np.where(np.isfinite(b.distance), b.distance, 1e6)
        return (self.distance - model[self.columns]) / self.sigma


def _column_fit(obs: ColumnObservations, pixel_error: float) -> _Residuals:
    m = np.flatnonzero(obs.observed)
    sig = obs.distance_sigma if obs.distance_sigma is not None else obs.pixel_sigma
    wgt = obs.weight if obs.weight is not None else np.ones(len(obs.lon))
    return _Residuals(weight=wgt[m], distance=obs.distance[m], sigma=pixel_error * sig[m], cap=3.0, columns=m)


def _robust_cost(fit: _Residuals, poly: FloatArray, ceiling_z: float, camera_height: float, width: int) -> float:
    """Sum over observed columns of weight * min(r^2, cap^2), r the distance residual in boundary-pixel errors."""
    r = fit.normalised(poly, ceiling_z, camera_height, width)
    return float(np.sum(fit.weight * np.minimum(r * r, fit.cap ** 2)))


def _refine_offsets(poly: FloatArray, axis: NDArray[np.intp], fit: _Residuals, ceiling_z: float,
                    camera_height: float, width: int, iterations: int = 8) -> FloatArray:
    """Move the wall lines of a Manhattan polygon to fit the column distances (soft-L1, reweighted least squares).

    A column that sees wall k (axis a, offset o) predicts ``d = o / dir_a``:
    linear in o, so with the columns assigned to the walls each offset has a
    closed-form weighted least-squares solution; the soft-L1 weights
    ``1 / sqrt(1 + (r / cap)^2)`` and the assignment are updated in turn.
    A step that would make the polygon invalid is not taken.
    """
    n = len(poly)
    off = poly[np.arange(n), axis].astype(np.float64)
    direction = column_directions(width)[1][fit.columns]
    best = poly
    for _ in range(iterations):
        cand = _offsets_to_polygon(axis, off)
        b = room_boundaries(cand, ceiling_z, [0.0, 0.0], camera_height, width)
        if not bool(b.valid):
            break
        k = b.wall_index[fit.columns]
        r = (fit.distance - b.distance[fit.columns]) / fit.sigma
        omega = fit.weight / np.sqrt(1.0 + (r / fit.cap) ** 2) / fit.sigma ** 2
        g = 1.0 / direction[np.arange(k.size), axis[k]]
        num = np.bincount(k, omega * g * fit.distance, minlength=n)
        den = np.bincount(k, omega * g * g, minlength=n)
        new = np.where(den > 0, num / np.where(den > 0, den, 1.0), off)
        step = _offsets_to_polygon(axis, new)
        if not _polygon_ok(step):
            break
        best, done = step, bool(np.max(np.abs(new - off)) < 1e-4 * camera_height)
        off = new
        if done:
            break
    return best


def _robust_rectangle(obs: ColumnObservations, fit: _Residuals, ceiling_z: float, camera_height: float,
                      width: int) -> FloatArray | None:
    """Axis-aligned rectangle fitted to the column distances; start: medians of the four viewing quadrants."""
    m = obs.observed
    lon, pts = obs.lon[m], obs.points[m]
    init = []
    for centre, k, sign in ((0.0, 0, 1), (np.pi / 2, 1, -1), (np.pi, 0, -1), (-np.pi / 2, 1, 1)):
        sel = angle_difference(lon, centre) < np.pi / 4
        v = pts[sel, k]
        v = v[v * sign > 0]
        if v.size == 0:
            return None
        init.append(float(np.median(v)))
    # CCW: bottom (y = ymin), right (x = xmax), top (y = ymax), left (x = xmin); vertex i starts wall i
    xmax, ymin, xmin, ymax = init
    rect = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
    if not _polygon_ok(rect):
        return None
    return _refine_offsets(rect, np.array([1, 0, 1, 0], dtype=np.intp), fit, ceiling_z, camera_height, width)


def _robust_selection(plan: FloorPlan, walls: list[WallObservation], close: Callable[[list[WallObservation]], FloorPlan],
                      obs: ColumnObservations, ceiling_z: float, camera_height: float, width: int,
                      pixel_error: float, corner_columns: float) -> tuple[FloorPlan, str]:
    """Choose the polygon that explains the column distances best, a price per corner (noisy labels).

    Candidates: the label-agreement polygon, the walls pruned again under
    the robust distance cost (drops notches that only a few columns
    support), and an axis-aligned rectangle; each has its wall lines
    refitted to the columns (:func:`_refine_offsets`). The cost is
    :func:`_robust_cost` plus ``corner_columns * cap^2`` per corner: a pair
    of corners must explain about ``2 * corner_columns`` columns that would
    otherwise be outliers. Returns the plan and, when the rectangle wins
    over a polygon with more corners, a reason to report.
    """
    fit = _column_fit(obs, pixel_error)
    if fit.columns.size < 4:
        return plan, ""
    kappa = corner_columns * fit.cap ** 2

    def cost(poly: FloatArray) -> float:
        return _robust_cost(fit, poly, ceiling_z, camera_height, width) + kappa * len(poly)

    cands: list[tuple[FloatArray, NDArray[np.intp], NDArray[np.intp], bool, str]] = []
    total = sum(wo.support for wo in walls)
    pruned, _ = prune_walls(walls, close, lambda p: -cost(p.polygon), max_support=total + 1)
    for p in (plan, pruned):
        if p.polygon.shape[0] >= 4 and len(p.wall_axis) == len(p.polygon) and np.all(
                p.wall_axis != np.roll(p.wall_axis, -1)):
            poly = _refine_offsets(p.polygon, p.wall_axis, fit, ceiling_z, camera_height, width)
            cands.append((poly, p.wall_axis, p.wall_support, p.uncertain, ""))
        else:
            cands.append((p.polygon, p.wall_axis, p.wall_support, p.uncertain, ""))
    rect = _robust_rectangle(obs, fit, ceiling_z, camera_height, width)
    if rect is not None:
        b = room_boundaries(rect, ceiling_z, [0.0, 0.0], camera_height, width)
        support = np.bincount(b.wall_index[fit.columns].clip(0), minlength=4)[:4].astype(np.intp)
        cands.append((rect, np.array([1, 0, 1, 0], dtype=np.intp), support, False,
                      "a rectangle fitted to the wall distances explains the labels better than the closed polygon"))
    costs = [cost(c[0]) for c in cands]
    best = int(np.argmin(costs))
    poly, axis, support, unc, why = cands[best]
    if best == 0 and poly is plan.polygon:
        return plan, ""
    if why and len(plan.polygon) == 4:
        why = ""
    new = FloorPlan(polygon=poly, wall_axis=axis, wall_support=support, uncertain=unc or plan.uncertain,
                    reasons=plan.reasons, n_observed=plan.n_observed)
    return new, why


def estimate_room_geometry(labels: ArrayLike, camera_height: float = DEFAULT_CAMERA_HEIGHT, *,
                           object_mask: ArrayLike | None = None, method: Method = "columns",
                           min_wall: float = 0.15, merge_tol: float = 0.07,
                           corner_cost: float = 0.125, robust: bool = True, pixel_error: float = 2.0,
                           corner_columns: float | None = None, prefer: Prefer = "ceiling",
                           shape_axis: bool = True, ceiling_estimate: CeilingEstimate = "lowest_mode",
                           robust_below: float = RELIABLE_INLIER_FRACTION, split_steps: bool = True) -> RoomGeometry:
    """Manhattan floor polygon and wall height of the room seen in a surface-label panorama.

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels 0..5 (shared/CONVENTIONS.md), upright, W == 2*H.
    camera_height : float
        Camera centre above the floor; the result is in its units (default
        1.6 m).
    object_mask : (H, W) bool, optional
        Object regions to ignore (e.g. detection boxes).
    method : {"columns", "pointcloud"}
        See the module docstring.
    min_wall, merge_tol : float
        In camera heights: walls shorter than ``min_wall`` are merged away;
        neighbouring parallel walls closer than ``merge_tol`` are one wall.
    corner_cost : float
        Model-selection price of a corner, in pixel columns (multiples of H
        pixels): a weakly supported wall is kept only if the polygon with it
        reproduces ``2 * corner_cost * H`` more label pixels than without.
    robust : bool
        When the polygon chosen by label agreement explains fewer than
        ``robust_below`` of the observed wall columns (unreliable labels), choose instead
        among it, its walls pruned under a robust cost of the column
        distances, and a fitted rectangle, each with its wall lines refitted
        robustly (:func:`_robust_selection`); else (``False``) fall back to
        the bounding rectangle of the wall points as before.
    pixel_error : float
        Boundary error, in pixel rows, that the robust cost takes as one
        unit of residual (residuals are capped at 3 units).
    corner_columns : float, optional
        Price of a corner in the robust cost, in columns of capped residual
        (default W / 64: a notch, two corners, must explain some 11 degrees
        of columns).
    prefer, shape_axis, ceiling_estimate
        See :func:`observe_columns`. ``prefer="floor", shape_axis=False,
        ceiling_estimate="median", robust=False`` reproduce the estimator
        before furniture-robustness was added.
    robust_below : float
        See ``robust`` (default :data:`RELIABLE_INLIER_FRACTION`).
    split_steps : bool
        Cut runs of columns where their wall offset steps between two flat
        parts (see :func:`column_wall_runs`; ``False``: the estimator
        before session 8).

    Returns
    -------
    RoomGeometry
        Never self-intersecting; ``uncertain`` with ``reasons`` when the
        labels leave part of the room to guesswork (floor mostly hidden, one
        wall orientation only, a polygon that explains few columns - e.g. a
        non-Manhattan room).

    Raises
    ------
    RoomGeometryError
        When the labels show no wall meeting the floor at all.
    ValueError
        For a label map that is not (H, W) with W == 2*H and labels 0..5.

    Convention: see the module docstring (world frame, CCW polygon).

    Examples
    --------
    >>> from layout.labelmap import render_room_labels
    >>> true = [[-1.0, -1.5], [3.0, -1.5], [3.0, 0.5], [1.0, 0.5], [1.0, 2.0], [-1.0, 2.0]]
    >>> lab = render_room_labels(true, 2.8, [0, 0], 1.6, 1024)
    >>> geo = estimate_room_geometry(lab, 1.6)
    >>> geo.n_corners, round(geo.ceiling_z, 2), geo.uncertain
    (6, 2.8, False)
    >>> bool(np.abs(np.sort(geo.floor, axis=0) - np.sort(np.array(true), axis=0)).max() < 0.03)
    True
    """
    t0 = time.perf_counter()
    h_cam = float(camera_height)
    if not (np.isfinite(h_cam) and h_cam > 0):
        raise ValueError(f"camera_height: expected a positive finite height, got {camera_height!r}")
    if method not in ("columns", "pointcloud"):
        raise ValueError(f"method: expected 'columns' or 'pointcloud', got {method!r}")
    lab = check_label_map(labels)
    obs = observe_columns(lab, h_cam, object_mask=object_mask, prefer=prefer, shape_axis=shape_axis,
                          ceiling_estimate=ceiling_estimate)
    reasons: list[str] = []
    alignment = None
    if method == "columns":
        walls = column_wall_runs(obs, h_cam, split_steps=split_steps)
        ceiling_z, ceiling_support = obs.ceiling_z, obs.ceiling_support
        points = obs.points[obs.observed]
    else:
        from .planefit import pointcloud_walls

        try:
            pc = pointcloud_walls(lab, h_cam, object_mask=object_mask)
        except ValueError as exc:
            raise RoomGeometryError(f"point-cloud route failed: {exc}") from exc
        walls, alignment = list(pc.walls), pc.alignment
        ceiling_z, ceiling_support = pc.ceiling_z, pc.ceiling_support
        if not np.isfinite(ceiling_z):
            ceiling_z, ceiling_support = obs.ceiling_z, obs.ceiling_support
        points = pc.points_xy
        reasons.extend(pc.reasons)
    w = lab.shape[1]
    counts = LabelCounts.from_labels(lab, object_mask)

    if len(points) < 2:
        raise RoomGeometryError("no wall is seen in enough columns to place it")
    max_range = 1.5 * float(np.max(np.hypot(points[:, 0], points[:, 1]))) + h_cam

    def close(ws: list[WallObservation]) -> FloorPlan:
        return close_manhattan_polygon(ws, points=points, merge_tol=merge_tol * h_cam, min_wall=min_wall * h_cam,
                                       max_range=max_range)

    corner_penalty = corner_cost * lab.shape[0]

    def score(p: FloorPlan) -> float:
        b = room_boundaries(p.polygon, ceiling_z, [0.0, 0.0], h_cam, w)
        if not bool(b.valid):
            return -np.inf
        return float(counts.agreement(b)) - corner_penalty * len(p.polygon)

    total = sum(wo.support for wo in walls)
    walls_in = list(walls)
    plan, walls = prune_walls(walls, close, score, max_support=max(8, total // 8))
    reasons.extend(plan.reasons)
    floor_frac = float(np.mean(obs.boundaries.floor_contact))
    if floor_frac < 0.3:
        reasons.append(f"the floor meets the walls visibly in only {100 * floor_frac:.0f}% of the columns")
    if ceiling_support < max(3, w // 100):
        reasons.append(f"wall height from only {ceiling_support} column(s)")
    inl = _inlier_fraction(plan.polygon, ceiling_z, h_cam, obs)
    if robust and inl < robust_below:
        # the labels are unreliable (furniture, wrong orientations): let the wall distances choose the polygon
        plan, robust_choice = _robust_selection(plan, walls_in, close, obs, ceiling_z, h_cam, w, pixel_error,
                                                w / 64 if corner_columns is None else float(corner_columns))
        if robust_choice:
            reasons.append(robust_choice)
        inl = _inlier_fraction(plan.polygon, ceiling_z, h_cam, obs)
    if inl < RELIABLE_INLIER_FRACTION and plan.polygon.shape != (4, 2) and not robust:
        # a non-Manhattan room or bad labels: the rectangle around the observed walls may explain them better
        rect = close_manhattan_polygon([], points=points)
        if score(rect) > score(plan):
            plan = rect
            reasons.append("the bounding rectangle of the observed walls explains the labels better than the closed "
                           "polygon")
            inl = _inlier_fraction(plan.polygon, ceiling_z, h_cam, obs)
    if inl < RELIABLE_INLIER_FRACTION:
        reasons.append(f"the polygon explains only {100 * inl:.0f}% of the observed wall columns "
                       "(non-Manhattan room or bad labels?)")
    return RoomGeometry(floor=plan.polygon, ceiling_z=float(ceiling_z), camera_height=h_cam,
                        wall_axis=plan.wall_axis, wall_support=plan.wall_support, inlier_fraction=inl,
                        ceiling_support=int(ceiling_support), uncertain=bool(reasons), reasons=tuple(reasons),
                        method=method, timing_s=time.perf_counter() - t0, alignment=alignment)
