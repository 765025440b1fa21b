"""Perspective (pinhole) views of a panorama and back-projection into it.

Convention:

- A view is pointed by ``(yaw, pitch, roll)`` in radians as in
  :mod:`panogeom.rotation` (yaw counter-clockwise from +x seen from above,
  pitch up positive). A view at yaw ``a`` and pitch 0 is centred on the
  panorama column ``lon = -a``.
- ``fov`` is the horizontal field of view in radians, in (0, pi). Pixels are
  square: ``f = (width / 2) / tan(fov / 2)``.
- The pinhole uses OpenCV's camera frame (x right, y down, z forward) and
  continuous pixel coordinates with centres at integer + 0.5, so the
  principal point is ``(width / 2, height / 2)``.
- ``view.R`` maps OpenCV camera coordinates into the panorama (world) frame:
  ``ray_world = R @ K^-1 @ (u, v, 1)``.

The paper's view sets (Sec. 3.1): :func:`layout_views` (6 views, 90 degree
FOV, 30 degree overlap between neighbours) and :func:`detection_views` (18
views for object detection).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array, pano_image, positive_size
from .coords import pixel_to_ray, ray_to_lonlat, ray_to_pixel
from .rotation import ypr_to_matrix
from .sampling import EquirectSampler, Interp

__all__ = [
    "PinholeView",
    "equirect_to_perspective",
    "ring_views",
    "layout_views",
    "detection_views",
    "perspective_to_pano",
    "pano_to_perspective",
    "segment_to_arc",
    "arc_points",
    "box_to_pano",
    "poles_in_box",
    "BoxInPano",
    "pano_box_union",
]

Array = NDArray[np.float64]

# OpenCV camera axes (x right, y down, z forward) expressed in the local view frame (x fwd, y left, z up).
_CV_TO_LOCAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class PinholeView:
    """A pinhole camera at the panorama centre.

    Attributes
    ----------
    yaw, pitch, roll : float
        Pointing of the optical axis, radians (see module docstring).
    fov : float
        Horizontal field of view, radians, in (0, pi).
    width, height : int
        Image size in pixels.
    """

    yaw: float
    pitch: float
    roll: float
    fov: float
    width: int
    height: int

    def __post_init__(self) -> None:
        if not (np.isfinite(self.fov) and 0.0 < self.fov < np.pi):
            raise ValueError(f"fov: expected a field of view in (0, pi) radians, got {self.fov!r}")
        positive_size((self.height, self.width), "view size")
        for n in ("yaw", "pitch", "roll"):
            if not np.isfinite(getattr(self, n)):
                raise ValueError(f"{n}: expected a finite angle in radians, got {getattr(self, n)!r}")

    @property
    def focal(self) -> float:
        """Focal length in pixels."""
        return 0.5 * self.width / np.tan(0.5 * self.fov)

    @property
    def K(self) -> Array:
        """(3, 3) intrinsics for continuous pixel coordinates (centres at +0.5)."""
        f = self.focal
        return np.array([[f, 0.0, 0.5 * self.width], [0.0, f, 0.5 * self.height], [0.0, 0.0, 1.0]])

    @cached_property
    def R(self) -> Array:
        """(3, 3) rotation from OpenCV camera coordinates to the panorama frame."""
        return ypr_to_matrix(self.yaw, self.pitch, self.roll) @ _CV_TO_LOCAL

    @property
    def direction(self) -> Array:
        """(3,) unit optical axis in the panorama frame."""
        return self.R[:, 2].copy()

    def pixel_to_ray(self, uv: ArrayLike) -> Array:
        """Perspective pixels (..., 2) to unit rays (..., 3) in the panorama frame."""
        uv = float_array(uv, "uv", last=2)
        f = self.focal
        x = (uv[..., 0] - 0.5 * self.width) / f
        y = (uv[..., 1] - 0.5 * self.height) / f
        d = np.stack([x, y, np.ones_like(x)], axis=-1) @ self.R.T
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def ray_to_pixel(self, rays: ArrayLike) -> tuple[Array, NDArray[np.bool_]]:
        """Rays (..., 3) in the panorama frame to perspective pixels.

        Returns
        -------
        uv : (..., 2) float
            Pinhole projection (meaningless where ``in_front`` is False).
        in_front : (...,) bool
            The ray points into the half-space in front of the camera.
        """
        r = float_array(rays, "rays", last=3)
        c = r @ self.R  # camera coordinates, row vectors
        z = c[..., 2]
        in_front = z > 1e-12
        zs = np.where(in_front, z, 1.0)
        f = self.focal
        uv = np.stack([f * c[..., 0] / zs + 0.5 * self.width, f * c[..., 1] / zs + 0.5 * self.height], axis=-1)
        return uv, in_front

    def grid_rays(self) -> Array:
        """(height, width, 3) unit rays of every pixel centre."""
        u = np.arange(self.width) + 0.5
        v = np.arange(self.height) + 0.5
        uu, vv = np.meshgrid(u, v)
        return self.pixel_to_ray(np.stack([uu, vv], axis=-1))


def equirect_to_perspective(pano: ArrayLike, view: PinholeView, interpolation: Interp = "linear") -> np.ndarray:
    """Render a pinhole view of a panorama.

    Parameters
    ----------
    pano : (H, W[, C]) array, W == 2*H
    view : PinholeView
    interpolation : {"linear", "nearest", "cubic"}

    Returns
    -------
    image : (view.height, view.width[, C]) array, dtype of ``pano``

    Examples
    --------
    >>> pano = np.zeros((256, 512, 3), np.uint8)
    >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=64, height=48)
    >>> equirect_to_perspective(pano, view).shape
    (48, 64, 3)
    """
    img = pano_image(pano, "pano")
    h, w = img.shape[:2]
    if not isinstance(view, PinholeView):
        raise ValueError(f"view: expected a PinholeView, got {type(view).__name__}")
    return _view_sampler(view, w, h, interpolation)(img)


@lru_cache(maxsize=32)
def _view_sampler(view: PinholeView, width: int, height: int, interpolation: Interp) -> EquirectSampler:
    """Remap maps of a view into a W x H panorama, cached per (view, size, interpolation)."""
    uv = ray_to_pixel(view.grid_rays(), width, height)
    return EquirectSampler.from_uv(uv, width, height, interpolation)


def ring_views(n: int, fov: float, size: tuple[int, int] | int, pitch: float = 0.0,
               yaw0: float = 0.0) -> list[PinholeView]:
    """``n`` views equally spaced in yaw at one pitch.

    Parameters
    ----------
    n : int
        Number of views (>= 1); yaw of view k is ``yaw0 + 2*pi*k/n``.
    fov : float
        Horizontal FOV, radians.
    size : int or (height, width)
    pitch, yaw0 : float
        Radians.
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n: expected a positive integer, got {n!r}")
    h, w = positive_size(size, "size")
    return [PinholeView(yaw=float(yaw0 + 2.0 * np.pi * k / n), pitch=float(pitch), roll=0.0, fov=float(fov),
                        width=w, height=h) for k in range(int(n))]


