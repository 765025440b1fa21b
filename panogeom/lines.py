"""Line segments of a panorama as great-circle arcs on the unit sphere.

A straight 3D line seen from the panorama centre lies on a great circle: the
plane through the camera centre and the line cuts the sphere along it. A
segment is therefore an arc, stored as its two endpoint rays and the unit
normal of that plane.

Segments are found with OpenCV's LSD on a few overlapping perspective views
(:func:`line_views`), lifted to arcs with :func:`panogeom.perspective.segment_to_arc`,
filtered by length and contrast, and the pieces that overlapping views (or
LSD's own fragmentation) report twice are merged (:func:`merge_collinear`).

Convention: rays and normals are unit (..., 3) vectors in the panorama frame
of CONVENTIONS.md (x at the centre column, y a quarter width to the left,
z up). The normal of an arc is ``a x b`` normalised, so a point ``p`` on the
great circle satisfies ``n . p = 0``; the sign of a normal carries no meaning.
Lengths are arc angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array, pano_image
from .coords import ray_to_pixel
from .perspective import PinholeView, arc_points, equirect_to_perspective, segment_to_arc

__all__ = [
    "LineSegments",
    "lsd_segments",
    "line_views",
    "detect_line_segments",
    "merge_collinear",
    "draw_segments",
    "VP_COLORS",
]

Array = NDArray[np.float64]

#: RGB colours used by :func:`draw_segments` for labels 0, 1, 2 (x: red, y: green,
#: vertical: blue); unassigned segments (label -1) are drawn grey.
VP_COLORS = np.array([[230, 40, 40], [40, 200, 40], [50, 90, 255]], dtype=np.uint8)
_GREY = (150, 150, 150)


def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("panogeom line detection needs OpenCV: pip install opencv-contrib-python-headless") from exc
    return cv2


@dataclass(frozen=True)
class LineSegments:
    """Line segments of a panorama as great-circle arcs.

    Attributes
    ----------
    a, b : (N, 3) float
        Unit rays of the endpoints.
    normals : (N, 3) float
        Unit normals of the great circles (``n . a = n . b = 0``).
    lengths : (N,) float
        Arc lengths in radians.
    strength : (N,) float
        Mean grey-level step across the segment (0..255), a contrast measure.

    Convention: panorama frame of CONVENTIONS.md; a normal's sign is arbitrary.
    """

    a: Array
    b: Array
    normals: Array
    lengths: Array
    strength: Array

    def __post_init__(self) -> None:
        n = len(self.lengths)
        for name in ("a", "b", "normals"):
            arr = getattr(self, name)
            if arr.shape != (n, 3):
                raise ValueError(f"LineSegments.{name}: expected shape ({n}, 3), got {arr.shape}")
        if self.strength.shape != (n,) or self.lengths.shape != (n,):
            raise ValueError(f"LineSegments: expected lengths and strength of shape ({n},), "
                             f"got {self.lengths.shape} and {self.strength.shape}")

    def __len__(self) -> int:
        return int(len(self.lengths))

    @classmethod
    def empty(cls) -> "LineSegments":
        """No segments."""
        z3 = np.zeros((0, 3))
        return cls(z3, z3.copy(), z3.copy(), np.zeros(0), np.zeros(0))

    @classmethod
    def from_endpoints(cls, a: ArrayLike, b: ArrayLike, strength: ArrayLike | None = None) -> "LineSegments":
        """Build segments from endpoint rays (normals and lengths are derived).

        Parameters
        ----------
        a, b : (N, 3) float
            Endpoint directions (normalised here); ``a`` and ``b`` must be
            neither equal nor antipodal.
        strength : (N,) float, optional
            Contrast values; 255 when omitted.

        Examples
        --------
        >>> s = LineSegments.from_endpoints([[1.0, 0, 0]], [[0, 1.0, 0]])
        >>> s.normals.round(6) + 0.0, np.rad2deg(s.lengths).round(6)
        (array([[0., 0., 1.]]), array([90.]))
        """
        a = float_array(a, "a", last=3).reshape(-1, 3)
        b = float_array(b, "b", last=3).reshape(-1, 3)
        if a.shape != b.shape:
            raise ValueError(f"a, b: expected the same shape (N, 3), got {a.shape} and {b.shape}")
        na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        if len(a) and (na.min() <= 0 or nb.min() <= 0):
            raise ValueError("a, b: expected non-zero directions, got a zero vector")
        a, b = a / na[:, None], b / nb[:, None]
        n = np.cross(a, b)
        s = np.linalg.norm(n, axis=1)
        if len(a) and s.min() < 1e-12:
            raise ValueError("a, b: expected distinct, non-antipodal endpoints, got a degenerate arc")
        lengths = np.arctan2(s, np.sum(a * b, axis=1))
        st = np.full(len(a), 255.0) if strength is None else float_array(strength, "strength").reshape(-1)
        if st.shape != (len(a),):
            raise ValueError(f"strength: expected shape ({len(a)},), got {st.shape}")
        return cls(a, b, n / np.where(s > 0, s, 1.0)[:, None], lengths, st)

    def subset(self, index: ArrayLike) -> "LineSegments":
        """The segments selected by a boolean mask or an index array."""
        idx = np.asarray(index)
        return LineSegments(self.a[idx], self.b[idx], self.normals[idx], self.lengths[idx], self.strength[idx])

    def rotated(self, R: ArrayLike) -> "LineSegments":
        """The same arcs seen from a frame rotated by ``R`` (directions ``d -> R @ d``).

        Convention: ``R`` maps this frame's directions into the new frame, as
        in :func:`panogeom.transform.rotate_pano`.
        """
        from .rotation import check_rotation

        Rm = check_rotation(R, "R")
        return LineSegments(self.a @ Rm.T, self.b @ Rm.T, self.normals @ Rm.T, self.lengths.copy(),
                            self.strength.copy())

    @property
    def midpoints(self) -> Array:
        """(N, 3) unit rays of the arc midpoints."""
        m = self.a + self.b
        return m / np.linalg.norm(m, axis=1, keepdims=True)

    def polylines(self, width: int, height: int, samples: int = 24) -> list[Array]:
        """Each arc as panorama pixel polylines, split where it crosses the seam.

        Parameters
        ----------
        width, height : int
            Panorama size.
        samples : int
            Points per arc before splitting.

        Returns
        -------
        lines : list of (M, 2) float
            Continuous pixel coordinates; an arc crossing the left/right edge
            yields two polylines.
        """
        return [piece for _, piece in _arc_pieces(self, width, height, samples)]


def _arc_pieces(segments: LineSegments, width: int, height: int, samples: int) -> list[tuple[int, Array]]:
    """(segment index, (M, 2) pixel polyline) pairs, arcs split at the seam."""
    if len(segments) == 0:
        return []
    pts = ray_to_pixel(arc_points(segments.a, segments.b, samples), width, height)
    out: list[tuple[int, Array]] = []
    for k, p in enumerate(pts):
        cut = np.nonzero(np.abs(np.diff(p[:, 0])) > 0.5 * width)[0]
        out.extend((k, piece) for piece in np.split(p, cut + 1) if len(piece) >= 2)
    return out


def lsd_segments(image: ArrayLike, scale: float = 0.8) -> tuple[Array, Array]:
    """Line segments of a grey image with OpenCV's LSD.

    Parameters
    ----------
    image : (h, w) uint8
        Grey image.
    scale : float
        LSD's internal rescaling (OpenCV's default 0.8 smooths noise).

    Returns
    -------
    segments : (N, 4) float
        ``(u0, v0, u1, v1)`` in continuous pixel coordinates (pixel centres at
        integer + 0.5, CONVENTIONS.md). OpenCV puts centres at integers and,
        when ``scale != 1``, shifts results by a further ``0.5/scale - 0.5``;
        both are undone here. OpenCV 5 returns (N, 4), 4.x (N, 1, 4): both
        are accepted.
    widths : (N,) float
        LSD's line widths in pixels.

    Examples
    --------
    >>> img = np.zeros((64, 64), np.uint8); img[:, 32:] = 200
    >>> seg, _ = lsd_segments(img)
    >>> bool(np.all(np.abs(seg[:, [0, 2]] - 32.0) < 0.05))
    True
    """
    cv2 = _cv2()
    img = np.asarray(image)
    if img.ndim != 2 or img.dtype != np.uint8:
        raise ValueError(f"image: expected a (h, w) uint8 grey image, got shape {img.shape} dtype {img.dtype}")
    if not (0.0 < scale <= 1.0):
        raise ValueError(f"scale: expected a value in (0, 1], got {scale!r}")
    det = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD, float(scale))
    lines, widths = det.detect(img)[:2]
    if lines is None or len(lines) == 0:
        return np.zeros((0, 4)), np.zeros(0)
    seg = np.asarray(lines, dtype=np.float64).reshape(-1, 4) + 0.5 / scale
    w = np.ones(len(seg)) if widths is None else np.asarray(widths, dtype=np.float64).reshape(-1)
    return seg, w


def line_views(pano_width: int, n: int = 4, fov: float = np.deg2rad(100.0), pitch: float = np.deg2rad(30.0),
               oversample: float = 1.0) -> list[PinholeView]:
    """The perspective views searched for line segments: two rings at +-pitch.

    ``n`` views at ``+pitch`` (yaw ``2*pi*k/n``) and ``n`` at ``-pitch``
    shifted by half a step, so that together they cover every direction
    except small caps around the poles (a little less than
    ``pitch + fov/2`` of latitude is reached everywhere), with overlaps where
    segments cross view borders.

    Parameters
    ----------
    pano_width : int
        Width W of the panorama; the view size keeps its angular resolution:
        ``ceil(oversample * W * fov / (2*pi))`` pixels square.
    n : int
        Views per ring.
    fov : float
        Field of view in radians (square views).
    pitch : float
        Radians.
    oversample : float
        View pixels per panorama pixel at the view centre.

    Returns
    -------
    views : list of PinholeView, ``2*n`` of them

    Examples
    --------
    >>> [v.width for v in line_views(1024)][:2], len(line_views(1024))
    ([285, 285], 8)
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n: expected a positive integer, got {n!r}")
    if not (0.0 < fov < np.pi):
        raise ValueError(f"fov: expected radians in (0, pi), got {fov!r}")
    if not (oversample > 0) or int(pano_width) <= 0:
        raise ValueError(f"pano_width, oversample: expected positive values, got {pano_width!r}, {oversample!r}")
    size = int(np.ceil(oversample * pano_width * fov / (2.0 * np.pi)))
    views = []
    for ring, p in enumerate((pitch, -pitch)):
        for k in range(int(n)):
            yaw = 2.0 * np.pi * (k + 0.5 * ring) / n
            views.append(PinholeView(yaw=float(yaw), pitch=float(p), roll=0.0, fov=float(fov), width=size,
                                     height=size))
    return views


