"""Surface labels of an upright panorama: geometric context and orientation map fused per pixel.

Paper Sec. 3.1: "we estimate surface orientations at each pixel by combining
estimates of their Orientation Map (OM) and Geometric Context (GC)". As in
PanoContext (Zhang et al. 2014), GC decides floor / ceiling / wall and the OM
decides which way a wall faces. :func:`estimate_surfaces` goes:

1. **GC** (:mod:`layout.surfaces.gc_net`): floor / ceiling / wall / clutter
   probabilities per pixel. Object regions given by the caller count as
   clutter.
2. **Column boundaries.** An upright camera between floor and ceiling sees,
   in every column, ceiling above one wall above floor (walls are full
   height; clutter may hide parts). Per column, the ceiling boundary
   (above the horizon) and the floor boundary (below it) are chosen to
   maximise the GC likelihood, clutter being allowed in front of the wall or
   the floor (exact 1-D search with prefix sums).
3. **OM** (:mod:`layout.surfaces.orientation_map`): Lee et al.'s line sweeps
   on the sphere, from the panorama's line segments.
4. **Wall orientation per column.** One wall per column, so the column is
   the unit of decision. Two kinds of evidence, fused in a hidden Markov
   chain around the panorama whose states are (wall normal x or y,
   perpendicular distance of the wall on a log grid):

   - the OM: the share of the column's wall pixels the OM labels 3 or 4;
   - the shape of the boundaries: the floor boundary of a wall facing +-x at
     distance D from the camera lies at ``tan(-lat) = h |cos(psi)| / D``
     (``psi`` the column's heading from the x axis, ``h`` the camera
     height), of a wall facing +-y at ``h |sin(psi)| / D``; the ceiling
     boundary likewise with the ceiling's height above the camera (their
     ratio is estimated from the columns where both boundaries are clean).
     A wall's columns then share one state.

   A Viterbi pass gives each column's wall orientation and distance, a
   forward-backward (min-sum) pass the margin between the best paths with
   either orientation: the orientation confidence.
5. **Per-pixel labels.** Clutter where GC says so (0), otherwise the
   column's floor / ceiling / wall label; the wall's orientation from step 4.
   A pixel is *unknown* (0) where both sources are unsure: GC's probability
   of the chosen class (times the orientation confidence for walls) is
   below ``min_confidence`` and the OM does not give the pixel the same
   label. Object regions are 5.

6. **Ceiling boundary on the image's edge** (:mod:`layout.surfaces.boundary`,
   optional, off by default): each column's ceiling-wall boundary moves to the strongest vertical
   grey-level step within a few rows, along a smooth path across the
   columns (a Viterbi pass); GC alone lets the ceiling label creep down a
   shadowed wall. ``snap_ceiling=True`` runs it. It gives better labels
   and a better room at the true scale, but in the whole pipeline the two
   tuning sets disagree on the layout (docs/EVALUATION.md, "Sessions 16-17
   on the tuning sets"), so it is not the default.

6'. **Ceiling boundary of the boundary network**
   (:mod:`layout.surfaces.boundary_net`, optional, ``ceiling_net``): the
   same move (:func:`layout.surfaces.boundary.move_ceiling_boundary`) onto
   the boundary a HorizonNet-style network regresses for every column of
   the empty room at once (docs/EVALUATION.md, "Session 19"). Its two
   boundaries (ceiling and floor of the empty room, every column) are then
   also the shape evidence of step 4, in place of GC's boundaries, which
   clutter and furniture break (docs/EVALUATION.md, "Session 33").

The clutter-free ``layout`` map fills the floor and ceiling boundaries hidden
by clutter from the fitted column states (the wall model of step 4), giving
the room's structure at every pixel.

Convention: panorama pixels and frames as in :mod:`panogeom.coords`; the
panorama is upright (rectified); ``axes`` rows are the Manhattan directions
``(x, y, up)`` in its frame, identity for a panorama rectified in ``"walls"``
mode, and labels 3 / 4 refer to them. Label ids: CONVENTIONS.md "Surface
labels". Rows ``v`` are continuous pixel coordinates; a boundary between rows
``k - 1`` and ``k`` is at ``v = k``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_to_lonlat
from panogeom.lines import LineSegments

from ._checks import pixel_mask, rgb_pano
from .boundary import ceiling_edge_path, edge_strength, move_ceiling_boundary
from .gc_net import GC_CEILING, GC_CLUTTER, GC_FLOOR, GC_WALL, GeometricContext, load_gc_net
from .orientation_map import OrientationMap, orientation_map

if TYPE_CHECKING:
    from .boundary_net import BoundaryNet

__all__ = [
    "SurfaceLabels",
    "ColumnLayout",
    "estimate_surfaces",
    "fuse_surfaces",
    "column_boundaries",
    "column_orientation",
    "boxes_to_mask",
]

UNKNOWN, FLOOR, CEILING, WALL_X, WALL_Y, OBJECT = 0, 1, 2, 3, 4, 5
_EPS = 1e-6
#: Default weights of the orientation chain in :func:`fuse_surfaces` (and :func:`estimate_surfaces`): OM votes,
#: boundary shape, change of wall (:func:`column_orientation`).
_OM_WEIGHT, _SHAPE_WEIGHT, _SWITCH_COST = 3.0, 1.0, 20.0


@dataclass(frozen=True)
class ColumnLayout:
    """Per-column structure found by the fusion (W = panorama width).

    Attributes
    ----------
    ceiling_v, floor_v : (W,) float
        Rows of the ceiling-wall and floor-wall boundaries chosen from GC.
    ceiling_weight, floor_weight : (W,) float
        How clean each boundary is, in [0, 1]: the share of pixels GC calls
        wall just inside it times the share it calls ceiling / floor just
        outside (a few rows each side).
    wall_label : (W,) uint8
        3 (wall facing +-x) or 4 (wall facing +-y).
    confidence : (W,) float
        Orientation confidence in [0, 1) (``tanh`` of half the min-sum
        margin between the two orientations).
    distance : (W,) float
        Perpendicular distance of the column's wall, in camera heights.
    ceiling_ratio : float
        Ceiling height above the camera over the camera height (NaN when no
        column had both boundaries clean).
    model_floor_v, model_ceiling_v : (W,) float
        Boundaries predicted by the fitted wall of each column.
    """

    ceiling_v: NDArray[np.float64]
    floor_v: NDArray[np.float64]
    ceiling_weight: NDArray[np.float64]
    floor_weight: NDArray[np.float64]
    wall_label: NDArray[np.uint8]
    confidence: NDArray[np.float64]
    distance: NDArray[np.float64]
    ceiling_ratio: float
    model_floor_v: NDArray[np.float64]
    model_ceiling_v: NDArray[np.float64]


@dataclass(frozen=True)
class SurfaceLabels:
    """Per-pixel surface labels of an upright panorama (result of :func:`estimate_surfaces`).

    Attributes
    ----------
    labels : (H, W) uint8
        0 unknown / clutter, 1 floor, 2 ceiling, 3 wall facing +-x, 4 wall
        facing +-y, 5 object (the regions given by the caller).
    confidence : (H, W) float32
        Support of each pixel's label in [0, 1] (0 for unknown).
    gc_probs : (H, W, 4) float32
        Geometric context: floor, ceiling, wall, clutter probabilities.
    om : (H, W) uint8
        Orientation map labels (0 none, 1 floor, 2 ceiling, 3, 4 walls).
    warnings : tuple of str
        What went wrong without stopping the labelling (e.g. no usable
        line segments).
    layout : (H, W) uint8
        Clutter-free structure: labels 1..4 at every pixel (floor and
        ceiling boundaries behind clutter from the fitted walls).
    columns : ColumnLayout
        The per-column boundaries, wall orientations and distances.
    om_confidence : (H, W) float32
        The orientation map's own confidence.

    Convention: CONVENTIONS.md "Surface labels"; pixel geometry of the
    (rectified) panorama the labels were computed on.
    """

    labels: NDArray[np.uint8]
    confidence: NDArray[np.float32]
    gc_probs: NDArray[np.float32]
    om: NDArray[np.uint8]
    warnings: tuple[str, ...]
    layout: NDArray[np.uint8]
    columns: ColumnLayout
    om_confidence: NDArray[np.float32]

    def labels_in_input(self, rotation: ArrayLike, which: str = "labels") -> NDArray[np.uint8]:
        """A label map carried back into the input panorama's pixel geometry (the labels.png contract).

        Parameters
        ----------
        rotation : (3, 3) float
            ``R`` of the rectification (input camera frame -> rectified
            frame, :attr:`panogeom.rectify.Rectification.rotation`).
        which : {"labels", "layout", "om"}

        Returns
        -------
        labels : (H, W) uint8
            Nearest-neighbour resampling: the input pixel of ray ``d`` gets
            the label of the rectified pixel of ray ``R @ d``.
        """
        from panogeom.transform import rotate_pano

        if which not in ("labels", "layout", "om"):
            raise ValueError(f"which: expected 'labels', 'layout' or 'om', got {which!r}")
        R = np.asarray(rotation, dtype=np.float64)
        if R.shape != (3, 3):
            raise ValueError(f"rotation: expected a (3, 3) rotation, got shape {R.shape}")
        return rotate_pano(getattr(self, which), R.T, "nearest")


def boxes_to_mask(boxes: ArrayLike, width: int, height: int) -> NDArray[np.bool_]:
    """Pixel boxes of the panorama as a mask.

    Parameters
    ----------
    boxes : (N, 4) float
        ``(u0, v0, u1, v1)`` in continuous pixel coordinates; ``u0 > u1``
        when a box wraps the seam (CONVENTIONS.md ``bbox_pano``).
    width, height : int

    Returns
    -------
    mask : (height, width) bool
        Pixels whose centre lies inside a box.

    Examples
    --------
    >>> m = boxes_to_mask([[6.0, 1.0, 2.0, 3.0]], 8, 4)  # wraps the seam
    >>> m.astype(int).tolist()
    [[0, 0, 0, 0, 0, 0, 0, 0], [1, 1, 0, 0, 0, 0, 1, 1], [1, 1, 0, 0, 0, 0, 1, 1], [0, 0, 0, 0, 0, 0, 0, 0]]
    """
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4) if np.size(boxes) else np.zeros((0, 4))
    if not np.all(np.isfinite(b)):
        raise ValueError("boxes: expected finite (u0, v0, u1, v1) values, got NaN or inf")
    w, h = int(width), int(height)
    uc = np.arange(w) + 0.5
    vc = np.arange(h) + 0.5
    mask = np.zeros((h, w), bool)
    for u0, v0, u1, v1 in b:
        if not (v0 <= v1):
            raise ValueError(f"boxes: expected v0 <= v1, got {[u0, v0, u1, v1]}")
        cols = (uc >= u0) & (uc < u1) if u0 <= u1 else (uc >= u0) | (uc < u1)
        rows = (vc >= v0) & (vc < v1)
        mask |= rows[:, None] & cols[None, :]
    return mask


def column_boundaries(gc_probs: ArrayLike, clutter_mask: ArrayLike | None = None,
                      clutter_share: float = 0.5) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Ceiling and floor boundary of every column maximising the GC likelihood.

    Parameters
    ----------
    gc_probs : (H, W, 4) float
        Floor, ceiling, wall, clutter probabilities.
    clutter_mask : (H, W) bool, optional
        Pixels known to be clutter (objects): neutral for the boundaries.
    clutter_share : float
        Clutter's probability counts this much towards the wall and the
        floor it may stand in front of.

    Returns
    -------
    ceiling_v : (W,) float
        Row in [0, H/2]: rows above are ceiling, rows below (to the horizon)
        wall.
    floor_v : (W,) float
        Row in [H/2, H]: rows below are floor.

    Examples
    --------
    >>> p = np.zeros((8, 16, 4)); p[:2, :, 1] = 1; p[2:6, :, 2] = 1; p[6:, :, 0] = 1
    >>> c, f = column_boundaries(p)
    >>> float(c[0]), float(f[0])
    (2.0, 6.0)
    """
    P = np.asarray(gc_probs, dtype=np.float64)
    if P.ndim != 3 or P.shape[2] != 4:
        raise ValueError(f"gc_probs: expected (H, W, 4), got shape {P.shape}")
    H, W = P.shape[:2]
    if H < 2 or H % 2:
        raise ValueError(f"gc_probs: expected an even number of rows >= 2, got {H}")
    clutter = P[..., GC_CLUTTER]
    if clutter_mask is not None:
        m = np.asarray(clutter_mask, dtype=bool)
        if m.shape != (H, W):
            raise ValueError(f"clutter_mask: expected shape {(H, W)}, got {m.shape}")
        P = P.copy()
        P[m] = (0.0, 0.0, 0.0, 1.0)
        clutter = P[..., GC_CLUTTER]
    cost_c = -np.log(P[..., GC_CEILING] + _EPS)
    cost_w = -np.log(P[..., GC_WALL] + clutter_share * clutter + _EPS)
    cost_f = -np.log(P[..., GC_FLOOR] + clutter_share * clutter + _EPS)
    half = H // 2
    zero = np.zeros((1, W))
    cc = np.concatenate([zero, np.cumsum(cost_c[:half], axis=0)])  # (half + 1, W)
    cw = np.concatenate([zero, np.cumsum(cost_w[:half], axis=0)])
    top = cc + (cw[-1:] - cw)
    ceiling_v = np.argmin(top, axis=0).astype(np.float64)
    bw = np.concatenate([zero, np.cumsum(cost_w[half:], axis=0)])
    bf = np.concatenate([zero, np.cumsum(cost_f[half:], axis=0)])
    bottom = bw + (bf[-1:] - bf)
    floor_v = half + np.argmin(bottom, axis=0).astype(np.float64)
    return ceiling_v, floor_v


