"""Upright (gravity- and Manhattan-aligned) rectification of a panorama (paper Sec. 3.1).

:func:`estimate_rectification` finds the line segments of a panorama
(:mod:`panogeom.lines`), its Manhattan vanishing points
(:mod:`panogeom.vanishing`) and the rotation ``R`` from the input camera
frame into the upright frame; the returned :class:`Rectification` rotates
the panorama and maps pixels and boxes both ways.

Convention (CONVENTIONS.md, "World / camera frame"): ``R`` maps input-camera
directions into the upright frame (scene.json's ``camera.rotation``); the
rectified panorama shows at the pixel of ray ``d`` what the input shows at
``R.T @ d`` (:func:`panogeom.transform.rotate_pano`). The upright frame's z
is the vertical vanishing direction (pointing up); its x axis depends on the
mode:

- ``"level"``: x is the horizontal projection of the input's centre-column
  direction, so only the horizon is levelled and the heading is kept (the
  input's centre column stays at ``lon = 0`` of the rectified panorama,
  wherever it was above or below the horizon).
- ``"walls"``: x is the horizontal Manhattan axis closest to that projection
  (the heading changes by at most 45 degrees), so walls face +-x and +-y.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array, pano_image, pano_size
from .coords import pixel_to_ray, ray_to_lonlat, ray_to_pixel
from .lines import LineSegments, detect_line_segments
from .perspective import PinholeView
from .rotation import check_rotation
from .transform import rotate_pano, rotate_pixels
from .vanishing import ManhattanFrame, estimate_manhattan_frame

__all__ = ["Mode", "Rectification", "upright_rotation", "estimate_rectification"]

Array = NDArray[np.float64]
Mode = Literal["level", "walls"]
_MODES = ("level", "walls")


def upright_rotation(axes: ArrayLike, mode: Mode = "level") -> Array:
    """Rotation from the input camera frame to the upright frame.

    Parameters
    ----------
    axes : (3, 3) float
        Rows ``(x, y, up)`` of a Manhattan frame in the input camera frame
        (:attr:`panogeom.vanishing.ManhattanFrame.axes`), ``up[2] > 0``.
    mode : {"level", "walls"}
        ``"level"`` keeps the heading (x = horizontal projection of the
        input's x), ``"walls"`` returns the Manhattan axes themselves.

    Returns
    -------
    R : (3, 3) float
        Proper rotation; ``R @ up == (0, 0, 1)``.

    Examples
    --------
    >>> from panogeom.rotation import rot_x, rot_z
    >>> axes = (rot_x(0.1) @ rot_z(0.3)).T         # a tilted, turned Manhattan frame
    >>> R = upright_rotation(axes, "level")
    >>> bool(np.allclose(R @ axes[2], [0, 0, 1])), bool(abs((R @ [1.0, 0, 0])[1]) < 1e-12)
    (True, True)
    >>> bool(np.allclose(upright_rotation(axes, "walls"), axes))
    True
    """
    A = check_rotation(axes, "axes")
    if mode not in _MODES:
        raise ValueError(f"mode: expected one of {_MODES}, got {mode!r}")
    up = A[2]
    if up[2] <= 0:
        raise ValueError(f"axes: expected the up row (row 2) to point up (z > 0), got {up.tolist()}")
    if mode == "walls":
        return A.copy()
    x = np.array([1.0, 0.0, 0.0]) - up[0] * up
    nx = np.linalg.norm(x)
    if nx < 1e-6:
        raise ValueError(f"axes: the input's centre-column direction is vertical (up = {up.tolist()}), "
                         f"its heading is undefined")
    x /= nx
    return np.stack([x, np.cross(up, x), up])


def _extent(rays: Array, pole_in: tuple[bool, bool], width: int, height: int) -> Array:
    """Seam-aware pixel extent (u0, v0, u1, v1) of a region given by dense boundary rays."""
    ll = ray_to_lonlat(rays)
    lat_max = np.pi / 2 if pole_in[0] else ll[:, 1].max()
    lat_min = -np.pi / 2 if pole_in[1] else ll[:, 1].min()
    v0 = (0.5 * np.pi - lat_max) * height / np.pi
    v1 = (0.5 * np.pi - lat_min) * height / np.pi
    if any(pole_in):
        return np.array([0.0, v0, float(width), v1])
    lon = np.sort(ll[:, 0])
    gaps = np.diff(np.concatenate([lon, lon[:1] + 2.0 * np.pi]))
    k = int(np.argmax(gaps))
    start, stop = lon[(k + 1) % len(lon)], lon[k]  # the region is the complement of the largest gap
    u0 = np.mod((start + np.pi) * width / (2.0 * np.pi), width)
    u1 = np.mod((stop + np.pi) * width / (2.0 * np.pi), width)
    if u1 == 0.0 and u0 > 0.0:
        u1 = float(width)
    return np.array([u0, v0, u1, v1])


def _rotate_box(box: ArrayLike, R: Array, width: int, height: int, samples: int = 64) -> Array:
    """Extent, in the panorama rotated by ``R``, of a pixel box of the original panorama."""
    w, h = pano_size(width, height)
    b = float_array(box, "box")
    if b.shape != (4,) or not (b[1] < b[3]) or not (0 <= b[0] <= w and 0 <= b[2] <= w):
        raise ValueError(f"box: expected (u0, v0, u1, v1) with 0 <= u <= W={w} and v0 < v1 "
                         f"(u0 > u1 when it wraps the seam), got {b.tolist()}")
    u0, v0, u1, v1 = b
    if u1 <= u0:
        u1 += w
    t = np.linspace(0.0, 1.0, samples)
    us, vs = u0 + t * (u1 - u0), v0 + t * (v1 - v0)
    top, bottom = np.stack([us, np.full_like(us, v0)], 1), np.stack([us[::-1], np.full_like(us, v1)], 1)
    right, left = np.stack([np.full_like(vs, u1), vs], 1), np.stack([np.full_like(vs, u0), vs[::-1]], 1)
    edge = np.concatenate([top, right, bottom, left])  # the boundary, clockwise in the image
    rays = pixel_to_ray(edge, w, h) @ R.T

    def inside(d: Array) -> bool:
        u, v = ray_to_pixel(d, w, h)
        du = np.mod(u - u0, w)
        return bool(v0 <= v <= v1 and du <= u1 - u0)

    poles = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]) @ R  # output poles seen in the input: R.T @ p
    return _extent(rays, (inside(poles[0]), inside(poles[1])), w, h)


@dataclass(frozen=True)
class Rectification:
    """The upright rotation of a panorama, with the evidence it came from.

    Attributes
    ----------
    rotation : (3, 3) float
        ``R``: input camera frame -> upright frame (scene.json's
        ``camera.rotation``).
    mode : {"level", "walls"}
    frame : ManhattanFrame
        Vanishing directions in the input camera frame; ``frame.labels``
        index its axes ``(x, y, up)``.
    segments : LineSegments
        The arcs the frame was estimated from, in the input camera frame.

    Convention: module docstring; radians.
    """

    rotation: Array
    mode: Mode
    frame: ManhattanFrame
    segments: LineSegments

    @property
    def tilt(self) -> float:
        """Angle between the input's up and the vertical, radians."""
        return self.frame.tilt

    @property
    def heading(self) -> float:
        """Rotation about the vertical from the level frame to this one, radians in (-pi, pi].

        0 in ``"level"`` mode; in ``"walls"`` mode the angle (counter-clockwise
        seen from above) of the rectified x axis from the horizontal
        projection of the input's centre-column direction, within +-pi/4.
        """
        level = upright_rotation(self.frame.axes, "level")
        x = level @ self.rotation[0]
        return float(np.arctan2(x[1], x[0]))

    def rays_to_rectified(self, rays: ArrayLike) -> Array:
        """Input-frame directions (..., 3) to upright-frame directions (``R @ d``)."""
        return float_array(rays, "rays", last=3) @ self.rotation.T

    def rays_to_input(self, rays: ArrayLike) -> Array:
        """Upright-frame directions (..., 3) to input-frame directions (``R.T @ d``)."""
        return float_array(rays, "rays", last=3) @ self.rotation

    def pixels_to_rectified(self, uv: ArrayLike, width: int, height: int) -> Array:
        """Input panorama pixels (..., 2) to the rectified panorama's pixels (same size)."""
        return rotate_pixels(uv, self.rotation, width, height)

    def pixels_to_input(self, uv: ArrayLike, width: int, height: int) -> Array:
        """Rectified panorama pixels (..., 2) back to the input panorama's pixels."""
        return rotate_pixels(uv, self.rotation, width, height, inverse=True)

    def box_to_rectified(self, box: ArrayLike, width: int, height: int) -> Array:
        """Smallest rectified-panorama box containing an input-panorama box.

        Parameters
        ----------
        box : (4,) float
            ``(u0, v0, u1, v1)`` in the input panorama, ``u0 > u1`` when it
            wraps the seam (CONVENTIONS.md ``bbox_pano``).
        width, height : int

        Returns
        -------
        box : (4,) float
            Same format; a box containing a pole spans the full width
            ``(0, v0, W, v1)``. A rotated lon/lat rectangle is no longer one,
            so mapping back and forth only grows a box.
        """
        return _rotate_box(box, self.rotation, width, height)

    def box_to_input(self, box: ArrayLike, width: int, height: int) -> Array:
        """Smallest input-panorama box containing a rectified-panorama box (see :meth:`box_to_rectified`)."""
        return _rotate_box(box, self.rotation.T, width, height)

    def apply(self, pano: ArrayLike, interpolation: Literal["linear", "nearest", "cubic"] = "linear") -> np.ndarray:
        """The rectified panorama: ``rotate_pano(pano, R)`` (``"nearest"`` for label images)."""
        return rotate_pano(pano, self.rotation, interpolation)


def estimate_rectification(pano: ArrayLike, mode: Mode = "level", *, views: list[PinholeView] | None = None,
                           line_options: dict[str, Any] | None = None,
                           vp_options: dict[str, Any] | None = None) -> Rectification:
    """Line segments -> Manhattan vanishing points -> upright rotation of a panorama.

    Parameters
    ----------
    pano : (H, W[, C]) array, W == 2*H
    mode : {"level", "walls"}
        Keep the input's heading (only level the horizon) or also turn x/y
        onto the walls (module docstring).
    views : list of PinholeView, optional
        Views searched for segments (default :func:`panogeom.lines.line_views`).
    line_options : dict, optional
        Keyword arguments of :func:`panogeom.lines.detect_line_segments`.
    vp_options : dict, optional
        Keyword arguments of :func:`panogeom.vanishing.estimate_manhattan_frame`.

    Returns
    -------
    Rectification
        Does not resample the panorama; call :meth:`Rectification.apply`.

    Raises
    ------
    panogeom.vanishing.VanishingPointError
        The panorama has too few lines or no Manhattan structure (a blank or
        noise image): no rotation is made up.

    Examples
    --------
    >>> from panogeom.vanishing import VanishingPointError
    >>> try:
    ...     estimate_rectification(np.full((128, 256, 3), 127, np.uint8))
    ... except VanishingPointError as err:
    ...     print(err)
    found 0 line segments, need at least 12
    """
    img = pano_image(pano, "pano")
    if mode not in _MODES:
        raise ValueError(f"mode: expected one of {_MODES}, got {mode!r}")
    segments = detect_line_segments(img, views, **(line_options or {}))
    frame = estimate_manhattan_frame(segments, **(vp_options or {}))
    return Rectification(rotation=upright_rotation(frame.axes, mode), mode=mode, frame=frame, segments=segments)
