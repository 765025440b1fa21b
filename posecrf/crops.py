"""Object crops of a panorama and the conversion of crop-relative yaw to world yaw.

The pose CRF (:mod:`posecrf.pose`) estimates a pose *relative to the viewing
ray*: the renders it compares with are taken by a camera aimed at the
model's centre (:mod:`posecrf.render`). This module cuts such crops out of a
panorama (a perspective view centred on the ray through the detection box,
:func:`crop_view`, :func:`extract_crop`) and turns the relative yaw back into
the object's yaw in the world frame (:func:`world_yaw`).

Convention:
    World frame of shared/CONVENTIONS.md (metres, z up; object yaw = rotation
    about +z from world +x to the object's front, counter-clockwise seen from
    above, in [0, 2*pi)). A viewing ray ``d`` goes from the camera towards
    the object; its azimuth is ``alpha = atan2(d_y, d_x)``.

    The crop-relative pose (yaw_rel, pitch) of :mod:`posecrf.render` is the
    direction object -> camera seen in the object's frame: yaw_rel = its
    angle from the object's front, counter-clockwise; pitch = its elevation.
    In the world frame the direction object -> camera is ``-d``, whose
    azimuth is ``alpha + pi``; the object's frame is the world frame turned
    by the object yaw ``theta``, so ``yaw_rel = alpha + pi - theta`` and

        ``theta = alpha + pi - yaw_rel  (mod 2*pi)``,

    the same formula both ways. The pitch is ``-elevation(d)`` (the camera
    looks down on an object below it: positive pitch). A 2-fold symmetric
    object's yaw is defined mod pi.

Examples
--------
A camera looking along +x (alpha = 0) that sees an object's front face
(yaw_rel = 0) faces an object turned towards the camera, i.e. yaw pi:

>>> float(world_yaw(0.0, [1.0, 0.0, -0.2])) == np.pi
True
>>> round(float(np.rad2deg(world_yaw(np.deg2rad(30.0), [0.0, 1.0, 0.0]))), 6)   # alpha = 90 deg
240.0
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_to_ray, ray_to_lonlat
from panogeom.perspective import PinholeView, equirect_to_perspective

__all__ = [
    "view_azimuth",
    "object_pitch",
    "world_yaw",
    "relative_yaw",
    "relative_yaw_shifts",
    "fold_yaw",
    "pano_box_ray",
    "crop_view",
    "outline_view",
    "extract_crop",
]

_TWO_PI = 2.0 * math.pi


def _ray(ray: ArrayLike) -> NDArray[np.float64]:
    d = np.asarray(ray, dtype=np.float64)
    if d.shape[-1:] != (3,) or not np.all(np.isfinite(d)):
        raise ValueError(f"ray: expected finite (..., 3) direction vectors, got shape {d.shape}")
    if np.any(np.hypot(d[..., 0], d[..., 1]) < 1e-12):
        raise ValueError("ray: expected a ray with a horizontal component (azimuth undefined straight up or down)")
    return d


def _angles(a: ArrayLike, name: str) -> NDArray[np.float64]:
    x = np.asarray(a, dtype=np.float64)
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name}: expected finite angles in radians, got NaN or inf")
    return x


def view_azimuth(ray: ArrayLike) -> NDArray[np.float64]:
    """Azimuth ``alpha = atan2(d_y, d_x)`` of viewing rays, radians in (-pi, pi].

    Parameters
    ----------
    ray : (..., 3) float
        World-frame directions camera -> object (need not be unit).

    Examples
    --------
    >>> float(view_azimuth([0.0, 2.0, -1.0])) == np.pi / 2
    True
    """
    d = _ray(ray)
    return np.arctan2(d[..., 1], d[..., 0])


def object_pitch(ray: ArrayLike) -> NDArray[np.float64]:
    """Pitch of the pose seen along a ray: the camera's elevation seen from the object.

    ``-atan2(d_z, |d_xy|)``: positive when the camera looks down at the object.

    Examples
    --------
    >>> round(float(np.rad2deg(object_pitch([1.0, 0.0, -1.0]))), 6)
    45.0
    """
    d = _ray(ray)
    return -np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))


def fold_yaw(yaw: ArrayLike, symmetry: str = "none") -> NDArray[np.float64]:
    """Wrap yaw into [0, 2*pi), or into [0, pi) for a 2-fold symmetric object.

    Examples
    --------
    >>> round(float(np.rad2deg(fold_yaw(np.deg2rad(-30.0), "two"))), 6)
    150.0
    """
    y = _angles(yaw, "yaw")
    if symmetry == "none":
        period = _TWO_PI
    elif symmetry == "two":
        period = math.pi
    else:
        raise ValueError(f"symmetry: expected 'none' or 'two' (a 'full' symmetric object has no yaw), got {symmetry!r}")
    out = np.mod(y, period)
    return np.where(out >= period, out - period, out)


def world_yaw(yaw_rel: ArrayLike, ray: ArrayLike, symmetry: str = "none") -> NDArray[np.float64]:
    """Object yaw in the world frame from the crop-relative yaw and the viewing ray.

    ``theta = alpha + pi - yaw_rel``, wrapped by :func:`fold_yaw`.

    Parameters
    ----------
    yaw_rel : (...) float
        Crop-relative yaw (pose of :mod:`posecrf.render`), radians.
    ray : (..., 3) float
        Direction camera -> object centre in the world frame (the ray through
        the detection box centre).
    symmetry : {"none", "two"}

    Returns
    -------
    (...) float
        Radians in [0, 2*pi) (in [0, pi) for "two").

    Convention: see the module docstring.
    """
    return fold_yaw(view_azimuth(ray) + math.pi - _angles(yaw_rel, "yaw_rel"), symmetry)


def relative_yaw(yaw: ArrayLike, ray: ArrayLike, symmetry: str = "none") -> NDArray[np.float64]:
    """Inverse of :func:`world_yaw`: crop-relative yaw of an object with world yaw `yaw` seen along `ray`.

    Examples
    --------
    >>> d = [0.3, -0.8, -0.4]
    >>> round(float(relative_yaw(world_yaw(1.2, d), d)), 12)
    1.2
    """
    return fold_yaw(view_azimuth(ray) + math.pi - _angles(yaw, "yaw"), symmetry)


def relative_yaw_shifts(rays: ArrayLike) -> NDArray[np.float64]:
    """How the crop-relative yaw of one object changes from view to view: ``relative_yaw(yaw, rays[j]) -
    relative_yaw(yaw, rays[0])`` for every world yaw, i.e. ``alpha_j - alpha_0`` (:func:`view_azimuth`).

    Parameters
    ----------
    rays : (V, 3) float
        Directions camera -> object centre of V crops of the same object (their views' centre rays).

    Returns
    -------
    (V,) float
        Radians, not wrapped; 0 for the first view.

    Examples
    --------
    >>> rays = [[1.0, 0.0, -0.2], [0.0, 1.0, -0.3]]
    >>> [round(float(np.degrees(s)), 6) for s in relative_yaw_shifts(rays)]
    [0.0, 90.0]
    """
    az = view_azimuth(np.asarray(rays, dtype=np.float64).reshape(-1, 3))
    return az - az[0]


def _pano_box(box: ArrayLike, width: int, height: int) -> tuple[NDArray[np.float64], float, float]:
    b = np.asarray(box, dtype=np.float64)
    if b.shape != (4,) or not np.all(np.isfinite(b)):
        raise ValueError(f"box: expected (u0, v0, u1, v1) panorama pixels, got {np.asarray(box).tolist()}")
    if int(width) != width or int(height) != height or width != 2 * height or height < 1:
        raise ValueError(f"width, height: expected a panorama size with W == 2*H, got {width} x {height}")
    if not (0.0 <= b[1] < b[3] <= height):
        raise ValueError(f"box: expected 0 <= v0 < v1 <= H = {height}, got v0 = {b[1]}, v1 = {b[3]}")
    u0, u1 = b[0], b[2] if b[2] > b[0] else b[2] + width  # u0 > u1: the box wraps the seam
    if not (0.0 <= b[0] <= width and 0.0 <= b[2] <= width) or u1 - u0 <= 0:
        raise ValueError(f"box: expected u0, u1 in [0, W = {width}] with u0 != u1, got {b[0]}, {b[2]}")
    return b, float(u0), float(u1)


def pano_box_ray(box: ArrayLike, width: int, height: int) -> NDArray[np.float64]:
    """Unit ray through the centre of a panorama box (seam-aware).

    Parameters
    ----------
    box : (4,) float
        ``(u0, v0, u1, v1)`` panorama pixels; ``u0 > u1`` wraps the seam.
    width, height : int
        Panorama size, W == 2*H.

    Returns
    -------
    (3,) float

    Examples
    --------
    >>> (pano_box_ray([1000, 192, 24, 320], 1024, 512).round(6) + 0.0).tolist()   # wraps: centre on the seam
    [-1.0, 0.0, 0.0]
    """
    b, u0, u1 = _pano_box(box, width, height)
    uc = 0.5 * (u0 + u1)
    return pixel_to_ray(np.array([uc, 0.5 * (b[1] + b[3])]), width, height)


def crop_view(box: ArrayLike, width: int, height: int, size: int = 128, margin: float = 0.1,
              samples_per_edge: int = 16) -> PinholeView:
    """A perspective view centred on a panorama box's ray that covers the box.

    The view's optical axis is :func:`pano_box_ray` (no roll: the view is
    level about its axis), its field of view just holds the box outline plus
    `margin` (fraction of the half-extent) on each side, and its pixel
    aspect follows the box: ``width = size`` and the height scaled to match.

    Parameters
    ----------
    box : (4,) float
        ``(u0, v0, u1, v1)`` panorama pixels (``u0 > u1`` wraps).
    width, height : int
        Panorama size.
    size : int
        View width in pixels.
    margin : float
        >= 0.
    samples_per_edge : int
        Outline samples per box edge.

    Returns
    -------
    PinholeView
    """
    b, u0, u1 = _pano_box(box, width, height)
    centre = pano_box_ray(box, width, height)
    t = np.linspace(0.0, 1.0, int(samples_per_edge) + 1)
    us = u0 + t * (u1 - u0)
    vs = b[1] + t * (b[3] - b[1])
    outline = np.concatenate([
        np.stack([us, np.full_like(us, b[1])], 1), np.stack([us, np.full_like(us, b[3])], 1),
        np.stack([np.full_like(vs, u0), vs], 1), np.stack([np.full_like(vs, u1), vs], 1),
    ])
    try:
        return outline_view(centre, pixel_to_ray(outline, width, height), size, margin)
    except ValueError as exc:
        if not str(exc).startswith("outline"):
            raise  # size or margin
        raise ValueError(f"box: expected a box narrower than 180 degrees that fits a perspective view, "
                         f"got {b.tolist()}") from None


def outline_view(centre: ArrayLike, outline: ArrayLike, size: int = 128, margin: float = 0.1) -> PinholeView:
    """A level perspective view along ``centre`` whose field of view just holds the rays ``outline``.

    What :func:`crop_view` does for a panorama box, for any outline: e.g. the four edges of a box in a
    perspective tile (``detect.TileBox``), whose panorama box is larger than the region it bounds
    whenever the tile is turned or pitched. The view has no roll; its half-extents are the largest
    tangent-plane coordinates of the outline times ``1 + margin``; ``width = size`` and the height
    follows the outline's aspect.

    Parameters
    ----------
    centre : (3,) float
        Optical axis (any length > 0), e.g. the ray through the box centre.
    outline : (N, 3) float
        Rays of the outline, all less than 90 degrees from ``centre``.
    size : int
        View width in pixels (>= 8).
    margin : float
        >= 0.

    Returns
    -------
    PinholeView

    Examples
    --------
    >>> v = outline_view([1.0, 0.0, 0.0], [[1.0, 0.1, 0.05], [1.0, -0.1, -0.05]], size=100, margin=0.0)
    >>> round(math.degrees(v.fov), 3), v.height
    (11.421, 50)
    """
    if int(size) != size or size < 8:
        raise ValueError(f"size: expected an integer >= 8 pixels, got {size!r}")
    if not (math.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin: expected a fraction >= 0, got {margin!r}")
    c = _ray(centre)
    rays = np.asarray(outline, dtype=np.float64).reshape(-1, 3)
    lon, lat = ray_to_lonlat(c)
    probe = PinholeView(yaw=float(-lon), pitch=float(lat), roll=0.0, fov=math.pi / 2, width=2, height=2)
    uv, front = probe.ray_to_pixel(rays)
    if len(rays) == 0 or not np.all(front):
        raise ValueError("outline: expected rays within 90 degrees of the centre")
    xy = (uv - 1.0) / probe.focal  # tangent-plane coordinates
    hx = float(np.abs(xy[:, 0]).max()) * (1.0 + margin)
    hy = float(np.abs(xy[:, 1]).max()) * (1.0 + margin)
    fov = 2.0 * math.atan(hx)
    if not (0.0 < fov < math.pi - 1e-6) or not hy > 0:
        raise ValueError("outline: expected an outline that fits a perspective view")
    h_px = max(8, int(round(size * hy / hx)))
    return PinholeView(yaw=float(-lon), pitch=float(lat), roll=0.0, fov=fov, width=int(size), height=h_px)


def extract_crop(pano: ArrayLike, box: ArrayLike, size: int = 128, margin: float = 0.1) -> tuple[np.ndarray, PinholeView]:
    """Perspective crop of a panorama box, centred on the box's ray (:func:`crop_view`).

    Returns
    -------
    crop : (h, size[, C]) array, dtype of `pano`
    view : PinholeView
        Its ``direction`` is the viewing ray for :func:`world_yaw`.

    Examples
    --------
    >>> pano = np.zeros((256, 512, 3), np.uint8)
    >>> crop, view = extract_crop(pano, [200, 120, 260, 160], size=64)
    >>> crop.shape[1], bool(abs(np.linalg.norm(view.direction) - 1) < 1e-12)
    (64, True)
    """
    p = np.asarray(pano)
    if p.ndim < 2:
        raise ValueError(f"pano: expected an (H, W[, C]) panorama, got shape {p.shape}")
    view = crop_view(box, p.shape[1], p.shape[0], size, margin)
    return equirect_to_perspective(p, view), view
