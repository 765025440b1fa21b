"""Panorama-level detection metrics: per-class average precision at an IoU threshold (VOC style).

Ground truth comes from synthetic room folders (gt.json ``objects``: ``class``,
``bbox_pano`` = seam-aware box of the object's *visible* pixels,
``visible_px``). An object whose visible area is below ``min_visible`` of the
panorama (default 200 pixels of a 1024 x 512 panorama, about a 14 x 14 pixel
patch or 5 x 5 degrees) is marked *difficult* and ignored as in PASCAL VOC:
it does not count as a positive to find, and a detection matched to it is
neither a true nor a false positive. Objects with no visible pixel are not
ground truth at all.

Matching is greedy by decreasing score, per room and class; the overlap is the
exact spherical IoU of lon/lat rectangles, :func:`detect.nms.pano_box_iou`
(seam-aware). AP is the area under the precision envelope (VOC 2010+
all-point interpolation).

Convention: boxes ``(u0, v0, u1, v1)`` in panorama pixels, ``u0 > u1`` wraps
the seam (CONVENTIONS.md).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..detection import Detection
from ..nms import pano_box_iou

__all__ = ["GroundTruth", "ClassResult", "EvalResult", "load_ground_truth", "average_precision",
           "evaluate", "match_counts", "detect_rooms", "tune_score_threshold", "DIFFICULT_FRACTION"]

Array = NDArray[np.float64]

#: Default difficulty threshold: 200 visible pixels of a 1024 x 512 panorama, as a fraction of its area.
DIFFICULT_FRACTION = 200.0 / (1024 * 512)


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """Annotated objects of one panorama.

    Attributes
    ----------
    name : str
    width, height : int
        Panorama size the boxes refer to.
    labels : tuple of str
    boxes : (N, 4) float
        Seam-aware panorama boxes.
    difficult : (N,) bool
    """

    name: str
    width: int
    height: int
    labels: tuple[str, ...]
    boxes: Array
    difficult: NDArray[np.bool_]

    def __post_init__(self) -> None:
        b = np.asarray(self.boxes, np.float64).reshape(-1, 4)
        d = np.asarray(self.difficult, bool).reshape(-1)
        if not (len(b) == len(d) == len(self.labels)):
            raise ValueError(f"expected as many boxes, labels and difficult flags, got {len(b)}, "
                             f"{len(self.labels)}, {len(d)}")
        object.__setattr__(self, "boxes", b)
        object.__setattr__(self, "difficult", d)


def load_ground_truth(folder: str | Path, width: int | None = None,
                      min_visible: float = DIFFICULT_FRACTION) -> GroundTruth:
    """Read a synthetic room's gt.json.

    Parameters
    ----------
    folder : str or Path
        Room folder (``room-0007``) holding gt.json.
    width : int, optional
        Scale the boxes to a panorama of this width (default: gt.json's).
    min_visible : float
        Objects with ``visible_px`` below this fraction of the panorama area are difficult.
    """
    d = Path(folder)
    gt = json.loads((d / "gt.json").read_text(encoding="utf-8"))
    W0, H0 = int(gt["image"]["width"]), int(gt["image"]["height"])
    W = W0 if width is None else int(width)
    s = W / W0
    objs = [o for o in gt["objects"] if o.get("bbox_pano") is not None]
    boxes = np.array([[x * s for x in o["bbox_pano"]] for o in objs], np.float64).reshape(-1, 4)
    diff = np.array([o["visible_px"] < min_visible * W0 * H0 for o in objs], bool)
    return GroundTruth(d.name, W, W // 2, tuple(o["class"] for o in objs), boxes, diff)


def average_precision(recall: ArrayLike, precision: ArrayLike) -> float:
    """Area under the monotone precision envelope (VOC all-point interpolation).

    Parameters
    ----------
    recall, precision : (K,) float
        At each rank of the score-sorted detections.

    Examples
    --------
    >>> average_precision([0.5, 0.5, 1.0], [1.0, 0.5, 0.67])
    0.835
    """
    r = np.concatenate([[0.0], np.asarray(recall, np.float64), [1.0]])
    p = np.concatenate([[0.0], np.asarray(precision, np.float64), [0.0]])
    p = np.maximum.accumulate(p[::-1])[::-1]
    i = np.flatnonzero(r[1:] != r[:-1])
    return float(np.sum((r[i + 1] - r[i]) * p[i + 1]))


@dataclass(frozen=True)
class ClassResult:
    """AP of one class.

    Attributes
    ----------
    label : str
    ap : float
        NaN when the class has no (non-difficult) ground truth.
    n_gt : int
        Non-difficult objects.
    n_difficult : int
    n_det : int
        Detections of the class (all scores).
    tp_at_best_f1, fp_at_best_f1 : int
        True and false positives at the score threshold of the best F1.
    """

    label: str
    ap: float
    n_gt: int
    n_difficult: int
    n_det: int
    tp_at_best_f1: int
    fp_at_best_f1: int


@dataclass(frozen=True)
class EvalResult:
    """Per-class results and their mean.

    Attributes
    ----------
    classes : dict of str -> ClassResult
    iou_threshold : float
    """

    classes: dict[str, ClassResult] = field(default_factory=dict)
    iou_threshold: float = 0.5

    @property
    def mean_ap(self) -> float:
        """Mean AP over the classes with ground truth."""
        aps = [c.ap for c in self.classes.values() if np.isfinite(c.ap)]
        return float(np.mean(aps)) if aps else float("nan")

    def ap(self, label: str) -> float:
        """AP of one class (NaN when it has no ground truth or is unknown)."""
        c = self.classes.get(label)
        return c.ap if c is not None else float("nan")


def _match(detections: Mapping[str, Sequence[Detection]], truths: Sequence[GroundTruth], label: str,
           iou_threshold: float) -> tuple[Array, NDArray[np.bool_], int, int]:
    """Greedy matching of one class: scores and hit flags of the counted detections, n_gt, n_difficult."""
    scores: list[float] = []
    hits: list[bool] = []
    n_gt = n_diff = 0
    for t in truths:
        g = np.array([lab == label for lab in t.labels], bool).reshape(-1)
        gb, gd = t.boxes[g], t.difficult[g]
        n_gt += int((~gd).sum())
        n_diff += int(gd.sum())
        ds = sorted((d for d in detections.get(t.name, ()) if d.label == label), key=lambda d: -d.score)
        if not ds:
            continue
        for d in ds:
            if (d.pano_width, d.pano_height) != (t.width, t.height):
                raise ValueError(f"{t.name}: expected detections in a {t.width}x{t.height} panorama, "
                                 f"got {d.pano_width}x{d.pano_height}")
        iou = pano_box_iou(np.stack([d.box for d in ds]), gb, t.width, t.height) if len(gb) else None
        taken = np.zeros(len(gb), bool)
        for k, d in enumerate(ds):
            j = int(np.argmax(iou[k])) if iou is not None else -1
            hit = False
            if j >= 0 and iou[k, j] >= iou_threshold:
                if gd[j]:
                    continue  # matched to a difficult object: neither true nor false positive
                if not taken[j]:
                    taken[j] = hit = True
            scores.append(d.score)
            hits.append(hit)
    order = np.argsort(-np.asarray(scores, np.float64), kind="stable")
    return np.asarray(scores, np.float64)[order], np.asarray(hits, bool)[order], n_gt, n_diff


def evaluate(detections: Mapping[str, Sequence[Detection]], truths: Sequence[GroundTruth],
             classes: Sequence[str] | None = None, iou_threshold: float = 0.5) -> EvalResult:
    """Per-class AP of panorama detections against ground truth.

    Parameters
    ----------
    detections : mapping room name -> sequence of Detection
        A room missing from the mapping has no detections.
    truths : sequence of GroundTruth
    classes : sequence of str, optional
        Classes to score (default: all classes of the ground truth and the detections).
    iou_threshold : float

    Returns
    -------
    EvalResult

    Examples
    --------
    >>> gt = GroundTruth("r", 2048, 1024, ("tv", "tv"), [[100, 400, 200, 500], [2000, 400, 40, 500]], [False, False])
    >>> dets = [Detection("tv", 0.9, [2002, 402, 40, 500], 2048, 1024), Detection("tv", 0.8, [600, 400, 700, 500], 2048, 1024)]
    >>> evaluate({"r": dets}, [gt]).ap("tv")
    0.5
    """
    if not 0.0 < float(iou_threshold) <= 1.0:
        raise ValueError(f"iou_threshold: expected a number in (0, 1], got {iou_threshold!r}")
    unknown = sorted(set(detections) - {t.name for t in truths})
    if unknown:
        raise ValueError(f"detections: expected room names of the ground truth, got unknown {unknown[:5]}")
    if classes is None:
        found = {lab for t in truths for lab in t.labels} | {d.label for ds in detections.values() for d in ds}
        classes = sorted(found)
    out: dict[str, ClassResult] = {}
    for c in classes:
        _, hits, n_gt, n_diff = _match(detections, truths, c, iou_threshold)
        n_det = sum(1 for ds in detections.values() for d in ds if d.label == c)
        if n_gt == 0:
            out[c] = ClassResult(c, float("nan"), 0, n_diff, n_det, 0, int(len(hits)))
            continue
        ctp, cfp = np.cumsum(hits), np.cumsum(~hits)
        recall = ctp / n_gt
        precision = ctp / np.maximum(ctp + cfp, 1)
        ap = average_precision(recall, precision) if len(hits) else 0.0
        best = (0, 0)
        if len(hits):
            f1 = 2 * precision * recall / np.maximum(precision + recall, 1e-12)
            k = int(np.argmax(f1))
            best = (int(ctp[k]), int(cfp[k]))
        out[c] = ClassResult(c, ap, n_gt, n_diff, n_det, *best)
    return EvalResult(out, float(iou_threshold))


def tune_score_threshold(detections: Mapping[str, Sequence[Detection]], truths: Sequence[GroundTruth],
                         classes: Sequence[str], candidates: ArrayLike | None = None,
                         iou_threshold: float = 0.5) -> float:
    """The score threshold with the best F1 averaged over ``classes`` (those with ground truth).

    Matching is greedy by score, so dropping the detections below a threshold
    after matching gives the matches of the kept ones.

    Parameters
    ----------
    detections, truths, iou_threshold
        As in :func:`evaluate`.
    classes : sequence of str
    candidates : (K,) float, optional
        Thresholds to try (default 0.05, 0.10, ..., 0.90).

    Examples
    --------
    >>> gt = GroundTruth("r", 2048, 1024, ("tv",), [[100, 400, 200, 500]], [False])
    >>> dets = [Detection("tv", 0.9, [100, 400, 200, 500], 2048, 1024), Detection("tv", 0.3, [600, 400, 700, 500], 2048, 1024)]
    >>> tune_score_threshold({"r": dets}, [gt], ["tv"])
    0.35
    """
    cand = np.round(np.arange(0.05, 0.901, 0.05), 2) if candidates is None else np.asarray(candidates, np.float64)
    matched = [_match(detections, truths, c, iou_threshold) for c in classes]
    matched = [m for m in matched if m[2] > 0]
    best, best_f1 = float(cand[0]), -1.0
    for t in cand:
        f1s = []
        for scores, hits, n_gt, _ in matched:
            keep = scores >= t
            tp = int((hits & keep).sum())
            fp = int((~hits & keep).sum())
            f1s.append(2.0 * tp / (tp + fp + n_gt))
        f1 = float(np.mean(f1s)) if f1s else 0.0
        if f1 > best_f1 + 1e-12:
            best, best_f1 = float(t), f1
    return best


def match_counts(detections: Mapping[str, Sequence[Detection]], truths: Sequence[GroundTruth],
                 classes: Sequence[str], iou_threshold: float = 0.5) -> dict[str, tuple[int, int, int]]:
    """Per class: (true positives, false positives, objects to find) of all the given detections.

    Detections matched to difficult objects count as neither.

    Examples
    --------
    >>> gt = GroundTruth("r", 2048, 1024, ("tv",), [[100, 400, 200, 500]], [False])
    >>> match_counts({"r": [Detection("tv", 0.5, [100, 400, 200, 500], 2048, 1024)]}, [gt], ["tv", "bed"])
    {'tv': (1, 0, 1), 'bed': (0, 0, 0)}
    """
    out = {}
    for c in classes:
        _, hits, n_gt, _ = _match(detections, truths, c, iou_threshold)
        out[c] = (int(hits.sum()), int((~hits).sum()), n_gt)
    return out


def detect_rooms(detector: object, folders: Sequence[str | Path], views: Sequence[object] | None = None,
                 width: int | None = None, **kwargs: object) -> dict[str, list[Detection]]:
    """Run :func:`detect.tiles.detect_panorama` on the ``pano.png`` of each room folder.

    Parameters
    ----------
    detector : Detector
    folders : sequence of room folders
    views : sequence of PinholeView, optional
        Tile set (default: the driver's).
    width : int, optional
        Resize the panoramas to this width first (area averaging or linear).
    **kwargs
        More arguments of ``detect_panorama``.

    Returns
    -------
    dict room name -> list of Detection
    """
    import cv2

    from ..tiles import detect_panorama

    out: dict[str, list[Detection]] = {}
    for f in folders:
        d = Path(f)
        bgr = cv2.imread(str(d / "pano.png"), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ValueError(f"{d / 'pano.png'}: expected a readable panorama image")
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        if width is not None and int(width) != rgb.shape[1]:
            w = int(width)
            interp = cv2.INTER_AREA if w < rgb.shape[1] else cv2.INTER_LINEAR
            rgb = cv2.resize(rgb, (w, w // 2), interpolation=interp)
        out[d.name] = detect_panorama(rgb, detector, views, **kwargs)  # type: ignore[arg-type]
    return out
