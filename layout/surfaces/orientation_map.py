"""Orientation map (Lee, Hebert and Kanade, CVPR 2009) computed on the sphere.

Lee et al. label each pixel of a perspective image with the orientation of
the Manhattan plane it lies on by *sweeping* line segments: a segment
pointing at vanishing point ``j`` is moved towards vanishing point ``k``
until it hits a segment of the third family ``i``; the swept region lies on
a plane containing directions ``j`` and ``k`` (normal along ``i``). A pixel
swept both by ``j``-segments moving towards ``k`` and by ``k``-segments
moving towards ``j`` is given the orientation "normal ``i``".

On the sphere the sweep is exact and simple. Moving a point towards the
vanishing point ``k`` means moving along the great circle through ``k``;
in an equirectangular raster whose north pole is ``k`` (the "``k``-frame")
those great circles are the columns. So each sweep is a column operation:
rasterise the ``j``-segments (sources) and the ``i``-segments (blockers) in
the ``k``-frame, split every column at the blockers, and mark every run that
contains a source pixel. The six sweep maps (3 choices of ``k`` x 2 source
families) are resampled (nearest) into the panorama and combined:

- normal x (label 3, wall facing +-x): y-segments swept towards z and
  z-segments swept towards y;
- normal y (label 4): x towards z and z towards x;
- normal z (labels 1 / 2, floor below the horizon, ceiling above): x
  towards y and y towards x.

``support[..., o]`` is the fraction (0, 1/2, 1) of the two sweeps of
orientation ``o`` covering a pixel; a pixel is labelled when exactly one
orientation has full support, and its confidence is the gap between the best
and the second-best support.

Convention: panorama pixels and frames as in :mod:`panogeom.coords`;
segments are great-circle arcs in the panorama's frame
(:class:`panogeom.lines.LineSegments`); ``axes`` rows are the Manhattan
directions ``(x, y, up)`` in that frame (identity for a panorama rectified
in ``"walls"`` mode). Label ids are those of CONVENTIONS.md ("Surface
labels"). Radians.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_grid_rays, pixel_to_lonlat, ray_to_pixel
from panogeom.lines import LineSegments
from panogeom.perspective import arc_points
from panogeom.sampling import EquirectSampler
from panogeom.vanishing import assign_segments

__all__ = ["OrientationMap", "orientation_map", "sweep_columns", "rasterize_arcs", "pole_frame", "SWEEPS"]

#: For each orientation (normal x, normal y, normal z): its two sweeps as
#: (source family, vanishing point swept towards). Families: 0 x, 1 y, 2 up.
SWEEPS = (((1, 2), (2, 1)), ((0, 2), (2, 0)), ((0, 1), (1, 0)))

# cyclic permutations: row order that puts axis k last (the k-frame's pole)
_PERM = {0: (1, 2, 0), 1: (2, 0, 1), 2: (0, 1, 2)}


@dataclass(frozen=True)
class OrientationMap:
    """Per-pixel Manhattan orientation from swept line segments.

    Attributes
    ----------
    labels : (H, W) uint8
        0 none or conflicting, 1 floor / 2 ceiling (normal along up, split at
        the horizon), 3 wall facing +-x, 4 wall facing +-y.
    confidence : (H, W) float32
        Best minus second-best support, in {0, 0.5, 1}.
    support : (H, W, 3) float32
        Fraction of the two sweeps of each orientation (normal x, normal y,
        normal up) that cover the pixel: 0, 0.5 or 1.
    n_segments : (3,) int
        Segments of each family (x, y, up) that were swept.

    Convention: see the module docstring.
    """

    labels: NDArray[np.uint8]
    confidence: NDArray[np.float32]
    support: NDArray[np.float32]
    n_segments: NDArray[np.int64]

    @property
    def usable(self) -> bool:
        """True when at least two families have two or more segments (some orientation can be swept)."""
        return bool(np.sum(self.n_segments >= 2) >= 2)

    @property
    def coverage(self) -> float:
        """Fraction of the pixels that received a label."""
        return float(np.mean(self.labels > 0))


def pole_frame(axes: ArrayLike, k: int) -> NDArray[np.float64]:
    """Rotation from the panorama frame to the frame whose +z is Manhattan axis ``k``.

    Parameters
    ----------
    axes : (3, 3) float
        Rows ``(x, y, up)``: Manhattan directions in the panorama frame.
    k : {0, 1, 2}

    Returns
    -------
    Q : (3, 3) float
        Proper rotation; ``Q @ axes[k] == (0, 0, 1)``.

    Examples
    --------
    >>> Q = pole_frame(np.eye(3), 0)
    >>> (Q @ [1.0, 0.0, 0.0]).tolist(), round(float(np.linalg.det(Q)), 6)
    ([0.0, 0.0, 1.0], 1.0)
    """
    A = np.asarray(axes, dtype=np.float64)
    if A.shape != (3, 3):
        raise ValueError(f"axes: expected shape (3, 3), got {A.shape}")
    if k not in _PERM:
        raise ValueError(f"k: expected 0, 1 or 2, got {k!r}")
    return A[list(_PERM[k])]


def rasterize_arcs(a: ArrayLike, b: ArrayLike, width: int, thickness: int = 1) -> NDArray[np.bool_]:
    """Mark the pixels of an equirectangular raster crossed by great-circle arcs.

    Parameters
    ----------
    a, b : (N, 3) float
        Unit endpoint rays of the arcs (shorter arc from ``a`` to ``b``).
    width : int
        Raster width W (height W / 2).
    thickness : int
        Line thickness in pixels.

    Returns
    -------
    mask : (W/2, W) bool
        8-connected polylines, wrapped at the seam: every column an arc
        passes is marked at least once (what a column sweep needs from a
        blocking line).

    Examples
    --------
    >>> m = rasterize_arcs([[1.0, 0.2, 0.05]], [[1.0, -0.2, 0.05]], 64)  # just above the equator
    >>> np.flatnonzero(m.any(axis=0)).tolist(), np.flatnonzero(m.any(axis=1)).tolist()
    ([30, 31, 32, 33, 34], [15])
    """
    import cv2

    w = int(width)
    if w < 4 or w % 2:
        raise ValueError(f"width: expected an even raster width >= 4, got {width!r}")
    h = w // 2
    a = np.asarray(a, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 3)
    if a.shape != b.shape:
        raise ValueError(f"a, b: expected the same (N, 3) shape, got {a.shape} and {b.shape}")
    mask = np.zeros((h, 3 * w), np.uint8)
    if len(a) == 0:
        return np.zeros((h, w), bool)
    length = np.arccos(np.clip(np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)),
                               -1.0, 1.0))
    n = int(np.clip(np.ceil(length.max() / (np.pi / h)) + 1, 2, 4 * w))
    uv = ray_to_pixel(arc_points(a, b, n), w, h)  # (N, n, 2)
    du = np.diff(uv[..., 0], axis=1)
    du -= w * np.round(du / w)  # unwrap across the seam
    u = uv[:, :1, 0] + np.concatenate([np.zeros((len(a), 1)), np.cumsum(du, axis=1)], axis=1) + w
    pts = np.stack([u, uv[..., 1]], axis=-1)
    shift = 4
    poly = np.round((pts - 0.5) * (1 << shift)).astype(np.int32)
    cv2.polylines(mask, list(poly), False, 1, int(thickness), cv2.LINE_8, shift)
    return (mask[:, :w] | mask[:, w:2 * w] | mask[:, 2 * w:]).astype(bool)


def sweep_columns(sources: ArrayLike, blockers: ArrayLike) -> NDArray[np.bool_]:
    """Sweep source pixels along the columns until they meet blocker pixels.

    Parameters
    ----------
    sources, blockers : (h, w) bool

    Returns
    -------
    swept : (h, w) bool
        Every run of a column between blockers (a blocker pixel closes the
        run above it) that contains a source pixel.

    Examples
    --------
    >>> s = np.zeros((6, 2), bool); s[1, 0] = True
    >>> b = np.zeros((6, 2), bool); b[3, 0] = True
    >>> sweep_columns(s, b)[:, 0].tolist()
    [True, True, True, True, False, False]
    """
    S = np.asarray(sources, dtype=bool)
    B = np.asarray(blockers, dtype=bool)
    if S.ndim != 2 or S.shape != B.shape:
        raise ValueError(f"sources, blockers: expected two (h, w) masks of one shape, got {S.shape} and {B.shape}")
    h, w = S.shape
    run = np.cumsum(B, axis=0) - B  # a blocker belongs to the run above it
    key = run + (h + 1) * np.arange(w)[None, :]
    has = np.zeros((h + 1) * w, bool)
    has[key[S]] = True
    return has[key]


@lru_cache(maxsize=8)
def _sampler(q: tuple[float, ...], width: int, om_width: int) -> EquirectSampler:
    """Nearest-neighbour maps from a W x W/2 panorama's pixels into a k-frame raster."""
    Q = np.array(q).reshape(3, 3)
    rays = pixel_grid_rays(width, width // 2) @ Q.T
    return EquirectSampler.from_uv(ray_to_pixel(rays, om_width, om_width // 2), om_width, om_width // 2, "nearest")


def orientation_map(segments: LineSegments, width: int, axes: ArrayLike | None = None, *, om_width: int = 512,
                    max_angle: float = np.deg2rad(2.0), min_length: float = np.deg2rad(2.0)) -> OrientationMap:
    """Orientation map of a panorama from its line segments (Lee et al. 2009, on the sphere).

    Parameters
    ----------
    segments : LineSegments
        Great-circle arcs in the panorama's frame (e.g.
        :func:`panogeom.lines.detect_line_segments` of the rectified
        panorama, or ``Rectification.segments.rotated(R)``).
    width : int
        Panorama width W (height W / 2) of the returned maps.
    axes : (3, 3) float, optional
        Rows ``(x, y, up)``: Manhattan directions in the panorama frame;
        identity (an upright, wall-aligned panorama) when omitted.
    om_width : int
        Width of the rasters the sweeps run in (even).
    max_angle : float
        Segments whose great circle misses every vanishing point by more
        than this (radians) are not used.
    min_length : float
        Shorter segments (radians) are not used.

    Returns
    -------
    OrientationMap

    Examples
    --------
    A box room seen from its centre: its 12 edges as arcs.

    >>> import itertools
    >>> c = np.array(list(itertools.product([-2.0, 2.0], [-2.0, 2.0], [-1.6, 1.0])))
    >>> edges = [(i, j) for i, j in itertools.combinations(range(8), 2) if np.sum(c[i] != c[j]) == 1]
    >>> a, b = c[[i for i, _ in edges]], c[[j for _, j in edges]]
    >>> om = orientation_map(LineSegments.from_endpoints(a, b), 256, om_width=256)
    >>> om.n_segments.tolist(), [int(om.labels[v, u]) for u, v in [(128, 64), (64, 64), (128, 120), (128, 8)]]
    ([4, 4, 4], [3, 4, 1, 2])
    """
    if not isinstance(segments, LineSegments):
        raise ValueError(f"segments: expected panogeom.lines.LineSegments, got {type(segments).__name__}")
    W = int(width)
    if W != width or W < 4 or W % 2:
        raise ValueError(f"width: expected an even panorama width >= 4, got {width!r}")
    if int(om_width) != om_width or om_width < 16 or om_width % 2:
        raise ValueError(f"om_width: expected an even integer >= 16, got {om_width!r}")
    A = np.eye(3) if axes is None else np.asarray(axes, dtype=np.float64)
    if A.shape != (3, 3) or not np.allclose(A @ A.T, np.eye(3), atol=1e-6) or np.linalg.det(A) < 0:
        raise ValueError(f"axes: expected a (3, 3) proper rotation (rows x, y, up), got {A.tolist()}")
    H = W // 2
    keep = segments.lengths >= min_length
    segs = segments.subset(keep)
    fam = assign_segments(segs, A, max_angle)
    counts = np.bincount(fam[fam >= 0], minlength=3)[:3].astype(np.int64)
    # sweep bits in the panorama: bit (2*o + s) for sweep s of orientation o
    bits = np.zeros((H, W), np.uint8)
    for k in range(3):
        raster = np.zeros((om_width // 2, om_width), np.uint8)
        Q = pole_frame(A, k)
        drawn: dict[int, NDArray[np.bool_]] = {}

        def family(j: int) -> NDArray[np.bool_]:
            if j not in drawn:
                sel = fam == j
                drawn[j] = rasterize_arcs(segs.a[sel] @ Q.T, segs.b[sel] @ Q.T, om_width)
            return drawn[j]

        for o, pair in enumerate(SWEEPS):
            for s, (j, kk) in enumerate(pair):
                if kk != k or counts[j] == 0:
                    continue
                i = 3 - j - k  # the third family blocks
                swept = sweep_columns(family(j), family(i))
                raster |= (swept.astype(np.uint8) << np.uint8(2 * o + s))
        if raster.any():
            bits |= _sampler(tuple(np.round(Q, 12).ravel().tolist()), W, int(om_width))(raster)
    sweeps = np.stack([(bits >> np.uint8(b)) & 1 for b in range(6)], axis=-1).astype(np.float32)
    support = 0.5 * (sweeps[..., 0::2] + sweeps[..., 1::2])  # (H, W, 3)
    top = support.max(axis=2)
    second = support.sum(axis=2) - top - support.min(axis=2)
    best = np.argmax(support, axis=2)
    conf = (top - second).astype(np.float32)
    full = (top >= 1.0) & (conf > 0)
    # up . ray, separably: cos(lat) (a0 cos(lon) - a1 sin(lon)) + a2 sin(lat)
    lon = pixel_to_lonlat(np.stack([np.arange(W) + 0.5, np.full(W, 0.5)], axis=-1), W, H)[:, 0]
    lat = pixel_to_lonlat(np.stack([np.full(H, 0.5), np.arange(H) + 0.5], axis=-1), W, H)[:, 1]
    up = (np.cos(lat)[:, None] * (A[2, 0] * np.cos(lon) - A[2, 1] * np.sin(lon))[None, :]
          + A[2, 2] * np.sin(lat)[:, None])
    horizontal = np.where(up > 0, np.uint8(2), np.uint8(1))
    lab = np.where(best == 0, np.uint8(3), np.where(best == 1, np.uint8(4), horizontal))
    labels = np.where(full, lab, np.uint8(0)).astype(np.uint8)
    return OrientationMap(labels=labels, confidence=conf, support=support.astype(np.float32), n_segments=counts)
