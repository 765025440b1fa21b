"""Whole-panorama transforms: rotating a panorama, and panoramas defined by a function of direction.

Convention: ``R`` is a proper 3x3 rotation that maps INPUT-camera-frame
directions into the OUTPUT frame (as ``camera.rotation`` of scene.json maps
the input camera frame into the world frame). The output pixel with ray ``d``
therefore shows what the input shows at ``R.T @ d``, and an input pixel with
ray ``d`` moves to the output pixel with ray ``R @ d``. Frames, pixels and
rays are those of CONVENTIONS.md (:mod:`panogeom.coords`).

Example: ``R = rot_z(a)`` turns the frame so that what the input saw at
``lon = 0`` appears at ``lon = -a`` (``a`` counter-clockwise seen from above,
towards +y, i.e. to the left in the image).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array, pano_image, pano_size
from .coords import pixel_grid_rays, pixel_to_ray, ray_to_pixel
from .rotation import check_rotation
from .sampling import Interp, sample_equirect

__all__ = ["rotate_pano", "rotate_pixels", "pano_from_directions", "procedural_pano"]

Array = NDArray[np.float64]


def rotate_pano(pano: ArrayLike, R: ArrayLike, interpolation: Interp = "linear") -> np.ndarray:
    """The panorama seen from a frame rotated by ``R``.

    Parameters
    ----------
    pano : (H, W[, C]) array, W == 2*H
    R : (3, 3) float
        Proper rotation mapping input-frame directions into the output frame.
    interpolation : {"linear", "nearest", "cubic"}
        ``"nearest"`` for label images.

    Returns
    -------
    out : (H, W[, C]) array, dtype of ``pano``
        ``out`` at the pixel of ray ``d`` samples ``pano`` at ray ``R.T @ d``
        (seam- and pole-correct, :func:`panogeom.sampling.sample_equirect`).

    Convention: ``R`` maps input-frame directions into the output frame, like
    scene.json's ``camera.rotation``: ``rotate_pano(pano, camera.rotation)``
    is the world-aligned (rectified) panorama.

    Examples
    --------
    >>> from panogeom.rotation import rot_z
    >>> pano = np.arange(4 * 8, dtype=np.float32).reshape(4, 8)
    >>> out = rotate_pano(pano, rot_z(2 * np.pi / 8))   # turn left by one column
    >>> bool(np.allclose(out, np.roll(pano, -1, axis=1)))
    True
    """
    img = pano_image(pano, "pano")
    Rm = check_rotation(R, "R")
    h, w = img.shape[:2]
    rays = pixel_grid_rays(w, h) @ Rm  # row vectors: (R.T @ d.T).T
    return sample_equirect(img, ray_to_pixel(rays, w, h), interpolation)


def rotate_pixels(uv: ArrayLike, R: ArrayLike, width: int, height: int, inverse: bool = False) -> Array:
    """Move panorama pixel coordinates through the rotation of :func:`rotate_pano`.

    Parameters
    ----------
    uv : (..., 2) float
        Pixel coordinates in the input panorama (or, with ``inverse``, in the
        output panorama).
    R : (3, 3) float
        Rotation from input frame to output frame.
    width, height : int
        Panorama size, W == 2*H.
    inverse : bool
        Map output pixels back into the input (uses ``R.T``).

    Returns
    -------
    uv : (..., 2) float, u wrapped into [0, W)
        Where the same scene direction lies in the other panorama.

    Convention: an input pixel with ray ``d`` moves to the output pixel with
    ray ``R @ d`` (pixels and rays as in :mod:`panogeom.coords`).

    Examples
    --------
    >>> from panogeom.rotation import rot_z
    >>> rotate_pixels([512.0, 256.0], rot_z(np.pi / 2), 1024, 512)   # lon 0 -> lon -pi/2
    array([256., 256.])
    """
    w, h = pano_size(width, height)
    Rm = check_rotation(R, "R")
    rays = pixel_to_ray(uv, w, h)
    return ray_to_pixel(rays @ (Rm if inverse else Rm.T), w, h)


def pano_from_directions(fn: Callable[[Array], ArrayLike], height: int,
                         rotation: ArrayLike | None = None) -> Array:
    """Evaluate a function of direction at the ray of every pixel centre.

    Parameters
    ----------
    fn : callable
        Takes unit rays ``(N, 3)`` and returns ``(N,)`` or ``(N, C)`` values.
    height : int
        Panorama height H; the width is 2*H.
    rotation : (3, 3) float, optional
        Evaluate in a frame rotated by ``R`` (same meaning as in
        :func:`rotate_pano`): the pixel with ray ``d`` gets ``fn(R.T @ d)``.

    Returns
    -------
    image : (H, 2H) or (H, 2H, C) float

    Examples
    --------
    >>> img = pano_from_directions(lambda d: d[:, 2], 4)   # z of each ray
    >>> img.shape, bool(img[0, 0] > 0 > img[-1, 0])
    ((4, 8), True)
    """
    if isinstance(height, (bool, np.bool_)) or not isinstance(height, (int, np.integer)) or height <= 0:
        raise ValueError(f"height: expected a positive integer (the output is (H, 2H)), got {height!r}")
    w, h = 2 * int(height), int(height)
    rays = pixel_grid_rays(w, h).reshape(-1, 3)
    if rotation is not None:
        rays = rays @ check_rotation(rotation)
    vals = float_array(fn(rays), "fn(rays)", finite=False)
    if vals.shape[0] != rays.shape[0] or vals.ndim not in (1, 2):
        raise ValueError(f"fn(rays): expected shape (N,) or (N, C) with N={rays.shape[0]}, got {vals.shape}")
    return vals.reshape((h, w) + vals.shape[1:])


def procedural_pano(height: int, seed: int = 0, rotation: ArrayLike | None = None) -> np.ndarray:
    """A smooth, band-limited synthetic RGB panorama for tests, examples and benchmarks.

    Each channel is a sum of low-frequency sinusoids of the ray direction
    (spatial frequencies up to 6 rad^-1, so it is smooth at any resolution of
    H >= 128), plus structure: dark soft lines along three great circles (the
    horizon, the meridian through lon = 0 and lon = pi crossing both poles and
    the seam, and a tilted one) and bright soft spots near the poles.

    Parameters
    ----------
    height : int
        H; the output is (H, 2H, 3).
    seed : int
        Seed of the random sinusoids.
    rotation : (3, 3) float, optional
        Render the pattern as seen from a frame rotated by ``R`` (see
        :func:`rotate_pano`): ``rotate_pano(procedural_pano(h), R)`` and
        ``procedural_pano(h, rotation=R)`` agree up to interpolation.

    Returns
    -------
    pano : (H, 2H, 3) uint8

    Examples
    --------
    >>> procedural_pano(32).shape
    (32, 64, 3)
    """
    rng = np.random.default_rng(seed)
    n_waves = 4
    freq = rng.normal(size=(3, n_waves, 3))
    freq *= rng.uniform(1.0, 6.0, size=(3, n_waves, 1)) / np.linalg.norm(freq, axis=-1, keepdims=True)
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(3, n_waves))
    amp = rng.uniform(8.0, 20.0, size=(3, n_waves))
    circles = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.6, -0.48, 0.64]])
    circles /= np.linalg.norm(circles, axis=1, keepdims=True)
    spots = np.array([[0.3, 0.2, 0.93], [-0.25, -0.3, -0.92]])
    spots /= np.linalg.norm(spots, axis=1, keepdims=True)
    sigma_line, sigma_spot = 0.03, 0.12

    def pattern(d: Array) -> Array:
        waves = np.sin(np.einsum("nk,wk->nw", d, freq.reshape(-1, 3)) + phase.reshape(-1))  # (N, 3 * n_waves)
        val = 128.0 + (waves * amp.reshape(-1)).reshape(-1, 3, n_waves).sum(axis=-1)
        lines = np.exp(-0.5 * ((d @ circles.T) / sigma_line) ** 2).sum(axis=1)
        spot = np.exp(-(1.0 - d @ spots.T) / (0.5 * sigma_spot ** 2)).sum(axis=1)
        val += (-45.0 * lines + 60.0 * spot)[:, None]
        return val

    img = pano_from_directions(pattern, height, rotation)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
