"""Detector backend: MediaPipe Objectron's SSD MobileNetV2 (Open Images V4), run with ai-edge-litert.

The model ships inside the npm package ``@mediapipe/objectron`` (Apache-2.0)
and is fetched by ``python -m detect.fetch_models`` (``make models``) into
``detect/models/objectron_ssd.tflite`` with its label map
``detect/models/objectron_ssd_labels.txt``.

Model: input ``(1, 300, 300, 3)`` float RGB in [-1, 1] (the image is
stretched to 300 x 300); outputs raw SSD box encodings ``(1, 1917, 4)`` and
class logits ``(1, 1917, 24)``. Decoding follows MediaPipe's
``object_detection_oid_v4_cpu.pbtxt``: 1917 anchors from
``SsdAnchorsCalculator`` (6 layers, strides 16..512, scales 0.2..0.95, aspect
ratios 1, 2, 1/2, 3, 1/3, reduced lowest layer), box encodings
``(y, x, h, w)`` with scales 10, 10, 5, 5 and exponential sizes, sigmoid
scores, class 0 (``???``) ignored; per-class NMS here.

Classes: its 23 Open Images classes are Bicycle, Boot, Laptop, Person, Chair,
Cattle, Desk, Cat, Computer mouse, Computer monitor, Box, Mug, Coffee cup,
Stationary bicycle, Table, Bottle, High heels, Vehicle, Footwear, Dog, Book,
Camera, Car. Mapped to the toolkit: Chair -> ``chair``, Table and Desk ->
``table``, Computer monitor -> ``tv``. It has no bed, sofa, plant,
nightstand or wardrobe. The other classes are dropped unless
``keep_others=True``, which keeps them under their lowercase names
(``laptop``, ``computer_mouse``, ...).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..detection import ImageDetection, check_rgb_image
from ..nms import box_nms
from ._common import KNOWN_CLASSES, ModelFileError, Options, canonical_label, resize_rgb

__all__ = ["TFLiteSSDDetector", "ssd_anchors", "from_spec", "DEFAULT_MODEL", "DEFAULT_LABELS"]

_MODELS = Path(__file__).resolve().parent.parent / "models"
#: Where ``python -m detect.fetch_models`` puts the model.
DEFAULT_MODEL = _MODELS / "objectron_ssd.tflite"
#: Its label map (line k = class k; line 0 is the background placeholder ``???``).
DEFAULT_LABELS = _MODELS / "objectron_ssd_labels.txt"

_OPTIONS = ("labels", "score", "iou", "keep_others", "threads", "max_detections")


def _interpreter_class():
    try:
        from ai_edge_litert.interpreter import Interpreter
    except ImportError as exc:
        raise ImportError("the tflite detector backend needs ai-edge-litert: pip install ai-edge-litert") from exc
    return Interpreter


def ssd_anchors(input_size: int = 300, strides: Sequence[int] = (16, 32, 64, 128, 256, 512),
                min_scale: float = 0.2, max_scale: float = 0.95,
                aspect_ratios: Sequence[float] = (1.0, 2.0, 0.5, 3.0, 0.3333),
                reduce_boxes_in_lowest_layer: bool = True,
                interpolated_scale_aspect_ratio: float = 1.0) -> NDArray[np.float64]:
    """SSD anchors as MediaPipe's ``SsdAnchorsCalculator`` makes them (square input, offsets 0.5).

    Returns
    -------
    anchors : (N, 4) float
        ``(y_center, x_center, h, w)`` normalised to [0, 1].

    Examples
    --------
    >>> ssd_anchors().shape
    (1917, 4)
    """
    n = len(strides)
    out = []

    def scale(i: int) -> float:
        return (min_scale + max_scale) / 2 if n == 1 else min_scale + (max_scale - min_scale) * i / (n - 1.0)

    for layer, stride in enumerate(strides):
        s = scale(layer)
        if layer == 0 and reduce_boxes_in_lowest_layer:
            ratios, scales = [1.0, 2.0, 0.5], [0.1, s, s]
        else:
            ratios, scales = list(aspect_ratios), [s] * len(aspect_ratios)
            if interpolated_scale_aspect_ratio > 0:
                nxt = 1.0 if layer == n - 1 else scale(layer + 1)
                ratios.append(interpolated_scale_aspect_ratio)
                scales.append(float(np.sqrt(s * nxt)))
        r = np.sqrt(np.asarray(ratios, dtype=np.float32))
        hs, ws = np.asarray(scales, np.float32) / r, np.asarray(scales, np.float32) * r
        fm = int(np.ceil(input_size / stride))
        y, x = np.meshgrid((np.arange(fm) + 0.5) / fm, (np.arange(fm) + 0.5) / fm, indexing="ij")
        k = len(ratios)
        a = np.empty((fm, fm, k, 4))
        a[..., 0] = y[..., None]
        a[..., 1] = x[..., None]
        a[..., 2] = hs
        a[..., 3] = ws
        out.append(a.reshape(-1, 4))
    return np.concatenate(out)


class TFLiteSSDDetector:
    """The Objectron SSD (Open Images) as a :class:`~detect.detection.Detector`.

    Parameters
    ----------
    model_path : str or Path, optional
        ``.tflite`` file (default :data:`DEFAULT_MODEL`).
    labels_path : str or Path, optional
        Label map, one Open Images name per line (default :data:`DEFAULT_LABELS`).
    score_threshold : float
        Minimum score (sigmoid of the class logit).
    iou_threshold : float
        Per-class NMS inside one image.
    keep_others : bool
        Also report classes that are not the toolkit's (see module docstring).
    num_threads : int
    max_detections : int

    Attributes
    ----------
    classes : tuple of str
        Toolkit class names it can report.
    """

    def __init__(self, model_path: str | Path | None = None, labels_path: str | Path | None = None, *,
                 score_threshold: float = 0.3, iou_threshold: float = 0.45, keep_others: bool = False,
                 num_threads: int = 2, max_detections: int = 50) -> None:
        self.model_path = Path(model_path) if model_path is not None else DEFAULT_MODEL
        self.labels_path = Path(labels_path) if labels_path is not None else DEFAULT_LABELS
        hint = "; fetch it with `python -m detect.fetch_models` (make models)" if model_path is None else ""
        if not self.model_path.is_file():
            raise ModelFileError(self.model_path, f"TFLite model file not found{hint}")
        if not self.labels_path.is_file():
            raise ModelFileError(self.labels_path, f"label map not found{hint}")
        lines = self.labels_path.read_text(encoding="utf-8").splitlines()
        while lines and not lines[-1].strip():
            lines.pop()
        try:
            names = [canonical_label(n) for n in lines]
        except ValueError as exc:
            raise ModelFileError(self.labels_path, f"expected one class name per line ({exc})") from None
        self._labels = [n if (n is None or keep_others or n in KNOWN_CLASSES) else None for n in names]
        self.raw_labels = tuple(lines)
        self.classes = tuple(sorted({n for n in self._labels if n is not None}))
        self.score_threshold, self.iou_threshold = float(score_threshold), float(iou_threshold)
        self.max_detections = int(max_detections)
        Interpreter = _interpreter_class()
        try:
            self._it = Interpreter(model_path=str(self.model_path), num_threads=int(num_threads))
            self._it.allocate_tensors()
        except (ValueError, RuntimeError) as exc:
            raise ModelFileError(self.model_path, f"not a loadable TFLite model ({exc})") from None
        ins, outs = self._it.get_input_details(), self._it.get_output_details()
        shape = tuple(int(s) for s in ins[0]["shape"]) if len(ins) == 1 else ()
        if len(shape) != 4 or shape[0] != 1 or shape[3] != 3 or ins[0]["dtype"] != np.float32:
            raise ModelFileError(self.model_path, f"expected one float input (1, H, W, 3), got "
                                                  f"{[(d['shape'].tolist(), d['dtype'].__name__) for d in ins]}")
        self._h, self._w = shape[1], shape[2]
        self._in = ins[0]["index"]
        self._anchors = ssd_anchors(self._w)
        N = len(self._anchors)
        box = [d for d in outs if tuple(d["shape"]) == (1, N, 4)]
        cls = [d for d in outs if len(d["shape"]) == 3 and d["shape"][1] == N and d["shape"][2] != 4]
        if len(box) != 1 or len(cls) != 1:
            raise ModelFileError(self.model_path, f"expected raw SSD outputs (1, {N}, 4) and (1, {N}, C) for the "
                                                  f"Objectron anchors, got {[d['shape'].tolist() for d in outs]}")
        self._box, self._cls = box[0]["index"], cls[0]["index"]
        if int(cls[0]["shape"][2]) != len(self._labels):
            raise ModelFileError(self.labels_path, f"the label map has {len(self._labels)} names but the model "
                                                   f"{self.model_path.name} outputs {int(cls[0]['shape'][2])} classes")

    def detect(self, image: NDArray[np.uint8]) -> list[ImageDetection]:
        """Detections in one ``(h, w, 3) uint8`` RGB image."""
        img = check_rgb_image(image)
        h, w = img.shape[:2]
        x, _ = resize_rgb(img, self._w, self._h, letterbox=False)
        self._it.set_tensor(self._in, (x.astype(np.float32) / 127.5 - 1.0)[None])
        self._it.invoke()
        raw = np.asarray(self._it.get_tensor(self._box)[0], dtype=np.float64)
        logits = np.asarray(self._it.get_tensor(self._cls)[0], dtype=np.float64)
        a = self._anchors
        yc = raw[:, 0] / 10.0 * a[:, 2] + a[:, 0]
        xc = raw[:, 1] / 10.0 * a[:, 3] + a[:, 1]
        bh = np.exp(np.clip(raw[:, 2] / 5.0, -20, 20)) * a[:, 2]
        bw = np.exp(np.clip(raw[:, 3] / 5.0, -20, 20)) * a[:, 3]
        scores = 1.0 / (1.0 + np.exp(-np.clip(logits, -60, 60)))
        scores[:, [k for k, n in enumerate(self._labels) if n is None]] = 0.0
        k = np.argmax(scores, axis=1)
        s = scores[np.arange(len(k)), k]
        keep = s >= self.score_threshold
        boxes = np.stack([(xc - bw / 2) * w, (yc - bh / 2) * h, (xc + bw / 2) * w, (yc + bh / 2) * h], -1)[keep]
        boxes = np.clip(boxes, 0.0, [w, h, w, h])
        s, k = s[keep], k[keep]
        valid = (boxes[:, 2] > boxes[:, 0]) & (boxes[:, 3] > boxes[:, 1])
        boxes, s, k = boxes[valid], s[valid], k[valid]
        labels = [self._labels[i] for i in k]
        idx = box_nms(boxes, s, self.iou_threshold, labels)[: self.max_detections]
        return [ImageDetection(labels[i], float(s[i]), boxes[i]) for i in idx]  # type: ignore[arg-type]

    def __repr__(self) -> str:
        return f"TFLiteSSDDetector({str(self.model_path)!r}, classes={self.classes})"


def from_spec(path: str | None, options: Mapping[str, object]) -> TFLiteSSDDetector:
    """Build a :class:`TFLiteSSDDetector` from ``tflite`` or ``tflite:FILE?labels=FILE&score=0.3``.

    Options: ``labels``, ``score``, ``iou``, ``keep_others``, ``threads``, ``max_detections``.
    """
    o = Options(options, _OPTIONS, "tflite")
    return TFLiteSSDDetector(path or None, o.get_path("labels"), score_threshold=o.get_float("score", 0.3),
                             iou_threshold=o.get_float("iou", 0.45), keep_others=o.get_bool("keep_others", False),
                             num_threads=o.get_int("threads", 2) or 2,
                             max_detections=o.get_int("max_detections", 50) or 50)
