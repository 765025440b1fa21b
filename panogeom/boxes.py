"""Seam-aware pixel boxes of regions in a panorama.

Convention: a panorama box is ``(u0, v0, u1, v1)`` in continuous pixel
coordinates (pixel centres at integer + 0.5, so a single pixel ``(i, j)``
has the box ``(j, i, j + 1, i + 1)``); ``u0 > u1`` means the box wraps the
left/right seam (CONVENTIONS.md, scene.json ``bbox_pano``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["mask_to_pano_box", "box_width"]


def mask_to_pano_box(mask: ArrayLike) -> NDArray[np.float64]:
    """Smallest seam-aware box around the True pixels of a panorama mask.

    The box spans the occupied columns by the shortest way round: where the
    occupied columns leave their largest gap, the box starts after it. A mask
    that occupies every column spans ``u0 = 0, u1 = W``.

    Parameters
    ----------
    mask : (H, W) bool

    Returns
    -------
    box : (4,) float
        ``(u0, v0, u1, v1)``, ``u0 > u1`` when it wraps the seam.

    Raises
    ------
    ValueError
        If the mask is not 2-D or has no True pixel.

    Examples
    --------
    >>> m = np.zeros((4, 8), bool); m[1, [0, 7]] = True
    >>> mask_to_pano_box(m)
    array([7., 1., 1., 2.])
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask: expected a (H, W) boolean array, got shape {m.shape}")
    rows = np.flatnonzero(m.any(axis=1))
    cols = np.flatnonzero(m.any(axis=0))
    if cols.size == 0:
        raise ValueError("mask: expected at least one True pixel, got an empty mask")
    w = m.shape[1]
    v0, v1 = float(rows[0]), float(rows[-1] + 1)
    if cols.size == w:
        return np.array([0.0, v0, float(w), v1])
    # Gaps between consecutive occupied columns, the wrap-around gap included.
    nxt = np.roll(cols, -1)
    gaps = np.mod(nxt - cols, w)
    gaps[gaps == 0] = w
    k = int(np.argmax(gaps))
    start, end = int(nxt[k]), int(cols[k])  # box runs from `start` round to `end`
    # Wrapping or not, the box is [start, end + 1): u0 > u1 exactly when it crosses the seam.
    return np.array([float(start), v0, float(end + 1), v1])


def box_width(box: ArrayLike, width: int) -> float:
    """Horizontal extent in pixels of a (possibly wrapping) panorama box."""
    b = np.asarray(box, dtype=np.float64)
    if b.shape != (4,):
        raise ValueError(f"box: expected (u0, v0, u1, v1), got shape {b.shape}")
    return float(b[2] - b[0]) if b[2] >= b[0] else float(b[2] + width - b[0])
