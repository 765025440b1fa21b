"""The pose CRF of the paper (Sec. 3.2): object pose and 3D model from HOG neighbours.

For one object class, every target crop of the scene (several if the class
occurs more than once) and every auxiliary image of the class (the paper
used web images found by image search; here an optional user folder,
:func:`load_aux_folder`) is a node of a CRF whose labels are the 360 poses
of the :class:`~posecrf.render.PoseGrid`.

- Unary: ``exp(-#{K nearest renders with that pose})``, K = 6 nearest
  renders in HOG space among all models of the class
  (:meth:`~posecrf.retrieval.RenderIndex.knn`).
- Binary on edges between images near in HOG space (each image linked to
  its ``graph_k`` nearest other images, if they are no farther apart than
  the renders that vote for their poses, see ``edge_radius``):
  ``d_gamma(theta_i, theta_j) *
  d_HOG(I_i, I_j)`` with ``d = |yaw_i - yaw_j| + |pitch_i - pitch_j|``
  (radians, yaw the short way round) truncated at ``gamma`` = 20 degrees.
- Solved by TRW-S (:func:`posecrf.trws.trws`, 100 iterations).
- Model retrieval: the model of the nearest render; ``E_o`` of a candidate
  pose: the Euclidean descriptor distance to the render of that model at that
  pose (:attr:`PoseEstimate.e_o`).

Two details the paper leaves open are fixed here. Votes of a 2-fold
symmetric model's render count for both of its equivalent yaws (and a fully
symmetric model's for every yaw at its pitch). Labels with equal votes are
told apart by a tie-break far smaller than one vote (``tie_break`` times the
smallest descriptor distance at that pose, see :func:`pose_unaries`).
By default (``refine=True``) the yaw is then refined below the grid step by
a parabola through E_o of the retrieved model at the chosen yaw bin and its
two neighbours (the label, pitch and model stay the CRF's).

Convention: poses are crop-relative (:mod:`posecrf.render`: yaw of the
camera seen from the object, from its front, counter-clockwise; pitch =
camera elevation), radians; :func:`posecrf.crops.world_yaw` turns yaw_rel
into the world yaw. Costs: lower is better.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .crops import fold_yaw, world_yaw
from .mrf import PairwiseMRF, knn_edges
from .render import PoseGrid
from .retrieval import Neighbours, RenderIndex, crop_descriptors
from .trws import trws

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .cache import LibraryRenders

__all__ = [
    "PoseEstimate",
    "PoseCRFResult",
    "pose_unaries",
    "estimate_poses",
    "load_aux_folder",
    "DEFAULT_GAMMA",
]

DEFAULT_GAMMA = math.radians(20.0)
"""The paper's truncation threshold gamma (20 degrees), radians."""

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".webp")


