"""Reading and checking panoramas given by users.

Accepted: any file Pillow reads (JPEG, PNG, WebP, TIFF, ...) in grayscale,
RGB, RGBA, palette or 16-bit form - converted to RGB uint8. Rejected with a
:class:`~apps.errors.UserError` naming the file: a missing or unreadable file,
a corrupt image, an image that is not equirectangular (width != 2*height).
Very large panoramas are decoded at reduced size (JPEG draft mode) and
downscaled to the working width, so a 9000x4500 input stays far below 4 GB.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import UserError

# A decompression bomb guard that still allows 16k x 8k panoramas.
_MAX_PIXELS = 16384 * 8192 + 1


@dataclass(frozen=True)
class Panorama:
    """A panorama read from disk.

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB, W == 2*H, at the working resolution
    path : Path
    original_size : (width, height) of the file
    """

    image: np.ndarray
    path: Path
    original_size: tuple[int, int]

    @property
    def width(self) -> int:
        return int(self.image.shape[1])

    @property
    def height(self) -> int:
        return int(self.image.shape[0])


def _to_rgb8(img) -> np.ndarray:
    """Pillow image of any mode -> (H, W, 3) uint8."""
    mode = img.mode
    if mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        a = np.asarray(img, dtype=np.float64)
        hi = 65535.0 if mode.startswith("I;16") or a.max() > 255 else 255.0
        a = np.clip(a / hi * 255.0 + 0.5, 0, 255).astype(np.uint8)
        return np.repeat(a[..., None], 3, axis=2)
    if mode == "RGBA" or mode == "LA" or (mode == "P" and "transparency" in img.info):
        rgba = img.convert("RGBA")
        a = np.asarray(rgba, dtype=np.float32)
        alpha = a[..., 3:4] / 255.0
        # Composite on mid-grey: transparent regions carry no information.
        rgb = a[..., :3] * alpha + 128.0 * (1.0 - alpha)
        return np.clip(rgb + 0.5, 0, 255).astype(np.uint8)
    return np.asarray(img.convert("RGB"), dtype=np.uint8)


def read_panorama(path: str | os.PathLike[str], max_width: int | None = None) -> Panorama:
    """Read a panorama, convert it to RGB uint8 and downscale it to at most ``max_width``.

    Parameters
    ----------
    path : path to an image file
    max_width : int, optional
        Working width; larger panoramas are resampled (area filter) to it.

    Raises
    ------
    UserError
        Missing file, unreadable or corrupt image, or not equirectangular.
    """
    from PIL import Image, UnidentifiedImageError

    p = Path(path)
    if not p.exists():
        raise UserError(f"{p}: no such file")
    if p.is_dir():
        raise UserError(f"{p}: is a folder, expected an image file")
    Image.MAX_IMAGE_PIXELS = _MAX_PIXELS
    try:
        with Image.open(p) as img:
            w0, h0 = img.size
            if w0 != 2 * h0:
                raise UserError(f"{p}: expected an equirectangular panorama with width == 2*height, got {w0}x{h0}")
            if max_width is not None and img.format == "JPEG" and w0 > 2 * max_width:
                img.draft("RGB", (max_width, max_width // 2))
            img.load()
            rgb = _to_rgb8(img)
    except UserError:
        raise
    except Image.DecompressionBombError as exc:
        raise UserError(f"{p}: image too large ({exc})") from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise UserError(f"{p}: cannot read the image ({type(exc).__name__}: {exc})") from None
    h, w = rgb.shape[:2]
    if w != 2 * h:
        # Draft decoding keeps the aspect ratio up to a pixel; re-fit exactly.
        w = 2 * h
    if max_width is not None and (w > max_width or rgb.shape[1] != w):
        import cv2

        tw = min(int(max_width), w)
        tw -= tw % 2
        rgb = cv2.resize(rgb, (tw, tw // 2), interpolation=cv2.INTER_AREA)
    return Panorama(image=np.ascontiguousarray(rgb), path=p, original_size=(w0, h0))
