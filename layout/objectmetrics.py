"""Object metrics of the paper's Table 2: per-class position and orientation errors after matching.

Objects of one class are matched to the ground truth by Hungarian
assignment on their floor-plane distance, with a gate (1.5 m by default, as
``shared/tools/score_scene.py``); unmatched ground-truth objects are counted
as misses, not dropped.

Convention: position error = distance between box centres projected on the
floor plane (metres); orientation error = smallest angle between the yaws
(radians, in [0, pi]); objects of rotationally symmetric classes (plant) have
no orientation error; two-fold symmetric ones (tables) are compared mod pi.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from panogeom.rotation import angle_difference

__all__ = ["ObjectRecord", "ClassErrors", "match_pairs", "match_objects", "yaw_error"]

#: Classes without an orientation (CONVENTIONS.md).
SYMMETRIC_CLASSES = frozenset({"plant"})
#: Classes whose orientation is defined up to a half turn.
TWO_FOLD_CLASSES = frozenset({"table"})


@dataclass(frozen=True)
class ObjectRecord:
    """What the metrics need of an object: class, floor position and yaw (radians; None if unknown)."""

    cls: str
    xy: tuple[float, float]
    yaw: float | None

    @classmethod
    def from_json(cls, d: Mapping) -> "ObjectRecord":
        """From a scene.json / gt.json object (``center``, ``yaw_deg``)."""
        yaw = d.get("yaw_deg")
        return cls(str(d["class"]).lower(), (float(d["center"][0]), float(d["center"][1])),
                   None if yaw is None else float(np.deg2rad(yaw)))


@dataclass(frozen=True)
class ClassErrors:
    """Errors of one class in one room.

    Attributes
    ----------
    n_gt, n_pred, matched : int
    position : (matched,) float
        Floor distances of the matched pairs, metres.
    orientation : (k,) float
        Yaw errors of matched pairs with an orientation, radians.
    """

    n_gt: int
    n_pred: int
    matched: int
    position: NDArray[np.float64]
    orientation: NDArray[np.float64]


def yaw_error(a: float | NDArray, b: float | NDArray, fold: int = 1) -> NDArray[np.float64]:
    """Smallest angle between yaws ``a`` and ``b`` (radians), with ``fold``-fold symmetry: the orientation error
    of Table 2 (:func:`panogeom.rotation.angle_difference`)."""
    return angle_difference(a, b, fold)


def match_pairs(pred: Sequence[ObjectRecord], gt: Sequence[ObjectRecord], gate: float = 1.5
                ) -> dict[str, list[tuple[int, int, float]]]:
    """Per ground-truth class: the Hungarian pairs on floor distance within ``gate``.

    Parameters
    ----------
    pred, gt : sequences of ObjectRecord
    gate : float
        Pairs farther apart than this (metres) do not count as a match.

    Returns
    -------
    dict class -> list of ``(gt index, pred index, distance)``, indices into ``gt`` and ``pred`` (every class
    present in ``gt``; an empty list where nothing matched)

    Examples
    --------
    >>> g = [ObjectRecord("bed", (1.0, 0.0), 0.0), ObjectRecord("tv", (0.0, 3.0), 0.0)]
    >>> p = [ObjectRecord("tv", (0.0, 9.0), 0.0), ObjectRecord("bed", (1.1, 0.0), 0.0)]
    >>> {c: [(i, j, round(d, 3)) for i, j, d in v] for c, v in match_pairs(p, g).items()}
    {'bed': [(0, 1, 0.1)], 'tv': []}
    """
    from scipy.optimize import linear_sum_assignment

    if not (np.isfinite(gate) and gate > 0):
        raise ValueError(f"gate: expected a positive distance, got {gate!r}")
    out: dict[str, list[tuple[int, int, float]]] = {}
    for cls in sorted({o.cls for o in gt}):
        gi = [i for i, o in enumerate(gt) if o.cls == cls]
        pj = [j for j, o in enumerate(pred) if o.cls == cls]
        out[cls] = []
        if not pj:
            continue
        gxy = np.array([gt[i].xy for i in gi], dtype=np.float64)
        pxy = np.array([pred[j].xy for j in pj], dtype=np.float64)
        d = np.linalg.norm(gxy[:, None] - pxy[None], axis=-1)
        rows, cols = linear_sum_assignment(d)
        out[cls] = [(gi[r], pj[c], float(d[r, c])) for r, c in zip(rows, cols) if d[r, c] <= gate]
    return out


def match_objects(pred: Sequence[ObjectRecord], gt: Sequence[ObjectRecord], gate: float = 1.5
                  ) -> dict[str, ClassErrors]:
    """Per ground-truth class: the errors of the pairs of :func:`match_pairs` (same arguments).

    Returns
    -------
    dict class -> ClassErrors (every class present in ``gt``)

    Examples
    --------
    >>> g = [ObjectRecord("bed", (1.0, 0.0), 0.0)]
    >>> p = [ObjectRecord("bed", (1.1, 0.0), np.deg2rad(5.0))]
    >>> e = match_objects(p, g)["bed"]
    >>> e.matched, round(float(e.position[0]), 3), round(float(np.rad2deg(e.orientation[0])), 3)
    (1, 0.1, 5.0)
    """
    out: dict[str, ClassErrors] = {}
    for cls, pairs in match_pairs(pred, gt, gate).items():
        fold = 2 if cls in TWO_FOLD_CLASSES else 1
        pos = [d for _, _, d in pairs]
        ori = [float(yaw_error(pred[j].yaw, gt[i].yaw, fold)) for i, j, _ in pairs
               if cls not in SYMMETRIC_CLASSES and gt[i].yaw is not None and pred[j].yaw is not None]
        n_pred = sum(1 for o in pred if o.cls == cls)
        out[cls] = ClassErrors(sum(1 for o in gt if o.cls == cls), n_pred, len(pos), np.array(pos), np.array(ori))
    return out