@dataclass(frozen=True, eq=False)
class PoseEstimate:
    """Pose and model of one target crop.

    Attributes
    ----------
    cls : str
    yaw_rel : float or None
        Crop-relative yaw, radians in [0, 2*pi) ([0, pi) when the retrieved
        model is 2-fold symmetric); None for a fully symmetric model (plant).
    pitch : float
        Camera elevation seen from the object, radians.
    model_id : str
        The retrieved model (nearest render in HOG space).
    symmetry : {"none", "two", "full"}
        The retrieved model's symmetry.
    confidence : float
        Fraction of the K nearest renders whose pose lies within gamma of the
        chosen pose, in [0, 1].
    label : int
        The CRF's pose label (grid pose nearest to the estimate).
    grid : PoseGrid
    e_o : (n_yaw, n_pitch) float
        E_o of the retrieved model at every grid pose: Euclidean distance
        between the crop's descriptor and that render's.
    e_o_models : (M, n_yaw, n_pitch) float
        The same for every model of the class (order of `model_ids`).
    model_ids : tuple of str
        Models of the class, in the order of `e_o_models`.
    neighbours : Neighbours
        The K nearest renders (one row).
    """

    cls: str
    yaw_rel: float | None
    pitch: float
    model_id: str
    symmetry: str
    confidence: float
    label: int
    grid: PoseGrid = field(repr=False)
    e_o: NDArray[np.float64] = field(repr=False)
    e_o_models: NDArray[np.float64] = field(repr=False)
    model_ids: tuple[str, ...] = field(repr=False)
    neighbours: Neighbours = field(repr=False)

    def world_yaw(self, ray: ArrayLike) -> float | None:
        """World yaw of the object seen along `ray` (camera -> object), or None if fully symmetric.

        :func:`posecrf.crops.world_yaw` with this estimate's symmetry.
        """
        if self.yaw_rel is None:
            return None
        return float(world_yaw(self.yaw_rel, ray, self.symmetry))

    def e_o_at(self, yaw_rel: float, pitch: float, model_id: str | None = None) -> float:
        """E_o of any candidate pose, interpolated bilinearly on the grid (yaw wraps, pitch clipped).

        Parameters
        ----------
        yaw_rel, pitch : float
            Crop-relative pose, radians.
        model_id : str, optional
            Default: the retrieved model.
        """
        if model_id is None:
            table = self.e_o
        else:
            if model_id not in self.model_ids:
                raise ValueError(f"model_id: expected one of {list(self.model_ids)}, got {model_id!r}")
            table = self.e_o_models[self.model_ids.index(model_id)]
        if not (math.isfinite(yaw_rel) and math.isfinite(pitch)):
            raise ValueError(f"yaw_rel, pitch: expected finite radians, got {yaw_rel!r}, {pitch!r}")
        g = self.grid
        fy = (yaw_rel % (2.0 * math.pi)) / g.yaw_step
        y0 = int(math.floor(fy)) % g.n_yaw
        y1 = (y0 + 1) % g.n_yaw
        ty = fy - math.floor(fy)
        if g.n_pitch == 1:
            p0 = p1 = 0
            tp = 0.0
        else:
            fp = min(max(pitch / g.pitch_step, 0.0), g.n_pitch - 1.0)
            p0 = min(int(math.floor(fp)), g.n_pitch - 2)
            p1 = p0 + 1
            tp = fp - p0
        top = (1 - ty) * table[y0, p0] + ty * table[y1, p0]
        bot = (1 - ty) * table[y0, p1] + ty * table[y1, p1]
        return float((1 - tp) * top + tp * bot)


@dataclass(frozen=True, eq=False)
class PoseCRFResult:
    """The pose CRF of one class.

    Attributes
    ----------
    cls : str
    estimates : tuple of PoseEstimate
        One per target crop, in input order.
    aux_labels : (A,) int
        Pose labels chosen for the auxiliary images.
    edges : (E, 2) int
        CRF edges (targets are nodes 0..T-1, auxiliary images T..T+A-1).
    energy, lower_bound : float
        TRW-S energy of the labelling and its lower bound.
    iterations : int
        TRW-S iterations run.
    seconds : float
        Wall time: descriptors, k-NN, CRF and retrieval.
    """

    cls: str
    estimates: tuple[PoseEstimate, ...]
    aux_labels: NDArray[np.int64] = field(repr=False)
    edges: NDArray[np.int64] = field(repr=False)
    energy: float = 0.0
    lower_bound: float = 0.0
    iterations: int = 0
    seconds: float = 0.0

    def __len__(self) -> int:
        return len(self.estimates)

    def __getitem__(self, i: int) -> PoseEstimate:
        return self.estimates[i]


def _vote_labels(label: int, symmetry: str, grid: PoseGrid) -> NDArray[np.int64]:
    """The pose labels a render at `label` stands for, given its model's symmetry."""
    iy, ip = divmod(int(label), grid.n_pitch)
    if symmetry == "full":
        return np.arange(grid.n_yaw, dtype=np.int64) * grid.n_pitch + ip
    if symmetry == "two":
        other = (iy + int(round(grid.n_yaw / 2))) % grid.n_yaw
        return np.unique(np.array([iy, other], dtype=np.int64)) * grid.n_pitch + ip
    return np.array([label], dtype=np.int64)


def _votes(nb: Neighbours, symmetries: Sequence[str], grid: PoseGrid) -> NDArray[np.float64]:
    votes = np.zeros((nb.label.shape[0], grid.size))
    for i in range(nb.label.shape[0]):
        for m, lab in zip(nb.model[i], nb.label[i]):
            votes[i, _vote_labels(int(lab), symmetries[int(m)], grid)] += 1.0
    return votes