def layout_views(size: int = 512) -> list[PinholeView]:
    """The paper's layout view set: 6 horizontal views, 90 degree FOV, 30 degree overlap (Sec. 3.1)."""
    return ring_views(6, np.pi / 2, size)


def detection_views(size: int = 416) -> list[PinholeView]:
    """The 18-view set used for object detection (Sec. 4: "18 perspective images").

    12 views every 30 degrees at pitch -10 degrees (furniture sits below the
    horizon) and 6 views every 60 degrees at pitch -50 degrees for what is
    close to the camera, all with a 90 degree FOV.
    """
    top = ring_views(12, np.pi / 2, size, pitch=np.deg2rad(-10.0))
    low = ring_views(6, np.pi / 2, size, pitch=np.deg2rad(-50.0), yaw0=np.deg2rad(15.0))
    return top + low


def perspective_to_pano(uv: ArrayLike, view: PinholeView, pano_width: int, pano_height: int) -> Array:
    """Perspective pixel coordinates (..., 2) to panorama pixel coordinates (..., 2)."""
    return ray_to_pixel(view.pixel_to_ray(uv), pano_width, pano_height)


def pano_to_perspective(uv: ArrayLike, view: PinholeView, pano_width: int,
                        pano_height: int) -> tuple[Array, NDArray[np.bool_]]:
    """Panorama pixel coordinates (..., 2) to perspective pixels and an in-front mask."""
    return view.ray_to_pixel(pixel_to_ray(uv, pano_width, pano_height))


def segment_to_arc(segments: ArrayLike, view: PinholeView) -> tuple[Array, Array, Array]:
    """Line segments of a perspective image lifted to great-circle arcs on the sphere.

    Parameters
    ----------
    segments : (N, 4) float
        ``(u0, v0, u1, v1)`` endpoints in the view's pixel coordinates.

    Returns
    -------
    a, b : (N, 3) float
        Unit rays of the endpoints.
    normal : (N, 3) float
        Unit normal of the plane through the camera centre and the segment
        (``a x b`` normalised): the great circle carrying the segment.
    """
    s = float_array(segments, "segments")
    if s.ndim != 2 or s.shape[1] != 4:
        raise ValueError(f"segments: expected shape (N, 4), got {s.shape}")
    a = view.pixel_to_ray(s[:, :2])
    b = view.pixel_to_ray(s[:, 2:])
    n = np.cross(a, b)
    nn = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(nn[:, 0] < 1e-15):
        raise ValueError("segments: expected segments of non-zero length, got a degenerate segment")
    return a, b, n / nn


