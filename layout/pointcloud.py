"""Per-view 3D point clouds from surface labels (paper Sec. 3.1, after Delage et al.).

The label panorama is cut into the paper's K = 6 perspective views
(:func:`panogeom.perspective.layout_views`: 90 degree FOV, 30 degree
overlap). In each view, as in Delage et al.'s single-image reconstruction,

* floor pixels are lifted onto the floor plane, one camera height below the
  camera;
* wall pixels are lifted onto the vertical line through their column's
  floor contact (the lowest wall pixel touching the floor): a wall is
  vertical, so the whole column of wall pixels shares the contact's
  horizontal distance;
* the column's ceiling contact, lifted the same way, gives a point of the
  wall top (the wall height).

Each view is its own point cloud with its own unknown scale: it is lifted
with a unit camera height, and :mod:`layout.align` finds the scales that
make overlapping regions agree. Object pixels (label 5 or the mask) and
clutter are never lifted.

Convention:
    Points are in the camera-centred frame: the panorama's world axes
    (x at lon = 0, y at lon = -pi/2, z up, shared/CONVENTIONS.md) with the
    camera centre at the origin, so the floor of a view lifted with camera
    height ``h`` lies at ``z = -h``. Normals come from the labels: floor
    (0, 0, 1), label 3 (+-1, 0, 0), label 4 (0, +-1, 0), facing the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import ray_to_lonlat
from panogeom.perspective import PinholeView, equirect_to_perspective, ring_views

from .labelmap import FLOOR, OBJECT, WALL_X, WALL_Y, check_label_map, observe_boundaries

__all__ = ["ViewCloud", "view_point_clouds", "lift_view"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ViewCloud:
    """The 3D points lifted from one perspective view.

    Attributes (M points, K ceiling points, view image h x w)
    ----------
    view : PinholeView
    points : (M, 3) float
        Camera-centred coordinates (module docstring), in units of the
        camera height used for lifting.
    normals : (M, 3) float
        Unit normals from the labels, facing the camera.
    labels : (M,) uint8
        1 floor, 3 or 4 wall.
    lon : (M,) float
        Panorama longitude of each point's view column (radians).
    pixel_index : (h, w) int
        Index into ``points`` of the point lifted from each view pixel, -1
        where none.
    ceiling_points : (K, 3) float
        Wall tops at the columns' ceiling contacts.
    camera_height : float
        The height used for lifting (this view's scale).

    Convention: camera-centred frame, see the module docstring.
    """

    view: PinholeView
    points: FloatArray
    normals: FloatArray
    labels: NDArray[np.uint8]
    lon: FloatArray
    pixel_index: NDArray[np.intp]
    ceiling_points: FloatArray
    camera_height: float

    def __len__(self) -> int:
        return int(len(self.points))

    def scaled(self, factor: float) -> "ViewCloud":
        """The same cloud scaled about the camera centre (another unknown scale)."""
        f = float(factor)
        if not (np.isfinite(f) and f > 0):
            raise ValueError(f"factor: expected a positive finite scale, got {factor!r}")
        return replace(self, points=self.points * f, ceiling_points=self.ceiling_points * f,
                       camera_height=self.camera_height * f)


def lift_view(view_labels: ArrayLike, view: PinholeView, camera_height: float = 1.0, *,
              floor_stride: int = 4, wall_rows: int = 6) -> ViewCloud:
    """Lift one perspective label image to 3D through the floor contacts of its columns.

    Parameters
    ----------
    view_labels : (h, w) uint8
        Surface labels of a pitch-0, roll-0 view (columns are vertical world
        lines, the horizon is row h / 2).
    view : PinholeView
    camera_height : float
        Height of the camera above the floor used for lifting (the view's
        scale; 1 for "unknown").
    floor_stride : int
        Lift every ``floor_stride``-th floor pixel in both directions.
    wall_rows : int
        Wall pixels lifted per column of a wall as tall as a quarter of the
        view (they lie on a grid of rows common to all columns).

    Returns
    -------
    ViewCloud

    Convention: camera-centred frame (module docstring).
    """
    lab = np.asarray(view_labels)
    if lab.shape != (view.height, view.width):
        raise ValueError(f"view_labels: expected shape {(view.height, view.width)}, got {lab.shape}")
    if abs(view.pitch) > 1e-9 or abs(view.roll) > 1e-9:
        raise ValueError(f"view: expected a level view (pitch = roll = 0), got pitch={view.pitch}, roll={view.roll}")
    h_cam = float(camera_height)
    if not (np.isfinite(h_cam) and h_cam > 0):
        raise ValueError(f"camera_height: expected a positive finite height, got {camera_height!r}")
    h, w = lab.shape
    ob = observe_boundaries(lab, horizon=h // 2, window=max(2, h // 96), max_gap=max(1, h // 192))
    cols = np.arange(w)
    index = np.full((h, w), -1, dtype=np.intp)
    pts, nrm, labs, pix = [], [], [], []

    # floor pixels -> plane z = -h
    rr, cc = np.nonzero(lab[::floor_stride, ::floor_stride] == FLOOR)
    rr, cc = rr * floor_stride, cc * floor_stride
    if rr.size:
        rays = view.pixel_to_ray(np.stack([cc + 0.5, rr + 0.5], axis=-1))
        down = rays[:, 2] < -1e-6
        rays, rr, cc = rays[down], rr[down], cc[down]
        p = rays * (-h_cam / rays[:, 2])[:, None]
        pts.append(p)
        nrm.append(np.tile([0.0, 0.0, 1.0], (len(p), 1)))
        labs.append(np.full(len(p), FLOOR, np.uint8))
        pix.append(np.stack([rr, cc], axis=-1))

    # wall pixels -> vertical line through the column's floor contact
    contact = ob.floor_contact & (ob.floor_v > h / 2 + 0.5)
    c_ok = cols[contact]
    ceil_pts = np.zeros((0, 3))
    if c_ok.size:
        fv = ob.floor_v[contact]
        fr = view.pixel_to_ray(np.stack([c_ok + 0.5, fv], axis=-1))
        rho = -h_cam * np.hypot(fr[:, 0], fr[:, 1]) / fr[:, 2]  # horizontal distance of the contact
        # wall rows of each contact column on a global row grid (so that no horizontal plane collects
        # one sample of every column), from the ceiling contact (or the top) down to the floor contact
        top = np.where(np.isfinite(ob.ceil_v[contact]), ob.ceil_v[contact], 0.0)
        stride = max(1, h // (4 * wall_rows))
        grid = np.arange(0, h, stride)
        rows = np.broadcast_to(grid[None, :], (c_ok.size, grid.size))
        in_run = (rows >= top[:, None]) & (rows + 1 <= fv[:, None])
        rows = np.where(in_run, rows, 0)
        cc2 = np.broadcast_to(c_ok[:, None], rows.shape)
        lv = lab[rows, cc2]
        is_wall = ((lv == WALL_X) | (lv == WALL_Y)) & in_run
        r_w, c_w, rho_w, l_w = rows[is_wall], cc2[is_wall], np.broadcast_to(rho[:, None], rows.shape)[is_wall], lv[is_wall]
        if r_w.size:
            rays = view.pixel_to_ray(np.stack([c_w + 0.5, r_w + 0.5], axis=-1))
            p = rays * (rho_w / np.hypot(rays[:, 0], rays[:, 1]))[:, None]
            n = np.zeros_like(p)
            ax = np.where(l_w == WALL_X, 0, 1)
            n[np.arange(len(p)), ax] = -np.sign(p[np.arange(len(p)), ax])
            pts.append(p)
            nrm.append(n)
            labs.append(l_w.astype(np.uint8))
            pix.append(np.stack([r_w, c_w], axis=-1))
        has_c = np.isfinite(ob.ceil_v[contact]) & ob.ceil_contact[contact]
        if np.any(has_c):
            cr = view.pixel_to_ray(np.stack([c_ok[has_c] + 0.5, ob.ceil_v[contact][has_c]], axis=-1))
            ceil_pts = cr * (rho[has_c] / np.hypot(cr[:, 0], cr[:, 1]))[:, None]

    if pts:
        points = np.concatenate(pts)
        normals = np.concatenate(nrm)
        labels = np.concatenate(labs)
        pixels = np.concatenate(pix)
    else:
        points, normals = np.zeros((0, 3)), np.zeros((0, 3))
        labels, pixels = np.zeros(0, np.uint8), np.zeros((0, 2), np.intp)
    index[pixels[:, 0], pixels[:, 1]] = np.arange(len(points))
    col_rays = view.pixel_to_ray(np.stack([cols + 0.5, np.full(w, h / 2)], axis=-1))
    col_lon = ray_to_lonlat(col_rays)[:, 0]
    lon = col_lon[pixels[:, 1]] if len(points) else np.zeros(0)
    return ViewCloud(view=view, points=points, normals=normals, labels=labels, lon=lon, pixel_index=index,
                     ceiling_points=ceil_pts, camera_height=h_cam)


def view_point_clouds(labels: ArrayLike, camera_height: float = 1.0, *, object_mask: ArrayLike | None = None,
                      views: Sequence[PinholeView] | None = None, view_size: int | None = None,
                      floor_stride: int = 4, wall_rows: int = 6) -> list[ViewCloud]:
    """One point cloud per perspective view of a label panorama (the paper's K = 6 views by default).

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels 0..5, W == 2*H, upright.
    camera_height : float
        Lifting height of every view (1: unknown scale).
    object_mask : (H, W) bool, optional
        Object regions, never lifted.
    views : sequence of PinholeView, optional
        Level views (pitch = roll = 0). Default: the paper's six views
        (:func:`panogeom.perspective.layout_views`: 90 degree horizontal
        FOV, 30 degree overlap) made twice as tall as wide, a vertical FOV
        of 127 degrees, so that the floor contact of walls closer than the
        camera height stays inside the view.
    view_size : int, optional
        Width of the default views; default W / 4 (the panorama's own
        resolution over 90 degrees).
    floor_stride, wall_rows : int
        Sampling of floor and wall pixels (see :func:`lift_view`).

    Returns
    -------
    list of ViewCloud

    Convention: camera-centred frame (module docstring); labels are
    resampled with nearest-neighbour interpolation.

    Examples
    --------
    >>> from layout.labelmap import render_room_labels
    >>> lab = render_room_labels([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 512)
    >>> clouds = view_point_clouds(lab, 1.6)
    >>> len(clouds), bool(np.allclose(clouds[0].points[clouds[0].labels == 1, 2], -1.6))
    (6, True)
    """
    lab = check_label_map(labels)
    if object_mask is not None:
        m = np.asarray(object_mask)
        if m.shape != lab.shape:
            raise ValueError(f"object_mask: expected shape {lab.shape}, got {m.shape}")
        lab = np.where(m.astype(bool), np.uint8(OBJECT), lab)
    if views is None:
        size = max(32, lab.shape[1] // 4) if view_size is None else int(view_size)
        views = ring_views(6, np.pi / 2, (2 * size, size))
    out = []
    for v in views:
        lv = equirect_to_perspective(lab, v, interpolation="nearest")
        out.append(lift_view(lv, v, camera_height, floor_stride=floor_stride, wall_rows=wall_rows))
    return out
