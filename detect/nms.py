"""Overlap and non-maximum suppression on the sphere (and in a plane, for single images).

The panorama driver sees one object from several overlapping tiles. Their
boxes must be compared where they live, on the sphere: a box near a pole
covers far fewer steradians than its pixel extent suggests, and a box across
the seam is split in two in pixel coordinates. Here every
:class:`~detect.detection.Detection` has a *region* on the unit sphere:

- with a ``tile``: the footprint of its tile box, the spherical quadrilateral
  bounded by the four great circles through the box edges;
- without: the lon/lat rectangle of its ``box`` (seam-aware).

Areas are exact solid angles (closed forms). So are intersections of two
lon/lat rectangles and of two boxes of the same tile. Other intersections
(boxes of different tiles) are integrated numerically with
``samples x samples`` points per region, spread evenly in solid angle (pixel
grid weighted by the pinhole Jacobian ``f / r^3``), and symmetrised.
Membership of a sample in a region is exact (projection into the tile, or a
lon/lat test), so the only error is the quadrature of the boundary, about
``1 / (2 * samples)`` of the overlap's width.

Convention: panorama pixels and boxes as in CONVENTIONS.md (``u0 > u1`` wraps
the seam); rays and lon/lat come from :mod:`panogeom.coords`.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse.csgraph import connected_components

from panogeom.coords import lonlat_to_ray, pixel_to_lonlat, ray_to_lonlat
from panogeom.perspective import arc_points

from .detection import Detection

__all__ = [
    "box_iou",
    "box_nms",
    "pano_box_solid_angle",
    "pano_box_iou",
    "solid_angle",
    "region_samples",
    "region_contains",
    "region_boundary",
    "spherical_overlaps",
    "spherical_iou",
    "merge_sphere",
    "nms_sphere",
    "suppress_across_classes",
]

Array = NDArray[np.float64]
_TWO_PI = 2.0 * np.pi


# --------------------------------------------------------------------------- planar (one image)

def _boxes(b: ArrayLike, name: str) -> Array:
    a = np.asarray(b, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 4:
        raise ValueError(f"{name}: expected shape (N, 4), got {a.shape}")
    return a


def box_iou(a: ArrayLike, b: ArrayLike) -> Array:
    """Intersection over union of axis-aligned boxes in one image.

    Parameters
    ----------
    a : (N, 4) float
    b : (M, 4) float
        ``(u0, v0, u1, v1)`` with ``u0 <= u1``, ``v0 <= v1``.

    Returns
    -------
    iou : (N, M) float

    Examples
    --------
    >>> box_iou([[0, 0, 2, 2]], [[1, 0, 3, 2]])
    array([[0.33333333]])
    """
    a, b = _boxes(a, "a"), _boxes(b, "b")
    iw = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    ih = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    inter = iw * ih
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def box_nms(boxes: ArrayLike, scores: ArrayLike, iou_threshold: float = 0.5,
            labels: Sequence[object] | None = None) -> NDArray[np.intp]:
    """Greedy non-maximum suppression of boxes in one image.

    Parameters
    ----------
    boxes : (N, 4) float
    scores : (N,) float
    iou_threshold : float
        A box is suppressed by a higher-scoring one whose IoU with it exceeds this.
    labels : sequence of N, optional
        Class of each box; suppression only acts within a class.

    Returns
    -------
    keep : (K,) int
        Indices of the kept boxes, by decreasing score.

    Examples
    --------
    >>> box_nms([[0, 0, 10, 10], [1, 1, 10, 10], [20, 20, 30, 30]], [0.9, 0.8, 0.7]).tolist()
    [0, 2]
    """
    b = _boxes(boxes, "boxes")
    s = np.asarray(scores, dtype=np.float64)
    if s.shape != (len(b),):
        raise ValueError(f"scores: expected shape ({len(b)},), got {s.shape}")
    if len(b) == 0:
        return np.zeros(0, dtype=np.intp)
    lab = np.zeros(len(b), dtype=np.intp)
    if labels is not None:
        if len(labels) != len(b):
            raise ValueError(f"labels: expected {len(b)} labels, got {len(labels)}")
        _, lab = np.unique(np.asarray(labels, dtype=object).astype(str), return_inverse=True)
    iou = box_iou(b, b)
    iou[lab[:, None] != lab[None, :]] = 0.0
    order = np.argsort(-s, kind="stable")
    alive = np.ones(len(b), dtype=bool)
    keep = []
    for i in order:
        if not alive[i]:
            continue
        keep.append(i)
        alive &= ~(iou[i] > iou_threshold)
    return np.asarray(keep, dtype=np.intp)


# --------------------------------------------------------------------------- lon/lat rectangles

def _rect_lonlat(boxes: Array, width: int, height: int) -> tuple[Array, Array, Array, Array]:
    """lon0, dlon, lat_bottom, lat_top of panorama boxes (seam-aware)."""
    u0, v0, u1, v1 = boxes.T
    span = np.where(u1 > u0, u1 - u0, u1 + width - u0)
    lon0 = pixel_to_lonlat(np.stack([u0, v0], -1), width, height)[:, 0]
    lat_top = pixel_to_lonlat(np.stack([u0, v0], -1), width, height)[:, 1]
    lat_bot = pixel_to_lonlat(np.stack([u0, v1], -1), width, height)[:, 1]
    return lon0, span * _TWO_PI / width, lat_bot, lat_top


def _check_pano_boxes(b: ArrayLike, name: str, width: int, height: int) -> Array:
    a = _boxes(b, name)
    if a.size and not (np.all(np.isfinite(a)) and np.all(a[:, 1] < a[:, 3]) and np.all(a[:, 0] != a[:, 2])):
        raise ValueError(f"{name}: expected panorama boxes (u0, v0, u1, v1) with v0 < v1 and u0 != u1")
    if int(width) != 2 * int(height):
        raise ValueError(f"panorama size: expected W == 2*H, got W={width}, H={height}")
    return a


def pano_box_solid_angle(boxes: ArrayLike, width: int, height: int) -> Array:
    """Exact solid angle of panorama boxes taken as lon/lat rectangles.

    Parameters
    ----------
    boxes : (N, 4) float
        ``(u0, v0, u1, v1)``, ``u0 > u1`` wraps the seam.
    width, height : int
        Panorama size (W == 2*H).

    Returns
    -------
    omega : (N,) float
        Steradians, ``dlon * (sin(lat_top) - sin(lat_bottom))``.

    Examples
    --------
    >>> float(pano_box_solid_angle([[0, 0, 2048, 1024]], 2048, 1024)[0] / np.pi)
    4.0
    """
    b = _check_pano_boxes(boxes, "boxes", width, height)
    _, dlon, lat_b, lat_t = _rect_lonlat(b, width, height)
    return dlon * (np.sin(lat_t) - np.sin(lat_b))


def pano_box_iou(a: ArrayLike, b: ArrayLike, width: int, height: int) -> Array:
    """Exact IoU on the sphere of panorama boxes taken as lon/lat rectangles (seam-aware).

    Parameters
    ----------
    a : (N, 4) float
    b : (M, 4) float
        ``(u0, v0, u1, v1)`` panorama boxes, ``u0 > u1`` wraps the seam.
    width, height : int

    Returns
    -------
    iou : (N, M) float
        Ratio of solid angles: the same pixel boxes overlap less near the
        poles than at the horizon only when their shapes differ there; two
        boxes that meet across the seam overlap as on the sphere.

    Examples
    --------
    >>> pano_box_iou([[2000, 400, 48, 500]], [[2032, 400, 80, 500]], 2048, 1024).round(3)
    array([[0.5]])
    """
    A = _check_pano_boxes(a, "a", width, height)
    B = _check_pano_boxes(b, "b", width, height)
    inter, area_a, area_b = _pano_box_inter(A, B, width, height)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def _pano_box_inter(A: Array, B: Array, width: int, height: int) -> tuple[Array, Array, Array]:
    """Exact solid angles: intersections (N, M) and areas (N,), (M,) of lon/lat rectangles."""
    la0, ldl, lab, lat = _rect_lonlat(A, width, height)
    lb0, mdl, mbb, mbt = _rect_lonlat(B, width, height)
    a0 = np.mod(la0, _TWO_PI)[:, None]
    b0 = np.mod(lb0, _TWO_PI)[None, :]
    a1 = a0 + ldl[:, None]
    inter_lon = np.zeros((len(A), len(B)))
    for shift in (-_TWO_PI, 0.0, _TWO_PI):
        lo = np.maximum(a0, b0 + shift)
        hi = np.minimum(a1, b0 + shift + mdl[None, :])
        inter_lon += np.clip(hi - lo, 0.0, None)
    inter_lon = np.minimum(inter_lon, np.minimum(ldl[:, None], mdl[None, :]))
    top = np.minimum(lat[:, None], mbt[None, :])
    bot = np.maximum(lab[:, None], mbb[None, :])
    inter = inter_lon * np.clip(np.sin(top) - np.sin(bot), 0.0, None)
    return inter, ldl * (np.sin(lat) - np.sin(lab)), mdl * (np.sin(mbt) - np.sin(mbb))


# --------------------------------------------------------------------------- regions of detections

def _tile_norm_box(det: Detection) -> tuple[float, float, float, float]:
    t = det.tile
    assert t is not None
    f = t.view.focal
    cx, cy = 0.5 * t.view.width, 0.5 * t.view.height
    return ((t.box[0] - cx) / f, (t.box[1] - cy) / f, (t.box[2] - cx) / f, (t.box[3] - cy) / f)


def _rect_solid_angle_plane(x0: ArrayLike, y0: ArrayLike, x1: ArrayLike, y1: ArrayLike) -> Array:
    """Solid angle of rectangles [x0, x1] x [y0, y1] on the plane z = 1 seen from the origin (any shapes)."""
    def F(x: ArrayLike, y: ArrayLike) -> Array:
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        return np.arctan(x * y / np.sqrt(1.0 + x * x + y * y))
    return F(x1, y1) - F(x0, y1) - F(x1, y0) + F(x0, y0)


def solid_angle(det: Detection) -> float:
    """Exact solid angle (steradians) of a detection's region on the sphere.

    Examples
    --------
    >>> d = Detection("bed", 1.0, [0, 0, 2048, 512], 2048, 1024)
    >>> round(solid_angle(d) / np.pi, 6)
    2.0
    """
    if det.tile is not None:
        return float(_rect_solid_angle_plane(*_tile_norm_box(det)))
    return float(pano_box_solid_angle(det.box[None], det.pano_width, det.pano_height)[0])


def region_samples(det: Detection, samples: int = 16) -> tuple[Array, Array]:
    """Points spread over a detection's region on the sphere, with solid-angle weights.

    Parameters
    ----------
    det : Detection
    samples : int
        Grid size per side (``samples**2`` points).

    Returns
    -------
    rays : (samples**2, 3) float
        Unit rays inside the region.
    weights : (samples**2,) float
        Solid angle represented by each ray; they sum to :func:`solid_angle`.
    """
    n = int(samples)
    if n < 1:
        raise ValueError(f"samples: expected a positive integer, got {samples!r}")
    t = (np.arange(n) + 0.5) / n
    if det.tile is not None:
        view, b = det.tile.view, det.tile.box
        uu, vv = np.meshgrid(b[0] + t * (b[2] - b[0]), b[1] + t * (b[3] - b[1]))
        uv = np.stack([uu.ravel(), vv.ravel()], -1)
        rays = view.pixel_to_ray(uv)
        f = view.focal
        r2 = f * f + (uv[:, 0] - 0.5 * view.width) ** 2 + (uv[:, 1] - 0.5 * view.height) ** 2
        w = f / r2 ** 1.5
    else:
        lon0, dlon, lat_b, lat_t = (x[0] for x in _rect_lonlat(det.box[None], det.pano_width, det.pano_height))
        z0, z1 = np.sin(lat_b), np.sin(lat_t)
        lon, z = np.meshgrid(lon0 + t * dlon, z0 + t * (z1 - z0))
        lat = np.arcsin(np.clip(z, -1.0, 1.0))
        rays = lonlat_to_ray(np.stack([lon.ravel(), lat.ravel()], -1))
        w = np.ones(n * n)
    w = w * (solid_angle(det) / w.sum())
    return rays, w


def region_contains(dets: Sequence[Detection], rays: ArrayLike) -> NDArray[np.bool_]:
    """Which rays lie in which detection's region.

    Parameters
    ----------
    dets : sequence of Detection (N)
    rays : (M, 3) float
        Unit rays in the panorama frame.

    Returns
    -------
    inside : (N, M) bool
    """
    r = np.asarray(rays, dtype=np.float64)
    if r.ndim != 2 or r.shape[1] != 3:
        raise ValueError(f"rays: expected shape (M, 3), got {r.shape}")
    out = np.zeros((len(dets), len(r)), dtype=bool)
    if len(r) == 0 or len(dets) == 0:
        return out
    by_view: dict[object, list[int]] = defaultdict(list)
    rect_idx = []
    for i, d in enumerate(dets):
        if d.tile is not None:
            by_view[d.tile.view].append(i)
        else:
            rect_idx.append(i)
    for view, idx in by_view.items():
        uv, front = view.ray_to_pixel(r)  # type: ignore[attr-defined]
        bx = np.stack([dets[i].tile.box for i in idx])  # type: ignore[union-attr]
        inside = ((uv[None, :, 0] >= bx[:, 0:1]) & (uv[None, :, 0] <= bx[:, 2:3])
                  & (uv[None, :, 1] >= bx[:, 1:2]) & (uv[None, :, 1] <= bx[:, 3:4]) & front[None, :])
        out[idx] = inside
    if rect_idx:
        ll = ray_to_lonlat(r)
        by_size: dict[tuple[int, int], list[int]] = defaultdict(list)
        for i in rect_idx:
            by_size[(dets[i].pano_width, dets[i].pano_height)].append(i)
        for (W, H), idx in by_size.items():
            lon0, dlon, lat_b, lat_t = _rect_lonlat(np.stack([dets[i].box for i in idx]), W, H)
            dl = np.mod(ll[None, :, 0] - lon0[:, None], _TWO_PI)
            inside = ((dl <= dlon[:, None] + 1e-12) | (dlon[:, None] >= _TWO_PI - 1e-12))
            inside &= (ll[None, :, 1] >= lat_b[:, None] - 1e-12) & (ll[None, :, 1] <= lat_t[:, None] + 1e-12)
            out[idx] = inside
    return out


def region_boundary(det: Detection, samples: int = 32) -> Array:
    """Unit rays along the boundary of a detection's region on the sphere.

    Parameters
    ----------
    det : Detection
    samples : int
        Points per edge (tile boxes: great-circle arcs; lon/lat rectangles:
        parallels and meridians).

    Returns
    -------
    rays : (4 * samples, 3) float
    """
    n = int(samples)
    if det.tile is not None:
        b = det.tile.box
        c = np.array([[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]])
        a = det.tile.view.pixel_to_ray(c)
        return arc_points(a, np.roll(a, -1, axis=0), n).reshape(-1, 3)
    lon0, dlon, lat_b, lat_t = (x[0] for x in _rect_lonlat(det.box[None], det.pano_width, det.pano_height))
    t = np.linspace(0.0, 1.0, n)
    lon = lon0 + t * dlon
    lat = lat_b + t * (lat_t - lat_b)
    ll = np.concatenate([np.stack([lon, np.full(n, lat_t)], -1), np.stack([lon, np.full(n, lat_b)], -1),
                         np.stack([np.full(n, lon0), lat], -1), np.stack([np.full(n, lon0 + dlon), lat], -1)])
    return lonlat_to_ray(ll)


def _exact_pairs(dets: Sequence[Detection], inter: Array) -> None:
    """Overwrite ``inter`` with exact values where both regions are lon/lat rectangles or boxes of one tile."""
    rects: dict[tuple[int, int], list[int]] = defaultdict(list)
    tiles: dict[object, list[int]] = defaultdict(list)
    for i, d in enumerate(dets):
        if d.tile is None:
            rects[(d.pano_width, d.pano_height)].append(i)
        else:
            tiles[d.tile.view].append(i)
    for (W, H), idx in rects.items():
        B = np.stack([dets[i].box for i in idx])
        inter[np.ix_(idx, idx)] = _pano_box_inter(B, B, W, H)[0]
    for idx in tiles.values():
        nb = np.array([_tile_norm_box(dets[i]) for i in idx])
        x0 = np.maximum(nb[:, None, 0], nb[None, :, 0])
        y0 = np.maximum(nb[:, None, 1], nb[None, :, 1])
        x1 = np.maximum(np.minimum(nb[:, None, 2], nb[None, :, 2]), x0)
        y1 = np.maximum(np.minimum(nb[:, None, 3], nb[None, :, 3]), y0)
        inter[np.ix_(idx, idx)] = _rect_solid_angle_plane(x0, y0, x1, y1)


def spherical_overlaps(dets: Sequence[Detection], samples: int = 16) -> tuple[Array, Array]:
    """Pairwise overlap of detection regions on the sphere.

    Parameters
    ----------
    dets : sequence of Detection (N)
    samples : int
        Quadrature grid size per side of each region.

    Returns
    -------
    iou : (N, N) float
        Intersection over union of solid angles (1 on the diagonal).
    inside : (N, N) float
        ``inside[i, j]``: fraction of region i's solid angle that lies in region j.
    """
    n = len(dets)
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 0))
    rays, weights = zip(*(region_samples(d, samples) for d in dets))
    R = np.stack(rays)                                       # (N, m, 3)
    Wt = np.stack(weights)                                   # (N, m)
    m = Wt.shape[1]
    # Regions lie inside their extents: only pairs whose extents overlap are integrated.
    sizes = {(d.pano_width, d.pano_height) for d in dets}
    if len(sizes) == 1:
        (Wp, Hp), = sizes
        ext = np.stack([d.box for d in dets])
        touch = pano_box_iou(ext, ext, Wp, Hp) > 0
    else:
        touch = np.ones((n, n), dtype=bool)
    by_source: dict[object, list[int]] = defaultdict(list)
    for i, d in enumerate(dets):
        by_source[d.tile.view if d.tile is not None else None].append(i)
    est = np.zeros((n, n))                                   # est[i, j] ~ |i & j| from i's samples
    for J in by_source.values():
        I = np.flatnonzero(touch[J].any(axis=0))
        inside_j = region_contains([dets[j] for j in J], R[I].reshape(-1, 3)).reshape(len(J), len(I), m)
        est[np.ix_(I, J)] = np.einsum("ik,jik->ij", Wt[I], inside_j)
    area = Wt.sum(axis=1)
    inter = 0.5 * (est + est.T)
    _exact_pairs(dets, inter)
    inter = np.minimum(inter, np.minimum(area[:, None], area[None, :]))
    np.fill_diagonal(inter, area)
    union = area[:, None] + area[None, :] - inter
    iou = np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)
    inside = inter / np.where(area > 0, area, 1.0)[:, None]
    return iou, inside


def spherical_iou(a: Sequence[Detection], b: Sequence[Detection] | None = None, samples: int = 16) -> Array:
    """IoU on the sphere between two lists of detections (or within one list).

    Parameters
    ----------
    a : sequence of Detection (N)
    b : sequence of Detection (M), optional
        Defaults to ``a``.
    samples : int

    Returns
    -------
    iou : (N, M) float

    Examples
    --------
    >>> d1 = Detection("chair", 0.9, [2000, 400, 48, 500], 2048, 1024)
    >>> d2 = Detection("chair", 0.8, [2032, 400, 80, 500], 2048, 1024)
    >>> bool(abs(spherical_iou([d1], [d2])[0, 0] - 0.5) < 0.02)
    True
    """
    a = list(a)
    bb = a if b is None else list(b)
    iou, _ = spherical_overlaps(a + ([] if b is None else bb), samples)
    if b is None:
        return iou
    return iou[: len(a), len(a):]


def merge_sphere(detections: Sequence[Detection], iou_threshold: float = 0.5, *, containment: float = 0.5,
                 truncated_weight: float = 0.5, class_aware: bool = True, samples: int = 16,
                 view_score: float = 0.2, max_views: int = 6) -> list[tuple[Detection, tuple[Detection, ...]]]:
    """Group detections of the same object seen in several tiles: greedy NMS on the sphere, with the groups.

    Parameters
    ----------
    detections : sequence of Detection
    iou_threshold : float
        Two regions of one class with a spherical IoU above this are one object.
    containment : float
        A box cut by its tile border (``tile.truncated``) is also merged into
        another when more than this fraction of it lies inside the other (a
        partial view of the object another tile sees whole).
    truncated_weight : float
        Truncated boxes are ranked at ``score * truncated_weight``, so a whole
        view of an object is preferred as the representative.
    class_aware : bool
        Only merge detections of the same class.
    samples : int
        Quadrature grid size (see :func:`spherical_overlaps`).
    view_score, max_views : float, int
        The merged detection's ``views``: the tile boxes of up to
        ``max_views`` members that see the object whole and score at least
        ``view_score``, the representative first, then by decreasing score
        (empty when fewer than two qualify). Measured on 30 rooms of the
        tuning seed 7000 (``benchmarks/eval_box_edges.py``: the builtin
        detector, objects of 2000 visible pixels or more, their true outline
        at the true pose): the median absolute deviation of the box edges
        (left, top, right, bottom) is 0.93 / 0.91 / 1.12 / 0.85 degrees for
        the representative's box and 0.74 / 0.79 / 1.03 / 0.78 for each
        edge's median over these views (docs/EVALUATION.md, "Detector box
        edges").

    Returns
    -------
    groups : list of (Detection, tuple of Detection), by decreasing score
        Per object: the merged detection and the group's members (the input
        detections merged into it, the representative among them). The merged
        detection has the box (and tile) of its representative, the highest
        score of the group and ``support`` = the group's summed support. The
        representative is the member *most in agreement with the group*: of
        the members that their tile sees whole, the one with the largest
        score-weighted sum of spherical IoU with those members (a medoid), so
        that one loose box, e.g. from a wide or oblique tile, is outvoted by
        the tighter boxes of the other tiles. When every member is truncated,
        the best-ranked one.
    """
    for name, val in (("iou_threshold", iou_threshold), ("containment", containment),
                      ("truncated_weight", truncated_weight), ("view_score", view_score)):
        if not 0.0 <= float(val) <= 1.0:
            raise ValueError(f"{name}: expected a number in [0, 1], got {val!r}")
    if int(max_views) != max_views or max_views < 1:
        raise ValueError(f"max_views: expected a positive integer, got {max_views!r}")
    dets = list(detections)
    sizes = {(d.pano_width, d.pano_height) for d in dets}
    if len(sizes) > 1:
        raise ValueError(f"detections: expected boxes of one panorama size, got sizes {sorted(sizes)}")
    by_class: dict[str, list[int]] = defaultdict(list)
    for i, d in enumerate(dets):
        by_class[d.label if class_aware else ""].append(i)
    out: list[tuple[Detection, tuple[Detection, ...]]] = []
    for idx in by_class.values():
        for g in _touching(dets[i] for i in idx):
            out.extend(_greedy(g, iou_threshold, containment, truncated_weight, samples, float(view_score),
                           int(max_views)))
    out.sort(key=lambda m: -m[0].score)
    return out


def nms_sphere(detections: Sequence[Detection], iou_threshold: float = 0.5, *, containment: float = 0.5,
               truncated_weight: float = 0.5, class_aware: bool = True, samples: int = 16) -> list[Detection]:
    """Merge detections of the same object seen in several tiles: greedy NMS on the sphere.

    The merged detections of :func:`merge_sphere` (same parameters), without
    the groups.

    Returns
    -------
    merged : list of Detection, by decreasing score

    Examples
    --------
    >>> a = Detection("chair", 0.9, [2030, 400, 30, 500], 2048, 1024)
    >>> b = Detection("chair", 0.6, [2032, 402, 32, 502], 2048, 1024)
    >>> c = Detection("table", 0.7, [2030, 400, 30, 500], 2048, 1024)
    >>> [(d.label, d.score, d.support) for d in nms_sphere([a, b, c])]
    [('chair', 0.9, 2), ('table', 0.7, 1)]
    """
    return [d for d, _ in merge_sphere(detections, iou_threshold, containment=containment,
                                       truncated_weight=truncated_weight, class_aware=class_aware,
                                       samples=samples)]


def suppress_across_classes(detections: Sequence[Detection], iou_threshold: float = 0.7,
                            samples: int = 16) -> list[Detection]:
    """One class per object: of detections of different classes whose regions overlap on the sphere by more
    than ``iou_threshold``, only the best-scoring is kept (greedy, by decreasing score).

    The merge (:func:`merge_sphere`) is class-aware, so one object that the tiles call a bed and a sofa comes out
    twice with nearly the same region; a scene cannot hold both (the sampler then pushes one of them away from the
    other). On the 90 rooms of the tuning seeds 7000 and 8000 (builtin detector, the detections a scene was built
    from) 13 pairs in 12 rooms overlapped by more than 0.7 (IoU of their panorama extents; chair / sofa, bed /
    sofa, chair / TV, ...; ``benchmarks/count_class_duplicates.py``).

    Parameters
    ----------
    detections : sequence of Detection
    iou_threshold : float in [0, 1]
    samples : int
        Quadrature grid size (see :func:`spherical_overlaps`).

    Returns
    -------
    list of Detection
        The kept detections, by decreasing score.

    Examples
    --------
    >>> bed = Detection("bed", 0.63, [700.0, 280.0, 1000.0, 500.0], 2048, 1024)
    >>> sofa = Detection("sofa", 0.57, [702.0, 282.0, 1000.0, 500.0], 2048, 1024)
    >>> lamp = Detection("plant", 0.5, [760.0, 300.0, 800.0, 360.0], 2048, 1024)  # in front of the bed
    >>> [d.label for d in suppress_across_classes([sofa, lamp, bed])]
    ['bed', 'plant']
    """
    if not 0.0 <= float(iou_threshold) <= 1.0:
        raise ValueError(f"iou_threshold: expected a number in [0, 1], got {iou_threshold!r}")
    dets = sorted(detections, key=lambda d: -d.score)
    if len(dets) < 2:
        return dets
    iou = spherical_iou(dets, samples=samples)
    keep: list[int] = []
    for i in range(len(dets)):
        if all(dets[k].label == dets[i].label or iou[i, k] <= iou_threshold for k in keep):
            keep.append(i)
    return [dets[i] for i in keep]


def _touching(dets: Iterable[Detection]) -> list[list[Detection]]:
    """Split detections into groups whose panorama extents overlap (transitively).

    A region lies inside its extent, so detections of different groups cannot
    overlap on the sphere; the quadratic overlap computation runs per group.
    """
    d = list(dets)
    if len(d) <= 1:
        return [d] if d else []
    W, H = d[0].pano_width, d[0].pano_height
    touch = pano_box_iou(np.stack([x.box for x in d]), np.stack([x.box for x in d]), W, H) > 0
    n, comp = connected_components(touch, directed=False)
    return [[x for x, c in zip(d, comp) if c == k] for k in range(n)]


def _greedy(g: list[Detection], iou_threshold: float, containment: float, truncated_weight: float,
            samples: int, view_score: float = 0.2,
            max_views: int = 6) -> list[tuple[Detection, tuple[Detection, ...]]]:
    """Greedy NMS within one group of mutually reachable detections (see :func:`merge_sphere`)."""
    out = []
    iou, inside = spherical_overlaps(g, samples)
    score = np.array([d.score for d in g])
    trunc = np.array([d.tile is not None and d.tile.truncated for d in g])
    rank = score * np.where(trunc, truncated_weight, 1.0)
    alive = np.ones(len(g), dtype=bool)
    for i in np.argsort(-rank, kind="stable"):
        if not alive[i]:
            continue
        same = iou[i] > iou_threshold
        same |= trunc & (inside[:, i] > containment)
        if trunc[i]:
            same |= inside[i, :] > containment
        same &= alive
        same[i] = True
        members = np.flatnonzero(same)
        alive[members] = False
        whole = members[~trunc[members]]
        # the medoid of the whole views: the largest score-weighted IoU with them
        rep = whole[np.argmax(iou[np.ix_(whole, whole)] @ score[whole])] if len(whole) else i
        seen = [k for k in whole[np.argsort(-score[whole], kind="stable")]
                if k != rep and score[k] >= view_score and g[k].tile is not None]
        views = tuple(g[k].tile for k in [rep] + seen[:max_views - 1]) \
            if len(whole) and g[rep].tile is not None and score[rep] >= view_score and seen else ()
        merged = replace(g[rep], score=float(score[members].max()),
                         support=int(sum(g[k].support for k in members)), views=views)
        out.append((merged, tuple(g[k] for k in members)))
    return out
