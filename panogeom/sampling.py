"""Sampling an equirectangular image at arbitrary continuous pixel coordinates.

Every resampling in panogeom (perspective views, cubemaps, rotation of a
panorama) goes through :func:`sample_equirect` (or its precomputed form
:class:`EquirectSampler`, for repeated geometry), which is correct across the
left/right seam and across the poles: the panorama is padded by one pixel on
each side with its wrapped columns, and by one row above and below with the
row seen across the pole (shifted by half the width), then sampled with
``cv2.remap``.

Convention: continuous pixel coordinates with centres at integer + 0.5
(CONVENTIONS.md); OpenCV's remap puts centres at integers, hence the 0.5 shift
done here and nowhere else.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from ._checks import float_array, pano_image, pano_size

__all__ = ["sample_equirect", "pad_equirect", "EquirectSampler"]

Interp = Literal["linear", "nearest", "cubic"]

# OpenCV's remap indexes with 16-bit integers internally; stay clear of that limit.
_MAX_REMAP_SIZE = 32000


def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("panogeom resampling needs OpenCV: pip install opencv-contrib-python-headless") from exc
    return cv2


def _flags() -> dict[str, int]:
    cv2 = _cv2()
    return {"linear": cv2.INTER_LINEAR, "nearest": cv2.INTER_NEAREST, "cubic": cv2.INTER_CUBIC}


def _pad_width(interpolation: str) -> int:
    return 2 if interpolation == "cubic" else 1


def pad_equirect(image: np.ndarray, pad: int = 1) -> np.ndarray:
    """Pad a panorama by ``pad`` pixels with seam- and pole-correct content.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array with W == 2*H
    pad : int
        Border width in pixels (>= 1, < H).

    Returns
    -------
    padded : (H + 2*pad, W + 2*pad[, C]) array
        Columns wrap around the seam; the rows above the top (below the
        bottom) are the first (last) rows mirrored and rotated by W/2, i.e.
        what lies across the pole.

    Examples
    --------
    >>> pano = np.arange(8 * 4).reshape(4, 8)
    >>> pad_equirect(pano)[0, 1:9].tolist()   # row 0 seen across the north pole
    [4, 5, 6, 7, 0, 1, 2, 3]
    """
    img = pano_image(image)
    h, w = img.shape[:2]
    if int(pad) != pad or not 1 <= pad < h:
        raise ValueError(f"pad: expected an integer 1 <= pad < H={h}, got {pad!r}")
    pad = int(pad)
    out = np.empty((h + 2 * pad, w + 2 * pad) + img.shape[2:], dtype=img.dtype)
    out[pad:pad + h, pad:pad + w] = img
    out[:pad, pad:pad + w] = np.roll(img[pad - 1::-1], w // 2, axis=1)
    out[pad + h:, pad:pad + w] = np.roll(img[h - 1:h - pad - 1:-1], w // 2, axis=1)
    out[:, :pad] = out[:, w:w + pad]
    out[:, pad + w:] = out[:, pad:2 * pad]
    return out


@dataclass(frozen=True, eq=False)
class EquirectSampler:
    """Precomputed ``cv2.remap`` maps that sample W x H panoramas at fixed coordinates.

    Build it once with :meth:`from_uv` and call it on any number of panoramas
    of that size (the cubemap and perspective functions cache one per output
    geometry, so repeated calls skip the trigonometry).

    Attributes
    ----------
    width, height : int
        Size of the panoramas it samples (W == 2*H).
    interpolation : {"linear", "nearest", "cubic"}
    pad : int
        Border added by :func:`pad_equirect` before remapping.
    map_x, map_y : (h, w) float32
        Remap coordinates into the padded panorama (OpenCV convention: pixel
        centres at integers).

    Convention: continuous pixel coordinates with centres at integer + 0.5
    (CONVENTIONS.md); the maps hold them shifted by ``pad - 0.5``.
    """

    width: int
    height: int
    interpolation: Interp
    pad: int
    map_x: np.ndarray
    map_y: np.ndarray

    @classmethod
    def from_uv(cls, uv: ArrayLike, width: int, height: int, interpolation: Interp = "linear") -> "EquirectSampler":
        """Maps that sample a ``width`` x ``height`` panorama at ``uv``.

        Parameters
        ----------
        uv : (h, w, 2) float
            Continuous pixel coordinates; u is wrapped, v clamped to [0, H].
        width, height : int
            Panorama size, W == 2*H.
        interpolation : {"linear", "nearest", "cubic"}
        """
        w, h = pano_size(width, height)
        if interpolation not in _flags():
            raise ValueError(f"interpolation: expected one of {sorted(_flags())}, got {interpolation!r}")
        uv = float_array(uv, "uv", last=2)
        if uv.ndim != 3:
            raise ValueError(f"uv: expected shape (h, w, 2), got {uv.shape}")
        if uv.shape[0] > _MAX_REMAP_SIZE or uv.shape[1] > _MAX_REMAP_SIZE or w + 4 > _MAX_REMAP_SIZE:
            raise ValueError(f"uv: expected sizes below {_MAX_REMAP_SIZE} (OpenCV remap), got {uv.shape[:2]} "
                             f"for a {w}x{h} panorama")
        pad = _pad_width(interpolation)
        u = np.mod(uv[..., 0], w)
        if interpolation == "nearest":
            # OpenCV rounds to the nearest integer centre; floor of the continuous coordinate is the pixel.
            map_x = np.floor(u) + pad
            map_y = np.floor(np.clip(uv[..., 1], 0.0, h - 1e-9)) + pad
        else:
            map_x = u - 0.5 + pad
            map_y = np.clip(uv[..., 1], 0.0, h) - 0.5 + pad
        map_x = np.ascontiguousarray(map_x, dtype=np.float32)
        map_y = np.ascontiguousarray(map_y, dtype=np.float32)
        map_x.setflags(write=False)
        map_y.setflags(write=False)
        return cls(width=w, height=h, interpolation=interpolation, pad=pad, map_x=map_x, map_y=map_y)

    @property
    def shape(self) -> tuple[int, int]:
        """(h, w) of the sampled output."""
        return self.map_x.shape  # type: ignore[return-value]

    def __call__(self, image: ArrayLike) -> np.ndarray:
        """Sample ``image`` (H, W[, C]) at the stored coordinates -> (h, w[, C]), same dtype."""
        cv2 = _cv2()
        img = pano_image(image)
        if img.shape[:2] != (self.height, self.width):
            raise ValueError(f"image: expected a {self.width}x{self.height} panorama for this sampler, "
                             f"got {img.shape[1]}x{img.shape[0]}")
        src = img
        squeeze = False
        if src.ndim == 3 and src.shape[2] == 1:
            src, squeeze = src[..., 0], True
        if src.dtype not in (np.uint8, np.uint16, np.int16, np.float32, np.float64):
            src = src.astype(np.float32)
        padded = pad_equirect(src, self.pad)
        out = cv2.remap(padded, self.map_x, self.map_y, _flags()[self.interpolation],
                        borderMode=cv2.BORDER_REPLICATE)
        if out.dtype != img.dtype:
            out = out.astype(img.dtype)
        return out[..., None] if squeeze else out


def sample_equirect(image: ArrayLike, uv: ArrayLike, interpolation: Interp = "linear") -> np.ndarray:
    """Sample a panorama at continuous pixel coordinates.

    Parameters
    ----------
    image : (H, W) or (H, W, C) uint8, uint16 or float array, W == 2*H
    uv : (h, w, 2) float
        Coordinates to sample (u may lie outside [0, W): it is wrapped; v is
        clamped to [0, H]).
    interpolation : {"linear", "nearest", "cubic"}
        ``"nearest"`` for label images.

    Returns
    -------
    out : (h, w) or (h, w, C) array, same dtype as ``image``

    Convention: pixel centres at integer + 0.5, so ``uv = (j + 0.5, i + 0.5)``
    returns pixel ``image[i, j]`` exactly.

    Examples
    --------
    >>> pano = np.arange(8 * 4, dtype=np.float32).reshape(4, 8)
    >>> float(sample_equirect(pano, np.array([[[2.5, 1.5]]]))[0, 0])
    10.0
    """
    img = pano_image(image)
    h, w = img.shape[:2]
    return EquirectSampler.from_uv(uv, w, h, interpolation)(img)