def arc_points(a: ArrayLike, b: ArrayLike, n: int = 32) -> Array:
    """Points along the shorter great-circle arc from ``a`` to ``b`` (slerp).

    Parameters
    ----------
    a, b : (..., 3) float
        Unit rays (not antipodal).
    n : int
        Number of samples, endpoints included.

    Returns
    -------
    points : (..., n, 3) float, unit norm
    """
    a = float_array(a, "a", last=3)
    b = float_array(b, "b", last=3)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    t = np.linspace(0.0, 1.0, int(n))
    cos = np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)[..., None]
    ang = np.arccos(cos)
    sin = np.sin(ang)
    safe = np.where(sin > 1e-12, sin, 1.0)
    wa = np.where(sin > 1e-12, np.sin((1.0 - t) * ang) / safe, 1.0 - t)
    wb = np.where(sin > 1e-12, np.sin(t * ang) / safe, t)
    p = wa[..., None] * a[..., None, :] + wb[..., None] * b[..., None, :]
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def _arc_extremes(a: Array, b: Array, axis: Array) -> Array:
    """Points of the shorter great-circle arcs ``a[i] -> b[i]`` that lie furthest along +-``axis``.

    Parameters
    ----------
    a, b : (N, 3) float
        Unit arc endpoints (not antipodal).
    axis : (3,) float
        Unit direction (the panorama's up axis for latitude extremes).

    Returns
    -------
    points : (M, 3) float
        For each arc and each sign, the point of its great circle closest to
        ``+-axis``, kept only where it lies strictly inside the arc (the arc's
        extremes are otherwise at its endpoints). ``M <= 2N``.
    """
    n = np.cross(a, b)
    nn = np.linalg.norm(n, axis=1)
    keep = nn > 1e-12
    n, a, b = n[keep] / nn[keep, None], a[keep], b[keep]
    out = []
    for s in (axis, -axis):
        e = s[None, :] - (n @ s)[:, None] * n
        en = np.linalg.norm(e, axis=1)
        ok = en > 1e-12
        e = e[ok] / en[ok, None]
        nk, ak, bk = n[ok], a[ok], b[ok]
        inside = (np.sum(np.cross(ak, e) * nk, axis=1) > 0) & (np.sum(np.cross(e, bk) * nk, axis=1) > 0)
        out.append(e[inside])
    return np.concatenate(out) if out else np.zeros((0, 3))


@dataclass(frozen=True)
class BoxInPano:
    """A perspective box back-projected into the panorama.

    Attributes
    ----------
    outline : (M, 2) float
        Panorama pixels along the box boundary (its spherical outline).
    extent : (4,) float
        ``(u0, v0, u1, v1)``; ``u0 > u1`` means the box wraps the seam. A box
        around a pole spans the full width: ``u0 = 0, u1 = W``.
    """

    outline: Array
    extent: Array

    @property
    def wraps(self) -> bool:
        """True when the extent crosses the left/right seam."""
        return bool(self.extent[0] > self.extent[2])


def _extent_from_rays(rays: Array, center: Array, pano_width: int, pano_height: int,
                      pole_inside: tuple[bool, bool]) -> Array:
    ll = ray_to_lonlat(rays)
    c_lon = ray_to_lonlat(center)[0]
    dlon = np.mod(ll[:, 0] - c_lon + np.pi, 2.0 * np.pi) - np.pi
    lat_max = np.pi / 2 if pole_inside[0] else ll[:, 1].max()
    lat_min = -np.pi / 2 if pole_inside[1] else ll[:, 1].min()
    v0 = (0.5 * np.pi - lat_max) * pano_height / np.pi
    v1 = (0.5 * np.pi - lat_min) * pano_height / np.pi
    if any(pole_inside) or dlon.max() - dlon.min() >= 2.0 * np.pi - 1e-9:
        return np.array([0.0, v0, float(pano_width), v1])
    u0 = (c_lon + dlon.min() + np.pi) * pano_width / (2.0 * np.pi)
    u1 = (c_lon + dlon.max() + np.pi) * pano_width / (2.0 * np.pi)
    return np.array([np.mod(u0, pano_width), v0, np.mod(u1, pano_width), v1])