def pose_unaries(
    index: RenderIndex,
    descriptors: ArrayLike,
    k: int = 6,
    tie_break: float = 1e-3,
) -> tuple[NDArray[np.float64], Neighbours, NDArray[np.float64]]:
    """The paper's unary costs ``exp(-votes)`` of every pose for each image.

    Parameters
    ----------
    index : RenderIndex
        Renders of the class.
    descriptors : (N, D) float
        HOG descriptors of the images (targets and auxiliary images).
    k : int
        Nearest renders that vote (the paper's K = 6).
    tie_break : float
        Added cost ``tie_break * (d_min(pose) - min d_min)``, where
        ``d_min(pose)`` is the smallest descriptor distance among the class's
        renders at that pose; it only orders labels with equal votes (set
        0 for the bare formula). Must be >= 0 and small against one vote.

    Returns
    -------
    unary : (N, L) float
    neighbours : Neighbours
    votes : (N, L) float
        Votes per pose after symmetry expansion.

    Examples
    --------
    >>> from posecrf.retrieval import RenderIndex
    >>> grid = PoseGrid(4, 1, 0.0)
    >>> idx = RenderIndex("x", grid, ("a",), ("none",), np.eye(4, dtype=np.float32))
    >>> u, nb, v = pose_unaries(idx, [[1.0, 0.1, 0.0, 0.0]], k=1, tie_break=0.0)
    >>> u.round(3).tolist(), v.tolist()
    ([[0.368, 1.0, 1.0, 1.0]], [[1.0, 0.0, 0.0, 0.0]])
    """
    if not (math.isfinite(tie_break) and tie_break >= 0):
        raise ValueError(f"tie_break: expected a finite value >= 0, got {tie_break!r}")
    q = np.asarray(descriptors, dtype=np.float64)
    nb = index.knn(q, k)
    votes = _votes(nb, index.symmetries, index.grid)
    unary = np.exp(-votes)
    if tie_break > 0:
        d = index.distances(q).reshape(q.shape[0], index.n_models, index.grid.size).min(axis=1)
        unary = unary + tie_break * (d - d.min(axis=1, keepdims=True))
    return unary, nb, votes


def _fold_for(symmetry: str, yaw: float) -> float | None:
    if symmetry == "full":
        return None
    return float(fold_yaw(yaw, "two" if symmetry == "two" else "none"))


def _refine_yaw(e_o: NDArray[np.float64], iy: int, ip: int, grid: PoseGrid) -> float:
    """Sub-bin yaw: vertex of the parabola through E_o at bins iy-1, iy, iy+1 (when iy is a local minimum)."""
    a = e_o[(iy - 1) % grid.n_yaw, ip]
    b = e_o[iy, ip]
    c = e_o[(iy + 1) % grid.n_yaw, ip]
    den = a - 2.0 * b + c
    off = 0.5 * (a - c) / den if (den > 1e-12 and b <= a and b <= c) else 0.0
    return (iy + float(np.clip(off, -0.5, 0.5))) * grid.yaw_step


def _check_images(name: str, images: Sequence[ArrayLike]) -> None:
    for i, im in enumerate(images):
        a = np.asarray(im)
        if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
            raise ValueError(f"{name}[{i}]: expected an (H, W, 3) uint8 image, got shape {a.shape} dtype {a.dtype}")


