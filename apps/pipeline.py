"""The reference pipeline of ``pano2cad run``: composition of the packages, no algorithm.

Stages, in the order of ARCHITECTURE.md ("Data flow of pano2cad run"):

1. read and check the image (:mod:`apps.imageio`) at the working resolution
2. line segments -> Manhattan vanishing points -> upright rotation R
   (:func:`panogeom.rectify.estimate_rectification`)
3. object detection on perspective tiles, boxes in the panorama, spherical
   NMS (:mod:`detect`), one class per object
   (:func:`detect.nms.suppress_across_classes`); grab-cut masks
   (``detect.grabcut``) are not used for the pose crops: on synthetic rooms
   they made the pose CRF worse than plain box crops
4. surface labels: orientation map + geometric context, objects masked
   (:mod:`layout.surfaces`; each detection's region inside all the tile
   boxes that see it whole, :func:`object_mask`, ``RunOptions.object_mask``);
   not in the paper, the ceiling-wall boundary
   moved onto the one the boundary network regresses per column
   (:mod:`layout.surfaces.boundary_net`, ``RunOptions.ceiling``)
5. room geometry from the labels: Manhattan floor polygon and wall height,
   metric under an assumed camera height (:mod:`layout.roomgeom`); where the
   object boxes leave the polygon explaining few of its wall columns, the room
   of the panorama labelled without them when that explains more
   (:func:`_room_without_boxes`)
6. object crops (the region each detection's tile box bounds, :func:`object_crop`)
   -> HOG -> k-NN against the model library's renders -> pose CRF by TRW-S
   -> yaw and model per object (:mod:`posecrf`); not in the paper, the E_o tables
   also pay the project's learned front/back prior on the crop-relative yaw
   (:mod:`posecrf.orientnet`, ``RunOptions.orientation``)
   Not in the paper, after the poses (stage ``refine``, ``RunOptions.box_edges``):
   every tile box of a detection refined by the project's box-edge network
   (:class:`detect.builtin.refine.BoxRefiner`), for the box fits below; or
   (stage ``edges``) each tile box edge that the object's grab-cut silhouette
   confirms moved onto it (:func:`detect.grabcut.silhouette_box`)
7. model choice by box fit (not in the paper, ``RunOptions.model_choice``):
   each object's model among its class's and its wall-aligned yaw, with the
   camera height they share, from how well they fit the detection boxes
   (:func:`layout.modelfit.select_models`; a box edge a nearer object or
   a tile border may have cut holds the object only weakly beyond the box,
   tile boxes as great-circle edges, each edge the median over the tiles
   that see the object whole), from how far
   each candidate's footprint would reach through the walls of the room of
   step 5, and from the wall height it gives that room (a prior on ceilings)
8. initial objects -> MAP sampling of scale, positions and yaws under E_s,
   E_o and the context prior (:mod:`layout.sampler`); before it, a wall
   that two or more initial objects agree stand beyond moves out to them
   (:mod:`layout.objectwalls`, noted in the warnings)

Everything runs in the upright (rectified) frame; results are reported in
the world frame of CONVENTIONS.md, with ``camera.rotation`` mapping the
input camera's directions into it, and boxes and label maps mapped back to
the input panorama's pixels.
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .errors import UserError
from .progress import Progress

DEFAULT_CAMERA_HEIGHT = 1.6
#: Lowest detection score kept as a candidate for evaluation (``PipelineResult.extra["candidates"]``).
CANDIDATE_SCORE = 0.05
#: ``RunOptions.crop``: the region a tile box bounds, or the whole panorama box.
CROP_MODES = ("tile", "box")
#: ``RunOptions.orientation``: E_o plus the learned front/back prior (:mod:`posecrf.orientnet`) read on every tile
#: that sees the object whole or on the pose crop alone, or E_o alone.
ORIENTATION_MODES = ("net", "net-tile", "hog")
#: ``RunOptions.box_edges``: where the box fits read a tile detection's edges.
BOX_EDGE_MODES = ("silhouette", "detector", "net", "net+silhouette")
#: ``RunOptions.ceiling``: where the room step reads the ceiling-wall boundary.
CEILING_MODES = ("labels", "network")
#: ``RunOptions.walls``: walls where the labels put them, or moved onto the image's ceiling-wall edges.
WALL_MODES = ("edges", "labels")
#: ``RunOptions.object_mask``: what the labeller and the room step mask of each detection.
OBJECT_MASK_MODES = ("tiles", "box")
#: Weight of the orientation network's cost ``-log(n_bins p)`` added to E_o (``RunOptions.orientation="net"``);
#: chosen on the tuning seeds 7000 and 8000 among 0.1 and 0.3 (docs/EVALUATION.md, session 10). Over the yaws of
#: one crop the cost spans about 9, E_o (HOG distance) about 0.3 (``benchmarks/eval_orientnet.py vs-hog``). With the
#: weights retrained in session 30, 0.1, 0.2, 0.3, 0.5 and 1.0 leave the same share of gt-box crops more than 45 deg
#: off on both tuning sets, to within one object per class (``vs-hog``; docs/EVALUATION.md, "Session 30"). With those
#: of session 31, 0.1 leaves 2 / 4 % of the chairs of seeds 7000 / 8000 that far off and 0.3 0 / 1 %, but 12 / 0 %
#: of the sofas instead of 6 / 3 % (docs/EVALUATION.md, "Session 31"); 0.1 is kept. Per view: since session 38 an
#: object seen whole by several tiles pays 0.1 times each view's cost.
ORIENTATION_WEIGHT = 0.1


@dataclass(frozen=True)
class RunOptions:
    """Options of :func:`run_pipeline` (the flags of ``pano2cad run``).

    Attributes
    ----------
    camera_height : float or None
        Metres; fixes the scale when given. None: the scale comes from the
        objects' known sizes (falling back to 1.6 m without objects).
    detector : str
        ``builtin``, ``tflite``, ``onnx:FILE`` or ``annotations:FILE``.
    samples : int
        N_S, hypotheses of the MAP sampler (the paper: 8 x 25 = 200; Table 2: 3000).
    seed : int
        Seed of the sampler (the only randomness of the pipeline).
    objects : bool
        False: layout only.
    sampler_mode : str
        ``"improved"`` (default) or ``"paper"`` (the paper's exact scheme). The improved mode also samples one
        object detected twice once (:func:`drop_duplicates`).
    model_choice : str
        ``"box"`` (default): each object's model among its class's by how well it fits its box at the shared
        camera height, with the HOG distance as appearance cost and the room's walls as a soft limit
        (:func:`layout.modelfit.select_models`);
        ``"appearance"``: the model of the nearest HOG render (the paper).
    crop : str
        The pose CRF's crop of a detection (:func:`object_crop`): ``"tile"`` (default) the region its tile box
        bounds where it has one, ``"box"`` its whole panorama box.
    orientation : str
        ``"net"`` (default): E_o of every pose plus ``ORIENTATION_WEIGHT`` times the cost of the project's
        orientation network (:mod:`posecrf.orientnet`, a learned p(yaw | crop) that tells fronts from backs),
        read on the pose crop and (with ``crop="tile"``) on the crop of every other tile that sees the object
        whole, their costs added on the world yaw; ``"net-tile"``: the network on the pose crop alone (sessions
        10-37); ``"hog"``: E_o alone (the paper).
    box_edges : str
        ``"net"`` (default): every tile box of a detection refined by the project's box-edge network
        (:class:`detect.builtin.refine.BoxRefiner`) before the model choice and the sampler fit the boxes
        (session 39; docs/EVALUATION.md); ``"silhouette"`` (sessions 18-38): each box edge that the
        object's grab-cut silhouette confirms (within 3 degrees) moves onto the silhouette
        (:func:`detect.grabcut.silhouette_box`); ``"net+silhouette"``: refined, then onto the silhouette;
        ``"detector"``: the detector's edges alone.
    ceiling : str
        ``"network"`` (default): the labels' ceiling-wall boundary moved onto the boundary network's
        (:mod:`layout.surfaces.boundary_net`, ``estimate_surfaces(ceiling_net=True)``), unless the two are
        far apart in most columns (a panorama unlike the network's training rooms: a note says so and the
        labels' boundary is kept); ``"labels"``: the ceiling-wall boundary of the fused surface labels.
    walls : str
        ``"edges"`` (default): after the room step, each wall moves onto the image's ceiling-wall edge where the
        image shows a clear one within 25 % of the labels' distance, and the ceiling height onto the walls that
        show both creases (:func:`layout.wallsnap.snap_walls`), then the room (walls and ceiling height, the
        ceiling curves fixed) scales onto the floor-wall edges where they show
        (:func:`layout.wallsnap.snap_ceiling_height`; both in :func:`layout.wallsnap.snap_room`); ``"labels"``: the
        room as the room step put it.
    object_mask : str
        What of each detection the surface labeller, the room step and the wall snaps mask as object
        (:func:`object_mask`): ``"tiles"`` (default) the region inside all the tile boxes that see it whole,
        ``"box"`` its whole panorama box (the lon/lat extent, larger where a tile is turned or pitched).
    """

    camera_height: float | None = None
    detector: str = "builtin"
    samples: int = 200
    seed: int = 0
    objects: bool = True
    sampler_mode: str = "improved"
    model_choice: str = "box"
    crop: str = "tile"
    orientation: str = "net"
    box_edges: str = "net"
    ceiling: str = "network"
    walls: str = "edges"
    object_mask: str = "tiles"

    def __post_init__(self) -> None:
        if self.object_mask not in OBJECT_MASK_MODES:
            raise ValueError(f"object_mask: expected one of {OBJECT_MASK_MODES}, got {self.object_mask!r}")
        if self.walls not in WALL_MODES:
            raise ValueError(f"walls: expected one of {WALL_MODES}, got {self.walls!r}")
        if self.ceiling not in CEILING_MODES:
            raise ValueError(f"ceiling: expected one of {CEILING_MODES}, got {self.ceiling!r}")
        if self.box_edges not in BOX_EDGE_MODES:
            raise ValueError(f"box_edges: expected one of {BOX_EDGE_MODES}, got {self.box_edges!r}")
        if self.crop not in CROP_MODES:  # checked here: a bad mode inside the pose stage would read as "no pose"
            raise ValueError(f"crop: expected one of {CROP_MODES}, got {self.crop!r}")
        if self.orientation not in ORIENTATION_MODES:
            raise ValueError(f"orientation: expected one of {ORIENTATION_MODES}, got {self.orientation!r}")


@dataclass(frozen=True)
class PipelineResult:
    """Everything ``pano2cad run`` writes, in memory.

    Attributes
    ----------
    scene : layout.scene.Scene
        The room and objects in the world frame, with rotation and timings.
    image : (H, W, 3) uint8
        The input panorama at the working resolution.
    labels_input : (H, W) uint8
        Surface labels in the input panorama's pixel geometry.
    detections : list of detect.detection.Detection
        In the upright panorama.
    warnings : tuple of str
        What went less well (no vanishing points, uncertain layout, ...).
    """

    scene: Any
    image: np.ndarray
    labels_input: np.ndarray
    detections: list
    warnings: tuple[str, ...] = ()
    extra: dict = field(default_factory=dict)


def _rectify(image: np.ndarray, prog: Progress, notes: list[str]):
    from panogeom.rectify import estimate_rectification
    from panogeom.vanishing import VanishingPointError

    try:
        rect = estimate_rectification(image, mode="walls")
    except VanishingPointError as exc:
        notes.append(f"no Manhattan vanishing points ({exc}); the panorama is assumed upright as given")
        return None, image
    prog.say(f"  tilt {math.degrees(rect.tilt):.2f} deg, heading {math.degrees(rect.heading):.2f} deg")
    return rect, rect.apply(image)


def _detect(image: np.ndarray, upright: np.ndarray, rect, spec: str, prog: Progress) -> tuple[list, list]:
    """Detections in the upright panorama (boxes read from a file refer to the input: mapped).

    Returns the detections the pipeline uses (at or above the backend's score threshold) and all the
    candidates down to :data:`CANDIDATE_SCORE` (for average precision in ``pano2cad eval``)."""
    from detect.backends import ModelFileError, get_detector
    from detect.nms import suppress_across_classes
    from detect.tiles import detect_panorama

    try:
        detector = get_detector(spec)
    except (ModelFileError, FileNotFoundError, ValueError) as exc:  # unknown spec, missing or broken model file
        raise UserError(f"--detector {spec}: {exc}") from None
    if spec.startswith("annotations:"):
        H, W = image.shape[:2]
        dets = detect_panorama(image, detector)
        if rect is not None:
            dets = [replace(d, box=tuple(float(b) for b in rect.box_to_rectified(d.box, W, H))) for d in dets]
        candidates = dets
    else:
        # A backend tuned on its own tile set (the builtin one: 18 views + wide views) says so with views().
        views = detector.views() if callable(getattr(detector, "views", None)) else None
        # Detect down to CANDIDATE_SCORE so that an evaluation can rank the whole list (AP integrates over
        # every recall level); the pipeline keeps the detections at or above the backend's own threshold.
        threshold = getattr(detector, "score_threshold", None)
        if threshold is not None and float(threshold) > CANDIDATE_SCORE:
            detector.score_threshold = CANDIDATE_SCORE
        candidates = detect_panorama(upright, detector, views=views, score_threshold=CANDIDATE_SCORE)
        dets = candidates if threshold is None else [d for d in candidates if d.score >= float(threshold)]
        # one class per object: the merge is class-aware, and a bed also called a sofa would stand in the scene
        # twice (the candidates, which average precision ranks per class, keep both)
        kept = suppress_across_classes(dets)
        for d in dets:
            if not any(k is d for k in kept):
                prog.say(f"  {d.label} (score {d.score:.2f}) left out: a better-scored detection of another class "
                         "covers the same region")
        dets = kept
    prog.say(f"  {len(dets)} objects: " + ", ".join(sorted({d.label for d in dets})))
    return dets, candidates


def object_mask(dets: list, shape: tuple[int, int], mode: str = "tiles") -> np.ndarray:
    """(H, W) bool: the detections' pixels masked for the labeller, the room step and the wall snaps.

    ``mode="tiles"``: each tile detection's region inside every tile box that sees it whole
    (``Detection.edge_planes``: the object lies inside each of them, so inside their intersection), bounded by
    its panorama box; a detection without a tile (boxes read from a file) masks its panorama box.
    ``mode="box"``: every detection's whole panorama box, the lon/lat extent of its tile box, which is larger
    wherever the tile is turned or pitched. The tighter mask leaves the room step more of the walls next to the
    furniture: on the synthetic tuning sets (seeds 7000 and 8000) the layout 3D IoU rose 0.878 -> 0.884 and the
    room step on the run's labels 0.895 / 0.912 -> 0.898 / 0.914 (docs/EVALUATION.md, "Session 35"). In session 5
    a tighter mask (the detection's own tile region) broke the hotel panorama's room (3D IoU 0.665 -> 0.173); in
    the pipeline of session 35 both real panoramas score the same with either mask.
    """
    from layout.likelihood import boxes_mask

    if mode not in OBJECT_MASK_MODES:
        raise ValueError(f"mode: expected one of {OBJECT_MASK_MODES}, got {mode!r}")
    if not dets:
        return np.zeros(shape, bool)
    planes = [d.edge_planes() for d in dets] if mode == "tiles" else None
    return boxes_mask(np.array([d.box for d in dets]), shape[1], planes=planes)


def _outline(model, max_points: int = 400) -> np.ndarray:
    """Object-frame outline points of a library model (:func:`layout.sampler.mesh_outline`, kept per process and
    on disk) for the box fits; the model choice fits every candidate with a lighter outline (``max_points=100``,
    the first rows of the full one)."""
    key = (model.id, model.content_hash())
    if key not in _OUTLINES:
        _OUTLINES[key] = _stored_outline(model)
    return _OUTLINES[key][:max_points]


_OUTLINES: dict[tuple, np.ndarray] = {}


@functools.lru_cache(maxsize=1)
def _sampler_source_hash() -> str:
    """SHA-256 of the source of :mod:`layout.sampler` (where :func:`~layout.sampler.mesh_outline` lives)."""
    import hashlib
    from pathlib import Path

    import layout.sampler

    return hashlib.sha256(Path(layout.sampler.__file__).read_bytes()).hexdigest()


def _stored_outline(model) -> np.ndarray:
    """:func:`layout.sampler.mesh_outline` of a model (400 points), stored in the model-library cache folder
    (:func:`posecrf.cache.default_cache_dir`, ``outlines/``) under the model's content hash and the source of
    :mod:`layout.sampler`, so that a later run loads it (0.1-0.9 s per model to compute,
    ``benchmarks/eval_outline.py``). A cache folder that cannot be read or written only costs the computation."""
    import hashlib
    import io

    from layout.sampler import mesh_outline
    from posecrf.cache import default_cache_dir

    from .atomic import write_bytes

    h = hashlib.sha256(model.content_hash().encode())
    h.update(_sampler_source_hash().encode())
    path = default_cache_dir() / "outlines" / f"{model.id}-{h.hexdigest()[:16]}.npy"
    try:
        pts = np.load(path)
        if pts.ndim == 2 and pts.shape[1] == 3 and len(pts) and np.isfinite(pts).all():
            return pts
    except (OSError, ValueError, EOFError):
        pass
    pts = mesh_outline(model.vertices, model.faces, max_points=400)
    buf = io.BytesIO()
    np.save(buf, pts)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_bytes(path, buf.getvalue())
    except OSError:
        pass
    return pts

_EO_BINS = np.arange(72) * (2.0 * np.pi / 72)


def _eo_at(est, ray: np.ndarray, model, world_yaws: np.ndarray) -> np.ndarray:
    """E_o of ``model`` for the pose estimate ``est`` seen along ``ray``, at world yaws (radians): (K,)."""
    from posecrf.crops import relative_yaw

    # a fully symmetric model looks the same at every yaw: any relative yaw reads its E_o
    rel = relative_yaw(world_yaws, ray, "none" if model.symmetry == "full" else model.symmetry)
    return np.array([est.e_o_at(float(r), est.pitch, model.id) for r in np.atleast_1d(rel)])


def object_crop(upright: np.ndarray, det, mode: str = "tile") -> tuple[np.ndarray, Any]:
    """The pose CRF's crop of a detection and its view: ((h, 128, 3) uint8, PinholeView).

    ``mode="tile"``: the region the detection's tile box bounds, where it has one (else its panorama box);
    ``"box"``: its panorama box.

    A tile box's panorama box (the lon/lat extent of its four great-circle edges) is wider than the region
    it bounds whenever the tile is turned or pitched (docs/EVALUATION.md, box edges: +4.5 / -4.0 deg left /
    right against the object's outline), and the library renders are cut tight around the silhouette."""
    from detect.nms import region_boundary
    from panogeom.perspective import equirect_to_perspective
    from posecrf.crops import extract_crop, outline_view

    if mode not in CROP_MODES:
        raise ValueError(f"crop: expected one of {CROP_MODES}, got {mode!r}")
    if det.tile is None or mode == "box":
        return extract_crop(upright, det.box)
    view = outline_view(det.tile.centre_ray(), region_boundary(det, 9), size=128, margin=0.1)
    return equirect_to_perspective(upright, view), view


def _with_orientation_prior(est, probs: np.ndarray, weight: float, shifts: np.ndarray | None = None):
    """The pose estimate with ``weight * orientation_costs`` added to its E_o tables (every model, every pitch).

    ``probs``: (n_bins,), or (V, n_bins) for V crops of the object, the first the estimate's own, with ``shifts``
    (V,) radians, each crop's relative yaw minus the first's (:func:`posecrf.crops.relative_yaw_shifts`,
    :func:`posecrf.orientnet.orientation_costs`)."""
    from posecrf.orientnet import orientation_costs

    c = weight * orientation_costs(probs, est.grid.yaws, shifts=shifts)
    return replace(est, e_o=est.e_o + c[:, None], e_o_models=est.e_o_models + c[None, :, None])


def other_tile_crops(upright: np.ndarray, det) -> list[tuple[np.ndarray, np.ndarray]]:
    """(crop, ray) of every tile that sees ``det`` whole other than its own (``Detection.views``), each cropped
    as :func:`object_crop` crops the detection's own tile; tiles whose region has no perspective crop are left out."""
    out = []
    for tb in det.views:
        if tb is det.tile:
            continue
        try:
            crop, view = object_crop(upright, replace(det, tile=tb), "tile")
        except ValueError:
            continue
        out.append((crop, view.direction))
    return out


def _poses(upright: np.ndarray, dets: list, prog: Progress, crop_mode: str = "tile",
           orientation: str = "net") -> list:
    """Per detection: (model, yaw in the upright frame or None, E_o table over 72 world-yaw bins or None,
    the pose estimate, the crop's ray), or None without a pose."""
    from posecrf.library import builtin_library
    from posecrf.crops import relative_yaw_shifts
    from posecrf.orientnet import ORIENT_CLASSES, load_orientation_net
    from posecrf.pose import estimate_poses
    from posecrf.render import PoseGrid, RenderSettings
    from posecrf.cache import library_renders

    lib = builtin_library()
    renders = library_renders(lib, grid=PoseGrid(), settings=RenderSettings())
    out: list = [None] * len(dets)
    H, W = upright.shape[:2]
    by_class: dict[str, list[int]] = {}
    for i, d in enumerate(dets):
        if lib.by_class(d.label):
            by_class.setdefault(d.label, []).append(i)
    for cls, idx in sorted(by_class.items()):
        # Box crops, no grab-cut masks: measured on synthetic rooms, grab-cut masks flipped TVs and beds
        # (front/back) where the plain box crop was within a few degrees (docs/EVALUATION.md, pipeline notes).
        crops, views, kept = [], [], []
        for i in idx:
            try:
                crop, view = object_crop(upright, dets[i], crop_mode)
            except ValueError as exc:  # a box 180 degrees wide or more has no perspective crop: no pose
                prog.say(f"  no pose for a {cls}: {exc}")
                continue
            crops.append(crop)
            views.append(view)
            kept.append(i)
        idx = kept
        if not idx:
            continue
        res = estimate_poses(renders, cls, crops)
        estimates = list(res.estimates)
        if orientation in ("net", "net-tile") and cls in ORIENT_CLASSES:
            # the network reads the pose crop and, with "net", the crop of every other tile that sees the object
            # whole; the views' costs add (docs/EVALUATION.md, "Session 38")
            more = orientation == "net" and crop_mode == "tile"
            per_object = [[(crop, view.direction)] + (other_tile_crops(upright, dets[i]) if more else [])
                          for crop, view, i in zip(crops, views, idx)]
            flat = [c for obj in per_object for c, _ in obj]
            probs = load_orientation_net().probabilities(flat, [cls] * len(flat))
            ends = np.cumsum([len(obj) for obj in per_object])
            estimates = [_with_orientation_prior(e, probs[end - len(obj):end], ORIENTATION_WEIGHT,
                                                 relative_yaw_shifts([ray for _, ray in obj]))
                         for e, obj, end in zip(estimates, per_object, ends)]
        for i, view, est in zip(idx, views, estimates):
            model = lib[est.model_id]
            ray = view.direction
            if est.yaw_rel is None:
                out[i] = (model, None, None, est, ray)
                continue
            # E_o over world-yaw bins (the sampler interpolates): the crop-relative grid seen along this ray.
            out[i] = (model, float(est.world_yaw(ray)), _eo_at(est, ray, model, _EO_BINS), est, ray)
    prog.say(f"  poses for {sum(o is not None for o in out)} of {len(dets)} objects")
    return out


def _unmasked_room(upright: np.ndarray, camera_height: float, ceiling_net: bool) -> tuple[Any, Any]:
    """``(surf, geom)`` of the panorama labelled again without the object boxes (what ``--no-objects`` does).

    Raises :class:`layout.roomgeom.RoomGeometryError` when those labels give no room either.
    """
    from layout.roomgeom import estimate_room_geometry
    from layout.surfaces import estimate_surfaces

    surf = estimate_surfaces(upright, ceiling_net=ceiling_net)
    return surf, estimate_room_geometry(surf.labels, camera_height)


def _room_without_boxes(upright: np.ndarray, surf: Any, geom: Any, camera_height: float, ceiling_net: bool,
                        notes: list[str]) -> tuple[Any, Any]:
    """The labels and room of the panorama labelled without the object boxes, where they explain the room better.

    The boxes are masked so that furniture does not pass for walls; but boxes
    over most of the floor-wall boundary (false detections, or a room full of
    furniture) leave the room step too little to go on. The caller asks when,
    with the boxes masked, the polygon ``geom`` explains fewer than
    :data:`layout.roomgeom.RELIABLE_INLIER_FRACTION` of the wall columns it
    observes: the panorama is labelled again without them
    (:func:`_unmasked_room`), and that room is kept when its polygon explains
    a larger share of its own observed wall columns
    (``RoomGeometry.inlier_fraction``). Returns ``(surf, geom)``, the
    unmasked pair or the given one.
    """
    from layout.roomgeom import RoomGeometryError

    try:
        free, geom_free = _unmasked_room(upright, camera_height, ceiling_net)
    except RoomGeometryError:
        return surf, geom
    if geom_free.inlier_fraction <= geom.inlier_fraction:
        return surf, geom
    notes.append(f"room geometry ignored the object boxes (with them masked the polygon explains "
                 f"{100 * geom.inlier_fraction:.1f}% of the observed wall columns, without them "
                 f"{100 * geom_free.inlier_fraction:.1f}%)")
    return free, geom_free


def _snap_walls(upright: np.ndarray, geom: Any, obj_mask: np.ndarray, prog: Progress, notes: list[str]) -> Any:
    """The room with its walls (and, where walls show both creases, its ceiling height) moved onto the image's
    ceiling-wall and floor-wall edges, then scaled about the camera until its floor-wall curves lie on the image's
    floor-wall edges (:func:`layout.wallsnap.snap_room`)."""
    from layout.wallsnap import snap_room

    try:
        snap = snap_room(upright, geom.floor, geom.ceiling_z, geom.camera_height, object_mask=obj_mask)
    except ValueError as exc:  # e.g. a ceiling the labels put below the camera: nothing to snap to
        notes.append(f"walls kept where the labels put them ({exc})")
        return geom
    walls, height = snap.walls, snap.height
    prog.say(f"  {int(walls.moved.sum())} of {len(walls.moved)} walls moved onto the ceiling-wall edge"
             + (f", ceiling height from {walls.height_walls} walls' two creases" if walls.height_walls else "")
             + (f"; room scaled by {height.factor:.3f} onto the floor-wall edges" if height.moved else ""))
    return replace(geom, floor=snap.floor, ceiling_z=snap.ceiling_z)


def drop_duplicates(objects: list, eo: list, width: int, height: int, camera_height: float,
                    notes: list[str]) -> tuple[list, list]:
    """Objects (``layout.sampler.DetectedObject``) without the copies of one object detected twice.

    Each object is placed by its box fit at ``camera_height`` (:func:`layout.sampler.fit_boxes`, as the improved
    sampler starts); of two of the same class whose footprints share half the smaller one's area, the lower-scored is
    dropped (:func:`layout.duplicates.same_class_duplicates`) with its ``eo`` entry, and a note says which."""
    from layout.duplicates import same_class_duplicates
    from layout.sampler import fit_boxes, initialise_objects

    if len(objects) < 2:
        return objects, eo
    centers, _ = fit_boxes(objects, initialise_objects(objects, width, height).centers, width, height,
                           camera_height=camera_height)
    dups = same_class_duplicates([o.cls for o in objects], [o.score for o in objects], centers[:, :2],
                                 [o.yaw for o in objects], [o.size[:2] for o in objects])
    for d in dups:
        o, k = objects[d.dropped], objects[d.kept]
        notes.append(f"dropped {o.cls} (score {o.score or 0.0:.2f}): it stands where {k.cls} (score "
                     f"{k.score or 0.0:.2f}) stands ({d.share:.0%} of the smaller footprint), "
                     "one object detected twice")
    gone = {d.dropped for d in dups}
    keep = [k for k in range(len(objects)) if k not in gone]
    return [objects[k] for k in keep], [eo[k] for k in keep]


def turned_to_input(objects, floor: np.ndarray, heading: float) -> tuple[list, np.ndarray]:
    """Objects (``layout.scene.SceneObject``) and floor polygon ``(K, 2)`` of the wall-aligned frame the pipeline
    computes in, turned into the input's world frame: about z by the rectification's ``heading`` (radians), centres
    and yaws; boxes are left as they are (the caller maps them to input pixels)."""
    from panogeom.rotation import rot_z

    turn = rot_z(heading)
    objs = [replace(o, center=turn @ o.center, yaw=o.yaw + heading) for o in objects]
    return objs, np.asarray(floor) @ turn[:2, :2].T


def run_pipeline(image: np.ndarray, options: RunOptions, progress: Progress | None = None) -> PipelineResult:
    """Run the whole pipeline on an RGB panorama.

    Parameters
    ----------
    image : (H, W, 3) uint8, W == 2*H
        The panorama at the working resolution.
    options : RunOptions
    progress : Progress, optional

    Returns
    -------
    PipelineResult
    """
    from layout.likelihood import observe_labels, surface_likelihood
    from layout.modelfit import candidate_yaws, occluded_edges, select_models
    from layout.placement import BACK_TO_WALL
    from posecrf.library import builtin_library
    from layout.roomgeom import RELIABLE_INLIER_FRACTION, RoomGeometryError, estimate_room_geometry
    from layout.sampler import DetectedObject, PosteriorError, SamplerConfig, map_estimate
    from layout.scene import Scene
    from layout.surfaces import estimate_surfaces
    from panogeom.rotation import rot_z
    from panogeom.transform import rotate_pano

    prog = progress or Progress(quiet=True)
    notes: list[str] = []
    H, W = image.shape[:2]
    h0 = options.camera_height or DEFAULT_CAMERA_HEIGHT

    with prog.stage("rectify", "vanishing points and upright rotation"):
        rect, upright = _rectify(image, prog, notes)
    R = rect.rotation if rect is not None else np.eye(3)

    dets: list = []
    candidates: list = []
    if options.objects:
        with prog.stage("detect", f"object detection ({options.detector})"):
            dets, candidates = _detect(image, upright, rect, options.detector, prog)
    obj_mask = object_mask(dets, (H, W), options.object_mask)
    ceiling_net = options.ceiling == "network"

    with prog.stage("surfaces", "surface labels (orientation map + geometric context)"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            surf = estimate_surfaces(upright, object_mask=obj_mask, ceiling_net=ceiling_net)
        notes.extend(str(w.message) for w in caught)
        notes.extend(surf.warnings)

    with prog.stage("room", "room geometry from the labels"):
        try:
            # With the objects masked, the furniture that a labeller calls floor (what the lowest-mode ceiling
            # estimate guards against) is mostly out of the columns, and the median ratio was the better estimate
            # on two synthetic sets (seed 0, the tuning set) and the worse on a third (seed 5000; see
            # docs/EVALUATION.md, Table 2 section); without objects the lowest mode stays.
            geom = estimate_room_geometry(surf.labels, h0, object_mask=obj_mask,
                                          ceiling_estimate="median" if obj_mask.any() else "lowest_mode")
        except RoomGeometryError as exc:
            if not obj_mask.any():
                raise UserError(f"no room layout could be found in this panorama ({exc})") from None
            # The detection boxes hide every floor-wall contact: use the labels under them rather than nothing.
            notes.append(f"room geometry ignored the object boxes ({exc})")
            try:
                geom = estimate_room_geometry(surf.labels, h0)
            except RoomGeometryError:
                # The labels themselves were computed with the boxes masked: label the panorama again without
                # them and keep those labels for the room and the sampler.
                try:
                    surf, geom = _unmasked_room(upright, h0, ceiling_net)
                except RoomGeometryError as exc2:
                    raise UserError(f"no room layout could be found in this panorama ({exc2})") from None
        else:
            if obj_mask.any() and geom.inlier_fraction < RELIABLE_INLIER_FRACTION:
                surf, geom = _room_without_boxes(upright, surf, geom, h0, ceiling_net, notes)
        if options.walls == "edges":
            geom = _snap_walls(upright, geom, obj_mask, prog, notes)
        if geom.uncertain:
            notes.append("uncertain layout: " + "; ".join(geom.reasons))

    poses: list = []
    if dets:
        with prog.stage("pose", "object poses (HOG + pose CRF)"):
            poses = _poses(upright, dets, prog, options.crop, options.orientation)

    silhouettes: list = [None] * len(dets)
    refine = [d.tile is not None and p is not None for d, p in zip(dets, poses)]
    if options.box_edges.startswith("net") and any(refine):
        from detect.builtin.refine import default_refiner

        with prog.stage("refine", "box edges refined by the edge network"):
            # only the objects the box fits will see (those with a pose)
            todo = [i for i, r in enumerate(refine) if r]
            dets = list(dets)
            for i, d in zip(todo, default_refiner().refine_detections(upright, [dets[i] for i in todo])):
                dets[i] = d
            prog.say(f"  {sum(max(1, len(dets[i].views)) for i in todo)} tile boxes of {len(todo)} objects refined")
    if options.box_edges.endswith("silhouette") and any(refine):
        from detect.grabcut import silhouette_box

        with prog.stage("edges", "box edges onto the grab-cut silhouettes"):
            silhouettes = [silhouette_box(upright, d) if r else None for d, r in zip(dets, refine)]
            moved = sum(int(s.snapped.any(axis=0).sum()) for s in silhouettes if s is not None)
            prog.say(f"  {moved} of {4 * len(dets)} box edges moved onto a silhouette")

    lib = builtin_library()
    objects, eo, alternatives = [], [], []
    # box edges a nearer object in front may have cut: in the box fits the object may reach beyond them (a weak
    # pull) but not stop short of them (DetectedObject.cut_edges)
    cut = occluded_edges(np.array([d.box for d in dets]), W) if dets else np.zeros((0, 4), bool)
    for d, p, c, sil in zip(dets, poses, cut, silhouettes):
        if p is None:
            continue
        model, yaw, e_o, est, ray = p

        # a tile detection's edges are great circles (planes through the camera); one at the tile border may not
        # be the object's own edge (cut as well); an object other tiles also see whole brings their edges too
        # (each edge's fit takes the median over the views); edges the grab-cut silhouette confirms are the
        # silhouette's
        planes = (sil if sil is not None else d).edge_planes()
        if d.tile is not None:
            c = c | d.tile.border_edges()

        def as_object(m, d=d, yaw=yaw, c=c, planes=planes, points=400) -> DetectedObject:
            return DetectedObject(d.label, d.box, m.size, 0.0 if yaw is None else yaw, model_id=m.id,
                                  score=float(d.score), symmetric=yaw is None, outline=_outline(m, points),
                                  cut_edges=c, edge_planes=planes)

        objects.append(as_object(model))
        eo.append(e_o)
        if options.model_choice != "box":
            continue
        # candidates: every model of the class at the yaws of layout.modelfit.candidate_yaws, E_o of each as its
        # appearance cost (a fully symmetric model: its best E_o over the poses); fitted with a lighter outline
        yaws = [yaw] if yaw is None else candidate_yaws(yaw)
        alt, cost, lib_models = [], [], []
        for k, mid in enumerate(est.model_ids):
            m = lib[mid]
            costs = [float(est.e_o_models[k].min())] if yaw is None else _eo_at(est, ray, m, np.array(yaws))
            for y, e in zip(yaws, costs):
                alt.append(as_object(m, yaw=y, points=100))
                cost.append(e)
                lib_models.append(m)
        alternatives.append((alt, np.array(cost), lib_models, est, ray))
    shared_height = None
    if objects and options.model_choice == "box":
        with prog.stage("models", "model choice by box fit"):
            choice = select_models([a[0] for a in alternatives], W, H, appearance=[a[1] for a in alternatives],
                                   camera_height=options.camera_height, floor=geom.floor, floor_camera_height=h0,
                                   wall_ratio=geom.ceiling_z / h0,
                                   back_to_wall=[a[0][0].cls in BACK_TO_WALL for a in alternatives])
            changed = 0
            for k, j in enumerate(choice.index):
                alt, _, lib_models, est, ray = alternatives[k]
                pick, m = alt[j], lib_models[j]
                if objects[k].model_id != pick.model_id:
                    changed += 1
                    if eo[k] is not None:
                        eo[k] = _eo_at(est, ray, m, _EO_BINS)
                objects[k] = replace(pick, outline=_outline(m))
            prog.say(f"  {changed} of {len(objects)} models changed; camera height {choice.camera_height:.2f} m")
            if math.isfinite(choice.camera_height):
                shared_height = choice.camera_height

    if objects and options.sampler_mode != "paper":
        cam = options.camera_height or (shared_height if shared_height is not None else h0)
        objects, eo = drop_duplicates(objects, eo, W, H, cam, notes)
    with prog.stage("posterior", f"MAP sampling ({options.samples} samples)"):
        if options.sampler_mode == "paper":
            config = SamplerConfig(n_samples=options.samples)
        else:
            config = replace(SamplerConfig.improved(), n_samples=options.samples, initial_camera_height=shared_height)
        if options.camera_height is not None or not objects:
            wh = geom.ceiling_z  # scale 1: the room is metric under the given (or default) camera height
            config = replace(config, wall_height_range=(wh, wh), initial_wall_height=wh)

        def sample(objs: list, tables: list, cfg):
            boxes = np.array([o.bbox_pano for o in objs]) if objs else None
            # each box's object evidence: the region its tile box bounds, not the looser panorama box
            planes = [o.region_planes for o in objs] if objs else None
            obs = observe_labels(surf.labels, boxes, object_pixels="matched" if objs else "masked", box_planes=planes)
            es = surface_likelihood(obs, geom.floor, geom.ceiling_z, h0)
            return map_estimate(es, objs, image_width=W, image_height=H, orientation=tables or None,
                                config=cfg, rng=options.seed)

        try:
            post = sample(objects, eo, config)
        except PosteriorError:
            # Some detection cannot stand in the estimated room (a wrong box, or a wall placed too close):
            # keep, by decreasing score, the objects the sampler can place, and say which were dropped.
            keep: list[int] = []
            quick = replace(config, n_samples=min(config.n_samples or 200, 100))
            for k in sorted(range(len(objects)), key=lambda k: -(objects[k].score or 0.0)):
                try:
                    sample([objects[j] for j in keep + [k]], [eo[j] for j in keep + [k]], quick)
                    keep.append(k)
                except PosteriorError:
                    notes.append(f"dropped {objects[k].cls} (score {objects[k].score:.2f}): it cannot stand inside "
                                 "the estimated room without overlapping a wall or another object")
            keep.sort()
            objects, eo = [objects[j] for j in keep], [eo[j] for j in keep]
            if not objects:
                wh = geom.ceiling_z
                config = replace(config, wall_height_range=(wh, wh), initial_wall_height=wh)
            try:
                post = sample(objects, eo, config)
            except PosteriorError as exc:
                raise RuntimeError(f"the sampler found no valid scene: {exc}") from None
    scene = post.scene
    if post.wall_moves:
        moved = ", ".join(f"{m.distance * scene.scale:.2f} m ({len(m.objects)} objects)" for m in post.wall_moves)
        notes.append(f"moved {len(post.wall_moves)} wall(s) out to the objects that stand beyond them: {moved}")

    # Report in the world frame of the conventions: gravity-aligned with x along the horizontal projection of
    # the INPUT's centre column. We computed in the wall-aligned frame (walls on x/y), which is turned by the
    # rectification's heading h about z from it: p_world = Rz(h) p_walls; boxes go back to input pixels.
    heading = rect.heading if rect is not None else 0.0
    objs, floor = turned_to_input(scene.objects, scene.floor, heading)
    if rect is not None:
        objs = [o if o.bbox_pano is None else replace(o, bbox_pano=rect.box_to_input(o.bbox_pano, W, H))
                for o in objs]
    R = rot_z(heading) @ R
    labels_input = surf.labels if rect is None else rotate_pano(surf.labels, rect.rotation.T, interpolation="nearest")
    timing = dict(prog.timings)
    timing["total"] = prog.total()
    scene = Scene(floor=floor, ceiling_z=scene.ceiling_z, camera_height=scene.camera_height,
                  objects=tuple(objs), floor_z=0.0, rotation=R, scale=scene.scale if objects else None,
                  image_width=W, image_height=H, timing=timing)
    return PipelineResult(scene=scene, image=image, labels_input=labels_input, detections=dets,
                          warnings=tuple(notes), extra={"rectification": rect, "geometry": geom, "posterior": post,
                                 "candidates": candidates})
