"""Layout metrics: 2D and 3D IoU, corner error, pixel error, wall-height error.

These are the room-layout scores of the literature (LayoutNet, HorizonNet,
the paper's Table of wall-height errors), computed exactly where possible:

* :func:`intersection_area` is exact for any two simple polygons (not only
  Manhattan ones): the plane is cut into horizontal slabs at every vertex
  and every edge-edge crossing; inside a slab both cross-sections are fixed
  sets of intervals whose ends move linearly, so the intersection length is
  linear in y and the midpoint rule integrates it exactly.
* :func:`iou_3d` extrudes both floors between their floor and ceiling
  heights (the usual room 3D IoU).
* :func:`corner_error` matches floor corners (Hungarian assignment) in
  metres; :func:`corner_error_px` is LayoutNet's corner error on
  ``corners_px``, as a percentage of the image diagonal.
* :func:`pixel_error` compares the analytic label maps of the two rooms
  (:func:`layout.labelmap.render_room_labels`), as LayoutNet's pixel error.

Convention:
    Floor polygons (N, 2) in metres seen from above, either orientation,
    no repeated closing vertex; heights in metres above z = 0; panorama
    pixels as in :mod:`panogeom.coords`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .labelmap import CEILING, FLOOR, render_room_labels
from .polygon import as_polygon, signed_area

__all__ = [
    "polygon_area",
    "intersection_area",
    "iou_2d",
    "iou_3d",
    "CornerError",
    "corner_error",
    "corner_error_px",
    "pixel_error",
    "wall_height_error",
    "LayoutScores",
    "score_layout",
]

FloatArray = NDArray[np.float64]


def _single(p: ArrayLike, name: str) -> FloatArray:
    a = as_polygon(p, name=name)
    if a.ndim != 2:
        raise ValueError(f"{name}: expected a single polygon (N, 2), got {a.shape}")
    return a


def polygon_area(polygon: ArrayLike) -> float:
    """Unsigned area of a simple polygon (shoelace).

    >>> polygon_area([[0, 0], [0, 2], [3, 2], [3, 0]])
    6.0
    """
    return float(abs(signed_area(_single(polygon, "polygon"))))


def _cross_section(poly: FloatArray, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Intervals (lo, hi) of the polygon on horizontal lines y = ys, padded with NaN: (S, K), (S, K)."""
    a, b = poly, np.roll(poly, -1, axis=0)
    ya, yb = a[:, 1], b[:, 1]
    y = ys[:, None]
    straddle = (ya[None, :] > y) != (yb[None, :] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = a[None, :, 0] + (y - ya[None, :]) * (b[None, :, 0] - a[None, :, 0]) / (yb - ya)[None, :]
    x = np.where(straddle, x, np.nan)
    x = np.sort(x, axis=1)  # NaN last
    if x.shape[1] % 2:
        x = np.concatenate([x, np.full((len(x), 1), np.nan)], axis=1)
    return x[:, 0::2], x[:, 1::2]


def _edge_crossing_ys(p: FloatArray, q: FloatArray) -> FloatArray:
    """y of every proper crossing between an edge of p and an edge of q."""
    a0, a1 = p, np.roll(p, -1, axis=0)
    b0, b1 = q, np.roll(q, -1, axis=0)
    d1 = (a1 - a0)[:, None, :]
    d2 = (b1 - b0)[None, :, :]
    r = b0[None, :, :] - a0[:, None, :]
    den = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (r[..., 0] * d2[..., 1] - r[..., 1] * d2[..., 0]) / den
        s = (r[..., 0] * d1[..., 1] - r[..., 1] * d1[..., 0]) / den
    ok = (np.abs(den) > 1e-15) & (t > 0) & (t < 1) & (s > 0) & (s < 1)
    y = a0[:, None, 1] + np.where(ok, t, 0.0) * d1[..., 1]
    return y[ok]


def intersection_area(a: ArrayLike, b: ArrayLike) -> float:
    """Exact area of the intersection of two simple polygons (any shape, either orientation).

    Parameters
    ----------
    a, b : (N, 2), (M, 2) float

    Returns
    -------
    float, square units of the input.

    Convention: even-odd rule; see the module docstring for the method.

    Examples
    --------
    >>> L = [[0, 0], [4, 0], [4, 1], [1, 1], [1, 4], [0, 4]]
    >>> intersection_area(L, [[0.5, 0.5], [3, 0.5], [3, 3], [0.5, 3]])  # 2.5 x 0.5 + 0.5 x 2
    2.25
    >>> round(intersection_area([[0, 0], [2, 0], [0, 2]], [[0, 0], [2, 0], [2, 2], [0, 2]]), 12)
    2.0
    """
    p, q = _single(a, "a"), _single(b, "b")
    ys = np.unique(np.concatenate([p[:, 1], q[:, 1], _edge_crossing_ys(p, q)]))
    lo_y = max(p[:, 1].min(), q[:, 1].min())
    hi_y = min(p[:, 1].max(), q[:, 1].max())
    ys = ys[(ys >= lo_y) & (ys <= hi_y)]
    if ys.size < 2:
        return 0.0
    y0, y1 = ys[:-1], ys[1:]
    keep = y1 - y0 > 0
    y0, y1 = y0[keep], y1[keep]
    mid = 0.5 * (y0 + y1)
    pl, ph = _cross_section(p, mid)
    ql, qh = _cross_section(q, mid)
    ov = np.minimum(ph[:, :, None], qh[:, None, :]) - np.maximum(pl[:, :, None], ql[:, None, :])
    length = np.nansum(np.clip(ov, 0.0, None), axis=(1, 2))
    return float(np.sum((y1 - y0) * length))


def iou_2d(a: ArrayLike, b: ArrayLike) -> float:
    """Intersection over union of two floor polygons (exact).

    >>> iou_2d([[0, 0], [2, 0], [2, 2], [0, 2]], [[1, 0], [3, 0], [3, 2], [1, 2]])
    0.3333333333333333
    """
    area_a, area_b = polygon_area(a), polygon_area(b)
    inter = min(intersection_area(a, b), area_a, area_b)  # round-off must not push the IoU past 1
    union = area_a + area_b - inter
    return float(inter / union) if union > 0 else 0.0


def iou_3d(a: ArrayLike, a_ceiling_z: float, b: ArrayLike, b_ceiling_z: float, *, a_floor_z: float = 0.0,
           b_floor_z: float = 0.0) -> float:
    """Intersection over union of two rooms extruded from their floor to their ceiling height.

    Examples
    --------
    >>> sq = [[0, 0], [2, 0], [2, 2], [0, 2]]
    >>> round(iou_3d(sq, 3.0, sq, 2.4), 12)
    0.8
    """
    ha = float(a_ceiling_z) - float(a_floor_z)
    hb = float(b_ceiling_z) - float(b_floor_z)
    if not (np.isfinite(ha) and np.isfinite(hb) and ha > 0 and hb > 0):
        raise ValueError(f"expected ceilings above floors, got heights {ha} and {hb}")
    dz = min(float(a_ceiling_z), float(b_ceiling_z)) - max(float(a_floor_z), float(b_floor_z))
    area_a, area_b = polygon_area(a), polygon_area(b)
    inter = min(intersection_area(a, b), area_a, area_b) * max(dz, 0.0)
    union = area_a * ha + area_b * hb - inter
    return float(inter / union) if union > 0 else 0.0


@dataclass(frozen=True)
class CornerError:
    """Floor-corner error after a one-to-one matching (result of :func:`corner_error`).

    Attributes
    ----------
    mean, max : float
        Distance between matched corners (units of the polygons; NaN
        without a match).
    n_pred, n_gt, n_matched : int
        Unmatched corners mean different corner counts.
    """

    mean: float
    max: float
    n_pred: int
    n_gt: int
    n_matched: int

    @property
    def same_count(self) -> bool:
        return self.n_pred == self.n_gt


def corner_error(pred: ArrayLike, gt: ArrayLike) -> CornerError:
    """Distances between floor corners matched one-to-one (Hungarian assignment on distance).

    Examples
    --------
    >>> e = corner_error([[0, 0], [2, 0], [2, 2], [0, 2.2]], [[0, 0], [2, 0], [2, 2], [0, 2]])
    >>> round(e.mean, 3), round(e.max, 3), e.same_count
    (0.05, 0.2, True)
    """
    from scipy.optimize import linear_sum_assignment

    p, g = _single(pred, "pred"), _single(gt, "gt")
    d = np.linalg.norm(p[:, None, :] - g[None, :, :], axis=-1)
    r, c = linear_sum_assignment(d)
    m = d[r, c]
    return CornerError(mean=float(m.mean()) if m.size else float("nan"), max=float(m.max()) if m.size else float("nan"),
                       n_pred=len(p), n_gt=len(g), n_matched=int(m.size))


def corner_error_px(pred_corners_px: ArrayLike, gt_corners_px: ArrayLike, width: int, height: int | None = None) -> float:
    """LayoutNet's corner error: mean pixel distance of matched corners, in % of the image diagonal.

    Ceiling and floor corners are matched one-to-one (Hungarian, u distance
    across the seam); with different corner counts only the matched ones
    count.

    Parameters
    ----------
    pred_corners_px, gt_corners_px : (N, 4), (M, 4) float
        ``[u_ceiling, v_ceiling, u_floor, v_floor]`` rows (:mod:`layout.corners`).
    width, height : int
        Panorama size (height defaults to width / 2).

    Examples
    --------
    >>> round(corner_error_px([[10, 100, 10, 400]], [[1020, 100, 1020, 400]], 1024), 4)  # 14 px across the seam
    1.2228
    """
    from scipy.optimize import linear_sum_assignment

    w = float(width)
    h = w / 2 if height is None else float(height)
    pc = np.asarray(pred_corners_px, dtype=np.float64)
    gc = np.asarray(gt_corners_px, dtype=np.float64)
    for name, a in (("pred_corners_px", pc), ("gt_corners_px", gc)):
        if a.ndim != 2 or a.shape[1] != 4 or not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: expected finite (N, 4), got {a.shape}")
    p = np.concatenate([pc[:, :2], pc[:, 2:]])
    g = np.concatenate([gc[:, :2], gc[:, 2:]])
    du = np.abs(p[:, None, 0] - g[None, :, 0])
    du = np.minimum(du, w - du)
    dv = p[:, None, 1] - g[None, :, 1]
    d = np.hypot(du, dv)
    r, c = linear_sum_assignment(d)
    return float(100.0 * d[r, c].mean() / np.hypot(w, h))


def pixel_error(pred_floor: ArrayLike, pred_ceiling_z: float, gt_floor: ArrayLike, gt_ceiling_z: float,
                camera_height: float = 1.6, width: int = 1024, *, camera_xy: ArrayLike = (0.0, 0.0),
                classes: Literal["surfaces", "labels"] = "surfaces") -> float:
    """Fraction of panorama pixels whose surface differs between two rooms seen from one camera.

    Both rooms are rendered analytically (:func:`layout.labelmap.render_room_labels`).

    Parameters
    ----------
    pred_floor, gt_floor : (N, 2), (M, 2) float
    pred_ceiling_z, gt_ceiling_z : float
    camera_height : float
    width : int
        Panorama width of the comparison.
    camera_xy : (2,) float
        Camera position, inside both rooms.
    classes : {"surfaces", "labels"}
        ``"surfaces"``: floor / ceiling / wall (LayoutNet's pixel error);
        ``"labels"``: also the wall orientation (3 vs 4).

    Examples
    --------
    >>> sq = [[-2, -2], [2, -2], [2, 2], [-2, 2]]
    >>> pixel_error(sq, 2.7, sq, 2.7), round(pixel_error(sq, 2.7, [[-2, -2], [2.5, -2], [2.5, 2], [-2, 2]], 2.7), 3)
    (0.0, 0.014)
    """
    if classes not in ("surfaces", "labels"):
        raise ValueError(f"classes: expected 'surfaces' or 'labels', got {classes!r}")
    a = render_room_labels(pred_floor, pred_ceiling_z, camera_xy, camera_height, width)
    b = render_room_labels(gt_floor, gt_ceiling_z, camera_xy, camera_height, width)
    if classes == "surfaces":
        a = np.where((a == FLOOR) | (a == CEILING), a, 3)
        b = np.where((b == FLOOR) | (b == CEILING), b, 3)
    return float(np.mean(a != b))


def wall_height_error(pred_ceiling_z: float, gt_ceiling_z: float, *, pred_floor_z: float = 0.0,
                      gt_floor_z: float = 0.0) -> float:
    """Absolute difference of wall heights (ceiling minus floor), units of the input.

    >>> round(wall_height_error(2.75, 2.6), 2)
    0.15
    """
    return float(abs((float(pred_ceiling_z) - float(pred_floor_z)) - (float(gt_ceiling_z) - float(gt_floor_z))))


@dataclass(frozen=True)
class LayoutScores:
    """All layout scores of one room (result of :func:`score_layout`).

    Attributes
    ----------
    iou_2d, iou_3d : float
    corner_error : CornerError
        Floor corners, metres.
    corner_error_px : float
        % of the image diagonal.
    pixel_error : float
        Fraction of pixels (floor / ceiling / wall).
    height_error : float
        Metres.
    """

    iou_2d: float
    iou_3d: float
    corner_error: CornerError
    corner_error_px: float
    pixel_error: float
    height_error: float

    @property
    def corners_ok(self) -> bool:
        """Same number of corners as the ground truth."""
        return self.corner_error.same_count


def score_layout(pred_floor: ArrayLike, pred_ceiling_z: float, gt_floor: ArrayLike, gt_ceiling_z: float,
                 camera_height: float = 1.6, width: int = 1024) -> LayoutScores:
    """Every layout score of a predicted room against the ground truth (camera at the origin).

    Examples
    --------
    >>> sq = [[-2, -2], [2, -2], [2, 2], [-2, 2]]
    >>> s = score_layout(sq, 2.7, sq, 2.7, 1.6, 256)
    >>> s.iou_3d, s.corners_ok, s.pixel_error
    (1.0, True, 0.0)
    """
    from .corners import polygon_to_corners_px

    pc = polygon_to_corners_px(pred_floor, pred_ceiling_z, camera_height, width)
    gc = polygon_to_corners_px(gt_floor, gt_ceiling_z, camera_height, width)
    return LayoutScores(iou_2d=iou_2d(pred_floor, gt_floor),
                        iou_3d=iou_3d(pred_floor, pred_ceiling_z, gt_floor, gt_ceiling_z),
                        corner_error=corner_error(pred_floor, gt_floor),
                        corner_error_px=corner_error_px(pc, gc, width),
                        pixel_error=pixel_error(pred_floor, pred_ceiling_z, gt_floor, gt_ceiling_z, camera_height, width),
                        height_error=wall_height_error(pred_ceiling_z, gt_ceiling_z))