def estimate_poses(
    renders: "LibraryRenders",
    cls: str,
    crops: Sequence[ArrayLike],
    masks: Sequence[ArrayLike | None] | None = None,
    *,
    aux: Sequence[tuple[ArrayLike, ArrayLike | None]] | str | Path | None = None,
    k: int = 6,
    gamma: float = DEFAULT_GAMMA,
    max_iter: int = 100,
    graph_k: int = 4,
    edge_radius: float | None = 1.0,
    pairwise_weight: float = 1.0,
    tie_break: float = 1e-3,
    refine: bool = True,
    index: RenderIndex | None = None,
) -> PoseCRFResult:
    """Estimate the pose and model of every crop of one class with the paper's CRF.

    Parameters
    ----------
    renders : LibraryRenders
        Library render descriptors (:func:`posecrf.cache.library_renders`).
    cls : str
        Class of the crops (the detector's); retrieval is restricted to it.
    crops : sequence of (H_i, W_i, 3) uint8
        Perspective crops of the detection boxes, centred on the object
        (:func:`posecrf.crops.extract_crop`); all of class `cls`.
    masks : sequence of (H_i, W_i) bool or None, optional
        Object segmentations (e.g. grab-cut); with one, the crop is cut to the
        mask and its background painted neutral, as the renders are.
    aux : folder or sequence of (image, mask or None), optional
        Auxiliary images of the class (extra CRF nodes, no output). A folder
        is read by :func:`load_aux_folder`. Default none: the CRF is the
        unary plus the edges among the scene's crops.
    k : int
        Nearest renders voting in the unary (paper: 6).
    gamma : float
        Truncation of the pose distance, radians (paper: 20 degrees).
    max_iter : int
        TRW-S iterations (paper: 100; stops early once converged).
    graph_k : int
        Each image is linked to its `graph_k` nearest other images in HOG space.
    edge_radius : float or None
        "Near in HOG space": of those links, keep (i, j) only when
        ``d_HOG(I_i, I_j) <= edge_radius * max(r_i, r_j)``, where ``r_i`` is
        the distance from image i to its K-th nearest render, i.e. only
        images at least about as alike as the renders voting for their poses.
        None keeps every link.
    pairwise_weight : float
        Multiplier of the binary term (1 = the paper's).
    tie_break : float
        See :func:`pose_unaries`.
    refine : bool
        Refine yaw below the grid step on E_o of the retrieved model
        (default True; False returns the grid yaw of the CRF label).
    index : RenderIndex, optional
        A prebuilt index of `cls` (saves concatenating descriptors per call).

    Returns
    -------
    PoseCRFResult

    Examples
    --------
    >>> from posecrf.library import builtin_library
    >>> from posecrf.cache import library_renders
    >>> from posecrf.render import PoseGrid, RenderSettings, render_poses
    >>> grid, st = PoseGrid(12, 2, np.deg2rad(30.0)), RenderSettings(size=32, viewport=64)
    >>> lib = builtin_library().subset(["tv"])
    >>> renders = library_renders(lib, grid=grid, settings=st, use_cache=False, workers=1)
    >>> view = render_poses(lib["tv-04"], PoseGrid(12, 2, np.deg2rad(30.0)), st)
    >>> res = estimate_poses(renders, "tv", [view.images[6]], [view.masks[6]])
    >>> e = res.estimates[0]
    >>> e.model_id, round(float(np.rad2deg(e.yaw_rel))), e.label
    ('tv-04', 90, 6)
    """
    t0 = time.perf_counter()
    if int(k) != k or k < 1:
        raise ValueError(f"k: expected a positive integer, got {k!r}")
    if not (math.isfinite(gamma) and gamma >= 0):
        raise ValueError(f"gamma: expected a finite angle >= 0 in radians, got {gamma!r}")
    if int(graph_k) != graph_k or graph_k < 1:
        raise ValueError(f"graph_k: expected a positive integer, got {graph_k!r}")
    if edge_radius is not None and not (math.isfinite(edge_radius) and edge_radius >= 0):
        raise ValueError(f"edge_radius: expected None or a finite value >= 0, got {edge_radius!r}")
    if not (math.isfinite(pairwise_weight) and pairwise_weight >= 0):
        raise ValueError(f"pairwise_weight: expected a finite value >= 0, got {pairwise_weight!r}")
    crops = list(crops)
    if not crops:
        raise ValueError("crops: expected at least one target crop, got 0")
    _check_images("crops", crops)
    if index is None:
        index = RenderIndex.from_renders(renders, cls)
    elif index.cls != cls or index.grid != renders.grid:
        raise ValueError(f"index: expected an index of class {cls!r} on the renders' grid, got class {index.cls!r}")
    grid = index.grid

    if isinstance(aux, (str, Path)):
        aux_items = load_aux_folder(aux)
    else:
        aux_items = list(aux) if aux is not None else []
    _check_images("aux", [a[0] for a in aux_items])
    n_t, n_a = len(crops), len(aux_items)
    all_crops = crops + [a[0] for a in aux_items]
    ms = list(masks) if masks is not None else [None] * n_t
    if len(ms) != n_t:
        raise ValueError(f"masks: expected one mask (or None) per crop, {n_t} crops, got {len(ms)}")
    all_masks = ms + [a[1] for a in aux_items]
    desc = crop_descriptors(all_crops, all_masks, renders.settings).astype(np.float64)
    kk = min(int(k), index.n_renders)
    unary, nb, votes = pose_unaries(index, desc, kk, tie_break)

    n = n_t + n_a
    mrf = PairwiseMRF(unary)
    edges = np.zeros((0, 2), dtype=np.int64)
    if n >= 2 and pairwise_weight > 0:
        edges = knn_edges(desc, min(int(graph_k), n - 1))
        d_ij = np.linalg.norm(desc[edges[:, 0]] - desc[edges[:, 1]], axis=1)
        if edge_radius is not None:
            r = nb.distance[:, -1]
            keep = d_ij <= edge_radius * np.maximum(r[edges[:, 0]], r[edges[:, 1]])
            edges, d_ij = edges[keep], d_ij[keep]
        if len(edges):
            mrf.add_grid_edges(edges, grid.label_grid(), pairwise_weight * d_ij, gamma=gamma, metric="l1")
    res = trws(mrf, max_iter=max_iter)
    labels = np.asarray(res.labels, dtype=np.int64)

    e_o_all = index.e_o(desc[:n_t])  # (T, M, n_yaw, n_pitch)
    e_o_all.setflags(write=False)
    lab_grid = grid.label_grid()
    estimates = []
    for i in range(n_t):
        lab = int(labels[i])
        iy, ip = divmod(lab, grid.n_pitch)
        m = int(nb.model[i, 0])
        sym = index.symmetries[m]
        e_o = e_o_all[i, m]
        yaw = _refine_yaw(e_o, iy, ip, grid) if refine else iy * grid.yaw_step
        near = lab_grid.distance(np.full(grid.size, lab), np.arange(grid.size)) <= gamma + 1e-12
        hits = [bool(np.any(near[_vote_labels(int(l2), index.symmetries[int(m2)], grid)]))
                for m2, l2 in zip(nb.model[i], nb.label[i])]
        conf = float(np.mean(hits))
        row = Neighbours(nb.distance[i:i + 1], nb.row[i:i + 1], nb.model[i:i + 1], nb.label[i:i + 1])
        estimates.append(PoseEstimate(
            cls=cls,
            yaw_rel=_fold_for(sym, yaw),
            pitch=float(grid.pitches[ip]),
            model_id=index.model_ids[m],
            symmetry=sym,
            confidence=conf,
            label=lab,
            grid=grid,
            e_o=e_o,
            e_o_models=e_o_all[i],
            model_ids=index.model_ids,
            neighbours=row,
        ))
    return PoseCRFResult(
        cls=cls,
        estimates=tuple(estimates),
        aux_labels=labels[n_t:].copy(),
        edges=edges,
        energy=float(res.energy),
        lower_bound=float(res.lower_bound),
        iterations=int(res.iterations),
        seconds=time.perf_counter() - t0,
    )


