"""Global alignment of the per-view point clouds (paper Sec. 3.1).

"Each image corresponds to a separate 3D point cloud with unknown scale. We
apply the constraint that corresponding pixels in overlapping regions in the
images have the same depth: we globally align the point clouds by minimizing
the sum of 3D point distances of points corresponding to the overlapping
image regions."

Two steps:

1. Scales. Pixels of neighbouring views that see the same panorama ray are
   correspondences (found by projecting one view's rays into the other).
   The per-view scales ``s_k`` minimising
   ``sum ||s_k p - s_j q||^2`` over all correspondences, with the gauge
   ``s_0 = 1``, solve a small linear least-squares problem; it is
   re-weighted with Tukey's biweight so that mislabelled pixels do not pull.
2. Residual rigid motion. Each scaled view is registered to its two
   neighbours with Open3D's point-to-plane ICP under a robust Tukey kernel
   (normals from the labels), which absorbs small rotations (e.g. a slightly
   wrong vertical vanishing point in one view) and reports Open3D's
   ``fitness`` and ``inlier_rmse`` per view.

Convention:
    Camera-centred frame of :mod:`layout.pointcloud` (camera at the origin,
    z up). ``transformations[k]`` maps view k's lifted points to the aligned
    frame: ``p' = R_k (s_k p) + t_k`` as a 4x4 matrix with the scale folded
    into its upper-left block.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from .pointcloud import ViewCloud

__all__ = ["CloudAlignment", "view_correspondences", "align_view_clouds"]

FloatArray = NDArray[np.float64]


def _o3d():
    try:
        import open3d as o3d
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("layout.align needs Open3D: pip install open3d-cpu") from exc
    return o3d


@dataclass(frozen=True)
class CloudAlignment:
    """Result of :func:`align_view_clouds` (like Open3D's RegistrationResult, one entry per view).

    Attributes (K views)
    ----------
    scales : (K,) float
        Scale of each view about the camera centre, ``scales[0] == 1``.
    transformations : (K, 4, 4) float
        Similarity applied to each view (scale, then the ICP rotation and
        translation).
    fitness : (K,) float
        Open3D ICP fitness: fraction of the view's overlap points with a
        neighbour point within ``max_distance``; NaN for a view with too few
        overlap points to register (it keeps its scale only).
    inlier_rmse : (K,) float
        Open3D ICP RMSE of those inlier correspondences (point-to-plane
        distance), in units of the aligned frame.
    correspondences : (K,) int
        Overlap correspondences of each view with its neighbours.
    scale_rmse : float
        RMS distance between corresponding points after the scale step.

    Convention: camera-centred frame (module docstring).
    """

    scales: FloatArray
    transformations: FloatArray
    fitness: FloatArray
    inlier_rmse: FloatArray
    correspondences: NDArray[np.intp]
    scale_rmse: float

    def apply(self, clouds: Sequence[ViewCloud]) -> list[FloatArray]:
        """Aligned points of every view, a list of (M_k, 3) arrays."""
        if len(clouds) != len(self.scales):
            raise ValueError(f"clouds: expected {len(self.scales)} views, got {len(clouds)}")
        return [c.points @ T[:3, :3].T + T[:3, 3] for c, T in zip(clouds, self.transformations)]

    def apply_points(self, k: int, points: FloatArray) -> FloatArray:
        """Map (M, 3) points lifted in view k (e.g. its ceiling points) to the aligned frame."""
        T = self.transformations[k]
        return np.asarray(points, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]


def view_correspondences(a: ViewCloud, b: ViewCloud) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Indices ``(ia, ib)`` of points of views a and b lifted from the same panorama ray.

    Each point of ``a`` is projected through its ray into view ``b``; when
    it lands on a pixel of ``b`` that was lifted, the two points correspond.
    """
    if len(a) == 0 or len(b) == 0:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    rays = a.points / np.linalg.norm(a.points, axis=1, keepdims=True)
    uv, front = b.view.ray_to_pixel(rays)
    col = np.floor(uv[:, 0]).astype(np.intp)
    row = np.floor(uv[:, 1]).astype(np.intp)
    inside = front & (col >= 0) & (col < b.view.width) & (row >= 0) & (row < b.view.height)
    ia = np.flatnonzero(inside)
    ib = b.pixel_index[row[ia], col[ia]]
    keep = (ib >= 0) & (a.labels[ia] == b.labels[np.maximum(ib, 0)])
    return ia[keep], ib[keep]


def _tukey(r: FloatArray, c: float) -> FloatArray:
    x = np.clip(np.abs(r) / max(c, 1e-12), 0.0, 1.0)
    return (1.0 - x ** 2) ** 2


def _solve_scales(pairs: list[tuple[int, int, FloatArray, FloatArray]], k: int,
                  iterations: int = 4) -> tuple[FloatArray, float]:
    """Scales s (s_0 = 1) minimising the robustly weighted sum of ||s_i p - s_j q||^2."""
    s = np.ones(k)
    weights = [np.ones(len(p)) for _, _, p, _ in pairs]
    rmse = 0.0
    for it in range(iterations):
        A = np.zeros((k, k))
        for (i, j, p, q), w in zip(pairs, weights):
            pp = float(np.sum(w * np.sum(p * p, axis=1)))
            qq = float(np.sum(w * np.sum(q * q, axis=1)))
            pq = float(np.sum(w * np.sum(p * q, axis=1)))
            A[i, i] += pp
            A[j, j] += qq
            A[i, j] -= pq
            A[j, i] -= pq
        # fix the gauge s_0 = 1: minimise over s_1.. with s_0 moved to the right-hand side
        if k > 1 and np.any(A[1:, 1:]):
            sub = A[1:, 1:]
            rhs = -A[1:, 0]
            sol, *_ = np.linalg.lstsq(sub, rhs, rcond=None)
            s = np.concatenate([[1.0], np.where(sol > 1e-6, sol, 1.0)])
        res = [np.linalg.norm(s[i] * p - s[j] * q, axis=1) for i, j, p, q in pairs]
        allres = np.concatenate(res) if res else np.zeros(0)
        rmse = float(np.sqrt(np.mean(allres ** 2))) if allres.size else 0.0
        if allres.size == 0 or it == iterations - 1:
            break
        c = 4.685 * 1.4826 * max(float(np.median(allres)), 1e-9)
        weights = [_tukey(r, c) for r in res]
    return s, rmse


def align_view_clouds(clouds: Sequence[ViewCloud], *, max_distance: float | None = None,
                      icp_iterations: int = 30, neighbours: str = "ring") -> CloudAlignment:
    """Solve per-view scales and small rigid corrections so that overlapping regions coincide.

    Parameters
    ----------
    clouds : sequence of ViewCloud
        One per view, in ring order (view k overlaps k - 1 and k + 1).
    max_distance : float, optional
        ICP correspondence distance; default 3 % of the median point
        distance from the camera.
    icp_iterations : int
        Open3D ICP iterations per view.
    neighbours : {"ring", "all"}
        Which view pairs are searched for correspondences.

    Returns
    -------
    CloudAlignment

    Raises
    ------
    ValueError
        With fewer than two views, or when no two views share a
        correspondence (nothing to align).

    Convention: camera-centred frame (module docstring).

    Examples
    --------
    >>> from layout.labelmap import render_room_labels
    >>> from layout.pointcloud import view_point_clouds
    >>> lab = render_room_labels([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 512)
    >>> clouds = view_point_clouds(lab, 1.0)
    >>> clouds[3] = clouds[3].scaled(1.3)  # one view with another unknown scale
    >>> al = align_view_clouds(clouds)
    >>> np.round(al.scales * 1.3, 2)[3], bool(np.nanmin(al.fitness) > 0.9)
    (np.float64(1.0), True)
    """
    o3d = _o3d()
    k = len(clouds)
    if k < 2:
        raise ValueError(f"clouds: expected at least 2 views, got {k}")
    if neighbours not in ("ring", "all"):
        raise ValueError(f"neighbours: expected 'ring' or 'all', got {neighbours!r}")
    if neighbours == "ring":
        cand = sorted({(min(i, (i + 1) % k), max(i, (i + 1) % k)) for i in range(k)} - {(0, 0)})
    else:
        cand = [(i, j) for i in range(k) for j in range(i + 1, k)]
    pairs = []
    ncorr = np.zeros(k, np.intp)
    for i, j in cand:
        ia, ib = view_correspondences(clouds[i], clouds[j])
        if ia.size:
            pairs.append((i, j, clouds[i].points[ia], clouds[j].points[ib]))
            ncorr[i] += ia.size
            ncorr[j] += ia.size
    if not pairs:
        raise ValueError("clouds: expected overlapping views with corresponding points, got no correspondences")
    scales, scale_rmse = _solve_scales(pairs, k)

    allpts = np.concatenate([c.points * s for c, s in zip(clouds, scales) if len(c)])
    ref = float(np.median(np.linalg.norm(allpts, axis=1))) if len(allpts) else 1.0
    md = 0.03 * ref if max_distance is None else float(max_distance)
    reg = o3d.pipelines.registration
    transformations = np.tile(np.eye(4), (k, 1, 1))
    fitness = np.full(k, np.nan)
    rmse = np.full(k, np.nan)
    for v in range(k):
        transformations[v, :3, :3] *= scales[v]
        nb = [u for u in ((v - 1) % k, (v + 1) % k) if u != v and len(clouds[u])]
        if not len(clouds[v]) or not nb:
            continue
        # source: the points of v that some neighbour also sees
        src_idx = np.unique(np.concatenate([view_correspondences(clouds[v], clouds[u])[0] for u in nb]))
        if src_idx.size < 10:
            continue
        src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(clouds[v].points[src_idx] * scales[v]))
        tgt = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
            np.concatenate([clouds[u].points * scales[u] for u in nb])))
        tgt.normals = o3d.utility.Vector3dVector(np.concatenate([clouds[u].normals for u in nb]))
        est = reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=md))
        res = reg.registration_icp(src, tgt, md, np.eye(4), est,
                                   reg.ICPConvergenceCriteria(max_iteration=int(icp_iterations)))
        T = np.asarray(res.transformation)
        transformations[v, :3, :3] = T[:3, :3] * scales[v]
        transformations[v, :3, 3] = T[:3, 3]
        fitness[v] = res.fitness
        rmse[v] = res.inlier_rmse
    return CloudAlignment(scales=scales, transformations=transformations, fitness=fitness, inlier_rmse=rmse,
                          correspondences=ncorr, scale_rmse=scale_rmse)
