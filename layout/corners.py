"""Floor polygon <-> corner pixels (``corners_px`` of the gt schema, HorizonNet-style).

A Manhattan room seen from the camera is fully given by the panorama pixels
of its wall corners: for floor vertex i, the pixel of the ceiling corner
above it and of the floor corner, ``[u_ceiling, v_ceiling, u_floor,
v_floor]``, in the order of the floor polygon (shared/CONVENTIONS.md,
"Ground truth"). This is the representation of HorizonNet, LayoutNet and
LGT-Net annotations, so results can be compared with other layout tools;
:func:`corners_to_horizonnet` / :func:`corners_from_horizonnet` read and
write their ``label_cor`` text files.

Convention:
    Continuous pixel coordinates of :mod:`panogeom.coords` (u right, v
    down, pixel centres at integer + 0.5), W == 2*H; world frame with the
    camera at ``(camera_xy, camera_height)`` and the floor at z = 0.
    HorizonNet files use pixel indices (centres at integers): this module
    adds / subtracts 0.5 when reading / writing them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import DEFAULT_CAMERA_HEIGHT, pixel_to_ray, world_to_pixel

from .polygon import as_polygon, signed_area

__all__ = [
    "CornerLayout",
    "polygon_to_corners_px",
    "corners_px_to_polygon",
    "corners_to_horizonnet",
    "corners_from_horizonnet",
]

FloatArray = NDArray[np.float64]


def _positive(x: float, name: str) -> float:
    v = float(x)
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name}: expected a positive finite value, got {x!r}")
    return v


def _size(width: int, height: int | None) -> tuple[int, int]:
    w = int(width)
    h = w // 2 if height is None else int(height)
    if w <= 0 or h <= 0 or w != 2 * h:
        raise ValueError(f"panorama size: expected W == 2*H > 0, got W={width}, H={height}")
    return w, h


def polygon_to_corners_px(floor: ArrayLike, ceiling_z: float, camera_height: float = DEFAULT_CAMERA_HEIGHT,
                          width: int = 1024, height: int | None = None, *,
                          camera_xy: ArrayLike = (0.0, 0.0)) -> FloatArray:
    """Corner pixels of a room: ``[u_ceiling, v_ceiling, u_floor, v_floor]`` per floor vertex.

    Parameters
    ----------
    floor : (N, 2) float
        Floor polygon, metres.
    ceiling_z : float
        Ceiling height, metres (> camera_height for a ceiling corner above
        the horizon).
    camera_height : float
        Camera centre above the floor, metres.
    width, height : int
        Panorama size (height defaults to width / 2).
    camera_xy : (2,) float
        Camera position on the floor plane.

    Returns
    -------
    corners_px : (N, 4) float
        In the order of ``floor``; u wrapped into [0, W).

    Convention: :func:`panogeom.coords.world_to_pixel`; see the module
    docstring.

    Examples
    --------
    >>> polygon_to_corners_px([[2, -2], [2, 2], [-2, 2], [-2, -2]], 2.6, 1.6, 1024).round(2).tolist()[0]
    [640.0, 200.62, 640.0, 339.9]
    """
    poly = as_polygon(floor, name="floor")
    if poly.ndim != 2:
        raise ValueError(f"floor: expected a single polygon (N, 2), got {poly.shape}")
    cam = np.asarray(camera_xy, dtype=np.float64)
    if cam.shape != (2,) or not np.all(np.isfinite(cam)):
        raise ValueError(f"camera_xy: expected finite (2,), got {cam.shape}")
    h_cam = _positive(camera_height, "camera_height")
    c_z = _positive(ceiling_z, "ceiling_z")
    w, h = _size(width, height)
    rel = poly - cam
    n = len(rel)
    top = np.concatenate([rel, np.full((n, 1), c_z)], axis=1)
    bottom = np.concatenate([rel, np.zeros((n, 1))], axis=1)
    uv_c = world_to_pixel(top, w, h, camera_height=h_cam)
    uv_f = world_to_pixel(bottom, w, h, camera_height=h_cam)
    return np.concatenate([uv_c, uv_f], axis=1)


@dataclass(frozen=True)
class CornerLayout:
    """A room read back from corner pixels (result of :func:`corners_px_to_polygon`).

    Attributes
    ----------
    floor : (N, 2) float
        Floor polygon, metres, camera at the origin of x, y;
        counter-clockwise (reversed from the input order when that was
        clockwise, vertex 0 kept first).
    ceiling_z : float
        Mean over corners of the ceiling height each ceiling corner gives.
    ceiling_z_per_corner : (N,) float
        In the order of ``floor``.
    reversed : bool
        The input order was clockwise and was reversed.
    """

    floor: FloatArray
    ceiling_z: float
    ceiling_z_per_corner: FloatArray
    reversed: bool


def corners_px_to_polygon(corners_px: ArrayLike, width: int, height: int | None = None,
                          camera_height: float = DEFAULT_CAMERA_HEIGHT) -> CornerLayout:
    """Floor polygon and ceiling height from corner pixels and the camera height.

    Each floor corner's ray meets the floor plane (z = 0) at the floor
    vertex; the ceiling corner's ray meets the vertical line above that
    vertex at the ceiling height.

    Parameters
    ----------
    corners_px : (N, 4) float
        ``[u_ceiling, v_ceiling, u_floor, v_floor]`` per corner, N >= 3.
    width, height : int
        Panorama size (height defaults to width / 2).
    camera_height : float
        Camera centre above the floor (the units of the result).

    Returns
    -------
    CornerLayout

    Raises
    ------
    ValueError
        For a floor corner on or above the horizon (no floor intersection).

    Convention: see the module docstring.

    Examples
    --------
    >>> c = polygon_to_corners_px([[2, -1], [2, 3], [-1, 3], [-1, -1]], 2.6, 1.6, 1024)
    >>> lay = corners_px_to_polygon(c, 1024, camera_height=1.6)
    >>> np.round(lay.floor, 6).tolist(), round(lay.ceiling_z, 6)
    ([[2.0, -1.0], [2.0, 3.0], [-1.0, 3.0], [-1.0, -1.0]], 2.6)
    """
    c = np.asarray(corners_px, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 4 or len(c) < 3 or not np.all(np.isfinite(c)):
        raise ValueError(f"corners_px: expected finite (N, 4) with N >= 3, got {c.shape}")
    w, h = _size(width, height)
    h_cam = _positive(camera_height, "camera_height")
    rf = pixel_to_ray(c[:, 2:4], w, h)
    if np.any(rf[:, 2] >= -1e-9):
        bad = np.flatnonzero(rf[:, 2] >= -1e-9).tolist()
        raise ValueError(f"corners_px: expected floor corners below the horizon (v_floor > H/2), got corners {bad}")
    t = -h_cam / rf[:, 2]
    floor = rf[:, :2] * t[:, None]
    rho = np.hypot(floor[:, 0], floor[:, 1])
    rc = pixel_to_ray(c[:, 0:2], w, h)
    horiz = np.hypot(rc[:, 0], rc[:, 1])
    zc = h_cam + rc[:, 2] * rho / np.maximum(horiz, 1e-12)
    rev = bool(signed_area(floor) < 0)
    if rev:
        order = np.concatenate([[0], np.arange(len(floor) - 1, 0, -1)])
        floor, zc = floor[order], zc[order]
    return CornerLayout(floor=floor, ceiling_z=float(np.mean(zc)), ceiling_z_per_corner=zc, reversed=rev)


def corners_to_horizonnet(corners_px: ArrayLike) -> str:
    """HorizonNet ``label_cor`` text: per corner a ceiling line then a floor line, ``"u v"`` pixel indices.

    Examples
    --------
    >>> print(corners_to_horizonnet([[100.5, 150.5, 100.5, 350.5]]))
    100 150
    100 350
    """
    c = np.asarray(corners_px, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 4 or not np.all(np.isfinite(c)):
        raise ValueError(f"corners_px: expected finite (N, 4), got {c.shape}")
    lines = []
    for uc, vc, uf, vf in c - 0.5:
        lines.append(f"{uc:.6g} {vc:.6g}")
        lines.append(f"{uf:.6g} {vf:.6g}")
    return "\n".join(lines)


def corners_from_horizonnet(text: str) -> FloatArray:
    """Parse a HorizonNet ``label_cor`` text into ``corners_px`` (N, 4), continuous coordinates.

    Lines alternate ceiling corner, floor corner (``"u v"`` pixel indices);
    blank lines are skipped.

    Examples
    --------
    >>> corners_from_horizonnet("100 150\\n100 350\\n").tolist()
    [[100.5, 150.5, 100.5, 350.5]]
    """
    rows = []
    for k, line in enumerate(str(text).splitlines()):
        if not line.strip():
            continue
        parts = line.split()
        if len(parts) < 2:
            raise ValueError(f"label_cor line {k + 1}: expected 'u v', got {line!r}")
        try:
            rows.append([float(parts[0]), float(parts[1])])
        except ValueError as exc:
            raise ValueError(f"label_cor line {k + 1}: expected two numbers, got {line!r}") from exc
    if len(rows) < 2 or len(rows) % 2:
        raise ValueError(f"label_cor: expected an even number (>= 2) of corner lines, got {len(rows)}")
    a = np.asarray(rows) + 0.5
    return np.concatenate([a[0::2], a[1::2]], axis=1)
