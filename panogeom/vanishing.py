"""Manhattan vanishing points of a panorama from its line segments.

In a Manhattan room every structural line runs along one of three mutually
orthogonal directions; on the sphere, the great circles of all lines along a
direction ``m`` pass through ``+-m`` (its vanishing points), i.e. their
normals satisfy ``n . m = 0``. The estimation (:func:`estimate_manhattan_frame`)
goes:

1. vertical: hypotheses ``n_i x n_j`` from pairs of long arcs whose great
   circles pass within ``max_tilt`` of the image's up direction, scored by
   the length-weighted consensus of all arcs (a truncated quadratic kernel
   of ``n . m``); the best one is refined by weighted least squares;
2. horizontal: every heading ``phi`` in [0, pi/2) (the two horizontal axes
   repeat every 90 degrees) is scored on a grid in the same way, each arc
   voting for its own heading ``v x n`` (exact, not a grid value), then
   refined;
3. joint refinement: iteratively re-weighted Gauss-Newton over the rotation
   (three parameters, so the three axes stay exactly orthogonal) minimising
   ``sum w_i (n_i . m_k(i))^2`` over the arcs assigned to each axis.

Convention: directions are unit vectors in the input panorama's camera frame
(CONVENTIONS.md: x at the centre column, y a quarter width to the left, z the
image's up). The axis closest to the image's up is the vertical; the result's
rows are ``(x, y, up)``, right-handed, with ``x`` the horizontal axis closest
to the horizontal projection of the input's x (the centre column), so the
matrix of rows maps input-camera directions into the Manhattan frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array
from .lines import LineSegments

__all__ = [
    "VanishingPointError",
    "ManhattanFrame",
    "estimate_manhattan_frame",
    "assign_segments",
    "vertical_hypotheses",
]

Array = NDArray[np.float64]

_UP = np.array([0.0, 0.0, 1.0])
_X = np.array([1.0, 0.0, 0.0])


class VanishingPointError(ValueError):
    """The line segments do not determine a Manhattan frame (too few, or no consensus).

    The message says which stage failed and with what numbers; nothing is
    estimated from such input.
    """


@dataclass(frozen=True)
class ManhattanFrame:
    """Three orthogonal vanishing directions and the segments supporting them.

    Attributes
    ----------
    axes : (3, 3) float
        Rows ``(x, y, up)``: unit directions in the input camera frame,
        a proper rotation (``axes @ d`` expresses an input direction in the
        Manhattan frame). ``up`` is the axis closest to the image's up
        (``+z``) with ``up[2] > 0``; ``x`` is the horizontal axis (of
        ``+-x, +-y``) closest to the input's centre-column direction.
    labels : (N,) int
        Axis index (0, 1, 2) each segment is assigned to, or -1 for none.
    support : (3,) float
        Total length (radians) of the segments assigned to each axis.
    rmse : float
        Root mean square of the inliers' angular distance (radians) from
        their vanishing point's great circle condition, ``asin(|n . m|)``.
    inlier_fraction : float
        Share of the total segment length assigned to an axis.
    significance : (3,) float
        How far each axis' support exceeds what as many arcs with random
        directions would give, in standard deviations (the support of a
        fixed direction by random arcs has mean ``p * sum(L)`` and variance
        ``p (1 - p) sum(L^2)``, ``p = sin(inlier_angle)``; the horizontal
        axes are measured against the non-vertical arcs).

    Convention: input camera frame of CONVENTIONS.md; radians.
    """

    axes: Array
    labels: NDArray[np.int64]
    support: Array
    rmse: float
    inlier_fraction: float
    significance: Array

    @property
    def vertical(self) -> Array:
        """(3,) the up direction in the input camera frame."""
        return self.axes[2].copy()

    @property
    def tilt(self) -> float:
        """Angle between the image's up and the true vertical, radians."""
        return float(np.arccos(np.clip(self.axes[2, 2], -1.0, 1.0)))

    @property
    def counts(self) -> NDArray[np.int64]:
        """(3,) number of segments assigned to each axis."""
        return np.bincount(self.labels[self.labels >= 0], minlength=3)[:3]


