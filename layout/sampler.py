"""MAP estimation of scale, object positions and orientations (paper Sec. 3.4 and Sec. 4).

The posterior of a scene hypothesis ``Phi = (lambda, p_j, theta_j)`` is

    P(I | Phi) pi(Phi) = exp(-(E_s + E_o)) * exp(-(E_ow + mu * E_oo))

with ``E_s`` the surface-label likelihood (:mod:`layout.likelihood`), ``E_o``
the orientation likelihood from the caller (the pose CRF of :mod:`posecrf`;
layout never imports it), and the context prior ``E_ow + mu * E_oo``
(:mod:`layout.context`). :func:`map_estimate` minimises
``w_s E_s + w_o E_o + E_ow + mu E_oo`` (paper: ``w_s = w_o = 1``) by sampling.

Scale. The room comes up to scale (floor polygon, ceiling and camera
height at scale 1, e.g. metric under an assumed camera height). A
hypothesis' scale ``lambda`` multiplies all three; the objects are metric
(their model sizes are known). The paper samples ``lambda`` through the wall
height ``lambda * ceiling_z``, uniform in [2.0 m, 3.5 m]; camera height and
wall height of the result follow from ``lambda``.

Initialisation (:func:`initialise_objects`): an object's direction is that
of its detection box; its distance is the one at which its known footprint
(model size, yaw from the pose estimate) spans the box's columns exactly -
independent of the unknown scale. Its box also gives the camera height in
closed form (:func:`camera_height_estimates`): the lowest point of the box
is the floor contact of the footprint point closest to the camera, so
``camera_height = elevation + r_min * tan(depression)``; the top edge gives a
second estimate.

Two sampling schemes (:class:`SamplerConfig`):

``"paper"`` (Sec. 4, exactly): epochs of samples; in each sample EVERY
object is moved, by a normal of variance ``0.1 d`` along the camera-object
ray and ``0.005 d`` across it around the seed (``d`` = camera-object
distance), its yaw drawn from a normal of variance 0.1 rad^2 around the pose
estimate, and the scale drawn afresh, uniformly in wall height; the best
sample of an epoch (or the seed, if none beats it) seeds the next epoch.
The scale starts at a wall height of 2.5 m (the paper's Table 2 setting);
``w_s = w_o = 1``. Default 8 epochs x 25 samples; ``N_S = 3000`` is
120 x 25. (The paper's "variance" is read literally: standard deviation
``sqrt(0.1 d)`` m.)

``"improved"`` (:meth:`SamplerConfig.improved`, not in the paper):

* the scale starts from the camera height of the boxes: each object's
  position and camera height fitted to all four edges of its box
  (:func:`fit_boxes`), median over the objects; the positions are then
  fitted again at that camera height (the box width alone fixes the
  distance of an object seen edge-on badly when its yaw is off);
* the predicted box edges come from the model's outline
  (:attr:`DetectedObject.outline`, :func:`mesh_outline` in the pipeline)
  where given: a cuboid puts a plant's pot or a chair's legs too near and
  the camera 4-9 % too high (measured on the seed-0 set with the true
  models), and a convex hull (:func:`hull_outline`) spans the gap between
  a bed's legs below what the image shows;
* the scale then stays (``sample_scale=False``): on the seed-0 set, scale
  moves driven by ``E_s`` and the context prior grew the rooms whose
  estimated floor polygon was too small for the objects, and with them the
  wall height (docs/EVALUATION.md, Table 2 section);
* each epoch proposes scale-only moves when ``sample_scale`` (normal around
  the seed in wall height, a fifth of them uniform in the range), then
  coordinate-wise object moves (each proposal moves ONE object: position as in the paper, yaw
  around the seed with variance ``yaw_variance`` 0.003 rad^2, a standard deviation of 3.1 degrees
  instead of the paper's 18, and the paper's while the seed violates a hard constraint
  (``invalid_yaw_variance``): the initial yaws of the orientation network and the model choice are
  mostly right, and on the tuning sets the paper's wide yaw moves ended beds / chairs / TVs 3.4 /
  6.6 / 2.1 degrees off on average against 1.3 / 5.6 / 0.8 at the start; at 0.003 they end 3.0 /
  5.8 / 0.6 degrees off, docs/EVALUATION.md, session 40); the per-object winners are combined when the
  combination is valid and better, else the single best move is taken;
  proposal widths anneal geometrically from the paper's to ``anneal_to``
  times them over the epochs; among each object's proposals, one turns it
  by 180 degrees in place (``flip_moves``) and six by +-90 degrees, refitted
  to its box (``quarter_moves``), each only where it raises the object's
  ``E_o`` by less than ``turn_eo_margin`` (0.3). On the tuning sets the
  turns had broken 13 right yaws and repaired 9 wrong ones; 12 of the 13
  broken ones had raised ``E_o`` by 0.37-1.14 (one TV by 0.11), 7 of the
  9 repairs by less than 0.09 (docs/EVALUATION.md, session 32);
* ``w_s = 100``: with the paper's ``w_s = 1`` the image term (a fraction of
  pixels, ~1e-3 per 10 cm of object motion) is outweighed by the context
  prior (metres, and 10 per unit of misalignment), which then drags
  objects and walls away from where the image puts them;
* ``keep_in_box``: an object's centre must stay within its detection box's
  columns;
* the box term ``E_b`` (``box_weight=1``, ``box_sigma`` 1.2 degrees): each
  object's predicted box edges (outline, edge planes, cut edges, as
  :func:`fit_boxes`) held robustly to its detection box. ``E_s`` counts
  every pixel of a box as the object's, which a box-shaped silhouette cannot
  cover at the true pose (a bed seen from above is no rectangle in the
  panorama), so it pulls objects towards the camera; on the tuning sets the
  box term brought the mean bed / chair / TV / plant position error from
  26.7 / 16.0 / 20.2 / 19.8 to 18.7 / 13.4 / 17.9 / 16.5 cm, at the cost of
  fewer beds turned right (docs/EVALUATION.md, session 23);
* yaw snap (``snap_yaw_deg`` 10): after the last epoch, each object
  without rotational symmetry whose yaw is within 10 degrees of a wall
  direction (:func:`snap_to_walls`) turns onto it where that keeps the
  hypothesis valid. The context prior's alignment term wants furniture
  square to the walls, but near its optimum it costs ``nu_n theta^2 / 2``
  (0.0015 at one degree), nothing against the box-edge noise the small yaw
  moves fit: on the tuning sets, the beds, chairs and TVs within 20 degrees
  of the truth after the sampler had a median yaw error of 0.71 degrees,
  against 0.28 from the pose estimate and 0.24 snapped (docs/EVALUATION.md,
  session 31);
* walls moved to the objects (``wall_move_objects`` 2): before sampling,
  a wall of the room that two or more initial footprints cross by about
  the same depth (within 0.1 m, each at least 0.1 m) moves out to the
  nearest of them and ``E_s`` is rebuilt on that room
  (:func:`layout.objectwalls.move_walls_to_objects`); the room step puts a
  far wall short where a few rows of ceiling boundary are off, and the
  repair then pushes every object against it in. On the tuning sets it
  moved 2 walls of 90 rooms (0.18 and 0.62 m), and the chairs / TVs /
  plants there came from 19-86 cm off to 2-17 cm (docs/EVALUATION.md,
  session 41);
* the repair turns a rotationally symmetric object (a plant) in place
  before it moves it, out of a wall or off another object: its yaw means
  nothing, and the corners of its square footprint through a wall pushed
  plants 10-25 cm off (tuning sets: plants 10.9 -> 10.8 cm; fresh seed 9000:
  5.7 -> 5.2 cm; docs/EVALUATION.md, session 43);
* meant for an observation with ``object_pixels="matched"``
  (:func:`layout.likelihood.observe_labels`).

Hard constraints (never violated by a returned scene): every footprint
inside the room, no two footprints overlapping by more than ``overlap_tol``,
the camera at least ``camera_clearance`` from every footprint, every object
below the ceiling (and, with ``keep_in_box``, on its box). An invalid
initial state is first repaired (the scale grows when it was assumed, as in
the paper scheme; each object takes the least move along and across its
viewing ray, or turns a little: :meth:`_Problem.repair`); the sampler then
never prefers a sample that violates a constraint to one that does not
(lexicographic order: violation, then energy). If no valid state was found,
:class:`PosteriorError` is raised.

Convention:
    World frame of shared/CONVENTIONS.md (metres, z up, camera at
    ``(0, 0, camera_height)``); yaw in radians CCW from +x to the object's
    front; ``bbox_pano`` in pixels of the upright panorama the boxes refer
    to (``u0 > u1`` wraps the seam). Wall height = ``ceiling_z - floor_z``
    with the floor at z = 0.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field, replace
from typing import Collection, Literal, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import DEFAULT_CAMERA_HEIGHT, pixel_to_lonlat, ray_to_lonlat, xy_to_lon

from .context import ALIGNMENT_MODES, MU, NU_N, context_energy, pair_overlap_areas
from .likelihood import (OrientationLikelihood, OrientationSpec, SurfaceLikelihood, orientation_likelihood,
                         surface_likelihood)
from .objectwalls import WallMove, move_walls_to_objects
from .placement import BACK_TO_WALL, CLASS_ALIGNMENT
from .polygon import convex_in_polygon, distance_to_boundary, oriented_rectangles, points_in_polygon, wall_direction
from .rooms import as_generator
from .scene import Scene, SceneObject

__all__ = [
    "SamplerMode",
    "SYMMETRIC_CLASSES",
    "DetectedObject",
    "CUT_EDGE_BEYOND",
    "InitialObjects",
    "initialise_objects",
    "geman_mcclure",
    "camera_height_estimates",
    "fit_boxes",
    "box_scale",
    "hull_outline",
    "mesh_outline",
    "thin_footprints",
    "wall_aligned_yaw",
    "snap_to_walls",
    "SamplerConfig",
    "SceneEnergies",
    "PosteriorResult",
    "PosteriorError",
    "map_estimate",
]

FloatArray = NDArray[np.float64]
SamplerMode = Literal["paper", "improved"]

#: Classes without a canonical orientation (no alignment term, no orientation error).
SYMMETRIC_CLASSES: frozenset[str] = frozenset({"plant"})

_INVALID = 1e9  # selection key offset of samples that violate a hard constraint


class PosteriorError(RuntimeError):
    """No hypothesis satisfying the hard constraints was found."""


@dataclass(frozen=True, eq=False)
class DetectedObject:
    """One object as the sampler receives it: detection box, retrieved model and pose estimate.

    Attributes
    ----------
    cls : str
        Lowercase class name.
    bbox_pano : (4,) float
        ``(u0, v0, u1, v1)`` pixel box in the upright panorama (``u0 > u1``
        wraps the seam).
    size : (3,) float
        Metric model size ``(l, w, h)``, metres.
    yaw : float
        Pose estimate, radians, CCW from +x to the object's front.
    model_id, id : str or None
        Passed through to the scene (``id`` defaults to ``"<cls>-<k>"``).
    score : float or None
        Detection score, passed through.
    elevation : float
        Height of the object's base above the floor (0: it stands on it).
    symmetric : bool or None
        Rotationally symmetric (no alignment term); None: True for the
        classes in :data:`SYMMETRIC_CLASSES`.
    outline : (M, 3) float or None
        Points of the model's surface that bound its image (e.g.
        :func:`mesh_outline`, or the convex hull's :func:`hull_outline`)
        in the object frame: x along the
        front, y to the left, z up from the base, x and y centred on the
        footprint. Given, :func:`fit_boxes` predicts the box edges from
        these points instead of the ``size`` cuboid: a plant's pot, a
        chair's legs or a TV's stand stand inside the cuboid, so the cuboid
        puts the object's lowest point too near and the camera too high.
    edge_weights : (4,) float or None
        Weights of the box's left, top, right and bottom edges in the box
        fits (:func:`fit_boxes`, the box term), 0 to leave one out; None:
        all 1 (the pipeline marks cut edges with ``cut_edges`` instead).
    cut_edges : (4,) bool or None
        Edges (left, top, right, bottom) that may not be the object's own:
        cut by a nearer object in front (:func:`layout.modelfit.occluded_edges`)
        or by the border of the tile it was detected in. The object may reach
        beyond such an edge (its visible part ends there) but not stop short
        of it: the box fits count a cut edge's residual fully where the
        predicted edge lies inside the box and weighted by
        :data:`CUT_EDGE_BEYOND` where it lies beyond (a weak pull, so that
        an object with every edge cut still keeps to its box). None: no
        edge cut.
    edge_planes : (4, 3) float or None
        Unit normals of the four planes through the camera that bound the
        detection region (left, top, right, bottom), pointing into it, in
        the frame of ``bbox_pano``: a box drawn in a perspective tile is
        bounded by great circles, and the lon/lat extent of that region
        (``bbox_pano``) is larger than the object's whenever the tile is
        turned or pitched. Given (with an ``outline``), the box fits measure
        each edge as ``asin`` of the smallest ``n . ray`` over the outline
        points (0 where the object touches the edge) instead of comparing
        the outline's lon/lat extent with ``bbox_pano``. ``(K, 4, 3)``: the
        object seen whole in K tiles (``detect.Detection.views``), the
        detection's own first; each edge's residual is then the median of
        its K residuals. :attr:`region_planes` is the first set.
    """

    cls: str
    bbox_pano: FloatArray
    size: FloatArray
    yaw: float
    model_id: str | None = None
    id: str | None = None
    score: float | None = None
    elevation: float = 0.0
    symmetric: bool | None = None
    outline: FloatArray | None = field(default=None, repr=False)
    edge_weights: FloatArray | None = field(default=None, repr=False)
    cut_edges: NDArray[np.bool_] | None = field(default=None, repr=False)
    edge_planes: FloatArray | None = field(default=None, repr=False)

    @property
    def region_planes(self) -> FloatArray | None:
        """(4, 3) edge planes of the detection's own tile box (the first of ``edge_planes``), or None."""
        if self.edge_planes is None:
            return None
        return self.edge_planes if self.edge_planes.ndim == 2 else self.edge_planes[0]

    def __post_init__(self) -> None:
        if not isinstance(self.cls, str) or not self.cls:
            raise ValueError(f"cls: expected a class name, got {self.cls!r}")
        box = np.asarray(self.bbox_pano, dtype=np.float64)
        if box.shape != (4,) or not np.all(np.isfinite(box)) or not box[1] < box[3]:
            raise ValueError(f"bbox_pano: expected finite (u0, v0, u1, v1) with v0 < v1, got {self.bbox_pano!r}")
        size = np.asarray(self.size, dtype=np.float64)
        if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 0):
            raise ValueError(f"size: expected (l, w, h) of 3 numbers > 0, got {self.size!r}")
        if not math.isfinite(float(self.yaw)):
            raise ValueError(f"yaw: expected a finite angle in radians, got {self.yaw!r}")
        if not (math.isfinite(float(self.elevation)) and self.elevation >= 0):
            raise ValueError(f"elevation: expected a height >= 0 in metres, got {self.elevation!r}")
        for a in (box, size):
            a.setflags(write=False)
        if self.outline is not None:
            pts = np.array(self.outline, dtype=np.float64)
            if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4 or not np.all(np.isfinite(pts)):
                raise ValueError(f"outline: expected (M, 3) finite points, M >= 4, got shape {np.shape(self.outline)}")
            pts.setflags(write=False)
            object.__setattr__(self, "outline", pts)
        if self.edge_weights is not None:
            ew = np.array(self.edge_weights, dtype=np.float64)
            if ew.shape != (4,) or not np.all(np.isfinite(ew)) or np.any(ew < 0):
                raise ValueError(f"edge_weights: expected 4 finite weights >= 0 (left, top, right, bottom), "
                                 f"got {self.edge_weights!r}")
            ew.setflags(write=False)
            object.__setattr__(self, "edge_weights", ew)
        if self.cut_edges is not None:
            ce = np.array(self.cut_edges)
            if ce.shape != (4,) or ce.dtype != np.bool_:
                raise ValueError(f"cut_edges: expected 4 booleans (left, top, right, bottom), got {self.cut_edges!r}")
            ce.setflags(write=False)
            object.__setattr__(self, "cut_edges", ce)
        if self.edge_planes is not None:
            ep = np.array(self.edge_planes, dtype=np.float64)
            if ep.ndim not in (2, 3) or ep.shape[-2:] != (4, 3) or len(ep) == 0 or not np.all(np.isfinite(ep)) or \
                    not np.allclose(np.linalg.norm(ep, axis=-1), 1.0, atol=1e-6):
                raise ValueError(f"edge_planes: expected (4, 3) or (K, 4, 3) unit normals, got "
                                 f"{np.shape(self.edge_planes)}")
            if self.outline is None:
                raise ValueError("edge_planes: expected an outline with them (the plane fit needs the model's points)")
            ep.setflags(write=False)
            object.__setattr__(self, "edge_planes", ep)
        object.__setattr__(self, "bbox_pano", box)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "yaw", float(self.yaw))
        object.__setattr__(self, "elevation", float(self.elevation))
        if self.symmetric is None:
            object.__setattr__(self, "symmetric", self.cls in SYMMETRIC_CLASSES)


