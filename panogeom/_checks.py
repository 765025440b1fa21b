"""Input checks shared by panogeom's public functions.

Every public function of the toolkit validates what it is given and raises a
``ValueError`` that says what was expected and what came (STYLE.md, rule 7).
The helpers here keep those messages uniform.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def float_array(x: ArrayLike, name: str, last: int | None = None, finite: bool = True) -> NDArray[np.float64]:
    """Return ``x`` as a float64 array, checking its last axis and finiteness.

    Parameters
    ----------
    x : array_like
    name : str
        Argument name used in the error message.
    last : int, optional
        Required size of the last axis (coordinates live on the last axis).
    finite : bool
        Reject NaN and inf.
    """
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a numeric array, got {type(x).__name__}") from exc
    if last is not None and (a.ndim == 0 or a.shape[-1] != last):
        raise ValueError(f"{name}: expected an array of shape (..., {last}), got {a.shape}")
    if finite and a.size and not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got NaN or inf")
    return a


def pano_size(width: int, height: int) -> tuple[int, int]:
    """Check an equirectangular size (W, H) and return it as ints.

    Convention: W == 2*H (CONVENTIONS.md, "Panorama pixels").
    """
    try:
        w, h = int(width), int(height)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"panorama size: expected integers, got width={width!r}, height={height!r}") from exc
    if w <= 0 or h <= 0 or w != width or h != height:
        raise ValueError(f"panorama size: expected positive integers, got width={width!r}, height={height!r}")
    if w != 2 * h:
        raise ValueError(f"panorama size: expected W == 2*H, got W={w}, H={h}")
    return w, h


def pano_image(image: ArrayLike, name: str = "image") -> np.ndarray:
    """Check an equirectangular image: (H, W) or (H, W, C) with W == 2*H.

    Accepts uint8, uint16 and float dtypes with 1, 3 or 4 channels; returns the
    array unchanged (no copy) when valid.
    """
    img = np.asarray(image)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3, 4)):
        raise ValueError(f"{name}: expected (H, W) or (H, W, C) with C in (1, 3, 4), got shape {img.shape}")
    if img.dtype.kind not in "uif" or img.dtype == np.bool_:
        raise ValueError(f"{name}: expected an integer or float dtype, got {img.dtype}")
    h, w = img.shape[:2]
    if h == 0 or w != 2 * h:
        raise ValueError(f"{name}: expected an equirectangular panorama with W == 2*H, got {w}x{h} (shape {img.shape})")
    return img


def positive_size(size: tuple[int, int] | int, name: str) -> tuple[int, int]:
    """Return ``(height, width)`` from an int or a pair, both > 0."""
    if np.isscalar(size):
        size = (size, size)  # type: ignore[assignment]
    try:
        h, w = (int(s) for s in size)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected an int or a (height, width) pair, got {size!r}") from exc
    if h <= 0 or w <= 0:
        raise ValueError(f"{name}: expected a positive size, got {size!r}")
    return h, w
