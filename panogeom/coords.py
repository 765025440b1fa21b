"""Pixel <-> (lon, lat) <-> unit ray: the single source of truth for panorama geometry.

Convention (CONVENTIONS.md, "Panorama pixels" and "World / camera frame"):

- Equirectangular image of width W and height H (W == 2*H for panoramas).
  Continuous pixel coordinates ``(u, v)``: u to the right, v downward, pixel
  centres at integer + 0.5, so pixel ``(0, 0)`` covers ``[0, 1) x [0, 1)``.
- ``lon = 2*pi*u/W - pi`` (0 at the centre column, -pi at the left edge),
  ``lat = pi/2 - pi*v/H`` (+pi/2 at the top row edge).
- Right-handed frame, z up; x points at lon = 0, y at lon = -pi/2.
  Ray of a pixel: ``d = (cos(lat) cos(lon), -cos(lat) sin(lon), sin(lat))``.
- World frame: metres, origin on the floor below the camera, camera centre at
  ``(0, 0, camera_height)``.

Every other module imports these functions; nothing re-derives them. All
functions take arrays of any leading shape with coordinates on the last axis.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array

__all__ = [
    "pixel_to_lonlat",
    "lonlat_to_pixel",
    "lonlat_to_ray",
    "ray_to_lonlat",
    "pixel_to_ray",
    "ray_to_pixel",
    "xy_to_lon",
    "pixel_grid",
    "pixel_grid_rays",
    "world_to_pixel",
    "wrap_u",
    "DEFAULT_CAMERA_HEIGHT",
]

#: Camera height in metres used when none is given (CONVENTIONS.md).
DEFAULT_CAMERA_HEIGHT = 1.6

Array = NDArray[np.float64]


def _size(width: float, height: float) -> tuple[float, float]:
    w, h = float(width), float(height)
    if not (w > 0 and h > 0 and np.isfinite(w) and np.isfinite(h)):
        raise ValueError(f"image size: expected positive finite width and height, got {width!r}, {height!r}")
    return w, h


def pixel_to_lonlat(uv: ArrayLike, width: float, height: float) -> Array:
    """Continuous pixel coordinates to (lon, lat) in radians.

    Parameters
    ----------
    uv : (..., 2) float
        Pixel coordinates (u right, v down; pixel centres at integer + 0.5).
    width, height : float
        Image size W, H in pixels.

    Returns
    -------
    lonlat : (..., 2) float
        ``lon = 2*pi*u/W - pi``, ``lat = pi/2 - pi*v/H``.

    Convention: lon is 0 at the centre column and increases to the right; lat
    is +pi/2 at the top edge.

    Examples
    --------
    >>> pixel_to_lonlat([[512.0, 256.0]], 1024, 512)
    array([[0., 0.]])
    """
    w, h = _size(width, height)
    uv = float_array(uv, "uv", last=2)
    out = np.empty_like(uv)
    out[..., 0] = 2.0 * np.pi * uv[..., 0] / w - np.pi
    out[..., 1] = 0.5 * np.pi - np.pi * uv[..., 1] / h
    return out


def lonlat_to_pixel(lonlat: ArrayLike, width: float, height: float) -> Array:
    """(lon, lat) in radians to continuous pixel coordinates (inverse of :func:`pixel_to_lonlat`).

    Parameters
    ----------
    lonlat : (..., 2) float
    width, height : float

    Returns
    -------
    uv : (..., 2) float
        Not wrapped: lon outside [-pi, pi) maps outside [0, W); see :func:`wrap_u`.
    """
    w, h = _size(width, height)
    ll = float_array(lonlat, "lonlat", last=2)
    out = np.empty_like(ll)
    out[..., 0] = (ll[..., 0] + np.pi) * w / (2.0 * np.pi)
    out[..., 1] = (0.5 * np.pi - ll[..., 1]) * h / np.pi
    return out


def lonlat_to_ray(lonlat: ArrayLike) -> Array:
    """(lon, lat) to unit direction vectors.

    Parameters
    ----------
    lonlat : (..., 2) float

    Returns
    -------
    rays : (..., 3) float
        ``(cos(lat) cos(lon), -cos(lat) sin(lon), sin(lat))``: x at lon = 0,
        y at lon = -pi/2, z up.

    Examples
    --------
    >>> lonlat_to_ray([[-np.pi / 2, 0.0]]).round(12) + 0.0
    array([[0., 1., 0.]])
    """
    ll = float_array(lonlat, "lonlat", last=2)
    lon, lat = ll[..., 0], ll[..., 1]
    c = np.cos(lat)
    return np.stack([c * np.cos(lon), -c * np.sin(lon), np.sin(lat)], axis=-1)


def ray_to_lonlat(rays: ArrayLike) -> Array:
    """Direction vectors (any non-zero length) to (lon, lat) in radians.

    Parameters
    ----------
    rays : (..., 3) float
        Non-zero, finite directions in the camera/world frame.

    Returns
    -------
    lonlat : (..., 2) float
        lon in [-pi, pi], lat in [-pi/2, pi/2].
    """
    r = float_array(rays, "rays", last=3)
    n = np.linalg.norm(r, axis=-1)
    if r.size and not np.all(n > 0):
        raise ValueError("rays: expected non-zero direction vectors, got a zero-length ray")
    lon = np.arctan2(-r[..., 1], r[..., 0])
    # atan2 against the horizontal norm keeps full precision at the poles (arcsin does not).
    lat = np.arctan2(r[..., 2], np.hypot(r[..., 0], r[..., 1]))
    return np.stack([lon, lat], axis=-1)


def xy_to_lon(xy: ArrayLike) -> Array:
    """Panorama longitude of horizontal directions (x, y): the column a floor-plane point is seen in.

    Parameters
    ----------
    xy : (..., 2) float
        Horizontal components of directions (or floor points relative to the camera).

    Returns
    -------
    lon : (...) float
        ``atan2(-y, x)`` in [-pi, pi] (CONVENTIONS.md: y points at lon = -pi/2).

    Examples
    --------
    >>> xy_to_lon([[0.0, 1.0]]).round(12)
    array([-1.57079633])
    """
    a = float_array(xy, "xy", last=2)
    return np.arctan2(-a[..., 1], a[..., 0])


def pixel_to_ray(uv: ArrayLike, width: float, height: float) -> Array:
    """Pixel coordinates to unit rays: ``lonlat_to_ray(pixel_to_lonlat(uv))``.

    Parameters
    ----------
    uv : (..., 2) float
    width, height : float

    Returns
    -------
    rays : (..., 3) float, unit norm
    """
    return lonlat_to_ray(pixel_to_lonlat(uv, width, height))


def wrap_u(u: ArrayLike, width: float) -> Array:
    """Wrap horizontal pixel coordinates into [0, W)."""
    w, _ = _size(width, 1.0)
    u = np.asarray(u, dtype=np.float64)
    out = np.mod(u, w)
    return np.where(out >= w, out - w, out)


def ray_to_pixel(rays: ArrayLike, width: float, height: float) -> Array:
    """Rays to pixel coordinates, u wrapped into [0, W).

    Parameters
    ----------
    rays : (..., 3) float
        Non-zero directions.
    width, height : float

    Returns
    -------
    uv : (..., 2) float

    Examples
    --------
    >>> ray_to_pixel([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], 1024, 512)
    array([[512., 256.],
           [256., 256.]])
    """
    uv = lonlat_to_pixel(ray_to_lonlat(rays), width, height)
    uv[..., 0] = wrap_u(uv[..., 0], width)
    return uv


def pixel_grid(width: int, height: int) -> Array:
    """Continuous coordinates of every pixel centre.

    Returns
    -------
    uv : (H, W, 2) float
        ``uv[i, j] = (j + 0.5, i + 0.5)``.
    """
    w, h = int(width), int(height)
    if w <= 0 or h <= 0:
        raise ValueError(f"pixel_grid: expected a positive size, got {width}x{height}")
    u = np.arange(w, dtype=np.float64) + 0.5
    v = np.arange(h, dtype=np.float64) + 0.5
    uu, vv = np.meshgrid(u, v)
    return np.stack([uu, vv], axis=-1)


def pixel_grid_rays(width: int, height: int) -> Array:
    """Unit rays of every pixel centre of a W x H equirectangular image.

    Returns
    -------
    rays : (H, W, 3) float
        Equal to ``pixel_to_ray(pixel_grid(W, H), W, H)``, computed
        separably (one lon per column, one lat per row) for speed.
    """
    w, h = int(width), int(height)
    if w <= 0 or h <= 0:
        raise ValueError(f"pixel_grid_rays: expected a positive size, got {width}x{height}")
    lon = pixel_to_lonlat(np.stack([np.arange(w) + 0.5, np.full(w, 0.5)], axis=-1), w, h)[:, 0]
    lat = pixel_to_lonlat(np.stack([np.full(h, 0.5), np.arange(h) + 0.5], axis=-1), w, h)[:, 1]
    # lonlat_to_ray with the lat factor per row and the lon factor per column.
    c = np.cos(lat)[:, None]
    out = np.empty((h, w, 3))
    np.multiply(c, np.cos(lon)[None, :], out=out[..., 0])
    np.multiply(c, -np.sin(lon)[None, :], out=out[..., 1])
    out[..., 2] = np.sin(lat)[:, None]
    return out


def world_to_pixel(points: ArrayLike, width: float, height: float,
                   camera_height: float = DEFAULT_CAMERA_HEIGHT,
                   rotation: ArrayLike | None = None) -> Array:
    """Project world-frame 3D points into panorama pixels.

    Parameters
    ----------
    points : (..., 3) float
        World coordinates in metres (origin on the floor below the camera, z up).
    width, height : float
        Panorama size.
    camera_height : float
        Height of the camera centre above the floor.
    rotation : (3, 3) float, optional
        Maps camera-frame directions into the world frame (scene.json's
        ``camera.rotation``). When given, points are projected into the
        *input* (unrectified) panorama: ``d_cam = R.T @ (p - c)``.

    Returns
    -------
    uv : (..., 2) float, u wrapped into [0, W)

    Convention: a point exactly at the camera centre has no direction and
    raises ``ValueError``.

    Examples
    --------
    >>> world_to_pixel([2.0, 0.0, 1.6], 1024, 512, camera_height=1.6)
    array([512., 256.])
    """
    p = float_array(points, "points", last=3)
    d = p - np.array([0.0, 0.0, float(camera_height)])
    if rotation is not None:
        from .rotation import check_rotation

        R = check_rotation(rotation)
        d = d @ R  # row vectors: (R.T @ d.T).T
    return ray_to_pixel(d, width, height)