# --------------------------------------------------------------------------- initialisation


def _box_lon(objects: Sequence[DetectedObject], width: int, height: int) -> tuple[FloatArray, FloatArray]:
    """Longitudes of the left and right box edges, right >= left (unwrapped across the seam)."""
    box = np.array([o.bbox_pano for o in objects], dtype=np.float64).reshape(-1, 4)
    u0, u1 = box[:, 0], box[:, 2]
    u1 = np.where(u1 < u0, u1 + width, u1)
    lon = pixel_to_lonlat(np.stack([np.stack([u0, u1], 1), np.zeros((len(box), 2))], -1), width, height)[..., 0]
    return lon[:, 0], lon[:, 1]


def _angular_extent(xy: FloatArray, yaw: FloatArray, size2: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Smallest and largest longitude of footprint corners (relative to the centre's, unwrapped)."""
    corners = oriented_rectangles(xy, yaw, size2)  # (..., 4, 2)
    lon_c = xy_to_lon(xy)
    lon = xy_to_lon(corners)
    rel = np.angle(np.exp(1j * (lon - lon_c[..., None])))
    return lon_c + rel.min(axis=-1), lon_c + rel.max(axis=-1)


def geman_mcclure(x: ArrayLike) -> FloatArray:
    """The robust cost ``rho(x) = x^2 / (1 + x^2)`` (Geman-McClure) of residuals ``x`` in units of their scale:
    about ``x^2`` near 0, at most 1 (an outlier costs one inlier's worth). Same shape as ``x``.

    >>> geman_mcclure([0.0, 1.0, 3.0]).tolist()
    [0.0, 0.5, 0.9]
    """
    x2 = np.square(np.asarray(x, dtype=np.float64))
    return x2 / (1.0 + x2)


def _wrap(angle: FloatArray) -> FloatArray:
    """Angles into [-pi, pi)."""
    return np.remainder(angle + np.pi, 2 * np.pi) - np.pi


def _rect_distance(xy: FloatArray, yaw: FloatArray, size2: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(closest, farthest) horizontal distance from the camera axis to each footprint."""
    c, s = np.cos(yaw), np.sin(yaw)
    ox = -(xy[..., 0] * c + xy[..., 1] * s)
    oy = xy[..., 0] * s - xy[..., 1] * c
    dx = np.maximum(np.abs(ox) - 0.5 * size2[..., 0], 0.0)
    dy = np.maximum(np.abs(oy) - 0.5 * size2[..., 1], 0.0)
    far = np.hypot(np.abs(ox) + 0.5 * size2[..., 0], np.abs(oy) + 0.5 * size2[..., 1])
    return np.hypot(dx, dy), far


@dataclass(frozen=True)
class InitialObjects:
    """Result of :func:`initialise_objects`.

    Attributes
    ----------
    centers : (N, 3) float
        Box centres, metres (``z = elevation + h / 2``).
    yaws : (N,) float
        The pose estimates, radians.
    distance : (N,) float
        Horizontal camera-to-centre distance, metres.
    camera_heights : (N, 2) float
        Closed-form camera height from the box bottom and from the box top
        at ``centers`` (:func:`camera_height_estimates`); NaN where the case
        does not apply.
    fitted_camera_heights : (N,) float
        Camera height of a least-squares fit of position and camera height
        to all four box edges (:func:`fit_boxes`), per object.
    """

    centers: FloatArray
    yaws: FloatArray
    distance: FloatArray
    camera_heights: FloatArray
    fitted_camera_heights: FloatArray


def camera_height_estimates(objects: Sequence[DetectedObject], centers: ArrayLike, width: int,
                            height: int) -> FloatArray:
    """Camera height implied by each object's box, given where the object stands.

    The lowest point of a box seen from the camera is the floor-contact
    point of its footprint closest to the camera axis, at horizontal
    distance ``r_min``: ``h_cam = elevation + r_min * tan(-lat_bottom)``. The
    highest point is the top of the farthest corner (``r_max``) when the
    object is lower than the camera (``lat_top < 0``), else the top of the
    closest point: ``h_cam = top - r * tan(lat_top)``.

    Parameters
    ----------
    objects : sequence of N DetectedObject
    centers : (N, 3) float
        Where the objects stand (metric), e.g. from :func:`initialise_objects`.
    width, height : int
        Size of the panorama the boxes refer to.

    Returns
    -------
    (N, 2) float
        ``[from the bottom, from the top]`` in metres; NaN where the box
        bottom is not below the horizon.

    Examples
    --------
    >>> o = DetectedObject("bed", [450.0, 291.4, 574.0, 360.9], [2.0, 1.6, 0.6], np.pi)  # 3 m ahead, camera 1.5 m
    >>> init = initialise_objects([o], 1024, 512)
    >>> init.centers.round(2).tolist(), camera_height_estimates([o], init.centers, 1024, 512).round(2).tolist()
    ([[3.0, -0.0, 0.3]], [[1.5, 1.5]])
    """
    objs = list(objects)
    c = np.asarray(centers, dtype=np.float64).reshape(len(objs), 3)
    if not objs:
        return np.zeros((0, 2))
    box = np.array([o.bbox_pano for o in objs])
    size = np.array([o.size for o in objs])
    yaw = np.array([o.yaw for o in objs])
    elev = np.array([o.elevation for o in objs])
    lat = pixel_to_lonlat(np.stack([np.zeros((len(objs), 2)), box[:, [1, 3]]], -1), width, height)[..., 1]
    lat_top, lat_bot = lat[:, 0], lat[:, 1]
    r_min, r_max = _rect_distance(c[:, :2], yaw, size[:, :2])
    with np.errstate(invalid="ignore"):
        from_bottom = np.where(lat_bot < 0, elev + r_min * np.tan(-lat_bot), np.nan)
        top = elev + size[:, 2]
        from_top = np.where(lat_top < 0, top + r_max * np.tan(-lat_top), top - r_min * np.tan(lat_top))
    return np.stack([from_bottom, from_top], axis=1)


def initialise_objects(objects: Sequence[DetectedObject], width: int, height: int) -> InitialObjects:
    """Place each object where its known size fits its detection box (paper Sec. 3.4 initialisation).

    The footprint (model length and width, pose-estimate yaw) is placed so
    that its corners span exactly the longitudes of the box's left and
    right edges: bisection on the distance for the angular width and turns
    about the camera to centre it, then Gauss-Newton on both edges. This
    uses only horizontal angles, so it does not depend on the unknown
    scale. A near, wide object may fit at several distances; the solver
    also starts nearer and farther, and of the exact fits keeps the one
    whose box top and bottom agree best on the camera height
    (:func:`camera_height_estimates`).

    Parameters
    ----------
    objects : sequence of N DetectedObject
    width, height : int
        Size of the panorama the boxes refer to.

    Returns
    -------
    InitialObjects

    Examples
    --------
    >>> o = DetectedObject("tv", [489.66, 266.41, 534.34, 294.6], [0.2, 0.8, 0.5], np.pi, elevation=0.8)  # 3 m ahead
    >>> (initialise_objects([o], 1024, 512).centers.round(2) + 0.0).tolist()
    [[3.0, 0.0, 1.05]]
    """
    objs = list(objects)
    n = len(objs)
    if n == 0:
        return InitialObjects(np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros((0, 2)), np.zeros(0))
    left, right = _box_lon(objs, width, height)
    size = np.array([o.size for o in objs])
    yaw = np.array([o.yaw for o in objs])
    r, phi = _fit_horizontal(left, right, yaw, size[:, :2])
    # A near, wide object can fit its box's columns at several places: start also nearer and farther,
    # and among the exact fits keep the one whose top and bottom edges agree on the camera height.
    starts = np.array([1.0, 0.5, 0.75, 1.5, 2.5])
    m = len(starts)
    rr, pp = _fit_horizontal(np.repeat(left, m), np.repeat(right, m), np.repeat(yaw, m), np.repeat(size[:, :2], m, 0),
                             r0=np.repeat(r, m) * np.tile(starts, n), phi0=np.repeat(phi, m))
    xy_c = (rr[:, None] * np.stack([np.cos(pp), -np.sin(pp)], axis=1)).reshape(n, m, 2)
    a, b = _angular_extent(xy_c.reshape(-1, 2), np.repeat(yaw, m), np.repeat(size[:, :2], m, 0))
    resid = np.hypot(_wrap(a - np.repeat(left, m)), _wrap(b - np.repeat(right, m))).reshape(n, m)
    z = np.array([o.elevation for o in objs]) + 0.5 * size[:, 2]
    cand = np.concatenate([xy_c, np.broadcast_to(z[:, None, None], (n, m, 1))], axis=-1)
    heights = camera_height_estimates([o for o in objs for _ in range(m)], cand.reshape(-1, 3), width,
                                      height).reshape(n, m, 2)
    spread = np.abs(heights[..., 0] - heights[..., 1])
    spread = np.where(np.isfinite(spread), spread, 0.0)
    exact = resid <= 1e-6 + resid.min(axis=1, keepdims=True)
    pick = np.argmin(np.where(exact, spread, np.inf), axis=1)
    centers = cand[np.arange(n), pick]
    h = heights[np.arange(n), pick]
    known = np.isfinite(h)
    fallback = float(np.median(h[known])) if known.any() else DEFAULT_CAMERA_HEIGHT
    start = np.where(known.any(axis=1), np.where(known, h, 0.0).sum(axis=1) / np.maximum(known.sum(axis=1), 1),
                     fallback)
    _, fitted = fit_boxes(objs, centers, width, height, camera_height=None, start_height=start)
    return InitialObjects(centers=centers, yaws=yaw.copy(), distance=np.hypot(centers[:, 0], centers[:, 1]),
                          camera_heights=h, fitted_camera_heights=fitted)


def hull_outline(vertices: ArrayLike, spacing: float = 0.03, max_points: int = 400) -> FloatArray:
    """Object-frame outline points of a model for :attr:`DetectedObject.outline`.

    The convex hull's vertices plus points every ``spacing`` metres along
    its edges (the lowest and highest points of a convex body seen from a
    camera lie on its edges, not only at its corners), centred on the
    footprint in x and y with z from the base.

    Parameters
    ----------
    vertices : (V, 3) float
        Model vertices, metres, x front, y left, z up.
    spacing : float
        Largest gap between outline points along a hull edge, metres.
    max_points : int
        Upper bound; the spacing grows when needed.

    Returns
    -------
    (M, 3) float

    Examples
    --------
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (2, 3)], float)
    >>> pts = hull_outline(cube, spacing=0.5)
    >>> pts.min(axis=0).tolist(), pts.max(axis=0).tolist(), len(pts)  # 8 + 12 edge midpoints + 6 x 2 on diagonals
    ([-0.5, -0.5, 0.0], [0.5, 0.5, 1.0], 32)
    """
    from scipy.spatial import ConvexHull

    v = _outline_frame(np.asarray(vertices, dtype=np.float64).reshape(-1, 3))
    hull = ConvexHull(v, qhull_options="QJ")
    pts = v[hull.vertices]
    # edges of the hull's facets, merged coplanar triangles included (their diagonals add points, harmlessly)
    edges = _triangle_edges(hull.simplices)
    a, b = v[edges[:, 0]], v[edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    while True:
        k = np.maximum(np.ceil(length / spacing).astype(int) - 1, 0)
        if len(pts) + k.sum() <= max_points or spacing > 10.0:
            break
        spacing *= 1.5
    return np.concatenate([pts, _points_along(a, b, k)])


def _outline_frame(v: FloatArray) -> FloatArray:
    """Vertices (V, 3) moved into the outline frame: footprint centred in x and y, z from the base."""
    lo, hi = v.min(axis=0), v.max(axis=0)
    return v - np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])


def _triangle_edges(tri: NDArray[np.integer]) -> NDArray[np.integer]:
    """The distinct edges (E, 2) of triangles (T, 3) of vertex indices, lower index first."""
    return np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1), axis=0)


def _points_along(a: FloatArray, b: FloatArray, k: NDArray[np.integer]) -> FloatArray:
    """``k[i]`` points evenly inside each segment ``a[i]``-``b[i]`` (endpoints excluded): (sum k, 3)."""
    t = np.concatenate([np.arange(1, n + 1) / (n + 1) for n in k]) if k.sum() else np.zeros(0)
    e = np.repeat(np.arange(len(a)), k)
    return a[e] + t[:, None] * (b[e] - a[e])


#: Camera heights above an object's base, metres, and distances from its footprint's bounding circle, metres, of
#: the viewpoints :func:`mesh_outline` looks from (at 48 azimuths each): the range of cameras and rooms the
#: pipeline meets.
_OUTLINE_VIEW_HEIGHTS = (0.8, 1.3, 1.9, 2.6)
_OUTLINE_VIEW_DISTANCES = (0.3, 1.0, 2.5, 6.0)
_OUTLINE_AZIMUTHS = 48


def mesh_outline(vertices: ArrayLike, faces: ArrayLike, spacing: float = 0.05, max_points: int = 400) -> FloatArray:
    """Object-frame outline points of a mesh for :attr:`DetectedObject.outline`: the points of its surface that
    bound its image from some camera.

    The convex hull (:func:`hull_outline`) spans the gaps of a non-convex
    model: between a bed's or a sofa's legs its hull's lowest edge runs along
    the floor where the image shows floor, so a bed seen from near its foot
    is predicted lower than its box (up to 24 px at 1024 wide) and the box
    fit pulls it away from the camera; and at a small budget its points
    along long edges are far apart and miss a near bed's lowest point. Here
    the candidates are the
    mesh's vertices and points every ``spacing`` metres along its edges (a
    face's extreme point from a camera lies on its boundary); each of
    768 viewpoints around the model (camera 0.8-2.6 m above its base,
    0.3-6 m outside its footprint's bounding circle, 48 azimuths) votes for
    the candidates that give its leftmost, rightmost, highest and lowest
    image point; the ``max_points`` candidates with the most votes are kept.
    From random viewpoints in the same range the image extent of the kept
    points of the builtin library's models is within 1.4 px (1024 wide) of
    that of the whole surface with ``max_points=100``; the convex hull's is
    off by up to 24 px (``benchmarks/eval_outline.py``). 0.1-0.9 s per
    model (the pipeline stores the outlines of its library models on disk).

    Parameters
    ----------
    vertices : (V, 3) float
        Model vertices, metres, x front, y left, z up.
    faces : (F, 3) int
        Triangles, vertex indices.
    spacing : float
        Largest gap between candidates along a mesh edge, metres.
    max_points : int
        Upper bound on the points returned.

    Returns
    -------
    (M, 3) float
        M <= max_points, centred on the footprint in x and y, z from the base;
        most votes first, so the first ``k`` rows are the outline of budget
        ``k``.

    Examples
    --------
    A table: a top on four legs. Its hull's lowest edges run along the
    floor between the legs; the outline's lowest points are the legs' feet:

    >>> top = [[x, y, z] for x in (-0.6, 0.6) for y in (-0.4, 0.4) for z in (0.7, 0.75)]
    >>> legs = [[sx * 0.55 + dx, sy * 0.35 + dy, z] for sx in (-1, 1) for sy in (-1, 1)
    ...         for dx in (-0.02, 0.02) for dy in (-0.02, 0.02) for z in (0.0, 0.7)]
    >>> v = np.array(top + legs, float)
    >>> box = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    ...        [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    >>> f = np.array([[i + 8 * k for i in t] for k in range(5) for t in box])
    >>> pts = mesh_outline(v, f)
    >>> low = pts[pts[:, 2] < 0.7]  # only leg points below the top
    >>> bool(np.all((np.abs(np.abs(low[:, 0]) - 0.55) <= 0.02 + 1e-9) & (np.abs(np.abs(low[:, 1]) - 0.35) <= 0.02 + 1e-9)))
    True
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or not np.isfinite(v).all():
        raise ValueError(f"vertices: expected a finite (V >= 4, 3) array, got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer) \
            or f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"faces: expected (F >= 1, 3) vertex indices below {len(v)}, got shape {f.shape}")
    if not spacing > 0 or int(max_points) < 1:
        raise ValueError(f"spacing and max_points: expected > 0 and >= 1, got {spacing!r} and {max_points!r}")
    v = _outline_frame(v)
    edges = _triangle_edges(f)
    a, b = v[edges[:, 0]], v[edges[:, 1]]
    k = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / spacing).astype(np.int64) - 1, 0)
    cand = np.unique(np.round(np.concatenate([v, _points_along(a, b, k)]), 6), axis=0)
    half = float(np.hypot(*np.abs(v[:, :2]).max(axis=0)))  # radius of the footprint's bounding circle
    az = np.arange(_OUTLINE_AZIMUTHS) * (2 * np.pi / _OUTLINE_AZIMUTHS)
    hs, ds, azs = np.meshgrid(np.array(_OUTLINE_VIEW_HEIGHTS), half + np.array(_OUTLINE_VIEW_DISTANCES), az,
                              indexing="ij")
    cams = np.stack([(ds * np.cos(azs)).ravel(), (ds * np.sin(azs)).ravel(), hs.ravel()], axis=1)
    centre_lon = ray_to_lonlat(np.column_stack([-cams[:, :2], np.zeros(len(cams))]))[:, 0]  # towards the model
    votes = np.zeros(len(cand), dtype=np.int64)
    chunk = max(1, min(128, 2_000_000 // len(cand)))  # viewpoints per pass: (chunk, M, 3) arrays of 48 MB at most
    for c0 in range(0, len(cams), chunk):
        lonlat = ray_to_lonlat(cand[None] - cams[c0:c0 + chunk, None])  # (chunk, M, 2)
        rel = _wrap(lonlat[..., 0] - centre_lon[c0:c0 + chunk, None])
        for idx in (rel.argmin(axis=1), rel.argmax(axis=1), lonlat[..., 1].argmin(axis=1), lonlat[..., 1].argmax(axis=1)):
            votes += np.bincount(idx, minlength=len(cand))
    keep = np.flatnonzero(votes)
    return cand[keep[np.argsort(-votes[keep], kind="stable")][:int(max_points)]]


#: Weight of a cut edge's residual (:attr:`DetectedObject.cut_edges`) where the predicted edge lies beyond the box
#: (the object reaching behind the occluder), against 1 where it stops short of the box.
#: 0.3 was chosen over 0 (one-sided) on the tuning sets (docs/EVALUATION.md, session 23).
CUT_EDGE_BEYOND = 0.3


class _BoxEdges:
    """Detection boxes of N objects as edge angles, and the edges their models predict (shared by
    :func:`fit_boxes` and the box term of the sampler).

    ``target`` (N, 4): box left and right longitudes relative to the box's middle ``mid`` (N,), and the
    latitudes of its top and bottom. :meth:`residual` predicts the same four angles from the outline
    (:attr:`DetectedObject.outline`) where given, else from the ``size`` cuboid, and weighs them by
    :attr:`DetectedObject.edge_weights`; a cut edge (:attr:`DetectedObject.cut_edges`) counts fully where the
    predicted edge lies inside the box, weighted by :data:`CUT_EDGE_BEYOND` where it lies beyond.
    """

    def __init__(self, objects: Sequence[DetectedObject], width: int, height: int) -> None:
        n = len(objects)
        left, right = _box_lon(objects, width, height)
        self.mid = 0.5 * (left + right)
        box = np.array([o.bbox_pano for o in objects], dtype=np.float64).reshape(n, 4)
        lat = pixel_to_lonlat(np.stack([np.zeros((n, 2)), box[:, [1, 3]]], -1), width, height)[..., 1]
        self.target = np.stack([left - self.mid, lat[:, 0], right - self.mid, lat[:, 1]], axis=1)
        self.size = np.array([o.size for o in objects], dtype=np.float64).reshape(n, 3)
        self.elevation = np.array([o.elevation for o in objects], dtype=np.float64)
        self.has = np.array([o.outline is not None for o in objects], dtype=bool)
        self.weights = np.array([np.ones(4) if o.edge_weights is None else o.edge_weights for o in objects],
                                dtype=np.float64).reshape(n, 4)
        self.cut = np.array([np.zeros(4, bool) if o.cut_edges is None else o.cut_edges for o in objects],
                            dtype=bool).reshape(n, 4)
        # the order of target and residual is (left, top, right, bottom)
        m = max((len(o.outline) for o in objects if o.outline is not None), default=0)
        # padded by repeating points (min / max are unchanged), only the objects that have one
        self.outline = np.stack([np.resize(o.outline, (m, 3)) for o in objects if o.outline is not None]) \
            if m else np.zeros((0, 0, 3))
        # objects with edge planes (all of them have an outline), as a mask over the outline objects
        self.planar = np.array([o.edge_planes is not None for o in objects if o.outline is not None], dtype=bool)
        # the sign of a residual whose predicted edge lies beyond the box: lon / lat residuals are predicted minus
        # detected angles (left and bottom beyond when negative, top and right when positive); a plane residual
        # is negative beyond its plane
        planar = np.zeros(n, dtype=bool)
        planar[np.flatnonzero(self.has)[self.planar]] = True
        self.beyond = np.where(planar[:, None], -1.0, np.array([-1.0, 1.0, 1.0, -1.0]))
        # (P, K, 4, 3) plane sets, padded to the most views; the edge residual is the median over the views
        sets = [o.edge_planes.reshape(-1, 4, 3) for o in objects if o.edge_planes is not None]
        k = max((len(p) for p in sets), default=1)
        self.planes = np.stack([np.concatenate([p, np.repeat(p[:1], k - len(p), axis=0)]) for p in sets]) \
            if sets else np.zeros((0, 1, 4, 3))
        self.views = np.array([len(p) for p in sets], dtype=np.int64)
        self._planes_t = self.planes.reshape(len(self.planes), k * 4, 3).transpose(0, 2, 1).copy()  # (P, 3, K * 4)

    def residual(self, xy: FloatArray, yaw: FloatArray, cam_h: FloatArray) -> FloatArray:
        """Predicted minus detected edge angles, radians, times the edge weights: ``xy (..., N, 2)``,
        ``yaw, cam_h (..., N)`` -> ``(..., N, 4)`` (left, top, right, bottom)."""
        shape = yaw.shape
        n = len(self.mid)
        flat = int(np.prod(shape[:-1], dtype=np.int64))
        ang = _box_angles(xy.reshape(-1, 2), yaw.reshape(-1), np.tile(self.size, (flat, 1)),
                          np.tile(self.elevation, flat), cam_h.reshape(-1), np.tile(self.mid, flat)).reshape(*shape, 4)
        if self.has.any():
            ang[..., self.has, :] = self._outline_angles(xy[..., self.has, :], yaw[..., self.has],
                                                         cam_h[..., self.has])
        lead = (1,) * (len(shape) - 1)
        r = ang - self.target.reshape(lead + (n, 4))
        if self.planar.any():  # plane edges: the residual is the angle itself (0 at tangency), no target
            sel = np.flatnonzero(self.has)[self.planar]
            r[..., sel, :] = self._plane_angles(xy[..., sel, :], yaw[..., sel], cam_h[..., sel])
        if self.cut.any():  # a cut edge: a weaker pull where the object reaches beyond it
            beyond = self.cut.reshape(lead + (n, 4)) & (r * self.beyond.reshape(lead + (n, 4)) > 0)
            r = np.where(beyond, CUT_EDGE_BEYOND * r, r)
        return r * self.weights.reshape(lead + (n, 4))

    def _outline_rays(self, xy: FloatArray, yaw: FloatArray, cam_h: FloatArray,
                      which: NDArray[np.bool_] | slice = slice(None)) -> FloatArray:
        """Camera-to-point vectors of the outline points of the outline objects ``which``: (..., K, M, 3)."""
        c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
        pts = self.outline[which]
        px, py, pz = pts[..., 0], pts[..., 1], pts[..., 2]  # (K, M)
        elev = self.elevation[self.has][which]
        return np.stack([xy[..., 0:1] + c * px - s * py, xy[..., 1:2] + s * px + c * py,
                         np.broadcast_to(elev[:, None] + pz - cam_h[..., None], c.shape[:-1] + px.shape[-1:])],
                        axis=-1)

    def _outline_angles(self, xy: FloatArray, yaw: FloatArray, cam_h: FloatArray) -> FloatArray:
        """:func:`_box_angles` of the outline points, broadcast over leading dimensions: (..., K, 4)."""
        lonlat = ray_to_lonlat(self._outline_rays(xy, yaw, cam_h))
        rel = _wrap(lonlat[..., 0] - self.mid[self.has][:, None])
        lat = lonlat[..., 1]
        return np.stack([rel.min(axis=-1), lat.max(axis=-1), rel.max(axis=-1), lat.min(axis=-1)], axis=-1)

    def _plane_angles(self, xy: FloatArray, yaw: FloatArray, cam_h: FloatArray) -> FloatArray:
        """Per edge plane, asin of the smallest ``n . ray / |ray|`` over the outline points, the median over
        each object's views: (..., P, 4)."""
        rays = self._outline_rays(xy, yaw, cam_h, self.planar)  # (..., P, M, 3)
        unit = rays / np.maximum(np.linalg.norm(rays, axis=-1, keepdims=True), 1e-12)
        v = self.planes.shape[1]
        dots = (unit @ self._planes_t).min(axis=-2)  # (..., P, V * 4)
        if v > 1:
            dots = _median_of_first(dots.reshape(dots.shape[:-1] + (v, 4)), self.views)
        return np.arcsin(np.clip(dots, -1.0, 1.0))


def _median_of_first(a: FloatArray, count: NDArray[np.int64]) -> FloatArray:
    """Median over axis -2 of ``a (..., P, V, E)`` of the first ``count[p]`` entries of each p: (..., P, E)."""
    v = a.shape[-2]
    pad = np.arange(v)[:, None] >= count[:, None, None]  # (P, V, 1): padding, sorted to the end
    s = np.sort(np.where(pad, np.inf, a), axis=-2)
    lo = ((count - 1) // 2)[:, None, None]
    hi = (count // 2)[:, None, None]
    shape = s.shape[:-2] + (1, s.shape[-1])

    def take(i: NDArray[np.int64]) -> FloatArray:
        return np.take_along_axis(s, np.broadcast_to(i, shape), axis=-2)[..., 0, :]

    return 0.5 * (take(lo) + take(hi))


def box_scale(objects: Sequence[DetectedObject], width: int, height: int, camera_height: float, ceiling_z: float,
              wall_height_range: tuple[float, float] = (2.0, 3.5),
              init: InitialObjects | None = None) -> tuple[float, FloatArray]:
    """The scale the detection boxes say, and the objects placed at it (the improved initialisation).

    Each object's position and camera height are fitted to all four edges
    of its box (:func:`fit_boxes`); the scale is the median camera height
    over the objects divided by the room's ``camera_height`` at scale 1,
    clipped to ``wall_height_range``; the positions are then fitted again
    at that camera height.

    Parameters
    ----------
    objects : sequence of N DetectedObject
    width, height : int
        Size of the panorama the boxes refer to.
    camera_height, ceiling_z : float
        Camera height and ceiling height of the room at scale 1.
    wall_height_range : (float, float)
        Allowed wall heights, metres.
    init : InitialObjects, optional
        :func:`initialise_objects` of the same objects, if already computed.

    Returns
    -------
    scale : float
        1.0 when no object gives a camera height.
    centers : (N, 3) float
        Metric object centres at that scale.
    """
    objs = list(objects)
    if not objs:
        return 1.0, np.zeros((0, 3))
    init = initialise_objects(objs, width, height) if init is None else init
    est = init.fitted_camera_heights[np.isfinite(init.fitted_camera_heights)]
    lam = float(np.median(est)) / camera_height if est.size else 1.0
    lo_h, hi_h = (float(v) for v in wall_height_range)
    lam = float(np.clip(lam, lo_h / ceiling_z, hi_h / ceiling_z))
    centers = fit_boxes(objs, init.centers, width, height, camera_height=lam * camera_height)[0]
    return lam, centers


def _box_angles(xy: FloatArray, yaw: FloatArray, size: FloatArray, elevation: FloatArray, cam_h: FloatArray,
                mid: FloatArray) -> FloatArray:
    """(N, 4) edges of the boxes seen from the camera: longitudes of the left and right edges relative
    to ``mid`` and latitudes of the top and bottom edges, radians."""
    a, b = _angular_extent(xy, yaw, size[:, :2])
    r_min, r_max = _rect_distance(xy, yaw, size[:, :2])
    r_min = np.maximum(r_min, 1e-6)
    bottom, top = elevation - cam_h, elevation + size[:, 2] - cam_h
    lat_top = np.where(top < 0, np.arctan2(top, r_max), np.arctan2(top, r_min))
    lat_bot = np.where(bottom < 0, np.arctan2(bottom, r_min), np.arctan2(bottom, r_max))
    return np.stack([_wrap(a - mid), lat_top, _wrap(b - mid), lat_bot], axis=1)


def fit_boxes(objects: Sequence[DetectedObject], centers: ArrayLike, width: int, height: int,
              camera_height: float | None = None,
              start_height: ArrayLike = 1.6, iterations: int = 30) -> tuple[FloatArray, FloatArray]:
    """Least-squares fit of the objects' floor positions to all four edges of their boxes.

    The width of a box alone fixes an object's distance badly when it is
    seen nearly edge-on and its yaw is a few degrees off; its top and bottom
    edges do not depend on the yaw that much. Levenberg-Marquardt on the
    four edge angles (radians) per object, from ``centers``.

    Parameters
    ----------
    objects : sequence of N DetectedObject
    centers : (N, 3) float
        Starting positions (e.g. :attr:`InitialObjects.centers`).
    width, height : int
        Size of the panorama the boxes refer to.
    camera_height : float or None
        Known camera height; None: fit one per object as well (3 unknowns,
        4 equations), starting from ``start_height``.
    start_height : float or (N,) float
    iterations : int
        Levenberg-Marquardt steps (fewer suffice from a close start).

    Returns
    -------
    centers : (N, 3) float
    camera_heights : (N,) float
        The fitted (or given) camera height per object.

    Examples
    --------
    >>> o = DetectedObject("bed", [450.0, 291.4, 574.0, 360.9], [2.0, 1.6, 0.6], np.pi + 0.05)  # yaw 3 deg off
    >>> c, h = fit_boxes([o], [[3.1, 0.2, 0.3]], 1024, 512)
    >>> c.round(1).tolist(), h.round(1).tolist()
    ([[3.0, 0.0, 0.3]], [1.5])
    """
    objs = list(objects)
    n = len(objs)
    c = np.asarray(centers, dtype=np.float64).reshape(n, 3).copy()
    if n == 0:
        return c, np.zeros(0)
    c, h, _ = _fit_edges(_BoxEdges(objs, width, height), np.array([o.yaw for o in objs]), c, camera_height,
                         start_height, iterations)
    return c, h


def _fit_edges(edges: _BoxEdges, yaw: FloatArray, centers: FloatArray, camera_height: float | None,
               start_height: ArrayLike, iterations: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`fit_boxes` on prepared box edges; also returns the final residual (N, 4) (weighted radians)."""
    c = centers.copy()
    n = len(c)
    size = edges.size
    free_h = camera_height is None
    h = np.broadcast_to(np.asarray(start_height if free_h else camera_height, dtype=np.float64), (n,)).copy()
    p = np.column_stack([c[:, :2], h]) if free_h else c[:, :2].copy()
    k = p.shape[1]

    def resid(q: FloatArray) -> FloatArray:
        return edges.residual(q[:, :2], yaw, q[:, 2] if free_h else h)

    def cost(r: FloatArray) -> FloatArray:
        return np.sum(r * r, axis=1)

    def camera_clear(q: FloatArray) -> NDArray[np.bool_]:
        near, _ = _rect_distance(q[:, :2], yaw, size[:, :2])
        ok = near > 1e-3
        return ok & (q[:, 2] > 0.05) if free_h else ok

    r0 = resid(p)
    damp = np.full(n, 1e-3)
    for _ in range(int(iterations)):
        jac = np.empty((n, 4, k))
        for i in range(k):
            dq = np.zeros_like(p)
            dq[:, i] = 1e-6 * np.maximum(np.abs(p[:, i]), 1.0)
            jac[:, :, i] = (resid(p + dq) - r0) / dq[:, i, None]
        jtj = np.einsum("nri,nrj->nij", jac, jac)
        jtr = np.einsum("nri,nr->ni", jac, r0)
        a = jtj + damp[:, None, None] * np.eye(k) * (1.0 + np.einsum("nii->ni", jtj)[:, :, None])
        step = np.linalg.solve(a, -jtr[..., None])[..., 0]
        q = p + step
        r1 = resid(q)
        better = (cost(r1) < cost(r0)) & camera_clear(q) & np.all(np.isfinite(r1), axis=1)
        p = np.where(better[:, None], q, p)
        r0 = np.where(better[:, None], r1, r0)
        damp = np.where(better, damp * 0.3, damp * 10.0)
    c[:, :2] = p[:, :2]
    return c, (p[:, 2] if free_h else h), r0


def _fit_horizontal(left: FloatArray, right: FloatArray, yaw: FloatArray, size2: FloatArray,
                    r0: FloatArray | None = None, phi0: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """Distance r and direction phi of footprint centres whose corners span longitudes [left, right].

    Without a start: four alternations of a bisection on r for the angular
    width and a turn of phi that centres the span, then Gauss-Newton on both
    edges (near, wide objects couple r and phi); with ``r0, phi0``:
    Gauss-Newton from there.
    """
    n = len(left)
    mid = 0.5 * (left + right)

    def r_min(phi: FloatArray) -> FloatArray:
        """Smallest centre distance along direction phi that keeps the camera outside the footprint."""
        rel = -phi - yaw  # angle of the camera-to-object direction in the object's frame
        c, s = np.abs(np.cos(rel)), np.abs(np.sin(rel))
        t = np.minimum(0.5 * size2[:, 0] / np.maximum(c, 1e-12), 0.5 * size2[:, 1] / np.maximum(s, 1e-12))
        return t * 1.001 + 1e-3

    def extent(r: FloatArray, phi: FloatArray) -> tuple[FloatArray, FloatArray]:
        return _angular_extent(r[:, None] * np.stack([np.cos(phi), -np.sin(phi)], axis=1), yaw, size2)

    if r0 is None or phi0 is None:
        phi = mid.copy()
        for _ in range(4):
            lo, hi = r_min(phi), np.full(n, 50.0)
            for _ in range(60):
                r = 0.5 * (lo + hi)
                a, b = extent(r, phi)
                wider = (b - a) > (right - left)
                lo = np.where(wider, r, lo)
                hi = np.where(wider, hi, r)
            r = 0.5 * (lo + hi)
            a, b = extent(r, phi)
            phi = phi + _wrap(mid - 0.5 * (a + b))
    else:
        phi = np.asarray(phi0, dtype=np.float64).copy()
        r = np.maximum(np.asarray(r0, dtype=np.float64), r_min(phi))
    for _ in range(25):
        a, b = extent(r, phi)
        res = np.stack([_wrap(a - left), _wrap(b - right)], axis=1)
        dr, dp = 1e-5 * r, 1e-6
        ar, br = extent(r + dr, phi)
        ap, bp = extent(r, phi + dp)
        j00, j01, j10, j11 = (ar - a) / dr, (ap - a) / dp, (br - b) / dr, (bp - b) / dp
        det = j00 * j11 - j01 * j10
        ok = np.abs(det) > 1e-12
        safe = np.where(ok, det, 1.0)
        step_r = np.where(ok, (j11 * res[:, 0] - j01 * res[:, 1]) / safe, 0.0)
        step_p = np.where(ok, (-j10 * res[:, 0] + j00 * res[:, 1]) / safe, 0.0)
        p_new = phi - np.clip(step_p, -0.2, 0.2)
        r_new = np.clip(r - np.clip(step_r, -0.5 * r, 0.5 * r), r_min(p_new), 50.0)
        a2, b2 = extent(r_new, p_new)
        better = np.hypot(_wrap(a2 - left), _wrap(b2 - right)) < np.hypot(res[:, 0], res[:, 1])
        r, phi = np.where(better, r_new, r), np.where(better, p_new, phi)
    return r, phi


# --------------------------------------------------------------------------- configuration and results


@dataclass(frozen=True)
class SamplerConfig:
    """Options of :func:`map_estimate` (defaults: the paper's Sec. 4).

    Attributes
    ----------
    mode : {"paper", "improved"}
        Sampling scheme (module docstring).
    epochs, samples_per_epoch : int
        Paper: 8 x 25. In ``"improved"`` mode ``samples_per_epoch`` is the
        number of scale proposals and of proposals per object in an epoch.
    n_samples : int or None
        Total budget of evaluated hypotheses ``N_S``; when given it sets the
        number of epochs (e.g. 3000 = 120 x 25 in paper mode).
    wall_height_range : (float, float)
        Uniform scale prior in wall height, metres (paper: [2.0, 3.5]);
        ``low == high`` fixes the scale.
    initial_wall_height : float or None
        Wall height of the initial hypothesis (paper mode default 2.5 m);
        None: from the camera height fitted to the boxes, and the positions
        refitted at that height (module docstring). Given, the improved mode
        fits the positions to the boxes at the camera height it implies.
    position_variance : (along, across)
        Variance of the position proposals as a multiple of the
        camera-object distance, m^2 per m (paper: 0.1, 0.005).
    yaw_variance : float
        Variance of the yaw proposals, rad^2 (paper: 0.1; the improved
        scheme: 0.003).
    invalid_yaw_variance : float or None
        Improved mode: the variance of the yaw proposals of an epoch whose
        seed violates a hard constraint, rad^2; None: ``yaw_variance``.
        The improved scheme: 0.1, the paper's, so that an object that only
        fits the estimated room turned can still be placed (with 0.003
        throughout, 5 of the 270 runs on the tuning rooms, 90 rooms x 3
        seeds, had to drop an object; none with 0.1; docs/EVALUATION.md,
        session 40).
    wall_height_sigma : float
        Standard deviation of the improved mode's scale proposals, metres.
    anneal_to : float
        Improved mode: proposal widths shrink to this fraction over the epochs.
    surface_weight, orientation_weight : float
        ``w_s``, ``w_o`` (paper: 1, 1).
    keep_in_box : bool
        Treat an object whose centre leaves its detection box's columns (in
        longitude) as a hard-constraint violation: the detector's direction
        is trusted. Not in the paper: False.
    nu_n, mu : float
        Context prior weights (paper: 10, 0.25).
    alignment : mapping class -> mode, or None
        Alignment mode per class (:mod:`layout.context`); None:
        :data:`layout.placement.CLASS_ALIGNMENT`, others ``"parallel"``.
    back_to_wall : collection of str
        Classes whose wall term is measured from the back edge
        (:data:`layout.placement.BACK_TO_WALL`); empty: the centre, as in
        the paper.
    overlap_tol : float
        Largest allowed footprint intersection, m^2.
    camera_clearance : float
        Smallest allowed distance from the camera axis to a footprint, metres.
    wall_tol : float
        Allowed footprint penetration into a wall, metres.
    sample_scale : bool
        False: the scale stays at its initial value (the camera height of
        the boxes in ``"improved"`` mode) and only the objects are sampled.
        The scale moves of the sampler are driven by ``E_s`` and the context
        prior, which reward a larger room whenever the estimated floor
        polygon is too small for the objects; the boxes measure it better.
    box_weight, box_sigma : float
        ``w_b`` and the scale (radians) of the box term ``E_b`` (not in the
        paper: 0): the sum over objects and their four box edges of the
        Geman-McClure misfit ``x^2 / (1 + x^2)``, ``x`` = (predicted edge -
        detected edge) / ``box_sigma``, the predicted edges from the object's
        outline or cuboid at the hypothesis' camera height. It ties each
        object to its detection box, robustly (a box cut by an occluder
        costs at most 1 per edge).
    flip_moves : bool
        Improved mode: the first proposal of every epoch for each object
        without rotational symmetry turns it by 180 degrees in place (not in
        the paper). The yaw proposals (0.32 rad) never reach the other
        side, and the HOG pose confuses front and back of beds, TVs and
        chairs; the flip lets the context prior (backs to walls) and E_o
        decide.
    quarter_moves : bool
        Improved mode: the next six proposals of every epoch for each object
        without rotational symmetry whose footprint is not thin (width at
        least half the length) turn it by +90 and -90 degrees, its
        position fitted again to its box at the new yaw and the current
        camera height (:func:`fit_boxes`; not in the paper), and also 3 and
        6 % nearer the camera. A HOG pose often gives an object's side view;
        the box fit of the model choice cannot always tell the two apart,
        the room evidence may.
    turn_eo_margin : float
        Improved mode: a flip or quarter-turn proposal is made only where it
        raises the object's ``E_o`` by less than this (``inf``: always, as
        before session 32). Where ``E_o`` is sure of the current yaw (the
        orientation network's cost dominates it), a turn is a guess of the
        room evidence alone, and the room is often the wrong one (a missed
        notch puts a wall where there is none). The improved scheme: 0.3,
        chosen on the tuning seeds 7000 and 8000 from the E_o rises of the
        turns that the sampler without it took (docs/EVALUATION.md,
        session 32).
    initial_camera_height : float or None
        Used when ``initial_wall_height`` is None: the camera height of the
        initial hypothesis, metres (e.g. the shared height of
        :func:`layout.modelfit.select_models`), clipped to the wall-height
        range, with the positions fitted to the boxes at it; None: the
        median of the per-object fits (:func:`box_scale`).
    wall_move_objects : int
        Before sampling, a wall of the room that this many objects' initial
        footprints cross by about the same depth (within
        ``wall_move_agree`` metres of each other, each at least
        ``wall_move_depth``) moves out to the nearest of them, and E_s is
        rebuilt on the moved room (:func:`layout.objectwalls.move_walls_to_objects`;
        not in the paper: 0, off). A far wall placed short by a few rows of
        ceiling boundary is what it repairs. The improved scheme: 2, with
        0.1 m and 0.1 m, chosen on the tuning seeds 7000 and 8000 and checked
        on a fresh seed 9000 (docs/EVALUATION.md, session 41).
    wall_move_depth, wall_move_agree : float
        Metres, at the initial scale; see ``wall_move_objects``.
    snap_yaw_deg : float
        After the last epoch, the yaw of each object without rotational
        symmetry within this many degrees of a wall direction of the floor
        polygon is set onto it (:func:`snap_to_walls`), object by object
        where the hypothesis stays valid (not in the paper: 0, off). The
        improved scheme: 10, chosen on the tuning seeds 7000 and 8000
        among 2-44 degrees (docs/EVALUATION.md, session 31).
    """

    mode: SamplerMode = "paper"
    epochs: int = 8
    samples_per_epoch: int = 25
    n_samples: int | None = None
    wall_height_range: tuple[float, float] = (2.0, 3.5)
    initial_wall_height: float | None = 2.5
    position_variance: tuple[float, float] = (0.1, 0.005)
    yaw_variance: float = 0.1
    invalid_yaw_variance: float | None = None
    wall_height_sigma: float = 0.25
    anneal_to: float = 0.02
    surface_weight: float = 1.0
    orientation_weight: float = 1.0
    keep_in_box: bool = False
    nu_n: float = NU_N
    mu: float = MU
    alignment: Mapping[str, str] | None = None
    back_to_wall: Collection[str] = field(default_factory=lambda: BACK_TO_WALL)
    overlap_tol: float = 1e-4
    camera_clearance: float = 0.1
    wall_tol: float = 1e-6
    sample_scale: bool = True
    box_weight: float = 0.0
    box_sigma: float = math.radians(1.0)
    flip_moves: bool = False
    quarter_moves: bool = False
    initial_camera_height: float | None = None
    snap_yaw_deg: float = 0.0
    turn_eo_margin: float = math.inf
    wall_move_objects: int = 0
    wall_move_depth: float = 0.1
    wall_move_agree: float = 0.1

    def __post_init__(self) -> None:
        if self.mode not in ("paper", "improved"):
            raise ValueError(f"mode: expected 'paper' or 'improved', got {self.mode!r}")
        for name in ("epochs", "samples_per_epoch"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {v!r}")
        if self.n_samples is not None and (not isinstance(self.n_samples, (int, np.integer)) or self.n_samples < 1):
            raise ValueError(f"n_samples: expected an integer >= 1 or None, got {self.n_samples!r}")
        lo, hi = (float(v) for v in self.wall_height_range)
        if not 0 < lo <= hi:
            raise ValueError(f"wall_height_range: expected 0 < low <= high metres, got {self.wall_height_range!r}")
        ich = self.initial_camera_height
        if ich is not None and not (math.isfinite(float(ich)) and float(ich) > 0):
            raise ValueError(f"initial_camera_height: expected metres > 0 or None, got {ich!r}")
        if self.initial_wall_height is not None and not lo <= self.initial_wall_height <= hi:
            raise ValueError(f"initial_wall_height: expected a value in {self.wall_height_range} or None, "
                             f"got {self.initial_wall_height!r}")
        pv = tuple(float(v) for v in self.position_variance)
        if len(pv) != 2 or not all(v > 0 for v in pv):
            raise ValueError(f"position_variance: expected two positive numbers, got {self.position_variance!r}")
        for name in ("yaw_variance", "wall_height_sigma", "anneal_to", "box_sigma"):
            if not float(getattr(self, name)) > 0:
                raise ValueError(f"{name}: expected a value > 0, got {getattr(self, name)!r}")
        if self.invalid_yaw_variance is not None and not float(self.invalid_yaw_variance) > 0:
            raise ValueError(f"invalid_yaw_variance: expected a value > 0 or None, got {self.invalid_yaw_variance!r}")
        for name in ("surface_weight", "orientation_weight", "nu_n", "mu", "overlap_tol", "camera_clearance",
                     "wall_tol", "box_weight"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: expected a finite value >= 0, got {getattr(self, name)!r}")
        wmo = self.wall_move_objects
        if isinstance(wmo, bool) or not isinstance(wmo, (int, np.integer)) or wmo < 0:
            raise ValueError(f"wall_move_objects: expected an integer >= 0 (0: off), got {wmo!r}")
        for name in ("wall_move_depth", "wall_move_agree"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: expected metres >= 0, got {getattr(self, name)!r}")
        if not float(self.turn_eo_margin) > 0:
            raise ValueError(f"turn_eo_margin: expected a value > 0 (inf: no limit), got {self.turn_eo_margin!r}")
        if not 0.0 <= float(self.snap_yaw_deg) <= 45.0:
            raise ValueError(f"snap_yaw_deg: expected degrees in [0, 45], got {self.snap_yaw_deg!r}")
        if self.alignment is not None:
            bad = [m for m in self.alignment.values() if m not in ALIGNMENT_MODES]
            if bad:
                raise ValueError(f"alignment: expected modes in {ALIGNMENT_MODES}, got {bad[0]!r}")

    @classmethod
    def improved(cls, **overrides: object) -> "SamplerConfig":
        """The improved scheme (module docstring): scale fitted to the boxes and kept (``sample_scale=False``),
        coordinate-wise annealed moves with flips and quarter turns, ``surface_weight=100``, ``keep_in_box=True``,
        the box term (``box_weight=1``, ``box_sigma`` 1.2 degrees), yaws snapped onto the walls within 10
        degrees (``snap_yaw_deg``), turns only where they raise E_o by less than 0.3 (``turn_eo_margin``),
        yaw moves of variance 0.003 rad^2 (``yaw_variance``), 0.1 while the seed violates a hard constraint
        (``invalid_yaw_variance``), a wall that two initial objects agree stands beyond moved out to them
        (``wall_move_objects``); ``overrides`` replace any of these."""
        opts: dict[str, object] = {"mode": "improved", "initial_wall_height": None, "surface_weight": 100.0,
                                   "keep_in_box": True, "sample_scale": False, "flip_moves": True,
                                   "quarter_moves": True, "box_weight": 1.0, "box_sigma": math.radians(1.2),
                                   "snap_yaw_deg": 10.0, "turn_eo_margin": 0.3, "yaw_variance": 0.003,
                                   "invalid_yaw_variance": 0.1, "wall_move_objects": 2}
        opts.update(overrides)
        return cls(**opts)  # type: ignore[arg-type]


@dataclass(frozen=True)
class SceneEnergies:
    """The terms of the posterior energy of one hypothesis.

    Attributes
    ----------
    surface, orientation : float
        ``E_s`` (in [0, 1]) and ``E_o``.
    object_wall, object_object : float
        ``E_ow`` and ``E_oo`` (m^2) of the context prior.
    total : float
        ``w_s E_s + w_o E_o + E_ow + mu E_oo + w_b E_b``.
    box : float
        ``E_b``, the box term (0 unless ``SamplerConfig.box_weight > 0``).
    """

    surface: float
    orientation: float
    object_wall: float
    object_object: float
    total: float
    box: float = 0.0

    def as_array(self) -> FloatArray:
        """``(5,)`` float: surface, orientation, object_wall, object_object, total."""
        return np.array([self.surface, self.orientation, self.object_wall, self.object_object, self.total])


@dataclass(frozen=True, eq=False)
class PosteriorResult:
    """Result of :func:`map_estimate`.

    Attributes
    ----------
    scene : Scene
        The MAP hypothesis: metric room (``scale * floor``, ceiling, camera
        height), objects, ``scale``, timing.
    energies : SceneEnergies
        Of ``scene``.
    initial : Scene
        The initial hypothesis (it may violate the hard constraints).
    initial_energies : SceneEnergies
    history : (E + 1, 6) float
        Per epoch (row 0: the state the sampling starts from, after the
        repair of an invalid initial hypothesis) the seed's ``E_s, E_o,
        E_ow, E_oo, total`` and wall height.
    n_samples : int
        Hypotheses evaluated.
    n_invalid : int
        Of those, how many violated a hard constraint.
    mode : str
    seconds : float
        Wall-clock time of the sampling.
    wall_moves : tuple of layout.objectwalls.WallMove
        Walls of the likelihood's room moved out to the objects before sampling
        (``SamplerConfig.wall_move_objects``; distances at scale 1, the room of ``scene`` and ``initial`` is the
        moved one).
    """

    scene: Scene
    energies: SceneEnergies
    initial: Scene
    initial_energies: SceneEnergies
    history: FloatArray
    n_samples: int
    n_invalid: int
    mode: str
    seconds: float
    wall_moves: tuple[WallMove, ...] = ()


# --------------------------------------------------------------------------- the problem


@dataclass
class _Batch:
    """Energies and constraint violation of a batch of hypotheses, (B,) each."""

    surface: FloatArray
    orientation: FloatArray
    wall: FloatArray
    overlap: FloatArray
    total: FloatArray
    violation: FloatArray
    box: FloatArray | None = None

    @property
    def key(self) -> FloatArray:
        """Selection key: energy for valid hypotheses, above every valid one for invalid ones."""
        return np.where(self.violation > 0, _INVALID + self.violation, self.total)

    def energies(self, i: int) -> SceneEnergies:
        return SceneEnergies(float(self.surface[i]), float(self.orientation[i]), float(self.wall[i]),
                             float(self.overlap[i]), float(self.total[i]),
                             0.0 if self.box is None else float(self.box[i]))


class _Problem:
    """Everything fixed during the sampling: room up to scale, objects, energies, constraints."""

    def __init__(self, likelihood: SurfaceLikelihood, objects: Sequence[DetectedObject],
                 orientation: OrientationLikelihood, cfg: SamplerConfig, image_width: int, image_height: int) -> None:
        self.lik = likelihood
        self.cfg = cfg
        self.floor = np.asarray(likelihood.floor, dtype=np.float64)
        self.ceiling = float(likelihood.ceiling_z)
        self.h0 = float(likelihood.camera_height)
        self.sizes = np.array([o.size for o in objects], dtype=np.float64).reshape(-1, 3)
        self.size2 = self.sizes[:, :2]
        self.z = np.array([o.elevation for o in objects]) + 0.5 * self.sizes[:, 2]
        self.top = self.z + 0.5 * self.sizes[:, 2]
        self.orientation = orientation
        align = dict(CLASS_ALIGNMENT if cfg.alignment is None else cfg.alignment)
        back = frozenset(cfg.back_to_wall)
        self.modes = ["parallel" if o.symmetric else align.get(o.cls, "parallel") for o in objects]
        self.weights = np.array([0.0 if o.symmetric else 1.0 for o in objects])
        self.anchors = np.array([-0.5 * o.size[0] if o.cls in back else 0.0 for o in objects])
        self.n = len(objects)
        left, right = _box_lon(objects, image_width, image_height)
        self.box_mid = 0.5 * (left + right)
        self.box_half = np.where(right - left < np.pi, 0.5 * (right - left), np.inf)  # no limit for huge boxes
        # objects the quarter turns may turn: asymmetric, not thin
        self.turnable = np.flatnonzero((self.weights > 0) & ~thin_footprints(self.size2))
        # the box edges, for the box term and the quarter turns' refits
        need_edges = self.n and (cfg.box_weight > 0 or cfg.quarter_moves)
        self.edges = _BoxEdges(objects, image_width, image_height) if need_edges else None

    def refit(self, lam: float, xy: FloatArray, yaw: FloatArray) -> FloatArray:
        """Floor positions (N, 2) of the objects at yaws ``yaw`` (N,) fitted to their boxes at scale ``lam``,
        starting from ``xy`` (N, 2)."""
        start = np.column_stack([xy, self.z])
        return _fit_edges(self.edges, yaw, start, lam * self.h0, lam * self.h0, iterations=10)[0][:, :2]

    def box_energy(self, lam: FloatArray, xy: FloatArray, yaw: FloatArray) -> FloatArray:
        """``E_b`` (B,): robust misfit of the objects' predicted box edges to their detection boxes."""
        cam = np.broadcast_to((lam * self.h0)[:, None], yaw.shape)
        return geman_mcclure(self.edges.residual(xy, yaw, cam) / self.cfg.box_sigma).sum(axis=(1, 2))

    def evaluate(self, lam: FloatArray, xy: FloatArray, yaw: FloatArray) -> _Batch:
        """Energies of hypotheses ``lam (B,)``, ``xy (B, N, 2)``, ``yaw (B, N)``."""
        cfg = self.cfg
        b = len(lam)
        if self.n == 0:
            zero = np.zeros(b)
            es = np.full(b, 1.0 - self.lik.room_correct / max(self.lik.observation.n_pix, 1))
            return _Batch(es, zero, zero, zero, cfg.surface_weight * es, zero)
        centers = np.concatenate([xy, np.broadcast_to(self.z, (b, self.n))[..., None]], axis=-1)
        es = self.lik(centers, self.sizes, yaw, lam).energy
        eo = self.orientation(yaw)
        floors = lam[:, None, None] * self.floor
        ctx = context_energy(xy, yaw, self.size2, floors, nu_n=cfg.nu_n, mu=cfg.mu, alignment=self.modes,
                             alignment_weights=self.weights, anchor_offsets=self.anchors)
        total = cfg.surface_weight * es + cfg.orientation_weight * eo + ctx.total
        eb = None
        if cfg.box_weight > 0:
            eb = self.box_energy(lam, xy, yaw)
            total = total + cfg.box_weight * eb
        viol = self._violation(lam, xy, yaw, ctx.pair_overlap)
        return _Batch(es, eo, np.asarray(ctx.wall, dtype=np.float64), np.asarray(ctx.overlap, dtype=np.float64),
                      total, viol, eb)

    def _violation(self, lam: FloatArray, xy: FloatArray, yaw: FloatArray, pair: FloatArray) -> FloatArray:
        cfg = self.cfg
        rects = oriented_rectangles(xy, yaw, np.broadcast_to(self.size2, xy.shape))
        unit = rects / lam[:, None, None, None]
        tol = cfg.wall_tol / float(lam.max())
        inside = convex_in_polygon(unit, self.floor, tol=tol)
        viol = np.zeros(len(lam))
        if not np.all(inside):
            bi, oi = np.nonzero(~inside)
            pts = unit[bi, oi]  # (K, 4, 2)
            out = ~points_in_polygon(pts, self.floor)
            depth = np.where(out, distance_to_boundary(pts, self.floor), 0.0).sum(axis=-1) * lam[bi]
            viol += np.bincount(bi, weights=0.01 + depth, minlength=len(lam))
        iu, ju = np.triu_indices(self.n, k=1)
        if len(iu):
            viol += np.maximum(pair[:, iu, ju] - cfg.overlap_tol, 0.0).sum(axis=-1)
        near, _ = _rect_distance(xy, yaw, np.broadcast_to(self.size2, xy.shape))
        viol += np.maximum(cfg.camera_clearance - near, 0.0).sum(axis=-1)
        viol += np.maximum(self.top[None, :] - lam[:, None] * self.ceiling, 0.0).sum(axis=-1)
        if cfg.keep_in_box:
            lon = xy_to_lon(xy)
            off = np.abs(np.angle(np.exp(1j * (lon - self.box_mid))))
            viol += np.maximum(off - self.box_half, 0.0).sum(axis=-1)
        return viol

    def object_ok(self, lam: FloatArray, xy: FloatArray, yaw: FloatArray,
                  which: int | None = None) -> NDArray[np.bool_]:
        """(B, N): footprint inside the room and clear of the camera (pairs not considered). With ``which``,
        ``xy (B, 1, 2)`` and ``yaw (B, 1)`` are that object's alone: (B, 1)."""
        size2 = np.broadcast_to(self.size2 if which is None else self.size2[[which]], xy.shape)
        rects = oriented_rectangles(xy, yaw, size2) / lam[:, None, None, None]
        inside = convex_in_polygon(rects, self.floor, tol=self.cfg.wall_tol / float(lam.max()))
        near, _ = _rect_distance(xy, yaw, size2)
        return inside & (near >= self.cfg.camera_clearance)

    def _least_move(self, lam: float, xy: FloatArray, yaw: float, j: int) -> tuple[FloatArray, float] | None:
        """Object ``j`` at ``xy (2,)``, ``yaw``: the cheapest move of :func:`_repair_moves` after which it is
        inside the room and clear of the camera (others not considered), as (position, yaw); None if none."""
        if self.cfg.mode == "improved" and self.weights[j] == 0:
            # a rotationally symmetric object (a plant) has no yaw to keep: its footprint's square corners through
            # a wall say nothing about where it stands, and a turn in place that fits costs nothing
            turns, fit = self._turns_in_place(lam, xy, yaw, j)
            if np.any(fit):
                return xy.copy(), float(turns[int(np.argmax(fit))])
        along, across, dist = _ray_frames(xy)
        for da, dc, dy in _repair_moves():
            for s in range(0, len(da), 4096):  # in chunks, cheapest first: most repairs stop in the first one
                r = np.maximum(dist + da[s:s + 4096], 0.05)
                pos = r[:, None] * along + dc[s:s + 4096, None] * across
                yaws = yaw + dy[s:s + 4096]
                fit = self.object_ok(np.full(len(r), lam), pos[:, None], yaws[:, None], which=j)[:, 0]
                if np.any(fit):
                    k = int(np.argmax(fit))
                    return pos[k], float(yaws[k])
        return None

    def _turns_in_place(self, lam: float, xy: FloatArray, yaw: float, j: int) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Object ``j`` at ``xy (2,)`` turned in place by :data:`_SYMMETRIC_TURNS` (least first): the yaws (T,) and
        whether each fits the room and clears the camera (T,), other objects not considered."""
        turns = yaw + _SYMMETRIC_TURNS
        fit = self.object_ok(np.full(len(turns), lam), np.broadcast_to(xy, (len(turns), 1, 2)), turns[:, None],
                             which=j)[:, 0]
        return turns, fit

    def _turn_apart(self, lam: float, xy: FloatArray, yaw: FloatArray, a: int, b: int) -> bool:
        """Improved scheme: of two overlapping objects, a rotationally symmetric one turned in place (the least turn
        after which it overlaps no object and still fits the room, so that a turn never trades one overlap for
        another); ``yaw`` is changed in place. False where neither is symmetric or no turn clears it."""
        if self.cfg.mode != "improved":
            return False
        for j in (a, b):
            if self.weights[j] != 0:
                continue
            turns, fit = self._turns_in_place(lam, xy[j], float(yaw[j]), j)
            cand = np.broadcast_to(yaw, (len(turns), self.n)).copy()
            cand[:, j] = turns
            fit &= pair_overlap_areas(np.broadcast_to(xy, (len(turns), self.n, 2)), cand,
                                      self.size2)[:, j].max(axis=-1) <= self.cfg.overlap_tol
            if np.any(fit):
                yaw[j] = turns[int(np.argmax(fit))]
                return True
        return False

    def repair(self, lam: float, xy: FloatArray, yaw: FloatArray,
               grow_scale: bool) -> tuple[float, FloatArray, FloatArray]:
        """A nearby hypothesis that satisfies the hard constraints, if a simple search finds one.

        1. The scale grows until every object is below the ceiling.
        2. With ``grow_scale``, the scale grows (1 cm wall-height steps, up to
           the top of the range) to the smallest value at which the most
           objects fit in the room.
        3. An object through a wall or on the camera takes the least move
           that fits (:func:`_repair_moves`): along its viewing ray (up to
           3 m) and across it (up to 30 cm), priced (along / 0.1 m)^2 +
           (across / 0.03 m)^2, so that a step of a few centimetres aside
           wins over a long slide out of an arm; if none fits, it also
           turns (up to 6 degrees) with smaller moves. In the improved
           scheme a rotationally symmetric object (no alignment term: a
           plant) first tries turns in place of up to 89 degrees, the
           least that fits taken: its yaw means nothing, its footprint's
           corners do.
        4. Of two overlapping objects, the farther one slides away from the
           camera (or, if it cannot, the nearer one towards it) by the
           smallest step that separates them. In the improved scheme a
           rotationally symmetric one of the two first turns in place, by
           the least turn after which it overlaps nothing and stays in the
           room.

        Steps 3-4 are repeated until nothing changes; the result may still
        violate a constraint (the sampler then looks for valid samples).
        """
        lo_h, hi_h = (float(v) for v in self.cfg.wall_height_range)
        lam_hi = max(hi_h / self.ceiling, lam)
        if self.n:
            lam = float(np.clip(max(lam, float(self.top.max()) / self.ceiling), None, lam_hi))
        xy, yaw = xy.copy(), yaw.copy()
        if self.n == 0:
            return lam, xy, yaw
        if grow_scale and not np.all(self.object_ok(np.array([lam]), xy[None], yaw[None])):
            grid = np.arange(lam * self.ceiling, hi_h + 1e-9, 0.01) / self.ceiling
            if len(grid):
                fits = self.object_ok(grid, np.broadcast_to(xy, (len(grid), self.n, 2)),
                                      np.broadcast_to(yaw, (len(grid), self.n))).sum(axis=1)
                lam = float(grid[int(np.argmax(fits))])  # the smallest scale at which the most objects fit
        along, _, dist = _ray_frames(xy)
        lam_a = np.array([lam])
        stuck: set[int] = set()  # objects no move fits (object_ok tests each alone: that stays so)
        for _ in range(20):
            changed = False
            ok = self.object_ok(lam_a, xy[None], yaw[None])[0]
            for j in np.flatnonzero(~ok):
                if j in stuck:
                    continue
                move = self._least_move(lam, xy[j], yaw[j], j)
                if move is None:
                    stuck.add(int(j))
                else:
                    xy[j], yaw[j] = move
                    changed = True
                    along, _, dist = _ray_frames(xy)
            pair = pair_overlap_areas(xy, yaw, self.size2)
            iu, ju = np.nonzero(np.triu(pair > self.cfg.overlap_tol, k=1))
            for a, b in zip(iu, ju):
                if self._turn_apart(lam, xy, yaw, a, b):
                    changed = True
                    continue
                far, near = (a, b) if dist[a] >= dist[b] else (b, a)
                for j, sign in ((far, 1.0), (near, -1.0)):
                    r = np.maximum(dist[j] + sign * np.arange(1, 301) * 0.01, 0.05)
                    cand = np.broadcast_to(xy, (len(r), self.n, 2)).copy()
                    cand[:, j] = r[:, None] * along[j]
                    yaws = np.broadcast_to(yaw, (len(r), self.n))
                    fit = self.object_ok(np.full(len(r), lam), cand[:, [j]], yaws[:, [j]], which=j)[:, 0]
                    fit &= pair_overlap_areas(cand, yaws, self.size2)[:, a, b] <= self.cfg.overlap_tol
                    if np.any(fit):
                        k = int(np.argmax(fit))
                        xy[j], dist[j], changed = cand[k, j], r[k], True
                        break
            if not changed:
                break
        return lam, xy, yaw

    def scene(self, lam: float, xy: FloatArray, yaw: FloatArray, objects: Sequence[DetectedObject],
              seconds: float | None = None) -> Scene:
        objs = []
        for j, o in enumerate(objects):
            objs.append(SceneObject(id=o.id or f"{o.cls}-{j}", cls=o.cls, center=[xy[j, 0], xy[j, 1], self.z[j]],
                                    size=o.size, yaw=float(yaw[j]), model_id=o.model_id, score=o.score,
                                    bbox_pano=o.bbox_pano))
        return Scene(floor=lam * self.floor, ceiling_z=lam * self.ceiling, camera_height=lam * self.h0,
                     objects=tuple(objs), scale=lam, timing={} if seconds is None else {"sampling": seconds})


#: Turns in place the repair tries first for a rotationally symmetric object, least first (0, 1, -1, 2, ... 89 deg).
_SYMMETRIC_TURNS = np.radians(np.r_[0.0, np.column_stack([np.arange(1.0, 90.0), -np.arange(1.0, 90.0)]).ravel()])


@functools.lru_cache(maxsize=1)
def _repair_moves() -> tuple[tuple[FloatArray, FloatArray, FloatArray], ...]:
    """Moves tried by the repair, least change first: (along the ray m, across m, turn rad) arrays.

    First without a turn: along the viewing ray up to 3 m and across it up to 30 cm, in 1 cm steps (36 661
    moves). Then, for an object none of those fits, turns of 1-6 degrees either way with moves along the ray up
    to 30 cm (2 cm steps) and across it up to 15 cm (3 cm steps), 4 092 moves: an object that fits nowhere costs
    about 40 000 tests, not the 476 000 of the full grid with turns. Cost (along / 0.1 m)^2 + (across / 0.03 m)^2
    + (turn / 2 deg)^2."""
    grids = ((np.arange(-300, 301) * 0.01, np.arange(-30, 31) * 0.01, np.zeros(1)),
             (np.arange(-15, 16) * 0.02, np.arange(-5, 6) * 0.03, np.radians(np.r_[np.arange(-6, 0), np.arange(1, 7)])))
    out = []
    for along, across, turns in grids:
        da, dc, dy = (g.ravel() for g in np.meshgrid(along, across, turns, indexing="ij"))
        cost = (da / 0.1) ** 2 + (dc / 0.03) ** 2 + (dy / np.radians(2.0)) ** 2
        order = np.argsort(cost, kind="stable")
        out.append((da[order], dc[order], dy[order]))
    return tuple(out)


def _ray_frames(xy: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Unit vectors along and across the camera-object ray and the distance, for (..., N, 2) positions."""
    d = np.hypot(xy[..., 0], xy[..., 1])
    safe = np.maximum(d, 1e-9)
    along = xy / safe[..., None]
    across = np.stack([-along[..., 1], along[..., 0]], axis=-1)
    return along, across, d


def _unique_ids(objects: Sequence[DetectedObject]) -> list[DetectedObject]:
    """Objects with ids ``<cls>-<k>`` filled in where missing (k counts per class)."""
    out, seen, count = [], set(), {}  # type: ignore[var-annotated]
    for o in objects:
        oid = o.id
        if oid is None:
            k = count.get(o.cls, 0)
            while f"{o.cls}-{k}" in seen:
                k += 1
            oid = f"{o.cls}-{k}"
            count[o.cls] = k + 1
        if oid in seen:
            raise ValueError(f"objects: expected unique ids, got {oid!r} twice")
        seen.add(oid)
        out.append(o if oid == o.id else replace(o, id=oid))  # every other field (outline, edges) kept
    return out


# --------------------------------------------------------------------------- the sampler


def map_estimate(likelihood: SurfaceLikelihood, objects: Sequence[DetectedObject], *, image_width: int,
                 image_height: int, orientation: OrientationSpec = None, config: SamplerConfig | None = None,
                 rng: int | np.random.Generator | None = 0) -> PosteriorResult:
    """MAP scale, object positions and yaws by epoch sampling (paper Sec. 3.4 / 4).

    Parameters
    ----------
    likelihood : SurfaceLikelihood
        ``E_s`` for the room up to scale (:func:`layout.likelihood.surface_likelihood`).
    objects : sequence of DetectedObject
        Detections with their retrieved model sizes and pose estimates.
    image_width, image_height : int
        Size of the panorama the boxes refer to.
    orientation : E_o specification
        See :func:`layout.likelihood.orientation_likelihood` (None: E_o = 0).
    config : SamplerConfig, optional
        Default: the paper's scheme, 8 epochs x 25 samples.
    rng : int, numpy Generator or None
        The only source of randomness (a seed gives the same result).

    Returns
    -------
    PosteriorResult

    Raises
    ------
    PosteriorError
        When no sampled hypothesis satisfied the hard constraints.

    Convention: see the module docstring.

    Examples
    --------
    A 5 m x 3.5 m room known up to scale (camera height assumed 1.6 m, so
    the wall height is 2.7 m at scale 1); really the camera is 1.5 m high
    and a TV of known size stands against the far wall:

    >>> from layout.likelihood import observe_labels, render_scene_labels, surface_likelihood
    >>> room = np.array([[-2.0, -1.5], [3.0, -1.5], [3.0, 2.0], [-2.0, 2.0]])
    >>> lam = 1.5 / 1.6  # the true scale: wall height 2.53 m
    >>> labels = render_scene_labels(room * lam, 2.7 * lam, 1.5, [[3 * lam - 0.1, 0.0, 0.3]], [[0.2, 0.8, 0.6]],
    ...                              [np.pi], width=256, object_label=0)
    >>> box = [121.81, 76.5, 134.19, 85.24]  # the TV's detection box
    >>> es = surface_likelihood(observe_labels(labels, [box], object_pixels="matched"), room, 2.7, 1.6)
    >>> tv = DetectedObject("tv", box, [0.2, 0.8, 0.6], np.pi)
    >>> res = map_estimate(es, [tv], image_width=256, image_height=128, config=SamplerConfig.improved(), rng=0)
    >>> round(res.scene.wall_height, 2), round(res.scene.camera_height, 2), (res.scene.objects[0].center.round(2) + 0.0)
    (2.53, 1.5, array([2.71, 0.  , 0.3 ]))
    """
    cfg = SamplerConfig() if config is None else config
    if not isinstance(likelihood, SurfaceLikelihood):
        raise ValueError(f"likelihood: expected a SurfaceLikelihood, got {type(likelihood).__name__}")
    for o in objects:
        if not isinstance(o, DetectedObject):
            raise ValueError(f"objects: expected DetectedObject items, got {type(o).__name__}")
    objs = _unique_ids(list(objects))
    g = as_generator(rng)
    t0 = time.perf_counter()
    eo = orientation_likelihood(orientation, [o.cls for o in objs])
    prob = _Problem(likelihood, objs, eo, cfg, image_width, image_height)
    n = prob.n
    init = initialise_objects(objs, image_width, image_height)
    yaw_pose = init.yaws.copy()
    xy = init.centers[:, :2].copy()
    if cfg.initial_wall_height is not None or (cfg.initial_camera_height is not None and n):
        if cfg.initial_wall_height is not None:
            lam0 = cfg.initial_wall_height / prob.ceiling
        else:
            lo_h, hi_h = (float(v) for v in cfg.wall_height_range)
            lam0 = float(np.clip(float(cfg.initial_camera_height) / prob.h0, lo_h / prob.ceiling,
                                 hi_h / prob.ceiling))
        # at a given scale the improved scheme fits the positions to all four box edges at that camera height
        # (the paper's initialisation uses the box's width alone)
        if n and (cfg.mode == "improved" or cfg.initial_wall_height is None):
            xy = fit_boxes(objs, init.centers, image_width, image_height, camera_height=lam0 * prob.h0)[0][:, :2]
    else:
        lam0, centers = box_scale(objs, image_width, image_height, prob.h0, prob.ceiling, cfg.wall_height_range,
                                  init=init)
        xy = centers[:, :2]
    yaw = init.yaws.copy()
    lam = lam0
    moves: tuple[WallMove, ...] = ()
    if cfg.wall_move_objects and n:
        walls = move_walls_to_objects(lam * prob.floor, oriented_rectangles(xy, yaw, prob.size2),
                                      min_objects=int(cfg.wall_move_objects), min_depth=float(cfg.wall_move_depth),
                                      agree=float(cfg.wall_move_agree))
        if walls.moves:
            likelihood = surface_likelihood(likelihood.observation, walls.floor / lam, likelihood.ceiling_z,
                                            likelihood.camera_height, coverage=likelihood.coverage)
            prob = _Problem(likelihood, objs, eo, cfg, image_width, image_height)
            moves = tuple(replace(m, distance=m.distance / lam) for m in walls.moves)
    initial = prob.evaluate(np.array([lam]), xy[None], yaw[None])
    initial_energies = initial.energies(0)
    initial_scene = prob.scene(lam, xy, yaw, objs)
    if initial.violation[0] > 0:
        lam, xy, yaw = prob.repair(lam, xy, yaw, grow_scale=cfg.initial_wall_height is not None)
    seed = prob.evaluate(np.array([lam]), xy[None], yaw[None])
    seed_key = float(seed.key[0])
    n_eval, n_invalid = 2, int(initial.violation[0] > 0) + int(seed.violation[0] > 0)
    s = int(cfg.samples_per_epoch)

    if cfg.mode == "paper":
        epochs = int(cfg.epochs) if cfg.n_samples is None else max(1, int(cfg.n_samples) // s)
    else:
        per_epoch = max(1, (s if cfg.sample_scale else 0) + n * s + (1 if n > 1 else 0))
        epochs = int(cfg.epochs) if cfg.n_samples is None else max(1, (int(cfg.n_samples) - 1) // per_epoch)
    history = np.zeros((epochs + 1, 6))
    history[0] = np.append(seed.energies(0).as_array(), lam * prob.ceiling)

    state = _State(lam, xy, yaw, seed_key, seed)
    for ep in range(epochs):
        if cfg.mode == "paper":
            evaluated, invalid = _paper_epoch(prob, state, yaw_pose, g)
        else:
            evaluated, invalid = _improved_epoch(prob, state, cfg.anneal_to ** (ep / max(epochs - 1, 1)), g)
        n_eval += evaluated
        n_invalid += invalid
        history[ep + 1] = np.append(state.batch.energies(0).as_array(), state.lam * prob.ceiling)
    lam, xy, yaw = state.lam, state.xy, state.yaw
    if cfg.snap_yaw_deg > 0 and n and state.batch.violation[0] <= 0:
        yaw, evaluated = _snap_yaws(prob, lam, xy, yaw, math.radians(float(cfg.snap_yaw_deg)))
        n_eval += evaluated

    seconds = time.perf_counter() - t0
    final = prob.evaluate(np.array([lam]), xy[None], yaw[None])
    if final.violation[0] > 0:
        raise PosteriorError(
            f"expected a hypothesis with every object inside the room, no overlaps beyond {cfg.overlap_tol} m^2, "
            f"the camera {cfg.camera_clearance} m clear and objects below the ceiling"
            f"{' and on their boxes' if cfg.keep_in_box else ''}; got none in {n_eval} samples "
            f"(best violation {float(final.violation[0]):.3g})")
    return PosteriorResult(scene=prob.scene(lam, xy, yaw, objs, seconds), energies=final.energies(0),
                           initial=initial_scene, initial_energies=initial_energies, history=history,
                           n_samples=n_eval, n_invalid=n_invalid, mode=cfg.mode, seconds=seconds,
                           wall_moves=moves)


def _take(b: _Batch, i: int) -> _Batch:
    """Row ``i`` of a batch as a batch of one."""
    sl = slice(i, i + 1)
    return _Batch(b.surface[sl], b.orientation[sl], b.wall[sl], b.overlap[sl], b.total[sl], b.violation[sl],
                  None if b.box is None else b.box[sl])


@dataclass
class _State:
    """The seed of the sampling: scale, positions (N, 2), yaws (N,), selection key and energies."""

    lam: float
    xy: FloatArray
    yaw: FloatArray
    key: float
    batch: _Batch

    def offer(self, res: _Batch, k: int, lam: float, xy: FloatArray, yaw: FloatArray) -> None:
        """Take row ``k`` of ``res`` (hypothesis ``lam, xy, yaw``) when it beats the seed."""
        if res.key[k] < self.key:
            self.lam, self.xy, self.yaw, self.key = float(lam), xy.copy(), yaw.copy(), float(res.key[k])
            self.batch = _take(res, k)


def _paper_epoch(prob: _Problem, st: _State, yaw_pose: FloatArray, g: np.random.Generator) -> tuple[int, int]:
    """One epoch of the paper's scheme: every sample moves the scale and every object. (evaluated, invalid)."""
    cfg, n, s = prob.cfg, prob.n, int(prob.cfg.samples_per_epoch)
    lo_h, hi_h = (float(v) for v in cfg.wall_height_range)
    lam_s = g.uniform(lo_h, hi_h, size=s) / prob.ceiling if cfg.sample_scale else np.full(s, st.lam)
    along, across, d = _ray_frames(st.xy)
    sd_a = np.sqrt(cfg.position_variance[0] * d)
    sd_c = np.sqrt(cfg.position_variance[1] * d)
    xy_s = (st.xy[None] + g.normal(size=(s, n, 1)) * sd_a[None, :, None] * along[None]
            + g.normal(size=(s, n, 1)) * sd_c[None, :, None] * across[None])
    yaw_s = yaw_pose[None] + g.normal(0.0, math.sqrt(cfg.yaw_variance), size=(s, n))
    res = prob.evaluate(lam_s, xy_s, yaw_s)
    k = int(np.argmin(res.key))
    st.offer(res, k, lam_s[k], xy_s[k], yaw_s[k])
    return s, int(np.count_nonzero(res.violation > 0))


_TURNS = (np.pi, 0.5 * np.pi, -0.5 * np.pi)  # the flip and the two quarter turns, radians
_QUARTER_PULL = (1.0, 0.97, 0.94)  # radial factors of the quarter-turn proposals (SamplerConfig.quarter_moves)
#: Footprints thinner than this (width / length) are never turned by 90 degrees: the side view of a TV is a
#: sliver no pose estimate mistakes for its front (with quarter turns for TVs too, 10 % of the TVs of the tuning
#: rooms ended 45 degrees or more off, 5 % without).
_QUARTER_ASPECT = 0.5


def thin_footprints(size2: ArrayLike) -> NDArray[np.bool_]:
    """``(N,)`` bool: footprints ``(N, 2)`` (length, width, metres) whose width is under half the length (TVs).

    Their side view is a sliver: the sampler never turns them by 90 degrees
    (``SamplerConfig.quarter_moves``) and :func:`layout.modelfit.select_models`
    picks the candidate of an object most of whose candidates are thin with
    the height's appearance weight.

    >>> thin_footprints([[0.3, 1.4], [2.1, 1.6]]).tolist()
    [True, False]
    """
    s = np.asarray(size2, dtype=np.float64).reshape(-1, 2)
    return s.min(axis=1) < _QUARTER_ASPECT * s.max(axis=1)


def wall_aligned_yaw(yaw: ArrayLike, direction: float = 0.0) -> FloatArray:
    """The wall-aligned yaw nearest each of ``yaw``: ``direction`` plus a multiple of 90 degrees (radians).

    ``direction`` is the walls' direction (:func:`layout.polygon.wall_direction`; 0 in an upright frame whose axes
    run along the walls). The result keeps the turn of ``yaw`` (no wrap to [0, 2 pi)).

    >>> np.degrees(wall_aligned_yaw(np.radians([3.0, 93.0, -179.0, 400.0]))).round(6).tolist()
    [0.0, 90.0, -180.0, 360.0]
    """
    quarter = 0.5 * np.pi
    return direction + np.round((np.asarray(yaw, dtype=np.float64) - direction) / quarter) * quarter


def snap_to_walls(yaw: ArrayLike, floor: ArrayLike, max_angle: float) -> FloatArray:
    """Yaws turned onto the nearest wall direction of a Manhattan floor polygon where they are near one.

    Parameters
    ----------
    yaw : (N,) float
        Radians, CCW from +x (any range).
    floor : (M, 2) float
        The floor polygon (its walls' direction: :func:`layout.polygon.wall_direction`).
    max_angle : float
        Radians, >= 0: a yaw farther than this from every wall direction is kept.

    Returns
    -------
    (N,) float
        ``yaw`` with the near ones replaced by the wall direction (the same turn, modulo 2 pi).

    >>> room = [[0, 0], [4, 0], [4, 3], [0, 3]]
    >>> np.degrees(snap_to_walls(np.radians([3.0, 88.0, -179.0, 30.0]), room, np.radians(10))).round(6).tolist()
    [0.0, 90.0, -180.0, 30.0]
    """
    if not (math.isfinite(float(max_angle)) and float(max_angle) >= 0):
        raise ValueError(f"max_angle: expected radians >= 0, got {max_angle!r}")
    y = np.asarray(yaw, dtype=np.float64)
    near = wall_aligned_yaw(y, wall_direction(floor))
    return np.where(np.abs(y - near) <= float(max_angle), near, y)


def _snap_yaws(prob: _Problem, lam: float, xy: FloatArray, yaw: FloatArray, max_angle: float) -> tuple[FloatArray, int]:
    """``yaw`` (N,) with :func:`snap_to_walls` applied to the asymmetric objects, one object at a time where the
    hypothesis stays valid (a turned footprint may cut a wall or a neighbour); also the hypotheses evaluated."""
    target = np.where(prob.weights > 0, snap_to_walls(yaw, prob.floor, max_angle), yaw)
    out, evaluated = yaw.copy(), 0
    for j in np.flatnonzero(target != yaw):
        trial = out.copy()
        trial[j] = target[j]
        res = prob.evaluate(np.array([lam]), xy[None], trial[None])
        evaluated += 1
        if res.violation[0] <= 0:
            out = trial
    return out, evaluated


def _turns_allowed(prob: _Problem, yaw: FloatArray, turns: Sequence[float]) -> NDArray[np.bool_]:
    """``(len(turns), N)``: whether each object's ``E_o`` rises by less than ``SamplerConfig.turn_eo_margin`` when
    turned by each of ``turns`` (radians) from ``yaw`` (N,)."""
    margin = float(prob.cfg.turn_eo_margin)
    if not math.isfinite(margin):
        return np.ones((len(turns),) + yaw.shape, dtype=bool)
    e = prob.orientation.per_object(yaw[None] + np.array([0.0, *turns])[:, None])  # E_o at yaw, then each turn
    return e[1:] - e[0] < margin


def _improved_epoch(prob: _Problem, st: _State, shrink: float, g: np.random.Generator) -> tuple[int, int]:
    """One epoch of the improved scheme (scale-only moves, then one-object moves). (evaluated, invalid)."""
    cfg, n, s = prob.cfg, prob.n, int(prob.cfg.samples_per_epoch)
    evaluated = invalid = 0
    if cfg.sample_scale:
        lo_h, hi_h = (float(v) for v in cfg.wall_height_range)
        hs = np.clip(st.lam * prob.ceiling + g.normal(0.0, cfg.wall_height_sigma * shrink, size=s), lo_h, hi_h)
        hs = np.where(g.random(s) < 0.2, g.uniform(lo_h, hi_h, size=s), hs)
        lam_s = hs / prob.ceiling
        res = prob.evaluate(lam_s, np.broadcast_to(st.xy, (s, n, 2)), np.broadcast_to(st.yaw, (s, n)))
        k = int(np.argmin(res.key))
        st.offer(res, k, lam_s[k], st.xy, st.yaw)
        evaluated, invalid = s, int(np.count_nonzero(res.violation > 0))
    if n == 0:
        return evaluated, invalid
    # proposal (j, i) moves object j only
    along, across, d = _ray_frames(st.xy)
    sd_a = np.sqrt(cfg.position_variance[0] * d) * shrink
    sd_c = np.sqrt(cfg.position_variance[1] * d) * shrink
    jj = np.arange(n)
    xy_s = np.broadcast_to(st.xy, (n, s, n, 2)).copy()
    yaw_s = np.broadcast_to(st.yaw, (n, s, n)).copy()
    xy_s[jj, :, jj] += (g.normal(size=(n, s, 1)) * sd_a[:, None, None] * along[:, None, :]
                        + g.normal(size=(n, s, 1)) * sd_c[:, None, None] * across[:, None, :])
    yaw_var = cfg.yaw_variance
    if cfg.invalid_yaw_variance is not None and st.batch.violation[0] > 0:
        yaw_var = cfg.invalid_yaw_variance  # wide yaw moves until the hypothesis is valid
    yaw_s[jj, :, jj] += g.normal(0.0, math.sqrt(yaw_var) * shrink, size=(n, s))
    # flips and quarter turns only where E_o is unsure of the current yaw (SamplerConfig.turn_eo_margin)
    allowed = _turns_allowed(prob, st.yaw, _TURNS)
    if cfg.flip_moves:  # proposal 0 of each asymmetric object: turned by 180 degrees in place
        f = jj[(prob.weights > 0) & allowed[0]]
        xy_s[f, 0, f] = st.xy[f]
        yaw_s[f, 0, f] = st.yaw[f] + _TURNS[0]
    # proposals 1-6: turned by +-90 degrees, refitted to the box, and pulled 0 / 3 / 6 % towards the camera
    # (a refit footprint flush against a wall may cut it by a centimetre)
    if cfg.quarter_moves and s > 2 * len(_QUARTER_PULL) and prob.turnable.size:
        k = 1
        for turn, ok in zip(_TURNS[1:], allowed[1:]):
            f = prob.turnable[ok[prob.turnable]]
            xy_q = prob.refit(st.lam, st.xy, st.yaw + turn) if f.size else st.xy
            for pull in _QUARTER_PULL:
                xy_s[f, k, f] = xy_q[f] * pull
                yaw_s[f, k, f] = st.yaw[f] + turn
                k += 1
    res = prob.evaluate(np.full(n * s, st.lam), xy_s.reshape(n * s, n, 2), yaw_s.reshape(n * s, n))
    evaluated += n * s
    invalid += int(np.count_nonzero(res.violation > 0))
    key = res.key.reshape(n, s)
    best = np.argmin(key, axis=1)
    better = np.flatnonzero(key[jj, best] < st.key)
    if better.size == 0:
        return evaluated, invalid
    top = int(better[np.argmin(key[better, best[better]])])
    if better.size > 1:  # all improving one-object moves at once, if that is better still
        xy_c, yaw_c = st.xy.copy(), st.yaw.copy()
        xy_c[better] = xy_s[better, best[better], better]
        yaw_c[better] = yaw_s[better, best[better], better]
        comb = prob.evaluate(np.array([st.lam]), xy_c[None], yaw_c[None])
        evaluated += 1
        invalid += int(comb.violation[0] > 0)
        if comb.key[0] <= key[top, best[top]]:
            st.offer(comb, 0, st.lam, xy_c, yaw_c)
            return evaluated, invalid
    st.offer(res, top * s + int(best[top]), st.lam, xy_s[top, best[top]], yaw_s[top, best[top]])
    return evaluated, invalid
