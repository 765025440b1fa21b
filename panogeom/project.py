"""Projection of world-frame 3D geometry (polylines, oriented boxes) into panorama pixels.

Convention (CONVENTIONS.md): world frame in metres, z up, origin on the floor
below the camera, camera centre at ``(0, 0, camera_height)``. ``rotation``
(optional, scene.json's ``camera.rotation``) maps input-camera-frame
directions into the world frame; with it, geometry is projected into the
INPUT panorama. Every point goes through :func:`panogeom.coords.world_to_pixel`.

A straight 3D segment seen from the camera centre lies in a plane through the
centre, so it projects onto a great-circle arc: a curve in the panorama,
sampled here at equal angular steps and split where it crosses the left/right
seam (u = 0 / u = W). Boxes follow the object convention: ``center`` is the
centre of the 3D box, ``size = (l, w, h)`` along the object's own x (its
front), y and z, ``yaw`` turns the object counter-clockwise about +z (seen
from above) from world +x to its front.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array, pano_size
from .coords import DEFAULT_CAMERA_HEIGHT, world_to_pixel
from .perspective import _arc_extremes
from .rotation import check_rotation, rot_z

__all__ = [
    "BOX_EDGES",
    "world_polyline_to_pano",
    "world_box_corners",
    "BoxProjection",
    "world_box_to_pano",
]

Array = NDArray[np.float64]

#: Corner index pairs of the 12 edges of :func:`world_box_corners`: bottom ring, top ring, verticals.
BOX_EDGES: NDArray[np.intp] = np.array([[0, 1], [1, 2], [2, 3], [3, 0],
                                        [4, 5], [5, 6], [6, 7], [7, 4],
                                        [0, 4], [1, 5], [2, 6], [3, 7]])
BOX_EDGES.setflags(write=False)

_BISECT_STEPS = 60


def _camera(camera_height: float) -> Array:
    ch = float(camera_height)
    if not np.isfinite(ch):
        raise ValueError(f"camera_height: expected a finite height in metres, got {camera_height!r}")
    return np.array([0.0, 0.0, ch])


def _segment_params(P: Array, Q: Array, c: Array, n: int) -> Array:
    """Parameters t in [0, 1] of ``P + t (Q - P)`` at ``n`` equal angular steps seen from ``c``.

    A point seen along the slerp ``wa * a/|a| + wb * b/|b|`` of the endpoint
    directions ``a = P - c``, ``b = Q - c`` is ``P + t (Q - P)`` with
    ``t = (wb/|b|) / (wa/|a| + wb/|b|)``.
    """
    a, b = P - c, Q - c
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    s = np.linspace(0.0, 1.0, n)
    cos = np.clip(np.sum(a * b, axis=-1) / (na * nb), -1.0, 1.0)
    ang = np.arccos(cos)[:, None]
    sin = np.sin(ang)
    ok = sin > 1e-12
    safe = np.where(ok, sin, 1.0)
    wa = np.where(ok, np.sin((1.0 - s) * ang) / safe, 1.0 - s)
    wb = np.where(ok, np.sin(s * ang) / safe, s)
    ta, tb = wa / na[:, None], wb / nb[:, None]
    return tb / (ta + tb)


def _check_clear_of_camera(P: Array, Q: Array, c: Array, name: str) -> None:
    """Raise if a point or a segment passes through the camera centre."""
    a, b = P - c, Q - c
    scale = np.maximum(np.maximum(np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)), 1e-300)
    d = b - a
    dd = np.sum(d * d, axis=-1)
    t = np.clip(np.where(dd > 0, -np.sum(a * d, axis=-1) / np.where(dd > 0, dd, 1.0), 0.0), 0.0, 1.0)
    dist = np.linalg.norm(a + t[:, None] * d, axis=-1)
    bad = dist <= 1e-12 * scale
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: expected geometry away from the camera centre {c.tolist()}, "
                         f"got segment {k} from {P[k].tolist()} to {Q[k].tolist()} through it")


def _seam_pieces(uv: Array, P: Array, Q: Array, t_lo: Array, t_hi: Array, width: int, height: int,
                 camera_height: float, rotation: Array | None) -> list[Array]:
    """Split a sampled pixel polyline where it crosses the seam.

    ``uv`` (M, 2) are the samples; the step from sample j to j + 1 runs along
    the 3D segment ``P[j] -> Q[j]`` between parameters ``t_lo[j]`` and
    ``t_hi[j]`` (arrays of length M - 1). The crossing is located by bisection
    on that segment with :func:`world_to_pixel`, so the cut points lie on the
    exact projected curve.
    """
    W = float(width)
    jumps = np.flatnonzero(np.abs(np.diff(uv[:, 0])) > 0.5 * W)
    if len(jumps) == 0:
        return [uv]
    P, Q = P[jumps], Q[jumps]
    lo, hi = t_lo[jumps].copy(), t_hi[jumps].copy()
    u_lo = uv[jumps, 0]
    for _ in range(_BISECT_STEPS):
        mid = 0.5 * (lo + hi)
        um = world_to_pixel(P + mid[:, None] * (Q - P), width, height, camera_height, rotation)[:, 0]
        same = np.abs(um - u_lo) <= 0.5 * W
        lo = np.where(same, mid, lo)
        hi = np.where(same, hi, mid)
    mid = 0.5 * (lo + hi)
    v_cut = world_to_pixel(P + mid[:, None] * (Q - P), width, height, camera_height, rotation)[:, 1]
    end_u = np.where(u_lo > 0.5 * W, W, 0.0)  # the side the curve leaves through
    bounds = np.concatenate([[0], jumps + 1, [len(uv)]])
    pieces = []
    for k in range(len(bounds) - 1):
        parts = [uv[bounds[k]:bounds[k + 1]]]
        if k > 0:
            parts.insert(0, np.array([[W - end_u[k - 1], v_cut[k - 1]]]))
        if k < len(jumps):
            parts.append(np.array([[end_u[k], v_cut[k]]]))
        piece = np.concatenate(parts)
        # A sample exactly on the seam duplicates the cut point next to it.
        dup = np.concatenate([[False], np.all(np.diff(piece, axis=0) == 0, axis=1)])
        pieces.append(piece[~dup])
    return pieces


def _check_size(width: int, height: int, n: int, name: str) -> tuple[int, int, int]:
    w, h = pano_size(width, height)
    if int(n) != n or n < 2:
        raise ValueError(f"{name}: expected an integer >= 2, got {n!r}")
    return w, h, int(n)


def world_polyline_to_pano(points: ArrayLike, width: int, height: int,
                           camera_height: float = DEFAULT_CAMERA_HEIGHT, rotation: ArrayLike | None = None,
                           samples_per_segment: int = 32, closed: bool = False) -> list[Array]:
    """Project a 3D polyline into the panorama as pixel polylines split at the seam.

    Parameters
    ----------
    points : (N, 3) float
        World-frame vertices in metres, N >= 1; no segment may pass through
        the camera centre.
    width, height : int
        Panorama size, W == 2*H.
    camera_height : float
        Height of the camera centre above the floor, metres.
    rotation : (3, 3) float, optional
        Camera-to-world rotation; project into the input panorama.
    samples_per_segment : int
        Samples per segment, endpoints included, at equal angles seen from
        the camera (the curve is a great-circle arc).
    closed : bool
        Also draw the segment from the last vertex back to the first.

    Returns
    -------
    polylines : list of (M, 2) float
        Pixel polylines; consecutive pieces meet at the seam (one ends at
        u = W where the next starts at u = 0, or the other way round). A
        closed polyline starts and ends on the seam when it crosses it.

    Convention: a pixel step counts as a seam crossing when u jumps by more
    than W/2. A curve through a pole direction (straight above or below the
    camera) turns there by half a width at v = 0 (or H), which may be split
    like a seam crossing.

    Examples
    --------
    >>> # a floor line 2 m in front of the camera, from its right (-y) to its left (+y)
    >>> pl = world_polyline_to_pano([[2.0, -1.0, 0.0], [2.0, 1.0, 0.0]], 1024, 512, samples_per_segment=3)
    >>> len(pl), pl[0].round(2)
    (1, array([[587.56, 357.22],
           [512.  , 365.97],
           [436.44, 357.22]]))
    """
    w, h, n = _check_size(width, height, samples_per_segment, "samples_per_segment")
    p = float_array(points, "points", last=3)
    if p.ndim != 2 or len(p) == 0:
        raise ValueError(f"points: expected shape (N, 3) with N >= 1, got {p.shape}")
    R = None if rotation is None else check_rotation(rotation)
    c = _camera(camera_height)
    if closed and len(p) > 1:
        p = np.vstack([p, p[:1]])
    if len(p) == 1:
        _check_clear_of_camera(p, p, c, "points")
        return [world_to_pixel(p, w, h, c[2], R)]
    P, Q = p[:-1], p[1:]
    _check_clear_of_camera(P, Q, c, "points")
    t = _segment_params(P, Q, c, n)  # (segments, n)
    # Samples: the first vertex, then samples 1..n-1 of every segment (sample 0 repeats the
    # previous vertex). The step into sample i of segment k runs from t[k, i-1] to t[k, i].
    t_lo, t_hi = t[:, :-1], t[:, 1:]
    seg = np.repeat(np.arange(len(P)), n - 1)
    pts = np.concatenate([P[:1], (P[:, None] + t_hi[..., None] * (Q - P)[:, None]).reshape(-1, 3)])
    uv = world_to_pixel(pts, w, h, c[2], R)
    pieces = _seam_pieces(uv, P[seg], Q[seg], t_lo.reshape(-1), t_hi.reshape(-1), w, h, c[2], R)
    if closed and len(pieces) > 1:
        pieces = [np.concatenate([pieces[-1], pieces[0][1:]])] + pieces[1:-1]
    return pieces


def world_box_corners(center: ArrayLike, size: ArrayLike, yaw: float) -> Array:
    """Corners of an oriented 3D box.

    Parameters
    ----------
    center : (3,) float
        Centre of the box, world frame, metres.
    size : (3,) float
        ``(l, w, h)``: length along the object's x (towards its front), width
        along its y, height along z; all > 0.
    yaw : float
        Radians, counter-clockwise about +z from world +x to the object's front.

    Returns
    -------
    corners : (8, 3) float
        Bottom face (0-3) then top face (4-7), each counter-clockwise seen
        from above starting at the front-right corner: local
        ``(+l/2, -w/2), (+l/2, +w/2), (-l/2, +w/2), (-l/2, -w/2)``.
        :data:`BOX_EDGES` lists the 12 edges.

    Examples
    --------
    >>> world_box_corners([0.0, 0.0, 0.5], [2.0, 1.0, 1.0], np.pi / 2)[:2].round(12) + 0.0
    array([[ 0.5,  1. ,  0. ],
           [-0.5,  1. ,  0. ]])
    """
    c = float_array(center, "center")
    sz = float_array(size, "size")
    if c.shape != (3,):
        raise ValueError(f"center: expected shape (3,), got {c.shape}")
    if sz.shape != (3,) or not np.all(sz > 0):
        raise ValueError(f"size: expected (l, w, h) with all sizes > 0 metres, got {sz.tolist()}")
    if not np.isfinite(yaw):
        raise ValueError(f"yaw: expected a finite angle in radians, got {yaw!r}")
    sx = np.array([1.0, 1.0, -1.0, -1.0])
    sy = np.array([-1.0, 1.0, 1.0, -1.0])
    local = np.concatenate([np.stack([sx, sy, -np.ones(4)], 1), np.stack([sx, sy, np.ones(4)], 1)]) * (0.5 * sz)
    return local @ rot_z(float(yaw)).T + c


@dataclass(frozen=True)
class BoxProjection:
    """An oriented 3D box projected into the panorama.

    Attributes
    ----------
    corners : (8, 2) float
        Pixels of :func:`world_box_corners`, u in [0, W).
    edges : tuple of 12 tuples of (M, 2) float
        For each edge of :data:`BOX_EDGES`, its pixel polylines (split at the seam).
    extent : (4,) float
        ``(u0, v0, u1, v1)`` containing the whole projected box; ``u0 > u1``
        means it wraps the seam. A box around a pole direction spans the full
        width (``u0 = 0, u1 = W``) and reaches v = 0 (or H); a box around the
        camera covers the whole panorama.
    """

    corners: Array
    edges: tuple[tuple[Array, ...], ...]
    extent: Array

    @property
    def wraps(self) -> bool:
        """True when the extent crosses the left/right seam."""
        return bool(self.extent[0] > self.extent[2])

    @property
    def polylines(self) -> list[Array]:
        """All edge polylines in one list, e.g. for drawing."""
        return [pl for edge in self.edges for pl in edge]


def _ray_hits_box(origin: Array, direction: Array, half: Array) -> bool:
    """Slab test of the ray ``origin + s * direction`` (s >= 0) against ``|x_i| <= half_i``."""
    tmin, tmax = 0.0, np.inf
    for i in range(3):
        if abs(direction[i]) < 1e-15:
            if abs(origin[i]) > half[i]:
                return False
            continue
        t0, t1 = sorted(((-half[i] - origin[i]) / direction[i], (half[i] - origin[i]) / direction[i]))
        tmin, tmax = max(tmin, t0), min(tmax, t1)
    return bool(tmax >= tmin)


def _u_range(u: Array, W: float) -> tuple[float, float]:
    """Smallest circular interval [u0, u1] (u0 > u1 when wrapping) containing all ``u``: cut the largest gap."""
    us = np.sort(np.mod(u, W))
    gaps = np.diff(np.concatenate([us, [us[0] + W]]))
    k = int(np.argmax(gaps))
    if k == len(us) - 1:
        return float(us[0]), float(us[-1])
    return float(us[k + 1]), float(us[k])


def world_box_to_pano(center: ArrayLike, size: ArrayLike, yaw: float, width: int, height: int,
                      camera_height: float = DEFAULT_CAMERA_HEIGHT, rotation: ArrayLike | None = None,
                      samples_per_edge: int = 32) -> BoxProjection:
    """Project an oriented 3D box: its corners, its 12 edges as curves and its pixel extent.

    Parameters
    ----------
    center, size, yaw
        As in :func:`world_box_corners`.
    width, height : int
        Panorama size, W == 2*H.
    camera_height : float
    rotation : (3, 3) float, optional
        Camera-to-world rotation; project into the input panorama.
    samples_per_edge : int
        Samples per edge curve, endpoints included.

    Returns
    -------
    BoxProjection
        The extent is exact for the edge curves: the vertical extreme of each
        great-circle arc is computed analytically, not read off the samples.

    Convention: ``yaw`` counter-clockwise about +z from world +x to the
    object's front, ``size = (l, w, h)`` along the object's x, y, z; pixels via
    :func:`panogeom.coords.world_to_pixel`; ``u0 > u1`` in the extent wraps the seam.

    Examples
    --------
    >>> bp = world_box_to_pano([-3.0, 0.0, 0.5], [1.0, 2.0, 1.0], 0.0, 1024, 512)   # behind the camera
    >>> bp.wraps, len(bp.polylines) > 12
    (True, True)
    """
    w, h, n = _check_size(width, height, samples_per_edge, "samples_per_edge")
    corners = world_box_corners(center, size, yaw)
    R = None if rotation is None else check_rotation(rotation)
    c = _camera(camera_height)
    P, Q = corners[BOX_EDGES[:, 0]], corners[BOX_EDGES[:, 1]]
    _check_clear_of_camera(P, Q, c, "box")
    corners_px = world_to_pixel(corners, w, h, c[2], R)
    edges = tuple(tuple(world_polyline_to_pano(np.stack([p, q]), w, h, c[2], R, n)) for p, q in zip(P, Q))
    samples = np.concatenate([pl for edge in edges for pl in edge])

    # Where do the camera's up and down directions leave through the box?
    half = 0.5 * float_array(size, "size")
    to_local = rot_z(float(yaw))  # row vectors: x_local = (x - center) @ Rz(yaw)
    origin = (c - float_array(center, "center")) @ to_local
    if np.all(np.abs(origin) < half):
        return BoxProjection(corners=corners_px, edges=edges, extent=np.array([0.0, 0.0, float(w), float(h)]))
    up = np.array([0.0, 0.0, 1.0]) if R is None else R[:, 2]
    north = _ray_hits_box(origin, up @ to_local, half)
    south = _ray_hits_box(origin, -up @ to_local, half)

    # Vertical extremes of each edge arc: the point of its great circle closest to +-up, if on the arc.
    a, b = P - c, Q - c
    extra_pts = _arc_extremes(a / np.linalg.norm(a, axis=1, keepdims=True),
                              b / np.linalg.norm(b, axis=1, keepdims=True), up)
    vs = samples[:, 1]
    if len(extra_pts):
        vs = np.concatenate([vs, world_to_pixel(c + extra_pts, w, h, c[2], R)[:, 1]])
    v0 = 0.0 if north else float(vs.min())
    v1 = float(h) if south else float(vs.max())
    if north or south:
        u0, u1 = 0.0, float(w)
    else:
        u0, u1 = _u_range(samples[:, 0], float(w))
    return BoxProjection(corners=corners_px, edges=edges, extent=np.array([u0, v0, u1, v1]))