def _contrast(gray: np.ndarray, seg: Array, offset: float = 1.5, samples: int = 8) -> Array:
    """Mean absolute grey difference across each segment (both sides at ``offset`` px)."""
    cv2 = _cv2()
    p0, p1 = seg[:, None, :2], seg[:, None, 2:]
    t = (np.arange(samples) + 0.5)[None, :, None] / samples
    pts = p0 + t * (p1 - p0)
    d = seg[:, 2:] - seg[:, :2]
    nrm = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.linalg.norm(d, axis=1, keepdims=True)
    side = offset * nrm[:, None, :]
    both = np.concatenate([pts + side, pts - side], axis=1) - 0.5  # OpenCV centres at integers
    vals = cv2.remap(gray.astype(np.float32), both[..., 0].astype(np.float32), both[..., 1].astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return np.abs(vals[:, :samples] - vals[:, samples:]).mean(axis=1)


def _to_gray(pano: np.ndarray) -> np.ndarray:
    cv2 = _cv2()
    img = pano
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if img.dtype != np.uint8:
        if img.dtype.kind == "f":
            img = np.clip(img * (255.0 if np.nanmax(img) <= 1.0 else 1.0), 0, 255)
        elif img.dtype == np.uint16:
            img = img / 257.0
        img = np.nan_to_num(np.asarray(img, dtype=np.float64)).round().clip(0, 255).astype(np.uint8)
    if img.ndim == 3:
        img = cv2.cvtColor(np.ascontiguousarray(img[..., :3]), cv2.COLOR_RGB2GRAY)
    return img


def detect_line_segments(pano: ArrayLike, views: list[PinholeView] | None = None, *,
                         min_length: float = np.deg2rad(2.5), min_contrast: float = 10.0,
                         merge_angle: float = np.deg2rad(0.5), merge_gap: float = np.deg2rad(1.0),
                         max_segments: int | None = 3000) -> LineSegments:
    """Line segments of a panorama, as merged great-circle arcs.

    LSD runs on each perspective view (default :func:`line_views`), segments
    are lifted to the sphere, those whose arc is shorter than ``min_length``
    or whose contrast is below ``min_contrast`` are dropped, and duplicates
    are merged by :func:`merge_collinear`.

    Parameters
    ----------
    pano : (H, W[, C]) array, W == 2*H
        RGB or grey panorama (uint8, uint16 or float in [0, 1] or [0, 255]).
    views : list of PinholeView, optional
    min_length : float
        Shortest kept arc, radians (checked before and after merging).
    min_contrast : float
        Smallest mean grey-level step across a kept segment (0..255).
    merge_angle, merge_gap : float
        Tolerances of :func:`merge_collinear`, radians.
    max_segments : int or None
        Keep at most this many of the longest segments.

    Returns
    -------
    LineSegments
        Possibly empty (a blank image has no lines); the caller decides
        whether that is enough.

    Examples
    --------
    >>> pano = np.zeros((128, 256), np.uint8); pano[:, 128:160] = 200  # two vertical edges
    >>> segs = detect_line_segments(pano)
    >>> len(segs) >= 2, bool(np.all(np.abs(segs.normals[:, 2]) < 0.01))
    (True, True)
    """
    img = pano_image(pano, "pano")
    for name, val in (("min_length", min_length), ("min_contrast", min_contrast), ("merge_angle", merge_angle),
                      ("merge_gap", merge_gap)):
        if not (np.isfinite(val) and val >= 0):
            raise ValueError(f"{name}: expected a finite value >= 0, got {val!r}")
    gray = _to_gray(img)
    views = line_views(gray.shape[1]) if views is None else list(views)
    a_all, b_all, s_all = [], [], []
    for view in views:
        tile = equirect_to_perspective(gray, view)
        seg, _ = lsd_segments(tile)
        if len(seg) == 0:
            continue
        plen = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        # cheap pre-filter: a pinhole segment of plen pixels subtends at most plen / focal radians
        keep = plen >= min_length * view.focal
        seg = seg[keep]
        if len(seg) == 0:
            continue
        contrast = _contrast(tile, seg)
        seg, contrast = seg[contrast >= min_contrast], contrast[contrast >= min_contrast]
        if len(seg) == 0:
            continue
        a, b, _ = segment_to_arc(seg, view)
        a_all.append(a)
        b_all.append(b)
        s_all.append(contrast)
    if not a_all:
        return LineSegments.empty()
    segs = LineSegments.from_endpoints(np.concatenate(a_all), np.concatenate(b_all), np.concatenate(s_all))
    segs = segs.subset(segs.lengths >= min_length)
    segs = merge_collinear(segs, angle=merge_angle, gap=merge_gap)
    segs = segs.subset(segs.lengths >= min_length)
    if max_segments is not None and len(segs) > max_segments:
        segs = segs.subset(np.sort(np.argsort(-segs.lengths, kind="stable")[:max_segments]))
    return segs


def _components(n: int, i: NDArray[np.intp], j: NDArray[np.intp]) -> NDArray[np.intp]:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    return connected_components(g, directed=False)[1]


def merge_collinear(segments: LineSegments, angle: float = np.deg2rad(0.5),
                    gap: float = np.deg2rad(1.0)) -> LineSegments:
    """Merge arcs that lie on the same great circle and overlap or nearly touch.

    Two arcs are linked when every endpoint of each lies within ``angle`` of
    the other's great circle and, along that circle, the arcs overlap or are
    at most ``gap`` apart. Each connected group becomes one arc: the normal
    is refitted to all endpoints (weighted by length) and the arc spans the
    group's extreme points along the new circle.

    Parameters
    ----------
    segments : LineSegments
    angle, gap : float
        Radians.

    Returns
    -------
    LineSegments
        Strength of a merged arc is the length-weighted mean of its pieces.

    Examples
    --------
    >>> d = np.deg2rad
    >>> ray = lambda lon: [np.cos(lon), -np.sin(lon), 0.0]
    >>> s = LineSegments.from_endpoints([ray(d(0)), ray(d(8))], [ray(d(10)), ray(d(20))])
    >>> m = merge_collinear(s)
    >>> len(m), float(np.rad2deg(m.lengths[0]).round(6))
    (1, 20.0)
    """
    n = len(segments)
    if n < 2:
        return segments
    a, b, nr, ln = segments.a, segments.b, segments.normals, segments.lengths
    sin_tol = np.sin(angle)
    # candidate pairs: parallel normals (both endpoints close to the other circle implies this)
    cosn = np.abs(np.einsum("ij,kj->ik", nr, nr))  # einsum: BLAS is slow for an inner dimension of 3
    ii, jj = np.nonzero(np.triu(cosn > np.cos(2.0 * angle + 1e-9), k=1))
    if len(ii) == 0:
        return segments
    da = np.abs(np.sum(a[jj] * nr[ii], axis=1))
    db = np.abs(np.sum(b[jj] * nr[ii], axis=1))
    dc = np.abs(np.sum(a[ii] * nr[jj], axis=1))
    dd = np.abs(np.sum(b[ii] * nr[jj], axis=1))
    ok = (da < sin_tol) & (db < sin_tol) & (dc < sin_tol) & (dd < sin_tol)
    ii, jj = ii[ok], jj[ok]
    if len(ii) == 0:
        return segments
    # positions along arc i's circle: a_i at 0, b_i at len_i
    e1 = a[ii]
    e2 = np.cross(nr[ii], e1)
    ta = np.arctan2(np.sum(a[jj] * e2, axis=1), np.sum(a[jj] * e1, axis=1))
    tb = np.arctan2(np.sum(b[jj] * e2, axis=1), np.sum(b[jj] * e1, axis=1))
    lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
    # an arc j straddling +-pi lies on the far side of the sphere: no overlap
    far = (hi - lo) > np.pi
    sep = np.maximum(lo, 0.0) - np.minimum(hi, ln[ii])
    ok = (~far) & (sep <= gap)
    ii, jj = ii[ok], jj[ok]
    if len(ii) == 0:
        return segments
    comp = _components(n, ii, jj)
    size = np.bincount(comp)
    single = size[comp] == 1
    out_a, out_b, out_s = [a[single]], [b[single]], [segments.strength[single]]
    multi = np.flatnonzero(~single)
    order = multi[np.argsort(comp[multi], kind="stable")]
    bounds = np.flatnonzero(np.diff(comp[order])) + 1
    for group in np.split(order, bounds) if len(order) else []:
        w = ln[group]
        pts = np.concatenate([a[group], b[group]])
        pw = np.concatenate([w, w])
        scatter = (pts * pw[:, None]).T @ pts
        normal = np.linalg.eigh(scatter)[1][:, 0]
        ref = group[np.argmax(w)]
        e1 = a[ref] - normal * (a[ref] @ normal)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(normal, e1)
        t = np.arctan2(pts @ e2, pts @ e1)
        t0, t1 = t.min(), t.max()
        out_a.append((np.cos(t0) * e1 + np.sin(t0) * e2)[None])
        out_b.append((np.cos(t1) * e1 + np.sin(t1) * e2)[None])
        out_s.append(np.array([np.sum(w * segments.strength[group]) / np.sum(w)]))
    return LineSegments.from_endpoints(np.concatenate(out_a), np.concatenate(out_b), np.concatenate(out_s))


def draw_segments(image: ArrayLike, segments: LineSegments, labels: ArrayLike | None = None,
                  thickness: int = 2, colors: ArrayLike = VP_COLORS) -> np.ndarray:
    """Draw arcs on a copy of a panorama, coloured by label.

    Parameters
    ----------
    image : (H, W, 3) uint8 or (H, W) uint8, W == 2*H
        RGB panorama (grey is converted to RGB).
    segments : LineSegments
    labels : (N,) int, optional
        Index into ``colors`` per segment; -1 (or no labels) draws grey.
    thickness : int
        Line width in pixels.
    colors : (K, 3) uint8
        RGB colours (default :data:`VP_COLORS`: x red, y green, vertical blue).

    Returns
    -------
    overlay : (H, W, 3) uint8
    """
    cv2 = _cv2()
    img = pano_image(image)
    if img.dtype != np.uint8:
        raise ValueError(f"image: expected uint8, got {img.dtype}")
    out = np.ascontiguousarray(np.repeat(img[..., None], 3, axis=2) if img.ndim == 2 else img[..., :3]).copy()
    if out.shape[2] == 1:
        out = np.repeat(out, 3, axis=2)
    h, w = out.shape[:2]
    n = len(segments)
    lab = np.full(n, -1) if labels is None else np.asarray(labels).reshape(-1)
    if lab.shape != (n,):
        raise ValueError(f"labels: expected shape ({n},), got {lab.shape}")
    pal = np.asarray(colors)
    if pal.ndim != 2 or pal.shape[1] != 3:
        raise ValueError(f"colors: expected shape (K, 3), got {pal.shape}")
    shift = 4
    rank = np.argsort(np.argsort(lab, kind="stable"), kind="stable")  # unassigned first, labelled on top
    for k, piece in sorted(_arc_pieces(segments, w, h, 24), key=lambda kp: rank[kp[0]]):
        col = tuple(int(c) for c in pal[lab[k]]) if 0 <= lab[k] < len(pal) else _GREY
        poly = np.round((piece - 0.5) * (1 << shift)).astype(np.int32)
        cv2.polylines(out, [poly], False, col, int(thickness), cv2.LINE_AA, shift)
    return out