def _band_mean(x: NDArray[np.float64], start: NDArray[np.int64], stop: NDArray[np.int64]) -> NDArray[np.float64]:
    """Mean of x[rows start..stop) per column (rows clipped to the image), 0 for empty bands."""
    H, W = x.shape
    cum = np.concatenate([np.zeros((1, W)), np.cumsum(x, axis=0)])
    a = np.clip(start, 0, H)
    b = np.clip(stop, 0, H)
    cols = np.arange(W)
    n = b - a
    return np.where(n > 0, (cum[b, cols] - cum[a, cols]) / np.maximum(n, 1), 0.0)


def column_orientation(heading: ArrayLike, floor_lat: ArrayLike, ceiling_lat: ArrayLike, floor_weight: ArrayLike,
                       ceiling_weight: ArrayLike, om_x: ArrayLike, om_y: ArrayLike, *, om_weight: float = 3.0,
                       shape_weight: float = 1.0, switch_cost: float = 20.0, sigma_px: float = 1.5,
                       height: int = 512, bins: int = 96) -> dict:
    """Wall orientation and distance of every column from boundary shape and OM votes (HMM around the panorama).

    Parameters
    ----------
    heading : (W,) float
        Heading ``psi`` of each column from the Manhattan x axis, radians.
    floor_lat, ceiling_lat : (W,) float
        Latitudes (radians) of the floor boundary (< 0) and ceiling
        boundary (> 0).
    floor_weight, ceiling_weight : (W,) float
        Reliability of each boundary in [0, 1] (0: no evidence).
    om_x, om_y : (W,) float
        Shares of the column's wall pixels that the OM labels 3 and 4.
    om_weight : float
        Cost of a state disagreeing with the OM, per unit share.
    shape_weight : float
        Weight of the boundary-shape costs (0: the OM alone decides).
    switch_cost : float
        Cost of changing state between neighbouring columns. The column
        costs are scaled by ``512 / W``, so that a wall of a given angular
        width carries the same evidence at any panorama width.
    sigma_px : float
        Boundary noise in pixels of an image of ``height`` rows.
    height : int
        Rows of the panorama the boundaries come from.
    bins : int
        Log-distance states per orientation (0.3 to 25 camera heights).

    Returns
    -------
    dict
        ``wall_label`` (W,) uint8 (3 or 4), ``confidence`` (W,) float in
        [0, 1), ``distance`` (W,) float (camera heights) and
        ``ceiling_ratio`` float (NaN when not measurable).

    Examples
    --------
    A square room 4 x 4 camera heights, camera at its centre, ceiling 1.5
    camera heights above the camera:

    >>> psi = np.linspace(-np.pi, np.pi, 256, endpoint=False)
    >>> lab = np.where(np.abs(np.cos(psi)) >= np.abs(np.sin(psi)), 3, 4)
    >>> d = 2.0 / np.maximum(np.abs(np.cos(psi)), np.abs(np.sin(psi)))
    >>> z = np.zeros(256); one = np.ones(256)
    >>> r = column_orientation(psi, -np.arctan(1 / d), np.arctan(1.5 / d), one, one, z, z, height=128)
    >>> float(np.mean(r["wall_label"] == lab)) > 0.97, round(r["ceiling_ratio"], 2)
    (True, 1.5)
    """
    psi = np.asarray(heading, dtype=np.float64).reshape(-1)
    W = len(psi)
    arrs = [np.asarray(a, dtype=np.float64).reshape(-1) for a in (floor_lat, ceiling_lat, floor_weight,
                                                                   ceiling_weight, om_x, om_y)]
    if any(len(a) != W for a in arrs) or W < 4:
        raise ValueError(f"expected per-column arrays of one length W >= 4, got lengths {[W] + [len(a) for a in arrs]}")
    flat, clat, fw, cw, ox, oy = arrs
    fw = np.clip(np.nan_to_num(fw), 0.0, 1.0)
    cw = np.clip(np.nan_to_num(cw), 0.0, 1.0)
    tf = np.tan(np.clip(-flat, 1e-3, np.pi / 2 - 1e-3))  # h / d
    tc = np.tan(np.clip(clat, 1e-3, np.pi / 2 - 1e-3))  # (c - h) / d
    both = np.minimum(fw, cw) >= 0.9
    ratio = float(np.clip(np.exp(np.median(np.log(tc[both] / tf[both]))), 0.1, 10.0)) if both.sum() >= 8 \
        else float("nan")
    # log of the column's horizontal distance, from each boundary (camera heights)
    ld_f = -np.log(tf)
    ld_c = np.log(ratio) - np.log(tc) if np.isfinite(ratio) else np.zeros(W)
    if not np.isfinite(ratio):
        cw = np.zeros(W)
    dlat = np.pi / height * sigma_px
    sig_f = np.hypot(dlat * 2.0 / np.maximum(np.abs(np.sin(2.0 * flat)), 0.05), 0.05)
    sig_c = np.hypot(dlat * 2.0 / np.maximum(np.abs(np.sin(2.0 * clat)), 0.05), 0.05)
    grid = np.linspace(np.log(0.3), np.log(25.0), int(bins))
    trig = np.stack([np.abs(np.cos(psi)), np.abs(np.sin(psi))])  # (2, W): x walls, y walls
    ltrig = np.log(np.maximum(trig, 0.03))
    trunc = 3.0
    # unary (W, 2, bins): log D = log d + log|trig|
    unary = np.zeros((W, 2, len(grid)))
    for o in range(2):
        for ld, sig, wt in ((ld_f, sig_f, fw), (ld_c, sig_c, cw)):
            r = (ld + ltrig[o])[:, None] - grid[None, :]
            unary[:, o, :] += shape_weight * wt[:, None] * np.minimum(0.5 * (r / sig[:, None]) ** 2, trunc)
    unary[:, 0, :] += om_weight * oy[:, None]
    unary[:, 1, :] += om_weight * ox[:, None]
    U = unary.reshape(W, -1) * (512.0 / W)  # evidence per 1/512 turn: the same chain at any width
    S = U.shape[1]
    # around the panorama: unroll a quarter turn on each side, keep the middle
    k = W // 4
    idx = np.concatenate([np.arange(W - k, W), np.arange(W), np.arange(k)])
    Uu = U[idx]
    n = len(idx)
    fwd = np.empty((n, S))
    back = np.zeros((n, S), np.int64)
    fwd[0] = Uu[0]
    for t in range(1, n):
        prev = fwd[t - 1]
        j = int(np.argmin(prev))
        jump = prev[j] + switch_cost
        stay = prev <= jump
        fwd[t] = Uu[t] + np.where(stay, prev, jump)
        back[t] = np.where(stay, np.arange(S), j)
    bwd = np.zeros((n, S))
    for t in range(n - 2, -1, -1):
        nxt = bwd[t + 1] + Uu[t + 1]
        bwd[t] = np.minimum(nxt, nxt.min() + switch_cost)
    path = np.empty(n, np.int64)
    path[-1] = int(np.argmin(fwd[-1]))
    for t in range(n - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    total = (fwd + bwd).reshape(n, 2, -1).min(axis=2)  # best path cost through each orientation
    mid = slice(k, k + W)
    state = path[mid]
    orient = state // len(grid)
    margin = np.abs(total[mid, 0] - total[mid, 1])
    return {"wall_label": np.where(orient == 0, np.uint8(WALL_X), np.uint8(WALL_Y)).astype(np.uint8),
            "confidence": np.tanh(0.5 * margin),
            "distance": np.exp(grid[state % len(grid)]),
            "ceiling_ratio": ratio}


def fuse_surfaces(gc_probs: ArrayLike, om: OrientationMap, axes: ArrayLike | None = None,
                  object_mask: ArrayLike | None = None, *, min_confidence: float = 0.5,
                  om_weight: float = _OM_WEIGHT, shape_weight: float = _SHAPE_WEIGHT,
                  switch_cost: float = _SWITCH_COST,
                  warnings: tuple[str, ...] = (), empty_room_rows: ArrayLike | None = None) -> SurfaceLabels:
    """Fuse geometric context and an orientation map into surface labels (steps 2, 4, 5 of the module docstring).

    Parameters
    ----------
    gc_probs : (H, W, 4) float
        GC probabilities at the panorama's size.
    om : OrientationMap
        Of the same size.
    axes : (3, 3) float, optional
        Manhattan directions (rows x, y, up) in the panorama frame; identity
        when omitted. ``up`` must be the panorama's vertical.
    object_mask : (H, W) bool, optional
        Object regions: labelled 5, and clutter for the boundaries.
    min_confidence : float
        Below this, a pixel the OM does not confirm is unknown.
    om_weight, shape_weight, switch_cost : float
        Weights of the OM votes and of the boundary shape, and the cost of a
        change of wall, in the orientation chain (:func:`column_orientation`).
    warnings : tuple of str
        Carried into the result.
    empty_room_rows : (2, W) float, optional
        Ceiling and floor boundary rows of the empty room in every column
        (e.g. the boundary network's, :mod:`layout.surfaces.boundary_net`):
        the orientation chain reads the walls' shape from them, at full
        weight in every column, instead of from GC's boundaries (which are
        weighted by how clean they are). The labels' own boundaries still
        come from GC.

    Returns
    -------
    SurfaceLabels
    """
    P = np.asarray(gc_probs, dtype=np.float32)
    if P.ndim != 3 or P.shape[2] != 4 or P.shape[1] != 2 * P.shape[0]:
        raise ValueError(f"gc_probs: expected (H, W, 4) with W == 2*H, got shape {P.shape}")
    H, W = P.shape[:2]
    if not isinstance(om, OrientationMap) or om.labels.shape != (H, W):
        raise ValueError(f"om: expected an OrientationMap of shape {(H, W)}, got "
                         f"{getattr(getattr(om, 'labels', None), 'shape', type(om).__name__)}")
    A = _upright_axes(axes)
    obj = pixel_mask(object_mask, (H, W), "object_mask")
    # 2. column boundaries
    ceil_v, floor_v = column_boundaries(P, obj)
    return _fuse(P, om, A, obj, ceil_v, floor_v, min_confidence=min_confidence, om_weight=om_weight,
                 shape_weight=shape_weight, switch_cost=switch_cost, warnings=warnings,
                 empty_room_rows=empty_room_rows)


def _fuse(P: NDArray[np.float32], om: OrientationMap, A: NDArray[np.float64], obj: NDArray[np.bool_] | None,
          ceil_v: NDArray[np.float64], floor_v: NDArray[np.float64], *, min_confidence: float, om_weight: float,
          shape_weight: float, switch_cost: float, warnings: tuple[str, ...],
          empty_room_rows: ArrayLike | None) -> SurfaceLabels:
    """Steps 4 and 5 of :func:`fuse_surfaces` on checked inputs and GC's column boundaries (step 2)."""
    H, W = P.shape[:2]
    warn = list(warnings)
    rows = np.arange(H)[:, None]
    gc_arg = np.argmax(P, axis=2)
    if obj is not None:
        gc_arg = np.where(obj, GC_CLUTTER, gc_arg)
    band = max(2, H // 64)
    ci, fi = ceil_v.astype(np.int64), floor_v.astype(np.int64)
    is_wall = (gc_arg == GC_WALL).astype(np.float64)
    # a boundary is clean where GC's decisions on both sides of it agree with it
    cw = _band_mean((gc_arg == GC_CEILING).astype(np.float64), ci - band, ci) * _band_mean(is_wall, ci, ci + band)
    fw = _band_mean((gc_arg == GC_FLOOR).astype(np.float64), fi, fi + band) * _band_mean(is_wall, fi - band, fi)
    # 4. wall orientation per column
    u = np.arange(W) + 0.5
    lon = pixel_to_lonlat(np.stack([u, np.full(W, H / 2.0)], axis=-1), W, H)[:, 0]
    dirs = np.stack([np.cos(lon), -np.sin(lon), np.zeros(W)], axis=-1) @ A.T
    psi = np.arctan2(dirs[:, 1], dirs[:, 0])
    def lat_of(v):  # row -> latitude, from panogeom.coords
        v = np.asarray(v, dtype=np.float64)
        return pixel_to_lonlat(np.stack([np.zeros_like(v), v], axis=-1), W, H)[..., 1]

    in_band = (rows >= ci[None, :]) & (rows < fi[None, :])
    if obj is not None:
        in_band &= ~obj
    n_band = np.maximum(in_band.sum(axis=0), 1)
    om_x = ((om.labels == WALL_X) & in_band).sum(axis=0) / n_band
    om_y = ((om.labels == WALL_Y) & in_band).sum(axis=0) / n_band
    if empty_room_rows is None:
        shape_c, shape_f, shape_cw, shape_fw = ceil_v, floor_v, cw, fw
    else:
        rb = np.asarray(empty_room_rows, dtype=np.float64)
        if rb.shape != (2, W) or not np.all(np.isfinite(rb)):
            raise ValueError(f"empty_room_rows: expected finite (2, {W}) rows, got shape {rb.shape}")
        shape_c, shape_f, shape_cw, shape_fw = rb[0], rb[1], np.ones(W), np.ones(W)
    col = column_orientation(psi, lat_of(shape_f), lat_of(shape_c), shape_fw, shape_cw, om_x, om_y, height=H,
                             om_weight=om_weight, shape_weight=shape_weight, switch_cost=switch_cost)
    if not np.isfinite(col["ceiling_ratio"]):
        warn.append("fewer than 8 columns show both a clean ceiling and a clean floor boundary: wall orientation "
                    "from the floor boundary and the orientation map only")
    # boundaries predicted by each column's fitted wall (fill what clutter hides)
    trig = np.where(col["wall_label"] == WALL_X, np.abs(np.cos(psi)), np.abs(np.sin(psi)))
    t_model = np.maximum(trig, 1e-3) / col["distance"]
    model_floor_v = (np.pi / 2 + np.arctan(t_model)) * H / np.pi
    ratio = col["ceiling_ratio"] if np.isfinite(col["ceiling_ratio"]) else np.nan
    model_ceil_v = (np.pi / 2 - np.arctan(ratio * t_model)) * H / np.pi if np.isfinite(ratio) else ceil_v.copy()
    lay_floor = np.where(fw >= 0.5, floor_v, np.clip(model_floor_v, H / 2, H))
    lay_ceil = np.where(cw >= 0.5, ceil_v, np.clip(model_ceil_v, 0, H / 2))
    wall_lab = col["wall_label"]
    v_c = rows + 0.5
    layout = np.where(v_c > lay_floor[None, :], np.uint8(FLOOR),
                      np.where(v_c < lay_ceil[None, :], np.uint8(CEILING), wall_lab[None, :])).astype(np.uint8)
    # 5. per-pixel labels
    structure = np.where(rows >= fi[None, :], np.uint8(FLOOR),
                         np.where(rows < ci[None, :], np.uint8(CEILING), wall_lab[None, :])).astype(np.uint8)
    is_clutter = gc_arg == GC_CLUTTER
    p_class = np.where(structure == FLOOR, P[..., GC_FLOOR],
                       np.where(structure == CEILING, P[..., GC_CEILING],
                                P[..., GC_WALL] * col["confidence"][None, :].astype(np.float32)))
    om_agrees = om.labels == structure
    support = np.where(om_agrees, np.maximum(p_class, om.confidence), p_class).astype(np.float32)
    unsure = (p_class < min_confidence) & ~om_agrees
    labels = np.where(is_clutter | unsure, np.uint8(UNKNOWN), structure).astype(np.uint8)
    confidence = np.where(labels == UNKNOWN, np.float32(0.0), support).astype(np.float32)
    if obj is not None:
        labels[obj] = OBJECT
        confidence[obj] = 1.0
    columns = ColumnLayout(ceiling_v=ceil_v, floor_v=floor_v, ceiling_weight=cw, floor_weight=fw,
                           wall_label=wall_lab, confidence=col["confidence"], distance=col["distance"],
                           ceiling_ratio=float(col["ceiling_ratio"]), model_floor_v=model_floor_v,
                           model_ceiling_v=model_ceil_v)
    return SurfaceLabels(labels=labels, confidence=confidence, gc_probs=P, om=om.labels, warnings=tuple(warn),
                         layout=layout, columns=columns, om_confidence=om.confidence)


#: ``estimate_surfaces(ceiling_net=...)`` keeps the labels' ceiling boundary when the network's is farther from it
#: than this in the median column (rows of a 512-row map). The network moves a drifting minority of columns; in the
#: tuning sets' rooms the median gap is at most 5.4 (seed 7000) and 14.5 rows (one room of 60, seed 8000), median
#: 1.2 (the 14-epoch weights of session 19); on the two real photos the committed weights give 22.3 and 30.1
#: (docs/EVALUATION.md, "Session 19").
CEILING_NET_MAX_GAP_512 = 8.0


def _upright_axes(axes: ArrayLike | None) -> NDArray[np.float64]:
    A = np.eye(3) if axes is None else np.asarray(axes, dtype=np.float64)
    if A.shape != (3, 3) or not np.allclose(A @ A.T, np.eye(3), atol=1e-6) or np.linalg.det(A) < 0:
        raise ValueError(f"axes: expected a (3, 3) proper rotation (rows x, y, up), got {np.asarray(axes).tolist()}")
    if A[2, 2] < np.cos(np.deg2rad(1.0)):
        raise ValueError(f"axes: expected an upright panorama (up row within 1 deg of (0, 0, 1)), got up = "
                         f"{A[2].round(4).tolist()}; rectify it first (panogeom.rectify)")
    return A


def estimate_surfaces(pano: ArrayLike, segments: LineSegments | None = None, axes: ArrayLike | None = None,
                      object_mask: ArrayLike | None = None, object_boxes: ArrayLike | None = None, *,
                      gc: GeometricContext | None = None, om_width: int = 512,
                      min_confidence: float = 0.5, min_segments: int = 12,
                      snap_ceiling: bool = False, ceiling_net: BoundaryNet | bool | None = None) -> SurfaceLabels:
    """Per-pixel surface labels of an upright panorama: GC + OM, fused (paper Sec. 3.1).

    Parameters
    ----------
    pano : (H, W, 3) uint8, W == 2*H
        Rectified (upright) RGB panorama.
    segments : LineSegments, optional
        Its line segments, in its own frame (e.g. ``rect.segments.rotated(rect.rotation)``
        of a :class:`panogeom.rectify.Rectification`); detected with
        :func:`panogeom.lines.detect_line_segments` when omitted.
    axes : (3, 3) float, optional
        Manhattan directions (rows x, y, up) in the panorama frame; identity
        (a panorama rectified in ``"walls"`` mode) when omitted.
    object_mask : (H, W) bool, optional
        Object regions (masked out: label 5).
    object_boxes : (N, 4) float, optional
        Object boxes ``(u0, v0, u1, v1)`` (``u0 > u1`` wraps the seam), added
        to ``object_mask``.
    gc : GeometricContext, optional
        Default: the committed network (:func:`layout.surfaces.gc_net.load_gc_net`).
    om_width : int
        Raster width of the orientation map's sweeps.
    min_confidence : float
        See :func:`fuse_surfaces`.
    min_segments : int
        With fewer segments assigned to the Manhattan directions the OM is
        not used (a warning says so); the labels still come from GC and the
        boundary shape.
    snap_ceiling : bool
        Move the ceiling-wall boundary onto the strongest smooth image edge
        within a few rows (step 6 of the module docstring,
        :mod:`layout.surfaces.boundary`). Off by default.
    ceiling_net : BoundaryNet or bool, optional
        Move the ceiling-wall boundary onto the one regressed by the
        boundary network (:mod:`layout.surfaces.boundary_net`; ``True``: the
        committed weights) instead, unless the two are more than
        ``CEILING_NET_MAX_GAP_512`` rows apart in the median column (a
        warning then says the labels' boundary was kept, and GC's boundaries
        give the walls' shape). Where kept, its ceiling and floor boundaries
        are also the walls' shape evidence of the orientation chain
        (``fuse_surfaces(empty_room_rows=...)``). Not together with
        ``snap_ceiling``.

    Returns
    -------
    SurfaceLabels

    Examples
    --------
    A blank panorama has no lines: GC labels and a warning, no exception.

    >>> s = estimate_surfaces(np.full((128, 256, 3), 200, np.uint8))
    >>> s.labels.shape, s.gc_probs.shape, any("line segments" in w for w in s.warnings)
    ((128, 256), (128, 256, 4), True)
    """
    img = rgb_pano(pano)
    H, W = img.shape[:2]
    A = _upright_axes(axes)
    obj = pixel_mask(object_mask, (H, W), "object_mask")
    if object_boxes is not None and np.size(object_boxes):
        boxes = boxes_to_mask(object_boxes, W, H)
        obj = boxes if obj is None else (obj | boxes)
    if segments is None:
        from panogeom.lines import detect_line_segments

        segments = detect_line_segments(img)
    elif not isinstance(segments, LineSegments):
        raise ValueError(f"segments: expected panogeom.lines.LineSegments or None, got {type(segments).__name__}")
    warn: list[str] = []
    probs = (gc if gc is not None else load_gc_net())(img)
    om = orientation_map(segments, W, A, om_width=om_width)
    if int(om.n_segments.sum()) < min_segments or not om.usable:
        warn.append(f"no usable line segments ({len(segments)} found, {int(om.n_segments.sum())} along the Manhattan "
                    f"directions, need {min_segments}): orientation map not used, walls oriented from the "
                    f"floor and ceiling boundary shape")
        om = OrientationMap(labels=np.zeros((H, W), np.uint8), confidence=np.zeros((H, W), np.float32),
                            support=np.zeros((H, W, 3), np.float32), n_segments=om.n_segments)
    if snap_ceiling and ceiling_net:
        raise ValueError("snap_ceiling and ceiling_net: expected at most one way to move the ceiling boundary")
    net_v = None
    if ceiling_net:
        # step 6': the boundaries of the boundary network (layout.surfaces.boundary_net), kept where they are near
        # the labels' ceiling boundary
        from .boundary_net import load_boundary_net

        net = load_boundary_net() if ceiling_net is True else ceiling_net
        net_v = net(img)
    gc_ceil_v, gc_floor_v = column_boundaries(probs, obj)  # step 2 once: the network's check and the fusion
    if net_v is not None:
        gap = float(np.median(np.abs(net_v[0] - gc_ceil_v))) * 512.0 / H
        if not gap <= CEILING_NET_MAX_GAP_512:
            warn.append(f"boundary network: its ceiling-wall boundary is {gap:.1f} rows (of 512) from the labels' in "
                        f"the median column (at most {CEILING_NET_MAX_GAP_512:g} expected): the panorama looks "
                        f"unlike its training rooms, the labels' boundary is kept")
            net_v = None
    fused = _fuse(np.asarray(probs, dtype=np.float32), om, A, obj, gc_ceil_v, gc_floor_v,
                  min_confidence=min_confidence, om_weight=_OM_WEIGHT, shape_weight=_SHAPE_WEIGHT,
                  switch_cost=_SWITCH_COST,
                  warnings=tuple(warn), empty_room_rows=net_v)
    if net_v is None and not snap_ceiling:
        return fused
    cols = fused.columns
    if net_v is not None:
        new_v = net_v[0]
    else:
        # step 6: the ceiling-wall boundary moved onto the image's edge (layout.surfaces.boundary)
        new_v = ceiling_edge_path(edge_strength(img, fused.labels.shape), cols.ceiling_v)
    return replace(fused, labels=move_ceiling_boundary(fused.labels, new_v, cols.wall_label),
                   layout=move_ceiling_boundary(fused.layout, new_v, cols.wall_label),
                   columns=replace(cols, ceiling_v=new_v))