def load_aux_folder(folder: str | Path) -> list[tuple[NDArray[np.uint8], NDArray[np.bool_] | None]]:
    """Auxiliary images of one class from a folder (the paper's web images).

    Every ``.png``, ``.jpg``, ``.jpeg``, ``.bmp`` or ``.webp`` file, sorted by
    name, except files named ``*_mask.*``. An image's mask is its alpha
    channel (> 127 = object) or a sibling file ``<stem>_mask.png`` (non-zero
    = object); otherwise None.

    Returns
    -------
    list of (image (H, W, 3) uint8 RGB, mask (H, W) bool or None)

    Raises
    ------
    ValueError
        The folder does not exist, or a file cannot be read as an image.
    """
    import cv2

    p = Path(folder)
    if not p.is_dir():
        raise ValueError(f"aux folder: expected an existing folder of images, got {str(p)!r}")
    out: list[tuple[NDArray[np.uint8], NDArray[np.bool_] | None]] = []
    for f in sorted(p.iterdir()):
        if f.suffix.lower() not in _IMAGE_SUFFIXES or f.stem.endswith("_mask"):
            continue
        raw = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        if raw is None or raw.ndim not in (2, 3):
            raise ValueError(f"aux image {str(f)!r}: expected a readable image file, got unreadable data")
        if raw.dtype != np.uint8:
            raw = (raw.astype(np.float64) * (255.0 / np.iinfo(raw.dtype).max)).round().astype(np.uint8)
        mask: NDArray[np.bool_] | None = None
        if raw.ndim == 2:
            rgb = np.repeat(raw[..., None], 3, axis=2)
        elif raw.shape[2] == 4:
            rgb = raw[..., 2::-1]
            mask = raw[..., 3] > 127
        else:
            rgb = raw[..., 2::-1]
        mfile = f.with_name(f.stem + "_mask.png")
        if mask is None and mfile.exists():
            mraw = cv2.imread(str(mfile), cv2.IMREAD_GRAYSCALE)
            if mraw is None or mraw.shape != rgb.shape[:2]:
                raise ValueError(f"aux mask {str(mfile)!r}: expected a readable grayscale image of size {rgb.shape[:2]}")
            mask = mraw > 0
        if mask is not None and not mask.any():
            mask = None
        out.append((np.ascontiguousarray(rgb, dtype=np.uint8), mask))
    return out
