"""Input checks shared by the surface-labelling modules (STYLE.md rule 7)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def rgb_pano(pano: ArrayLike, name: str = "pano") -> NDArray[np.uint8]:
    """Check an RGB equirectangular panorama: (H, W, 3) uint8 with W == 2*H.

    Examples
    --------
    >>> rgb_pano(np.zeros((4, 8, 3), np.uint8)).shape
    (4, 8, 3)
    >>> rgb_pano(np.zeros((4, 4, 3), np.uint8))
    Traceback (most recent call last):
    ...
    ValueError: pano: expected (H, W, 3) uint8 with W == 2*H, got shape (4, 4, 3) dtype uint8
    """
    img = np.asarray(pano)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8 or img.shape[0] < 2 \
            or img.shape[1] != 2 * img.shape[0]:
        raise ValueError(f"{name}: expected (H, W, 3) uint8 with W == 2*H, got shape {img.shape} dtype {img.dtype}")
    return img


def pixel_mask(mask: ArrayLike | None, shape: tuple[int, int], name: str) -> NDArray[np.bool_] | None:
    """Check an optional (H, W) boolean (or 0/1 integer) mask of a given shape."""
    if mask is None:
        return None
    m = np.asarray(mask)
    if m.shape != tuple(shape):
        raise ValueError(f"{name}: expected shape {tuple(shape)} (the panorama's H, W), got {m.shape}")
    if m.dtype != np.bool_:
        if m.dtype.kind not in "ui" or (m.size and (m.min() < 0 or m.max() > 1)):
            raise ValueError(f"{name}: expected a boolean mask (or 0/1 integers), got dtype {m.dtype}")
        m = m.astype(bool)
    return m
