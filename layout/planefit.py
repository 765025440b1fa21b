"""Greedy Manhattan plane fitting on the aligned wall points (paper Sec. 3.1).

"This is followed by greedy plane fitting, starting from the largest
segment, using the Iterative Closest Point algorithm, resulting in an
initial estimate of 3D room geometry."

:func:`fit_manhattan_planes` repeatedly takes the plane with the most
inliers among the remaining wall points (Open3D ``segment_plane``, RANSAC),
snaps its normal to the nearest horizontal axis (x or y; planes more than
``max_tilt`` off are set aside), re-estimates its offset as the median of
its inliers, splits the inliers into contiguous segments along the viewing
angle (two walls on one line, e.g. the ends of a U-shaped room, are two
segments) and removes them. When no plane with enough inliers is left, an
ICP-style refinement alternates between assigning every wall point to the
nearest segment plane of its own label and angular range and re-estimating
each offset. :func:`pointcloud_walls` runs the whole paper route - view
clouds, Open3D alignment, plane fitting - and returns the wall observations
for :func:`layout.floorplan.close_manhattan_polygon`.

Convention:
    Camera-centred world axes (:mod:`layout.pointcloud`) until the metric
    step; ``axis = 0`` is a plane ``x = offset`` (label 3), ``axis = 1`` a
    plane ``y = offset`` (label 4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .align import CloudAlignment, align_view_clouds
from .floorplan import WallObservation
from .labelmap import FLOOR, WALL_X, WALL_Y
from .pointcloud import view_point_clouds

__all__ = ["ManhattanPlane", "fit_manhattan_planes", "PointCloudWalls", "pointcloud_walls"]

FloatArray = NDArray[np.float64]
_TWO_PI = 2.0 * np.pi


def _o3d():
    try:
        import open3d as o3d
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("layout.planefit needs Open3D: pip install open3d-cpu") from exc
    return o3d


@dataclass(frozen=True)
class ManhattanPlane:
    """A vertical, axis-aligned wall segment found in the point cloud.

    Attributes
    ----------
    axis : int
        0: plane ``x = offset``; 1: plane ``y = offset``.
    offset : float
    lon_start, lon_end : float
        Viewing-angle range of its points (panorama longitude, unwrapped so
        that ``lon_start <= lon_end``).
    inliers : int
    rmse : float
        RMS distance of its inliers to the plane.
    order : int
        0 for the largest (first) segment, then in the greedy order.
    """

    axis: int
    offset: float
    lon_start: float
    lon_end: float
    inliers: int
    rmse: float
    order: int

    def observation(self) -> WallObservation:
        return WallObservation(axis=self.axis, offset=self.offset, lon_start=self.lon_start, lon_end=self.lon_end,
                               support=self.inliers, spread=self.rmse)


def _angular_segments(lon: FloatArray, max_gap: float) -> list[NDArray[np.intp]]:
    """Split indices of points into runs of contiguous viewing angle (circular)."""
    if lon.size == 0:
        return []
    order = np.argsort(lon)
    sl = lon[order]
    gaps = np.diff(np.concatenate([sl, [sl[0] + _TWO_PI]]))
    cuts = np.flatnonzero(gaps > max_gap)
    if cuts.size == 0:
        return [order]
    start = (cuts[-1] + 1) % len(sl)
    rolled = np.roll(order, -start)
    rolled_cuts = (cuts - start) % len(sl)
    bounds = np.sort(rolled_cuts) + 1
    return [seg for seg in np.split(rolled, bounds) if seg.size]


def _segment_range(lon: FloatArray) -> tuple[float, float]:
    """Unwrapped (start, end) of a set of angles known to be contiguous."""
    if lon.size == 1:
        return float(lon[0]), float(lon[0])
    sl = np.sort(lon)
    gaps = np.diff(np.concatenate([sl, [sl[0] + _TWO_PI]]))
    g = int(np.argmax(gaps))  # the largest gap is outside the segment
    start = sl[(g + 1) % len(sl)]
    end = sl[g]
    return float(start), float(start + (end - start) % _TWO_PI)


def fit_manhattan_planes(points: ArrayLike, labels: ArrayLike, lon: ArrayLike, *,
                         distance_threshold: float, min_points: int = 30, max_planes: int = 24,
                         max_tilt: float = np.deg2rad(12.0), max_gap: float = np.deg2rad(4.0),
                         icp_iterations: int = 3, seed: int = 0) -> list[ManhattanPlane]:
    """Greedy Manhattan plane fitting, largest segment first (Open3D RANSAC + ICP-style refinement).

    Parameters
    ----------
    points : (M, 3) float
        Aligned wall points (camera-centred).
    labels : (M,) int
        3 or 4 per point; a plane keeps only the inliers of its own label.
    lon : (M,) float
        Viewing angle of each point (for the angular split).
    distance_threshold : float
        RANSAC inlier distance (units of ``points``).
    min_points : int
        Smallest segment kept.
    max_planes : int
        Upper bound on greedy iterations.
    max_tilt : float
        Radians a RANSAC normal may deviate from the x or y axis.
    max_gap : float
        Radians of viewing angle without inliers that split a plane into
        two segments.
    icp_iterations : int
        Assignment / re-estimation rounds after the greedy pass.
    seed : int
        Open3D's random seed (the result is reproducible).

    Returns
    -------
    list of ManhattanPlane, in greedy order (largest first).

    Convention: ``axis`` 0 is ``x = offset`` (label 3), 1 is ``y = offset``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> y = rng.uniform(-1, 2, 300); z = rng.uniform(-1, 1, 300)
    >>> wall = np.stack([np.full(300, 3.0), y, z], axis=1)  # the plane x = 3
    >>> lon = -np.arctan2(wall[:, 1], wall[:, 0])
    >>> planes = fit_manhattan_planes(wall, np.full(300, 3), lon, distance_threshold=0.02)
    >>> [(p.axis, round(p.offset, 3), p.inliers) for p in planes]
    [(0, 3.0, 300)]
    """
    o3d = _o3d()
    pts = np.asarray(points, dtype=np.float64)
    lab = np.asarray(labels)
    ang = np.asarray(lon, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or lab.shape != (len(pts),) or ang.shape != (len(pts),):
        raise ValueError(f"expected points (M, 3), labels (M,), lon (M,), got {pts.shape}, {lab.shape}, {ang.shape}")
    if not (np.isfinite(distance_threshold) and distance_threshold > 0):
        raise ValueError(f"distance_threshold: expected a positive value, got {distance_threshold!r}")
    o3d.utility.random.seed(int(seed))
    axis_of = np.where(lab == WALL_X, 0, np.where(lab == WALL_Y, 1, -1))
    remaining = np.flatnonzero(axis_of >= 0)
    segments: list[tuple[int, float, NDArray[np.intp]]] = []
    rejected = 0
    for _ in range(int(max_planes)):
        if remaining.size < max(min_points, 3):
            break
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts[remaining]))
        model, inl = pc.segment_plane(distance_threshold=float(distance_threshold), ransac_n=3,
                                      num_iterations=500)
        inl = np.asarray(inl, dtype=np.intp)
        n = np.asarray(model[:3], dtype=np.float64)
        n = n / max(np.linalg.norm(n), 1e-12)
        ax = int(np.argmax(np.abs(n[:2])))
        if inl.size < min_points:
            break
        if np.abs(n[ax]) < np.cos(max_tilt):
            # not a Manhattan wall: set these points aside and go on
            remaining = np.delete(remaining, inl)
            rejected += inl.size
            continue
        cand = remaining[inl]
        cand = cand[axis_of[cand] == ax]
        if cand.size < min_points:
            remaining = np.delete(remaining, inl)
            continue
        off = float(np.median(pts[cand, ax]))
        near = remaining[(np.abs(pts[remaining, ax] - off) <= distance_threshold) & (axis_of[remaining] == ax)]
        for seg in _angular_segments(ang[near], max_gap):
            idx = near[seg]
            if idx.size >= min_points:
                segments.append((ax, float(np.median(pts[idx, ax])), idx))
        remaining = np.setdiff1d(remaining, near, assume_unique=True)

    # ICP-style refinement: reassign every wall point to the nearest segment of its axis and angular range
    wall_idx = np.flatnonzero(axis_of >= 0)
    for _ in range(int(icp_iterations)):
        if not segments:
            break
        ranges = [_segment_range(ang[idx]) for _, _, idx in segments]
        best = np.full(wall_idx.size, -1)
        best_d = np.full(wall_idx.size, np.inf)
        for s_i, ((ax, off, _), (lo, hi)) in enumerate(zip(segments, ranges)):
            rel = (ang[wall_idx] - lo) % _TWO_PI
            inside = (rel <= (hi - lo) + 1e-9) & (axis_of[wall_idx] == ax)
            d = np.abs(pts[wall_idx, ax] - off)
            better = inside & (d < best_d) & (d <= distance_threshold)
            best[better], best_d[better] = s_i, d[better]
        new = []
        for s_i, (ax, off, idx) in enumerate(segments):
            members = wall_idx[best == s_i]
            if members.size >= min_points:
                new.append((ax, float(np.median(pts[members, ax])), members))
        segments = new

    planes = []
    for order, (ax, off, idx) in enumerate(segments):
        lo, hi = _segment_range(ang[idx])
        r = float(np.sqrt(np.mean((pts[idx, ax] - off) ** 2)))
        planes.append(ManhattanPlane(axis=ax, offset=off, lon_start=lo, lon_end=hi, inliers=int(idx.size), rmse=r,
                                     order=order))
    return planes


@dataclass(frozen=True)
class PointCloudWalls:
    """Result of the paper route up to the wall planes (:func:`pointcloud_walls`).

    Attributes
    ----------
    walls : tuple of WallObservation
        Metric wall observations (camera at the origin of x, y).
    planes : tuple of ManhattanPlane
        The fitted planes in the aligned (unit) frame, greedy order.
    alignment : CloudAlignment
    ceiling_z : float
        Metric ceiling height.
    ceiling_support : int
        Wall-top points behind it.
    points_xy : (M, 2) float
        Metric wall points seen from above.
    unit : float
        Metres per aligned unit (camera height / aligned camera height).
    reasons : tuple of str
        What makes the estimate uncertain (empty when nothing).
    """

    walls: tuple[WallObservation, ...]
    planes: tuple[ManhattanPlane, ...]
    alignment: CloudAlignment
    ceiling_z: float
    ceiling_support: int
    points_xy: FloatArray
    unit: float
    reasons: tuple[str, ...]


def pointcloud_walls(labels: ArrayLike, camera_height: float, *, object_mask: ArrayLike | None = None,
                     view_size: int | None = None, distance_threshold: float = 0.04,
                     seed: int = 0) -> PointCloudWalls:
    """The paper's route from labels to wall observations: view clouds, alignment, greedy planes.

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels 0..5, W == 2*H.
    camera_height : float
        Metres; sets the metric scale after alignment.
    object_mask : (H, W) bool, optional
    view_size : int, optional
        Width of the six views (default W / 4).
    distance_threshold : float
        Plane inlier distance in camera heights.
    seed : int
        RANSAC seed.

    Returns
    -------
    PointCloudWalls

    Raises
    ------
    ValueError
        When the views hold no wall points or do not overlap.

    Convention: metric output in the world x, y of the camera (origin below
    it); scale from the aligned floor: the median floor point lies one
    camera height below the camera.
    """
    h_cam = float(camera_height)
    if not (np.isfinite(h_cam) and h_cam > 0):
        raise ValueError(f"camera_height: expected a positive finite height, got {camera_height!r}")
    clouds = view_point_clouds(labels, 1.0, object_mask=object_mask, view_size=view_size)
    alignment = align_view_clouds(clouds)
    aligned = alignment.apply(clouds)
    pts = np.concatenate(aligned)
    labs = np.concatenate([c.labels for c in clouds])
    lon = np.concatenate([c.lon for c in clouds])
    floor_z = pts[labs == FLOOR, 2]
    if floor_z.size == 0 or not np.median(floor_z) < 0:
        raise ValueError("labels: expected floor pixels below the horizon in the views, got none")
    cam_units = -float(np.median(floor_z))  # aligned camera height
    unit = h_cam / cam_units
    wall = labs >= WALL_X
    if np.count_nonzero(wall) < 10:
        raise ValueError("labels: expected wall pixels meeting the floor in the views, got none")
    planes = fit_manhattan_planes(pts[wall], labs[wall], lon[wall], distance_threshold=distance_threshold * cam_units,
                                  min_points=max(10, int(np.count_nonzero(wall)) // 400), seed=seed)
    ceil = [alignment.apply_points(k, c.ceiling_points) for k, c in enumerate(clouds) if len(c.ceiling_points)]
    ceil_z = np.concatenate(ceil)[:, 2] if ceil else np.zeros(0)
    reasons: list[str] = []
    if ceil_z.size:
        ceiling_z = (float(np.median(ceil_z)) + cam_units) * unit
    else:
        ceiling_z = float("nan")
        reasons.append("no wall top visible in the views")
    fit = alignment.fitness[np.isfinite(alignment.fitness)]
    if fit.size and np.min(fit) < 0.5:
        reasons.append(f"view alignment weak (lowest ICP fitness {float(np.min(fit)):.2f})")
    if fit.size < len(clouds) // 2:
        reasons.append(f"only {fit.size} of {len(clouds)} views overlap enough to be registered")
    walls = tuple(WallObservation(axis=p.axis, offset=p.offset * unit, lon_start=p.lon_start, lon_end=p.lon_end,
                                  support=p.inliers, spread=p.rmse * unit) for p in planes)
    return PointCloudWalls(walls=walls, planes=tuple(planes), alignment=alignment, ceiling_z=ceiling_z,
                           ceiling_support=int(ceil_z.size), points_xy=pts[wall, :2] * unit, unit=unit,
                           reasons=tuple(reasons))