def vertical_hypotheses(normals: ArrayLike, weights: ArrayLike, max_tilt: float, max_arcs: int = 150,
                        min_cross: float = np.deg2rad(5.0)) -> Array:
    """Candidate vertical directions from pairs of arcs (great-circle intersections).

    Parameters
    ----------
    normals : (N, 3) float
        Unit arc normals in the input camera frame.
    weights : (N,) float
        The ``max_arcs`` heaviest arcs whose great circle passes within
        ``max_tilt`` of ``+z`` are paired.
    max_tilt : float
        Largest angle (radians) between a hypothesis and the image's up.
    max_arcs : int
    min_cross : float
        Pairs of circles crossing at less than this angle (radians) are
        ill-conditioned and skipped.

    Returns
    -------
    hyps : (M, 3) float
        Unit directions with ``angle(h, +z) <= max_tilt`` (possibly M == 0).

    Examples
    --------
    >>> n = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    >>> vertical_hypotheses(n, [1.0, 1.0, 1.0], np.deg2rad(20)).round(6) + 0.0
    array([[0., 0., 1.]])
    """
    n = float_array(normals, "normals", last=3).reshape(-1, 3)
    w = float_array(weights, "weights").reshape(-1)
    if len(w) != len(n):
        raise ValueError(f"weights: expected shape ({len(n)},), got {w.shape}")
    near = np.flatnonzero(np.abs(n[:, 2]) < np.sin(max_tilt) + 1e-12)
    near = near[np.argsort(-w[near], kind="stable")[:max_arcs]]
    if len(near) < 2:
        return np.zeros((0, 3))
    i, j = np.triu_indices(len(near), k=1)
    h = np.cross(n[near[i]], n[near[j]])
    s = np.linalg.norm(h, axis=1)
    keep = s > np.sin(min_cross)
    h = h[keep] / s[keep, None]
    h *= np.where(h[:, 2] < 0, -1.0, 1.0)[:, None]
    return h[h[:, 2] >= np.cos(max_tilt)]


def _consensus(normals: Array, w: Array, dirs: Array, tol: float) -> Array:
    """Truncated-quadratic consensus of each direction in ``dirs`` (M, 3): (M,) scores."""
    # einsum's plain loop: BLAS is slow (and multi-threaded) for an inner dimension of 3
    r = np.einsum("ij,kj->ik", dirs.astype(np.float32), normals.astype(np.float32))
    r *= np.float32(1.0 / np.sin(tol))
    np.square(r, out=r)
    np.subtract(np.float32(1.0), r, out=r)
    np.maximum(r, np.float32(0.0), out=r)
    return np.einsum("ij,j->i", r, w.astype(np.float32)).astype(np.float64)


def _refine_axis(normals: Array, w: Array, m: Array, tol: float, iters: int = 3) -> Array:
    for _ in range(iters):
        inl = np.abs(normals @ m) < np.sin(tol)
        if inl.sum() < 2:
            break
        nn = normals[inl]
        scatter = (nn * w[inl, None]).T @ nn
        new = np.linalg.eigh(scatter)[1][:, 0]
        m = new if new @ m >= 0 else -new
    return m


def _significance(support: float, pool: Array, angle: float) -> float:
    """How far a length-weighted support exceeds chance, in standard deviations.

    A great circle with a uniformly random normal passes within ``angle`` of
    a fixed direction with probability ``p = sin(angle)``; for arcs of
    lengths ``pool`` the support of a fixed direction then has mean
    ``p * sum(L)`` and variance ``p (1 - p) sum(L^2)``.
    """
    p = float(np.sin(angle))
    var = p * (1.0 - p) * float(np.sum(pool * pool))
    if var <= 0:
        return 0.0
    return float((support - p * float(np.sum(pool))) / np.sqrt(var))