def poles_in_box(box: ArrayLike, view: PinholeView) -> tuple[bool, bool]:
    """Whether the zenith and the nadir (straight above and below the camera) lie inside a box of a view.

    Parameters
    ----------
    box : (4,) float
        ``(u0, v0, u1, v1)`` in the view's pixels.
    view : PinholeView

    Returns
    -------
    (zenith, nadir) : (bool, bool)
        True where that pole projects in front of the view, inside the box
        (edges included). A box around a pole spans the panorama's whole
        width (:func:`box_to_pano`).

    Examples
    --------
    >>> down = PinholeView(yaw=0.0, pitch=-np.pi / 2, roll=0.0, fov=np.pi / 2, width=100, height=100)
    >>> poles_in_box([40, 40, 60, 60], down), poles_in_box([0, 0, 30, 30], down)
    ((False, True), (False, False))
    """
    b = np.asarray(box, dtype=np.float64)
    puv, front = view.ray_to_pixel(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]))
    inside = front & (puv[:, 0] >= b[0]) & (puv[:, 0] <= b[2]) & (puv[:, 1] >= b[1]) & (puv[:, 1] <= b[3])
    return bool(inside[0]), bool(inside[1])


def box_to_pano(box: ArrayLike, view: PinholeView, pano_width: int, pano_height: int,
                samples_per_edge: int = 16) -> BoxInPano:
    """Back-project an axis-aligned box of a perspective view into the panorama.

    Parameters
    ----------
    box : (4,) float
        ``(u0, v0, u1, v1)`` in the view's pixels, ``u0 < u1``, ``v0 < v1``.
    view : PinholeView
    pano_width, pano_height : int
    samples_per_edge : int
        Points sampled along each edge for the outline (edges of a
        perspective box are great-circle arcs on the sphere).

    Returns
    -------
    BoxInPano
        Its extent contains the projection of every point of the box.
    """
    b = float_array(box, "box")
    if b.shape != (4,) or not (b[0] < b[2] and b[1] < b[3]):
        raise ValueError(f"box: expected (u0, v0, u1, v1) with u0 < u1 and v0 < v1, got {b.tolist()}")
    corners = np.array([[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]])
    t = np.linspace(0.0, 1.0, int(samples_per_edge), endpoint=False)[:, None]
    pts = np.concatenate([corners[i] + t * (corners[(i + 1) % 4] - corners[i]) for i in range(4)])
    rays = view.pixel_to_ray(pts)
    # Great-circle edges bulge towards the poles: the extreme latitude of an edge
    # can lie between samples, so add the exact extremes of each edge arc.
    ends = view.pixel_to_ray(corners)
    dense = np.concatenate([rays, _arc_extremes(ends, np.roll(ends, -1, axis=0), np.array([0.0, 0.0, 1.0]))])
    center = view.pixel_to_ray(np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2]))
    extent = _extent_from_rays(dense, center, pano_width, pano_height, poles_in_box(b, view))
    return BoxInPano(outline=ray_to_pixel(rays, pano_width, pano_height), extent=extent)


def pano_box_union(boxes: ArrayLike, pano_width: int) -> Array:
    """Smallest seam-aware box containing several panorama boxes.

    Parameters
    ----------
    boxes : (N, 4) float
        ``(u0, v0, u1, v1)`` panorama boxes, ``u0 > u1`` when wrapping.
    pano_width : int

    Returns
    -------
    box : (4,) float, ``u0 > u1`` when the union wraps the seam.
    """
    bx = float_array(boxes, "boxes")
    if bx.ndim != 2 or bx.shape[1] != 4 or len(bx) == 0:
        raise ValueError(f"boxes: expected shape (N, 4) with N >= 1, got {bx.shape}")
    W = float(pano_width)
    u0, u1 = bx[:, 0], np.where(bx[:, 2] < bx[:, 0], bx[:, 2] + W, bx[:, 2])
    if np.any(u1 - u0 >= W - 1e-9):
        return np.array([0.0, bx[:, 1].min(), W, bx[:, 3].max()])
    # Try each box start as the union's left edge; keep the narrowest cover.
    best = None
    for s in u0:
        a = np.mod(u0 - s, W)
        e = a + (u1 - u0)
        width = e.max()
        if best is None or width < best[0]:
            best = (width, s)
    width, s = best
    if width >= W:
        return np.array([0.0, bx[:, 1].min(), W, bx[:, 3].max()])
    return np.array([s % W, bx[:, 1].min(), (s + width) % W if s + width > W else s + width, bx[:, 3].max()])
