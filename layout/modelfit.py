"""Model retrieval by box fit: which library model of its class each object is, and the shared camera height.

Not in the paper (it takes the model of the nearest HOG render). An
object's distance, and through it the camera height and the room's scale,
follow from the size of its model: a wrong model puts the object too near
or too far. The appearance alone picks the right model of a class for only
a third of the objects (docs/EVALUATION.md, Table 2 breakdown), since many
models of a class look alike in a 64 px HOG crop but differ in size by
10-40 %.

The detection box says more about the size than the crop's appearance
does, once the camera height is shared by all objects of the room: at a
known camera height the box's bottom edge fixes the object's distance, and
its width and top edge then fix its size. So, for every object ``i`` and
every candidate model ``j`` of its class (with its outline and the yaw of
the pose estimate), and for a grid of camera heights ``H``:

    R_ij(H) = sum over the 4 box edges of rho((predicted - detected edge) / sigma)

with the object's floor position fitted to its box at ``H``
(:func:`layout.sampler.fit_boxes`, Levenberg-Marquardt on the four edge
angles) and ``rho(x) = x^2 / (1 + x^2)`` (Geman-McClure: an edge cut by an
occluder or by the panorama's border costs at most 1). The camera height is
the ``H`` of least ``sum_i min_j (R_ij(H) + w_a A_ij) + P(H)``, with ``A_ij`` an
appearance cost of model ``j`` for object ``i`` from the caller (e.g. the
pose CRF's E_o of each model at the estimated pose, minus the smallest of
the object's), ``w_a`` its weight and ``P(H)`` a weak log-normal prior on
the camera height (where people hold or mount a camera; it decides where
the boxes leave the height nearly free: few objects, boxes cut by
occluders, false detections); each object then takes its best candidate
at that height, by ``R_ij(H) + w_y Y_ij + w_p (A_ij - Y_ij)`` with stronger
appearance weights, ``Y_ij`` being the lowest ``A`` of object ``i``'s
candidates at candidate ``j``'s yaw (the yaw's part of the cost; the
orientation network's share of it is the same for every model): ``w_y``
(:data:`DEFAULT_PICK_YAW_WEIGHT`) for the yaw, ``w_p``
(:data:`DEFAULT_PICK_APPEARANCE_WEIGHT`) for the model at that yaw. Objects
whose candidates are mostly thin footprints, such as TVs, keep ``w_a`` for
both; one pair of weights for all the candidates of an object. The box sets
the shared height well, but often cannot tell a bed seen from its foot from
the same bed turned 90 degrees with another model, which the appearance
can; it tells model sizes apart better than the appearance does. The grid
of heights is refined twice around each of its lowest local minima.

Given the room's floor polygon (``select_models(floor=...)``, the room step's
polygon up to scale), each candidate also pays ``w_r rho(depth / sigma_r)``,
``depth`` being how far its footprint, fitted to its box at ``H``, reaches
through the walls of the floor scaled to ``H`` (:func:`room_misfit`): a
model too large or a yaw 90 degrees off (the HOG pose's side view) that the
box alone cannot rule out often puts the object through a wall, which the
sampler's hard constraint would otherwise resolve by pulling the object
towards the camera.

Objects that stand with their back to a wall (beds, TVs, wardrobes, sofas,
nightstands: ``select_models(back_to_wall=...)``, the context prior's
:data:`layout.placement.BACK_TO_WALL`) also pay ``w_g rho(gap / sigma_g)``,
``gap`` being how far the middle of the footprint's back edge, fitted to its
box at ``H``, stands clear of the walls of the floor scaled to ``H``
(:func:`wall_gap`): a bed turned by 180 degrees (its box is the same) or a
model of the wrong size leaves its back in the middle of the room. This is
the paper's object-to-wall term (Sec. 3.3, measured from the back edge as
the sampler does) brought into the model choice, where it can still change
the model and the yaw; the sampler, which keeps each object's model, can only
move the object, which its box then holds in place.

Given the room's wall height in camera heights (``wall_ratio``, which the
room step measures well: 0.006 camera heights mean absolute error on the
synthetic seed-0 rooms, docs/EVALUATION.md), ``P(H)`` also holds a log-normal prior on
the wall height ``wall_ratio * H`` (:data:`DEFAULT_WALL_PRIOR`): a room
whose boxes all fit models 20 % larger at a camera 20 % higher (the boxes
alone cannot tell) is then held to the ceilings rooms have.

Convention:
    World frame of shared/CONVENTIONS.md (metres, z up, camera at
    ``(0, 0, H)``); boxes in pixels of the upright panorama the objects
    refer to; yaw radians CCW from +x to the object's front.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_to_lonlat

from .polygon import distance_to_boundary, oriented_rectangles, points_in_polygon
from .sampler import (DetectedObject, _BoxEdges, _fit_edges, geman_mcclure, initialise_objects, thin_footprints,
                      wall_aligned_yaw)

__all__ = ["ModelChoice", "select_models", "candidate_yaws", "occluded_edges", "room_misfit", "wall_gap",
           "DEFAULT_EDGE_SIGMA", "DEFAULT_GAP_WEIGHT", "DEFAULT_GAP_SIGMA",
           "DEFAULT_APPEARANCE_WEIGHT", "DEFAULT_PICK_APPEARANCE_WEIGHT", "DEFAULT_PICK_YAW_WEIGHT",
           "DEFAULT_HEIGHT_PRIOR", "DEFAULT_WALL_PRIOR",
           "DEFAULT_ROOM_WEIGHT", "DEFAULT_ROOM_SIGMA"]

FloatArray = NDArray[np.float64]

#: Scale of the box-edge misfit, radians (about 3.4 px at 1024 px width). The silhouette-refined edges the choice
#: reads are off by a median absolute 0.23-0.57 deg per edge, but 10-20 % of them by more than 2 deg (seed 7000,
#: docs/EVALUATION.md, "Detector box edges"); at 0.6 deg (until session 21) each such edge cost as much as a wrong
#: model. 0.9 and 1.2 deg chose the camera height equally well on both tuning sets (mean error 0.040 -> 0.034 m),
#: 1.2 deg with the better bed orientation (22.0 -> 14.0 deg; docs/EVALUATION.md, "Session 21").
DEFAULT_EDGE_SIGMA: float = math.radians(1.2)
#: Prior on the camera height (``select_models(height_prior=...)``): log-normal, median 1.5 m, sigma 0.45 (about
#: 0.6-3.7 m at two sigma: it only decides where the boxes leave the height nearly free). Chosen on a tuning set
#: (seed 7000) during development with a temporary switch (session-3 note of issue 10), sigma 0.3 until session 21;
#: with the edge scale at 1.2 deg the weaker prior chose the camera height better on both tuning sets (mean error
#: 0.034 -> 0.032 m; docs/EVALUATION.md, "Session 21").
DEFAULT_HEIGHT_PRIOR: tuple[float, float] | None = (1.5, 0.45)
#: Prior on the wall height (``select_models(wall_prior=...)``, with the room's ``wall_ratio``): log-normal, median
#: 2.6 m, sigma 0.15 (about 1.9-3.5 m at two sigma): living rooms, bedrooms and hotel rooms are mostly 2.4-2.8 m high,
#: and the boxes now fix the scale well enough that the prior need only hold the rooms they cannot. Sigma 0.1 (sessions
#: 7-35) decided the camera height of tall rooms against their boxes; on the tuning sets 0.15 lowered the camera
#: height's mean error 0.029 -> 0.025 m and raised the layout 3D IoU 0.883 -> 0.886 (docs/EVALUATION.md, "Session 36").
DEFAULT_WALL_PRIOR: tuple[float, float] | None = (2.6, 0.15)
_FINE = 9  # points of each finer grid of heights
_KEEP = 8  # candidates per object fitted on the finer grids
_BASINS = 3  # local minima of the first grid refined by the finer ones
#: Weight of the caller's appearance cost against the box misfit (units of one edge's robust cost).
DEFAULT_APPEARANCE_WEIGHT: float = 1.0
#: Weight of the appearance cost when each object picks its candidate at the chosen camera height (the height
#: itself is chosen with :data:`DEFAULT_APPEARANCE_WEIGHT`). The box often cannot tell a bed seen from its foot from
#: the same bed turned 90 degrees with another model; the pose's appearance cost (HOG distance plus the orientation
#: network's) can. Not for objects whose candidates are mostly thin footprints (TVs), whose side view the box tells
#: apart better than the appearance.
#: Chosen on the tuning seeds 7000 and 8000 (docs/EVALUATION.md, "Session 22"): 3, for the whole appearance cost
#: until session 32; since then for the part of it that tells models apart at one yaw
#: (:data:`DEFAULT_PICK_YAW_WEIGHT` weighs the part that tells yaws apart).
DEFAULT_PICK_APPEARANCE_WEIGHT: float = 3.0
#: Weight of the yaw's appearance cost when each object picks its candidate: the cost of the object's best
#: candidate at that yaw (the orientation network's cost is the same for every model). Since session 32, when the
#: network retrained in session 31 made it surer: with the whole cost at 10, the beds' yaws improved on the tuning
#: seeds 7000 and 8000 but the model choice took models the room could not hold (docs/EVALUATION.md, "Session 32").
DEFAULT_PICK_YAW_WEIGHT: float = 10.0
#: Weight of the room term (a footprint through a wall; units of one edge's robust cost) and its depth scale, m.
DEFAULT_ROOM_WEIGHT: float = 1.0
DEFAULT_ROOM_SIGMA: float = 0.2
#: Weight of the wall-gap term (an object that stands with its back to a wall, :func:`wall_gap`, whose back is clear
#: of every wall; units of one edge's robust cost) and its gap scale, m. Weight 2 against 1 and against the term in the
#: pick alone, tuning seeds 7000 / 8000 (docs/EVALUATION.md, "Session 27").
DEFAULT_GAP_WEIGHT: float = 2.0
DEFAULT_GAP_SIGMA: float = 0.2


@dataclass(frozen=True)
class ModelChoice:
    """Result of :func:`select_models`.

    Attributes
    ----------
    objects : tuple of DetectedObject
        One per input object: the chosen candidate.
    index : (N,) int
        Index of the chosen candidate in each object's list (picked at
        ``camera_height`` with ``pick_yaw_weight`` and ``pick_appearance_weight``).
    camera_height : float
        The shared camera height of least total cost, metres; NaN when no
        object constrains it (no box bottom below the horizon).
    cost : (N, M_max) float
        Total cost of every candidate at ``camera_height`` (box misfit plus
        appearance weighted by ``appearance_weight``, the height's); inf where an object has fewer candidates,
        or for candidates left out of the finer grids (each object keeps
        its 8 best of the first grid near the local minimum refined).
    heights : (K,) float
        The camera heights tried, metres.
    profile : (K,) float
        Total cost at each of them.
    """

    objects: tuple[DetectedObject, ...]
    index: NDArray[np.int64]
    camera_height: float
    cost: FloatArray
    heights: FloatArray
    profile: FloatArray


def candidate_yaws(yaw: float, keep_within_deg: float = 5.0) -> list[float]:
    """The yaws the model choice tries for a pose estimate ``yaw`` (radians).

    The four wall-aligned yaws (multiples of 90 degrees in the upright, wall-aligned frame), starting at the one
    nearest ``yaw``, and ``yaw`` itself first where it is more than ``keep_within_deg`` off that one: a HOG pose
    often gives an object's side view, 90 degrees off, which a box fit at the pose's yaw alone cannot undo.

    Examples
    --------
    >>> [round(math.degrees(y)) for y in candidate_yaws(math.radians(93.0))]
    [90, 180, 270, 360]
    >>> [round(math.degrees(y)) for y in candidate_yaws(math.radians(30.0))]
    [30, 0, 90, 180, 270]
    """
    quarter = 0.5 * math.pi
    aligned = float(wall_aligned_yaw(float(yaw)))
    yaws = [aligned + k * quarter for k in range(4)]
    if abs(float(yaw) - aligned) > math.radians(keep_within_deg):
        yaws.insert(0, float(yaw))
    return yaws


def occluded_edges(boxes: ArrayLike, width: int, margin: float = 2.0, same_iou: float = 0.3) -> NDArray[np.bool_]:
    """Which edges of each detection box another, nearer object's box may have cut.

    Objects stand on the floor, so of two overlapping boxes the one whose
    bottom edge is lower in the image is (in the common case) the nearer
    one, in front. An edge of box ``i`` counts as occluded when it runs
    inside the box of such a nearer object ``j`` (bottom lower by more than
    ``margin`` pixels):

    * bottom: ``j`` covers part of ``i``'s columns and reaches above
      ``i``'s bottom row;
    * left / right: ``i``'s left / right column lies inside ``j``'s columns
      (by more than ``margin``) and their rows overlap;
    * top: ``j`` covers part of ``i``'s columns and reaches above ``i``'s
      top row.

    Parameters
    ----------
    boxes : (N, 4) float
        ``(u0, v0, u1, v1)`` panorama pixels (``u0 > u1`` wraps the seam).
    width : int
        Panorama width in pixels.
    margin : float
        Pixels.
    same_iou : float
        IoU (of the unwrapped pixel boxes) above which two boxes are not
        taken for an occluder and an occluded object.

    Returns
    -------
    (N, 4) bool
        ``(left, top, right, bottom)``: True where occluded.

    Examples
    --------
    >>> occluded_edges([[100, 200, 200, 300], [150, 250, 260, 340]], 1024).astype(int).tolist()
    [[0, 0, 1, 1], [0, 0, 0, 0]]
    """
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    n = len(b)
    out = np.zeros((n, 4), dtype=bool)
    if n < 2:
        return out
    u0 = b[:, 0]
    u1 = np.where(b[:, 2] < b[:, 0], b[:, 2] + width, b[:, 2])
    v0, v1 = b[:, 1], b[:, 3]

    def inside(u: FloatArray, j: int) -> NDArray[np.bool_]:
        """Columns ``u`` strictly inside box j's columns (seam-aware), by more than ``margin``."""
        rel = np.remainder(u - u0[j], width)
        return (rel > margin) & (rel < (u1[j] - u0[j]) - margin)

    # pixel IoU of every pair, the columns unwrapped across the seam
    du = np.remainder(u0[None, :] - u0[:, None] + 0.5 * width, width) - 0.5 * width  # u0_j - u0_i, shortest way
    lo_u = np.maximum(0.0, du)
    hi_u = np.minimum((u1 - u0)[:, None], du + (u1 - u0)[None, :])
    inter = np.clip(hi_u - lo_u, 0.0, None) * np.clip(np.minimum(v1[:, None], v1[None, :])
                                                      - np.maximum(v0[:, None], v0[None, :]), 0.0, None)
    area = (u1 - u0) * (v1 - v0)
    iou = inter / np.maximum(area[:, None] + area[None, :] - inter, 1e-9)
    for j in range(n):
        nearer = (v1[j] > v1 + margin) & (iou[:, j] <= same_iou)  # j's bottom is lower than i's: j stands nearer
        nearer[j] = False
        if not nearer.any():
            continue
        # column overlap of i and j (either contains a point of the other)
        cols = inside(u0, j) | inside(u1, j) | (np.remainder(u0[j] - u0, width) < (u1 - u0))
        rows = (v0[j] < v1) & (v1[j] > v0)
        out[:, 3] |= nearer & cols & (v0[j] < v1 - margin)
        out[:, 0] |= nearer & rows & inside(u0, j)
        out[:, 2] |= nearer & rows & inside(u1, j)
        out[:, 1] |= nearer & cols & (v0[j] < v0 - margin)
    return out


def _check(candidates: Sequence[Sequence[DetectedObject]], appearance: Sequence[ArrayLike] | None) \
        -> tuple[list[list[DetectedObject]], list[FloatArray]]:
    cands = [list(c) for c in candidates]
    for i, c in enumerate(cands):
        if not c:
            raise ValueError(f"candidates[{i}]: expected at least one DetectedObject, got none")
        for o in c:
            if not isinstance(o, DetectedObject):
                raise ValueError(f"candidates[{i}]: expected DetectedObject items, got {type(o).__name__}")
        box0 = c[0].bbox_pano
        if any(not np.array_equal(o.bbox_pano, box0) for o in c):
            raise ValueError(f"candidates[{i}]: expected every candidate of one object to share its box")
    if appearance is None:
        app = [np.zeros(len(c)) for c in cands]
    else:
        app = [np.asarray(a, dtype=np.float64).reshape(-1) for a in appearance]
        if len(app) != len(cands):
            raise ValueError(f"appearance: expected one cost array per object ({len(cands)}), got {len(app)}")
        for i, (a, c) in enumerate(zip(app, cands)):
            if a.shape != (len(c),) or not np.all(np.isfinite(a)):
                raise ValueError(f"appearance[{i}]: expected {len(c)} finite costs, got shape {a.shape}")
    return cands, app


def _misfit(edges: _BoxEdges, yaw: FloatArray, centers: FloatArray, free_h: FloatArray, cam_h: float,
            sigma: float) -> tuple[FloatArray, FloatArray]:
    """Robust box misfit of every flattened candidate at camera height ``cam_h``: (F,), and the fitted
    floor positions (F, 2).

    The fit starts from the free-height fit (``centers`` at ``free_h``) scaled to ``cam_h``, which is exact
    for a scaled model and close otherwise, so a few Levenberg-Marquardt steps suffice."""
    start = centers.copy()
    start[:, :2] *= (cam_h / free_h)[:, None]
    fitted, _, resid = _fit_edges(edges, yaw, start, cam_h, cam_h, iterations=8)
    rho = geman_mcclure(resid / sigma)
    return np.where(np.isfinite(rho), rho, 1.0).sum(axis=1), fitted[:, :2]


def room_misfit(xy: ArrayLike, yaw: ArrayLike, size2: ArrayLike, floor: ArrayLike, sigma: float) -> FloatArray:
    """Robust cost of footprints reaching through the walls: ``rho(depth / sigma)``, (F,).

    Parameters
    ----------
    xy : (F, 2) float
        Footprint centres, metres.
    yaw : (F,) float
        Radians.
    size2 : (F, 2) float
        Footprint length and width, metres.
    floor : (K, 2) float
        Floor polygon at the same scale.
    sigma : float
        Depth scale, metres.

    Returns
    -------
    (F,) float
        In [0, 1): 0 for a footprint inside the floor, ``depth`` being the
        largest distance of a corner outside it from the boundary.

    Examples
    --------
    >>> room = [[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]]
    >>> room_misfit([[0.0, 0.0], [1.7, 0.0]], [0.0, 0.0], [[1.0, 1.0], [1.0, 1.0]], room, 0.2).round(2).tolist()
    [0.0, 0.5]
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    rect = oriented_rectangles(xy, np.asarray(yaw, dtype=np.float64).reshape(-1),
                               np.asarray(size2, dtype=np.float64).reshape(-1, 2))  # (F, 4, 2)
    out = ~points_in_polygon(rect, floor)
    depth = np.zeros(out.shape)
    if out.any():
        depth[out] = distance_to_boundary(rect[out], floor)
    return geman_mcclure(depth.max(axis=1) / float(sigma))


def wall_gap(xy: ArrayLike, yaw: ArrayLike, length: ArrayLike, floor: ArrayLike, sigma: float) -> FloatArray:
    """Robust cost of a back edge standing clear of the walls: ``rho(gap / sigma)``, (F,).

    ``gap`` is the distance from the middle of the footprint's back edge
    (half the length behind the centre, opposite the front) to the floor
    polygon's boundary, 0 where that point is outside the floor (the room
    term, :func:`room_misfit`, prices a footprint through a wall). Beds, TVs,
    wardrobes, sofas and nightstands stand with their back to a wall
    (:data:`layout.placement.BACK_TO_WALL`, the context prior's anchor): a
    wrong model of such an object, or its yaw turned by 90 or 180 degrees,
    fitted to the object's box, leaves its back in the middle of the room.

    Parameters
    ----------
    xy : (F, 2) float
        Footprint centres, metres.
    yaw : (F,) float
        Radians, CCW from +x to the front.
    length : (F,) float
        Footprint length along the front, metres.
    floor : (K, 2) float
        Floor polygon at the same scale.
    sigma : float
        Gap scale, metres.

    Returns
    -------
    (F,) float
        In [0, 1).

    Examples
    --------
    >>> room = [[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]]
    >>> wall_gap([[1.5, 0.0], [1.3, 0.0], [0.0, 0.0]], [math.pi, math.pi, 0.0], [1.0, 1.0, 1.0], room, 0.2
    ...          ).round(2).tolist()
    [0.0, 0.5, 0.98]
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    yaw = np.asarray(yaw, dtype=np.float64).reshape(-1)
    half = 0.5 * np.asarray(length, dtype=np.float64).reshape(-1)
    back = xy - half[:, None] * np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    gap = np.where(points_in_polygon(back, floor), distance_to_boundary(back, floor), 0.0)
    return geman_mcclure(gap / float(sigma))


def _term_scales(name: str, weight: float | None, sigma: float | None, default_weight: float,
                 default_sigma: float) -> tuple[float, float]:
    """A floor term's weight (finite, >= 0) and scale (metres, > 0), defaults where None; ValueError otherwise."""
    weight = default_weight if weight is None else float(weight)
    sigma = default_sigma if sigma is None else float(sigma)
    if not (math.isfinite(weight) and weight >= 0):
        raise ValueError(f"{name}_weight: expected a finite weight >= 0, got {weight!r}")
    if not (math.isfinite(sigma) and sigma > 0):
        raise ValueError(f"{name}_sigma: expected metres > 0, got {sigma!r}")
    return weight, sigma


def _best_per_yaw(cost: FloatArray, owner: NDArray[np.int64], yaw: FloatArray) -> FloatArray:
    """Per candidate (flat, ``owner`` its object, ``yaw`` radians), the lowest ``cost`` among its object's candidates
    at the same yaw (to a microradian, modulo a full turn)."""
    turn = int(round(2 * math.pi * 1e6))
    key = np.rint(np.remainder(yaw, 2 * math.pi) * 1e6).astype(np.int64) % turn
    _, group = np.unique(np.stack([owner, key], axis=1), axis=0, return_inverse=True)
    group = group.reshape(-1)
    best = np.full(int(group.max()) + 1 if group.size else 0, np.inf)
    np.minimum.at(best, group, cost)
    return best[group]


def select_models(candidates: Sequence[Sequence[DetectedObject]], width: int, height: int, *,
                  appearance: Sequence[ArrayLike] | None = None, camera_height: float | None = None,
                  height_range: tuple[float, float] = (0.8, 2.6), n_heights: int = 19, levels: int = 3,
                  height_prior: tuple[float, float] | None = DEFAULT_HEIGHT_PRIOR,
                  edge_sigma: float | None = None,
                  appearance_weight: float | None = None,
                  floor: ArrayLike | None = None, floor_camera_height: float | None = None,
                  room_weight: float | None = None, room_sigma: float | None = None,
                  wall_ratio: float | None = None,
                  wall_prior: tuple[float, float] | None = DEFAULT_WALL_PRIOR,
                  pick_appearance_weight: float | None = None,
                  pick_yaw_weight: float | None = None,
                  back_to_wall: Sequence[bool] | None = None,
                  gap_weight: float | None = None, gap_sigma: float | None = None) -> ModelChoice:
    """Choose each object's model by how well it fits its box at one shared camera height.

    Parameters
    ----------
    candidates : sequence of N sequences of DetectedObject
        Per object, its candidate models: the same box and class, each with
        its own ``size``, ``outline``, ``model_id`` and ``yaw``.
    width, height : int
        Size of the panorama the boxes refer to.
    appearance : sequence of N (M_i,) float, optional
        Appearance cost of each candidate (lower is better; only
        differences within an object matter). None: 0.
    camera_height : float, optional
        Known camera height, metres: only the models are chosen.
    height_range : (float, float)
        Camera heights searched, metres (log-spaced grids, see ``levels``).
    n_heights : int
        Points of the first grid (each finer one has 9).
    levels : int
        Grids: the first spans ``height_range``; each next one lies between
        the two neighbours of the best height so far (about 7 %, 1.3 % and
        0.3 % apart with the defaults), for each of the three lowest local
        minima of the first grid.
    height_prior : (float, float) or None
        ``(median metres, sigma)``: a log-normal prior on the camera height
        added to the total, ``(log(H / median) / sigma)^2`` (a hand-held
        or tripod camera); None: uniform in ``height_range``. Unused with a
        known ``camera_height``.
    edge_sigma : float, optional
        Scale of the edge misfit, radians (default :data:`DEFAULT_EDGE_SIGMA`).
    appearance_weight : float, optional
        ``w_a`` of the module docstring (default :data:`DEFAULT_APPEARANCE_WEIGHT`).
    floor : (K, 2) float, optional
        The room's floor polygon at camera height ``floor_camera_height``
        (the room step's, up to scale): each candidate then also pays
        ``w_r`` :func:`room_misfit` of its footprint, fitted to its box at
        each height ``H``, against the floor scaled to ``H``.
    floor_camera_height : float, optional
        Required with ``floor``, metres.
    room_weight, room_sigma : float, optional
        ``w_r`` and the depth scale of the room term (defaults
        :data:`DEFAULT_ROOM_WEIGHT`, :data:`DEFAULT_ROOM_SIGMA` m).
    back_to_wall : sequence of N bool, optional
        Objects that stand with their back to a wall (beds, TVs, ...,
        :data:`layout.placement.BACK_TO_WALL`). With a ``floor``, each of
        their candidates also pays ``w_g`` :func:`wall_gap` of its footprint
        fitted to its box at each height, against the floor scaled to it.
        None: no object.
    gap_weight, gap_sigma : float, optional
        ``w_g`` and the gap scale of that term (defaults
        :data:`DEFAULT_GAP_WEIGHT`, :data:`DEFAULT_GAP_SIGMA` m).
    wall_ratio : float, optional
        The room's wall height in camera heights (the room step's: mean
        absolute error 0.006 camera heights on the synthetic seed-0 rooms,
        docs/EVALUATION.md, "Where the scale and position errors come
        from"). Given, the wall height
        ``wall_ratio * H`` of each camera height ``H`` also pays
        ``wall_prior``.
    wall_prior : (float, float) or None
        ``(median metres, sigma)`` of a log-normal prior on the wall height,
        ``(log(wall_ratio * H / median) / sigma)^2`` (default
        :data:`DEFAULT_WALL_PRIOR`); None or no ``wall_ratio``: none. Unused
        with a known ``camera_height``.
    pick_appearance_weight, pick_yaw_weight : float, optional
        Weights of the appearance cost when, at the chosen camera height,
        each object picks its candidate (defaults
        :data:`DEFAULT_PICK_APPEARANCE_WEIGHT`, :data:`DEFAULT_PICK_YAW_WEIGHT`).
        The cost is split in two: the yaw's, the cost of the object's best
        candidate at the candidate's yaw, weighted ``pick_yaw_weight``, and
        the rest, which tells the models apart at that yaw, weighted
        ``pick_appearance_weight``. The height itself is chosen
        with ``appearance_weight``, and so are the objects more than half
        of whose candidates have a thin footprint (width under half the
        length, the sampler's rule for quarter turns,
        :func:`layout.sampler.thin_footprints`: TVs; the weight is the same
        for all the candidates of an object). Where
        the two weights differ and the height comes from a finer grid,
        every candidate is fitted again at it (the finer grids fit only each
        object's best few).

    Returns
    -------
    ModelChoice

    Examples
    --------
    A 2.0 m bed 3 m ahead of a camera 1.5 m high; its candidates are a 1.6 m, a 2.0 m and a 2.4 m long bed
    of the same proportions (a box alone cannot tell them apart: the shared camera height of a chair does):

    >>> beds = [DetectedObject("bed", [450.0, 291.4, 574.0, 360.9], [s, 0.8 * s, 0.3 * s], np.pi)
    ...         for s in (1.6, 2.0, 2.4)]
    >>> chair = DetectedObject("chair", [572.3, 289.9, 616.4, 354.8], [0.5, 0.5, 0.9], np.pi)  # 2.5 m away
    >>> res = select_models([beds, [chair]], 1024, 512)
    >>> res.index.tolist(), round(res.camera_height, 2)
    ([1, 0], 1.5)
    """
    cands, app = _check(candidates, appearance)
    w, h = int(width), int(height)
    n = len(cands)
    m_max = max((len(c) for c in cands), default=0)
    if n == 0:
        return ModelChoice((), np.zeros(0, np.int64), float("nan"), np.zeros((0, 0)), np.zeros(0), np.zeros(0))
    edge_sigma = DEFAULT_EDGE_SIGMA if edge_sigma is None else float(edge_sigma)
    appearance_weight = DEFAULT_APPEARANCE_WEIGHT if appearance_weight is None else float(appearance_weight)
    if not (math.isfinite(edge_sigma) and edge_sigma > 0):
        raise ValueError(f"edge_sigma: expected radians > 0, got {edge_sigma!r}")
    if not (math.isfinite(appearance_weight) and appearance_weight >= 0):
        raise ValueError(f"appearance_weight: expected a finite weight >= 0, got {appearance_weight!r}")
    pick_appearance_weight = (DEFAULT_PICK_APPEARANCE_WEIGHT if pick_appearance_weight is None
                              else float(pick_appearance_weight))
    if not (math.isfinite(pick_appearance_weight) and pick_appearance_weight >= 0):
        raise ValueError(f"pick_appearance_weight: expected a finite weight >= 0, got {pick_appearance_weight!r}")
    pick_yaw_weight = DEFAULT_PICK_YAW_WEIGHT if pick_yaw_weight is None else float(pick_yaw_weight)
    if not (math.isfinite(pick_yaw_weight) and pick_yaw_weight >= 0):
        raise ValueError(f"pick_yaw_weight: expected a finite weight >= 0, got {pick_yaw_weight!r}")
    lo, hi = (float(v) for v in height_range)
    if not 0 < lo < hi:
        raise ValueError(f"height_range: expected 0 < low < high metres, got {height_range!r}")
    if camera_height is not None and not (math.isfinite(camera_height) and camera_height > 0):
        raise ValueError(f"camera_height: expected metres > 0 or None, got {camera_height!r}")
    if int(n_heights) < 3:
        raise ValueError(f"n_heights: expected 3 or more, got {n_heights!r}")
    if height_prior is not None and not (len(height_prior) == 2 and float(height_prior[0]) > 0
                                         and float(height_prior[1]) > 0):
        raise ValueError(f"height_prior: expected (median metres > 0, sigma > 0) or None, got {height_prior!r}")
    if int(levels) < 1:
        raise ValueError(f"levels: expected 1 or more, got {levels!r}")
    if wall_prior is not None and not (len(wall_prior) == 2 and float(wall_prior[0]) > 0
                                       and float(wall_prior[1]) > 0):
        raise ValueError(f"wall_prior: expected (median metres > 0, sigma > 0) or None, got {wall_prior!r}")
    if wall_ratio is not None and not (math.isfinite(wall_ratio) and wall_ratio > 0):
        raise ValueError(f"wall_ratio: expected a wall height in camera heights > 0 or None, got {wall_ratio!r}")
    room_weight, room_sigma = _term_scales("room", room_weight, room_sigma, DEFAULT_ROOM_WEIGHT, DEFAULT_ROOM_SIGMA)
    gap_weight, gap_sigma = _term_scales("gap", gap_weight, gap_sigma, DEFAULT_GAP_WEIGHT, DEFAULT_GAP_SIGMA)
    if back_to_wall is not None:
        back_to_wall = np.asarray(back_to_wall)
        if back_to_wall.shape != (n,) or back_to_wall.dtype != bool:
            raise ValueError(f"back_to_wall: expected {n} booleans (one per object), got shape {back_to_wall.shape} "
                             f"of {back_to_wall.dtype}")
    if floor is not None:
        floor = np.asarray(floor, dtype=np.float64)
        if floor.ndim != 2 or floor.shape[1] != 2 or len(floor) < 3 or not np.isfinite(floor).all():
            raise ValueError(f"floor: expected a (K >= 3, 2) finite polygon, got shape {floor.shape}")
        if floor_camera_height is None or not (math.isfinite(floor_camera_height) and floor_camera_height > 0):
            raise ValueError(f"floor_camera_height: expected metres > 0 with a floor, got {floor_camera_height!r}")
    levels = int(levels)

    flat = [o for c in cands for o in c]
    owner = np.repeat(np.arange(n), [len(c) for c in cands])
    slot = np.concatenate([np.arange(len(c)) for c in cands])
    init = initialise_objects(flat, w, h)
    centers = init.centers
    free_h = init.fitted_camera_heights
    free_h = np.where(np.isfinite(free_h) & (free_h > 0), free_h, np.median(np.r_[free_h[free_h > 0], 1.6]))
    yaw_flat = np.array([o.yaw for o in flat])
    size2_flat = np.array([o.size[:2] for o in flat], dtype=np.float64).reshape(-1, 2)
    use_room = floor is not None and room_weight > 0
    backed = (np.zeros(len(flat), bool) if back_to_wall is None or floor is None or gap_weight == 0
              else back_to_wall[owner])
    a_raw = np.concatenate([a - a.min() for a in app])
    a_flat = a_raw * float(appearance_weight)

    def prior(hk: float) -> float:
        if camera_height is not None:
            return 0.0
        p = 0.0
        if height_prior is not None:
            p += (math.log(hk / float(height_prior[0])) / float(height_prior[1])) ** 2
        if wall_prior is not None and wall_ratio is not None:
            p += (math.log(float(wall_ratio) * hk / float(wall_prior[0])) / float(wall_prior[1])) ** 2
        return float(p)

    def totals(hs: FloatArray, sel: NDArray[np.int64], edges: _BoxEdges) -> tuple[FloatArray, list[FloatArray]]:
        """Total cost at each height and the (N, M_max) cost matrices, candidates ``sel`` (their ``edges``)."""
        prof, costs = np.zeros(len(hs)), []
        yaw_s, size_s, cen_s, free_s, b = yaw_flat[sel], size2_flat[sel], centers[sel], free_h[sel], backed[sel]
        for k, hk in enumerate(hs):
            cost = np.full((n, m_max), np.inf)
            fit, xy = _misfit(edges, yaw_s, cen_s, free_s, float(hk), edge_sigma)
            if use_room or b.any():
                floor_h = floor * (float(hk) / float(floor_camera_height))
            if use_room:
                fit = fit + room_weight * room_misfit(xy, yaw_s, size_s, floor_h, room_sigma)
            if b.any():
                fit[b] += gap_weight * wall_gap(xy[b], yaw_s[b], size_s[b, 0], floor_h, gap_sigma)
            cost[owner[sel], slot[sel]] = fit + a_flat[sel]
            prof[k] = cost.min(axis=1).sum() + prior(float(hk))
            costs.append(cost)
        return prof, costs

    everything = np.arange(len(flat))
    all_edges = _BoxEdges(flat, w, h)
    if camera_height is not None:
        hs = np.array([float(camera_height)])
        prof, costs = totals(hs, everything, all_edges)
        best, n_complete = 0, 1
    else:
        coarse = np.geomspace(lo, hi, int(n_heights))
        prof0, costs0 = totals(coarse, everything, all_edges)
        n_complete = len(coarse)  # heights whose costs cover every candidate: the first grid's, listed first
        hs, prof, costs = [coarse], [prof0], list(costs0)
        # the finer grids refine the best few local minima of the coarse profile (several objects with many
        # candidates make it multimodal), each fitting only each object's best few candidates there
        padded = np.r_[np.inf, prof0, np.inf]
        minima = np.flatnonzero((padded[1:-1] <= padded[:-2]) & (padded[1:-1] <= padded[2:]))
        for k0 in minima[np.argsort(prof0[minima])][:_BASINS]:
            near = np.min(np.stack(costs0[max(k0 - 1, 0):k0 + 2]), axis=0)  # (N, M_max)
            rank = np.argsort(np.argsort(near, axis=1, kind="stable"), axis=1)
            sel = everything[rank[owner, slot] < _KEEP]
            sel_edges = _BoxEdges([flat[i] for i in sel], w, h)
            centre, centre_cost = float(coarse[k0]), float(prof0[k0])
            step = (hi / lo) ** (1.0 / (int(n_heights) - 1))
            for _ in range(levels - 1):  # a finer grid strictly between the neighbours of the best height so far
                fine = np.geomspace(max(centre / step, lo), min(centre * step, hi), _FINE + 2)[1:-1]
                fine = fine[np.abs(np.log(fine / centre)) > 1e-9]
                prof2, costs2 = totals(fine, sel, sel_edges)
                hs.append(fine)
                prof.append(prof2)
                costs += costs2
                if prof2.min() < centre_cost:
                    centre, centre_cost = float(fine[int(np.argmin(prof2))]), float(prof2.min())
                step = step ** (2.0 / (_FINE + 1))
        hs, prof = np.concatenate(hs), np.concatenate(prof)
        best = int(np.argmin(prof))
    cost = costs[best]
    pick = cost
    if pick_appearance_weight != appearance_weight or pick_yaw_weight != appearance_weight:
        # every candidate at the chosen height: the first grid (or a known height) fitted them all, the finer grids
        # only each object's best few
        full = cost if best < n_complete else totals(hs[best:best + 1], everything, all_edges)[1][0]
        extra = np.zeros((n, m_max))
        # objects whose candidates are mostly thin footprints (TVs: width under half the length) keep the height's
        # weight: the box tells their side view from their front, the appearance of a side view less so (tuning
        # seeds 7000 / 8000, "Session 22"). One weight per object: a narrow single bed among double beds paid the
        # lighter weight alone and was picked for beds of other models ("Session 25")
        n_thin = np.bincount(owner, weights=thin_footprints(size2_flat), minlength=n)
        thin = n_thin > 0.5 * np.bincount(owner, minlength=n)
        w_model = np.where(thin[owner], appearance_weight, pick_appearance_weight)
        w_yaw = np.where(thin[owner], appearance_weight, pick_yaw_weight)
        a_yaw = _best_per_yaw(a_raw, owner, yaw_flat)
        extra[owner, slot] = a_yaw * (w_yaw - appearance_weight) + (a_raw - a_yaw) * (w_model - appearance_weight)
        pick = full + extra
    index = np.argmin(pick, axis=1).astype(np.int64)
    bottom = np.array([[0.0, c[0].bbox_pano[3]] for c in cands])
    below = pixel_to_lonlat(bottom, w, h)[:, 1] < 0  # a box bottom below the horizon constrains the height
    cam = float(hs[best]) if (camera_height is not None or below.any()) else float("nan")
    order = np.argsort(hs)
    return ModelChoice(objects=tuple(cands[i][int(index[i])] for i in range(n)), index=index, camera_height=cam,
                       cost=cost, heights=hs[order], profile=prof[order])