def _spread(normals: Array, w: Array) -> float:
    """Angular spread (radians) of the normals of the arcs meeting at one point.

    ``atan(sqrt(l2 / l3))`` from the eigenvalues ``l1 <= l2 <= l3`` of the
    weighted scatter: 0 when all arcs lie on one great circle (which does not
    locate a point on it), about the RMS angle between the circles otherwise.
    """
    if len(normals) < 2:
        return 0.0
    ev = np.linalg.eigvalsh((normals * w[:, None]).T @ normals)
    return float(np.arctan(np.sqrt(max(ev[1], 0.0) / ev[2]))) if ev[2] > 0 else 0.0


def _horizontal_basis(up: Array) -> tuple[Array, Array]:
    """e1: the input x projected onto the horizon plane of ``up``; e2 = up x e1."""
    e1 = _X - (_X @ up) * up
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(up, e1)


def _skew(v: Array) -> Array:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rodrigues(w: Array) -> Array:
    th = float(np.linalg.norm(w))
    if th < 1e-15:
        return np.eye(3)
    K = _skew(w / th)
    return np.eye(3) + np.sin(th) * K + (1.0 - np.cos(th)) * (K @ K)


def assign_segments(segments: LineSegments, axes: ArrayLike, max_angle: float = np.deg2rad(2.0)) -> NDArray[np.int64]:
    """Assign each segment to the vanishing direction its great circle passes closest to.

    Parameters
    ----------
    segments : LineSegments
    axes : (3, 3) float
        Rows are unit vanishing directions.
    max_angle : float
        A segment whose circle misses every direction by more than this
        (radians, measured as ``asin(|n . m|)``) is labelled -1.

    Returns
    -------
    labels : (N,) int in {-1, 0, 1, 2}

    Examples
    --------
    >>> s = LineSegments.from_endpoints([[1.0, 0.5, 0.2], [1.0, 0.3, 0.5]], [[1.0, 0.5, -0.2], [0.2, 1.0, -0.4]])
    >>> assign_segments(s, np.eye(3)).tolist()
    [2, -1]
    """
    A = float_array(axes, "axes")
    if A.shape != (3, 3):
        raise ValueError(f"axes: expected shape (3, 3), got {A.shape}")
    if len(segments) == 0:
        return np.zeros(0, dtype=np.int64)
    r = np.abs(segments.normals @ A.T)
    lab = np.argmin(r, axis=1).astype(np.int64)
    lab[r[np.arange(len(r)), lab] >= np.sin(max_angle)] = -1
    return lab


def _joint_refine(normals: Array, w: Array, M: Array, tol: float, iters: int) -> Array:
    """Gauss-Newton over a rotation: minimise sum w (n . m_k)^2 with robust weights; rows of M stay orthonormal."""
    s_tol = np.sin(tol)
    for _ in range(iters):
        r_all = normals @ M.T
        lab = np.argmin(np.abs(r_all), axis=1)
        r = r_all[np.arange(len(normals)), lab]
        inl = np.abs(r) < s_tol
        if inl.sum() < 3:
            break
        n, rr, mk = normals[inl], r[inl], M[lab[inl]]
        rw = w[inl] / (1.0 + (rr / (0.5 * s_tol)) ** 2)  # Cauchy re-weighting
        J = np.cross(mk, n)  # d(n . (m + om x m)) / d om = m x n
        H = (J * rw[:, None]).T @ J
        g = (J * rw[:, None]).T @ rr
        if np.linalg.cond(H) > 1e10:
            break
        om = -np.linalg.solve(H, g)
        M = M @ _rodrigues(om).T
        if np.linalg.norm(om) < 1e-9:
            break
    U, _, Vt = np.linalg.svd(M)
    return U @ Vt


