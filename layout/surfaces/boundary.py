"""The ceiling-wall boundary snapped to the image's edges: a Viterbi path across the columns.

The geometric-context network places the ceiling-wall boundary of each
column from its probabilities alone. In dark, evenly lit rooms the ceiling
label creeps down a shadowed wall or the wall label climbs a dark ceiling,
although the image still shows the junction as a step of grey level
(docs/EVALUATION.md, "Sessions 13-15 on the tuning sets"). The room step
reads each wall's distance from this boundary first, so it is worth moving
onto the edge:

- per column, every row within ``band`` rows of the labeller's boundary is
  a candidate, scored by the vertical grey-level step of the (slightly
  blurred) panorama at that row;
- a Viterbi pass across the columns pays ``jump_cost`` per row the boundary
  moves between neighbouring columns (a boundary is a smooth curve except at
  the room's corners, where the price is paid once); where the image shows
  no edge the path therefore runs level within the band rather than along
  the labeller's curve (ties go to the labeller's row);
- the labels are then moved to the path: wall pixels above it become
  ceiling, ceiling pixels below it (above the horizon) take the column's
  wall label. Floor, clutter, unknown and object pixels are left alone.

Convention: rows ``v`` are continuous pixel coordinates of the label map; a
boundary between rows ``k - 1`` and ``k`` is at ``v = k`` (as
:mod:`layout.surfaces.fusion`). The panorama is upright; the horizon is row
``H / 2``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.raycast import LABEL_CEILING as CEILING
from panogeom.raycast import LABEL_WALL_X as WALL_X
from panogeom.raycast import LABEL_WALL_Y as WALL_Y

from ._checks import rgb_pano

__all__ = ["edge_strength", "ceiling_edge_path", "move_ceiling_boundary"]

#: Search band, in rows of a 512-row label map (scaled with the height).
BAND_ROWS_512 = 20
#: Price of a one-row step of the boundary between neighbouring columns, in units of grey-level step (0..1).
JUMP_COST = 0.008
#: Price per row away from the labeller's boundary: only breaks ties (an image without edges keeps the labels).
TIE_COST = 1e-6


def edge_strength(pano: ArrayLike, shape: tuple[int, int], sigma: float = 0.8) -> NDArray[np.float64]:
    """Vertical grey-level step of a panorama, at the label map's resolution.

    Parameters
    ----------
    pano : (H0, W0, 3) uint8
        The panorama the labels were computed on.
    shape : (H, W)
        Shape of the label map.
    sigma : float
        Gaussian blur, in label-map pixels, before the step is taken.

    Returns
    -------
    (H, W) float
        ``|g[v] - g[v - 1]|`` of the grey levels ``g`` in [0, 1]: the edge
        strength of a boundary at row ``v`` (0 in row 0).
    """
    import cv2

    h, w = int(shape[0]), int(shape[1])
    img = rgb_pano(pano)
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    if gray.shape != (h, w):
        gray = cv2.resize(gray, (w, h), interpolation=cv2.INTER_AREA)
    g = gray.astype(np.float64) / 255.0
    if sigma > 0:
        g = cv2.GaussianBlur(g, (0, 0), sigmaX=sigma, sigmaY=sigma, borderType=cv2.BORDER_REPLICATE)
    out = np.zeros_like(g)
    out[1:] = np.abs(np.diff(g, axis=0))
    return out


def ceiling_edge_path(edges: ArrayLike, ceiling_v: ArrayLike, *, band: int | None = None,
                      jump_cost: float = JUMP_COST) -> NDArray[np.float64]:
    """Rows of the ceiling-wall boundary along the strongest smooth edge near the labeller's boundary.

    Parameters
    ----------
    edges : (H, W) float
        Edge strength of a boundary at each row (:func:`edge_strength`).
    ceiling_v : (W,) float
        The labeller's ceiling-wall boundary per column (continuous rows,
        above the horizon ``H / 2``); NaN where it has none (the band then
        follows the neighbouring columns).
    band : int, optional
        Rows searched on each side (default ``BAND_ROWS_512 * H / 512``).
    jump_cost : float
        Price per row of change between neighbouring columns.

    Returns
    -------
    (W,) float
        Integer rows in ``[1, H / 2 - 1]`` (as floats).

    Examples
    --------
    >>> e = np.zeros((64, 128)); e[20] = 1.0
    >>> ceiling_edge_path(e, np.full(128, 17.0), band=5)[:3]
    array([20., 20., 20.])
    """
    e = np.asarray(edges, dtype=np.float64)
    cv = np.asarray(ceiling_v, dtype=np.float64)
    if e.ndim != 2 or cv.shape != (e.shape[1],):
        raise ValueError(f"edges (H, W) and ceiling_v (W,) expected, got {e.shape} and {cv.shape}")
    h, w = e.shape
    band = max(1, round(BAND_ROWS_512 * h / 512)) if band is None else int(band)
    ok = np.isfinite(cv)
    if not ok.any():
        return np.full(w, np.nan)
    centre = cv if ok.all() else np.interp(np.arange(w), np.flatnonzero(ok), cv[ok], period=w)
    offsets = np.arange(-band, band + 1)
    rows = np.clip(np.round(centre)[None, :] + offsets[:, None], 1, h // 2 - 1).astype(np.intp)  # (K, W)
    score = e[rows, np.arange(w)[None, :]] - TIE_COST * np.abs(offsets)[:, None]
    k = offsets.size
    acc = score[:, 0].copy()
    back = np.zeros((k, w), dtype=np.intp)
    cost = float(jump_cost)
    for c in range(1, w):
        # (K to, K from): the path's value so far minus the price of the step between the two rows
        m = acc[None, :] - cost * np.abs(rows[:, c, None] - rows[None, :, c - 1])
        back[:, c] = np.argmax(m, axis=1)
        acc = m[np.arange(k), back[:, c]] + score[:, c]
    path = np.empty(w, dtype=np.intp)
    path[-1] = int(np.argmax(acc))
    for c in range(w - 1, 0, -1):
        path[c - 1] = back[path[c], c]
    return rows[path, np.arange(w)].astype(np.float64)


def move_ceiling_boundary(labels: ArrayLike, new_v: ArrayLike, wall_label: ArrayLike) -> NDArray[np.uint8]:
    """Labels with each column's ceiling-wall boundary moved to ``new_v``.

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels (CONVENTIONS.md ids).
    new_v : (W,) float
        New boundary rows in continuous pixel coordinates (the boundary
        between pixel rows k - 1 and k is at k, as
        :mod:`layout.surfaces.boundary_net` gives them; NaN: column left
        alone).
    wall_label : (W,) uint8
        The column's wall label (3 or 4), given to ceiling pixels that end
        up below the boundary; other values leave those pixels alone.

    Returns
    -------
    (H, W) uint8
        Wall pixels (3, 4) whose centre (row + 0.5) lies above ``new_v``
        become ceiling; ceiling pixels whose centre lies below it, down to
        the horizon, take ``wall_label``; every other pixel is unchanged.
        A pixel is on the side of its centre, as in
        :meth:`layout.labelmap.LabelCounts.agreement` (until session 36 a
        pixel row r was ceiling for any ``r < new_v``: the boundary rounded
        up, half a row low on average).

    Examples
    --------
    >>> lab = np.full((8, 1), 3, np.uint8); lab[:2] = 2
    >>> move_ceiling_boundary(lab, np.array([3.4]), np.array([3]))[:4, 0].tolist()
    [2, 2, 2, 3]
    >>> move_ceiling_boundary(lab, np.array([3.6]), np.array([3]))[:4, 0].tolist()
    [2, 2, 2, 2]
    """
    lab = np.array(labels, dtype=np.uint8, copy=True)
    if lab.ndim != 2:
        raise ValueError(f"labels: expected (H, W), got shape {lab.shape}")
    v = np.asarray(new_v, dtype=np.float64)
    wl = np.asarray(wall_label)
    h, w = lab.shape
    if v.shape != (w,) or wl.shape != (w,):
        raise ValueError(f"new_v and wall_label: expected ({w},), got {v.shape} and {wl.shape}")
    centres = np.arange(h)[:, None] + 0.5
    rows = np.arange(h)[:, None]
    ok = np.isfinite(v)
    above = (centres < np.where(ok, v, -1.0)[None, :]) & ok[None, :]
    lab[above & ((lab == WALL_X) | (lab == WALL_Y))] = CEILING
    fill = ok & np.isin(wl, (WALL_X, WALL_Y))
    below = ~above & (rows < h // 2) & (lab == CEILING) & fill[None, :]
    lab[below] = np.broadcast_to(wl.astype(np.uint8)[None, :], lab.shape)[below]
    return lab