def estimate_manhattan_frame(segments: LineSegments, *, max_tilt: float = np.deg2rad(40.0),
                             inlier_angle: float = np.deg2rad(1.5), min_segments: int = 12,
                             min_axis_segments: int = 3, min_inlier_fraction: float = 0.2,
                             min_significance: float = 8.0, min_spread: float = np.deg2rad(5.0),
                             heading_step: float = np.deg2rad(0.25), refine_iters: int = 10) -> ManhattanFrame:
    """Three orthogonal Manhattan directions from great-circle arcs.

    Parameters
    ----------
    segments : LineSegments
        Arcs in the input camera frame (e.g. from
        :func:`panogeom.lines.detect_line_segments`); longer arcs weigh more.
    max_tilt : float
        Largest angle (radians) between the image's up and the vertical
        vanishing point that is searched for.
    inlier_angle : float
        An arc supports a direction when its great circle passes within this
        angle (radians) of it; also the assignment threshold of ``labels``.
    min_segments : int
        Fewer arcs than this raise :class:`VanishingPointError`.
    min_axis_segments : int
        The vertical and at least one horizontal axis need this many arcs.
    min_inlier_fraction : float
        Smallest share of the total arc length that must be explained.
    min_significance : float
        The vertical and at least one horizontal axis must be supported
        beyond chance by at least this many standard deviations
        (:attr:`ManhattanFrame.significance`; the best of many hypotheses on
        random input reaches about 5).
    min_spread : float
        The arcs of those axes must not all lie on one great circle: their
        normals must spread by at least this angle (radians).
    heading_step : float
        Grid step (radians) of the horizontal heading search.
    refine_iters : int
        Gauss-Newton iterations of the joint refinement.

    Returns
    -------
    ManhattanFrame

    Raises
    ------
    VanishingPointError
        Too few arcs, no vertical hypothesis, no meaningful (more than
        chance, spread over several great circles) support for the vertical
        or for both horizontal axes, or too small an explained share.

    Convention: input camera frame (CONVENTIONS.md); see the module docstring
    for the order and signs of the axes.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> R = np.array([[0.8, -0.6, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]])  # 36.87 deg heading
    >>> d = np.repeat(R, 12, axis=0)                                        # 12 arcs per axis
    >>> p = rng.normal(size=(36, 3)); p -= (p * d).sum(1, keepdims=True) * d
    >>> p /= np.linalg.norm(p, axis=1, keepdims=True)
    >>> segs = LineSegments.from_endpoints(p + 0.3 * d, p - 0.3 * d)
    >>> f = estimate_manhattan_frame(segs)
    >>> bool(np.allclose(f.axes, R, atol=1e-9)), f.counts.tolist()
    (True, [12, 12, 12])
    """
    if not isinstance(segments, LineSegments):
        raise ValueError(f"segments: expected LineSegments, got {type(segments).__name__}")
    if not (0.0 < max_tilt < np.pi / 2):
        raise ValueError(f"max_tilt: expected radians in (0, pi/2), got {max_tilt!r}")
    if not (0.0 < inlier_angle < np.pi / 4):
        raise ValueError(f"inlier_angle: expected radians in (0, pi/4), got {inlier_angle!r}")
    if not (0.0 < heading_step < np.pi / 8):
        raise ValueError(f"heading_step: expected radians in (0, pi/8), got {heading_step!r}")
    n_seg = len(segments)
    if n_seg < min_segments:
        raise VanishingPointError(f"found {n_seg} line segments, need at least {min_segments}")
    normals, w = segments.normals, segments.lengths  # longer arcs weigh more
    total = float(w.sum())

    # 1. vertical
    hyps = vertical_hypotheses(normals, w, max_tilt)
    if len(hyps) == 0:
        raise VanishingPointError(f"no two line segments meet within {np.rad2deg(max_tilt):.1f} deg of the "
                                  f"image's up direction ({n_seg} segments): no vertical vanishing point")
    # only arcs whose circle passes within max_tilt + inlier_angle of +z can support a hypothesis
    able = np.abs(normals[:, 2]) <= np.sin(min(max_tilt + inlier_angle, 0.5 * np.pi))
    scores = np.concatenate([_consensus(normals[able], w[able], hyps[k:k + 2048], inlier_angle)
                             for k in range(0, len(hyps), 2048)])
    up = _refine_axis(normals, w, hyps[int(np.argmax(scores))], inlier_angle)
    if up[2] < 0:
        up = -up
    vert = np.abs(normals @ up) < np.sin(inlier_angle)

    # 2. heading of the horizontal axes, modulo 90 degrees
    e1, e2 = _horizontal_basis(up)
    rest = ~vert
    nr, wr = normals[rest], w[rest]
    phis = np.arange(0.0, 0.5 * np.pi, heading_step)
    # each arc's own heading (where its circle crosses the horizon) is added as an exact candidate
    h = np.cross(up, nr)
    hs = np.linalg.norm(h, axis=1)
    ok = hs > np.sin(np.deg2rad(10.0))
    own = np.mod(np.arctan2(h[ok] @ e2, h[ok] @ e1), 0.5 * np.pi)
    cand = np.concatenate([phis, own])
    c, s = np.cos(cand)[:, None], np.sin(cand)[:, None]
    d1 = c * e1 + s * e2
    d2 = -s * e1 + c * e2
    hscore = _consensus(nr, wr, d1, inlier_angle) + _consensus(nr, wr, d2, inlier_angle)
    phi = cand[int(np.argmax(hscore))]
    x0 = np.cos(phi) * e1 + np.sin(phi) * e2
    M = np.stack([x0, np.cross(up, x0), up])

    # 3. joint refinement under orthogonality
    M = _joint_refine(normals, w, M, 2.0 * inlier_angle, refine_iters)
    M = _joint_refine(normals, w, M, inlier_angle, refine_iters)

    # vertical: the axis closest to the image's up; x: the horizontal one closest to the input x
    k_up = int(np.argmax(np.abs(M[:, 2])))
    upv = M[k_up] * np.sign(M[k_up, 2])
    hor = np.delete(M, k_up, axis=0)
    ex, _ = _horizontal_basis(upv)
    cands = np.concatenate([hor, -hor])
    xv = cands[int(np.argmax(cands @ ex))]
    axes = np.stack([xv, np.cross(upv, xv), upv])

    labels = assign_segments(segments, axes, inlier_angle)
    counts = np.bincount(labels[labels >= 0], minlength=3)[:3]
    support = np.array([w[labels == k].sum() for k in range(3)])
    hor_pool = w[labels != 2]
    signif = np.array([_significance(support[0], hor_pool, inlier_angle),
                       _significance(support[1], hor_pool, inlier_angle),
                       _significance(support[2], w, inlier_angle)])
    spread = np.array([_spread(normals[labels == k], w[labels == k]) for k in range(3)])
    found = (counts >= min_axis_segments) & (signif >= min_significance) & (spread >= min_spread)

    def why(k: int) -> str:
        return (f"{int(counts[k])} segments (need {min_axis_segments}), significance {signif[k]:.1f} "
                f"(need {min_significance:.1f}), spread {np.rad2deg(spread[k]):.1f} deg "
                f"(need {np.rad2deg(min_spread):.1f})")

    if not found[2]:
        raise VanishingPointError(f"no meaningful vertical vanishing point: {why(2)}")
    if not (found[0] or found[1]):
        raise VanishingPointError(f"no meaningful horizontal vanishing point: x has {why(0)}; y has {why(1)}")
    frac = float(support.sum() / total) if total > 0 else 0.0
    if frac < min_inlier_fraction:
        raise VanishingPointError(f"the Manhattan frame explains {100 * frac:.0f}% of the segment length, "
                                  f"need at least {100 * min_inlier_fraction:.0f}%: no Manhattan structure")
    inl = labels >= 0
    r = np.arcsin(np.clip(np.abs(np.sum(normals[inl] * axes[labels[inl]], axis=1)), 0.0, 1.0))
    rmse = float(np.sqrt(np.mean(r * r)))
    return ManhattanFrame(axes=axes, labels=labels, support=support, rmse=rmse, inlier_fraction=frac,
                          significance=signif)
