"""Detector backend for any ONNX detection model, run with onnxruntime (optional dependency).

Two output layouts are understood; ``layout="auto"`` picks one from the
model's outputs (one 3-D output: YOLO, otherwise SSD):

``yolo`` (raw YOLO heads, NMS done here)
    One output ``(B, 4 + C, N)`` (YOLOv8 and later: ``cx, cy, w, h`` and C
    class scores per column) or ``(B, N, 5 + C)`` (YOLOv5: ``cx, cy, w, h,
    objectness`` and C class scores per row). Boxes are in pixels of the
    network input (``normalized_boxes=True``: in [0, 1]). ``C`` is the number
    of classes in the class mapping, so a mapping that does not fit the model
    is an error rather than a silent misreading.

``ssd`` (decoded boxes, as exported by the TF object detection API and torchvision)
    A boxes output ``(B, N, 4)``, scores ``(B, N)`` with class indices
    ``(B, N)`` or per-class scores ``(B, N, C)``, and optionally a detection
    count ``(B,)``. Boxes are ``(y0, x0, y1, x1)`` normalised to [0, 1] by
    default (``box_order="xyxy"``, ``normalized_boxes=False`` for others).
    Scores and class outputs are told apart by dtype and name ("score",
    "class"/"label").

The class mapping (model class index -> toolkit class) is a file
(:func:`~detect.backends._common.load_class_map`) given as ``classes``, or
found next to the model: ``MODEL.classes.json``, ``MODEL.names``,
``MODEL.txt`` or ``labels.txt``.

Input: ``(B, 3, H, W)`` or ``(B, H, W, 3)``, uint8 (0..255) or float
(``input_range``: ``unit`` = [0, 1], ``symmetric`` = [-1, 1], ``byte`` =
0..255), RGB. Fixed sizes are read from the model, dynamic ones come from
``input_size`` (default 640). Images are letterboxed (YOLO, grey 114) or
stretched (SSD); a dynamic batch dimension makes the detector a
:class:`~detect.detection.BatchDetector`.

Every problem with the files (missing model, unreadable model, output layout
that fits neither form, class mapping that does not fit the model) raises one
:class:`~detect.backends._common.ModelFileError` naming the file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..detection import ImageDetection, check_rgb_image
from ..nms import box_nms
from ._common import ModelFileError, Options, _parse_map_entries, load_class_map, resize_rgb

__all__ = ["OnnxDetector", "from_spec", "SIDECAR_NAMES"]

#: Class-mapping files looked for next to a model ``M.onnx``, in order ({stem} = ``M``).
SIDECAR_NAMES = ("{stem}.classes.json", "{stem}.names", "{stem}.txt", "labels.txt")

_OPTIONS = ("classes", "layout", "score", "iou", "input_size", "resize", "input_range", "box_order",
            "normalized_boxes", "logits", "threads", "max_detections")


def _ort():
    try:
        import onnxruntime
    except ImportError as exc:
        raise ImportError("the onnx detector backend needs onnxruntime: pip install onnxruntime") from exc
    return onnxruntime


def _sigmoid(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return 1.0 / (1.0 + np.exp(-np.clip(x, -60.0, 60.0)))


class OnnxDetector:
    """Run an ONNX detection model on perspective images.

    Parameters
    ----------
    model_path : str or Path
        The ``.onnx`` file.
    classes : str, Path, sequence or mapping, optional
        Class mapping: a file, a list of names (index = position) or a
        ``{index: name}`` mapping; ``None`` looks for a file next to the model
        (:data:`SIDECAR_NAMES`).
    layout : {"auto", "yolo", "ssd"}
    score_threshold, iou_threshold : float
        Minimum score; IoU for the per-class NMS inside one image.
    input_size : int, optional
        Side of the network input where the model's size is dynamic (640).
    resize : {"letterbox", "stretch"}, optional
        Default: letterbox for YOLO, stretch for SSD.
    input_range : {"unit", "symmetric", "byte"}
        Scaling of float inputs.
    box_order : {"yxyx", "xyxy"}
        SSD box coordinate order.
    normalized_boxes : bool, optional
        Boxes in [0, 1] of the network input (default: False for YOLO, True for SSD).
    logits : bool
        Scores are logits (a sigmoid is applied).
    num_threads : int
    max_detections : int
        Per image, after NMS.

    Attributes
    ----------
    classes : tuple of str
        Toolkit classes the model can report.
    layout : str
        ``"yolo"`` or ``"ssd"``, resolved.
    batchable : bool
        The model takes a dynamic batch: :meth:`detect_batch` runs one session call.
    """

    def __init__(self, model_path: str | Path, classes: str | Path | Sequence[str | None] | Mapping[int, str | None]
                 | None = None, *, layout: str = "auto", score_threshold: float = 0.25, iou_threshold: float = 0.45,
                 input_size: int | None = None, resize: str | None = None, input_range: str = "unit",
                 box_order: str = "yxyx", normalized_boxes: bool | None = None, logits: bool = False,
                 num_threads: int = 2, max_detections: int = 100) -> None:
        self.model_path = Path(model_path)
        if not self.model_path.is_file():
            raise ModelFileError(self.model_path, "ONNX model file not found")
        for name, val, ok in (("layout", layout, ("auto", "yolo", "ssd")),
                              ("resize", resize, (None, "letterbox", "stretch")),
                              ("input_range", input_range, ("unit", "symmetric", "byte")),
                              ("box_order", box_order, ("yxyx", "xyxy"))):
            if val not in ok:
                raise ValueError(f"{name}: expected one of {list(ok)}, got {val!r}")
        self.map_path, self._map = self._load_map(classes)
        self.score_threshold, self.iou_threshold = float(score_threshold), float(iou_threshold)
        self.max_detections = int(max_detections)
        self.input_range, self.box_order, self.logits = input_range, box_order, bool(logits)
        ort = _ort()
        so = ort.SessionOptions()
        so.intra_op_num_threads = int(num_threads)
        so.inter_op_num_threads = 1
        so.log_severity_level = 3
        try:
            self._sess = ort.InferenceSession(str(self.model_path), so, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types for unreadable models
            raise ModelFileError(self.model_path, f"not a loadable ONNX model ({type(exc).__name__}: {exc})") from None
        self._setup_input(input_size)
        outs = self._run(np.zeros((1, self._h, self._w, 3), np.uint8))
        self.layout = self._resolve_layout(layout, outs)
        self._letterbox = (resize or ("letterbox" if self.layout == "yolo" else "stretch")) == "letterbox"
        self._normalized = (self.layout == "ssd") if normalized_boxes is None else bool(normalized_boxes)
        self.classes = tuple(sorted({v for v in self._map.values() if v is not None}))

    # ------------------------------------------------------------------ set-up
    def _load_map(self, classes: object) -> tuple[Path, dict[int, str | None]]:
        if classes is None:
            stem = self.model_path.stem
            for pattern in SIDECAR_NAMES:
                cand = self.model_path.parent / pattern.format(stem=stem)
                if cand.is_file():
                    return cand, load_class_map(cand)
            looked = ", ".join(p.format(stem=stem) for p in SIDECAR_NAMES)
            raise ModelFileError(self.model_path, f"no class-mapping file next to the model (looked for {looked}); "
                                                  "pass classes=FILE")
        if isinstance(classes, (str, Path)):
            return Path(classes), load_class_map(classes)
        where = Path("<classes argument>")
        if isinstance(classes, Mapping) or (isinstance(classes, Sequence) and not isinstance(classes, str)):
            m = _parse_map_entries(classes, where)
            if not any(v is not None for v in m.values()):
                raise ModelFileError(where, "expected at least one class name, got none")
            return where, m
        raise ValueError(f"classes: expected a file, a list or a mapping of class names, got {type(classes).__name__}")

    def _setup_input(self, input_size: int | None) -> None:
        ins = self._sess.get_inputs()
        if len(ins) != 1 or len(ins[0].shape) != 4:
            got = [(i.name, i.shape) for i in ins]
            raise ModelFileError(self.model_path, f"expected one image input of rank 4 (NCHW or NHWC), got {got}")
        inp = ins[0]
        shape = inp.shape
        if shape[1] == 3:
            self._nchw, hw = True, (shape[2], shape[3])
        elif shape[3] == 3:
            self._nchw, hw = False, (shape[1], shape[2])
        else:
            raise ModelFileError(self.model_path,
                                 f"expected an input of shape (B, 3, H, W) or (B, H, W, 3), got {shape}")
        size = 640 if input_size is None else int(input_size)
        self._h = hw[0] if isinstance(hw[0], int) and hw[0] > 0 else size
        self._w = hw[1] if isinstance(hw[1], int) and hw[1] > 0 else size
        types = {"tensor(uint8)": np.uint8, "tensor(float)": np.float32, "tensor(float16)": np.float16}
        if inp.type not in types:
            raise ModelFileError(self.model_path, f"expected a uint8 or float image input, got {inp.type}")
        self._dtype = types[inp.type]
        self._input_name = inp.name
        self.batchable = not (isinstance(shape[0], int) and shape[0] > 0)
        if not self.batchable and shape[0] != 1:
            raise ModelFileError(self.model_path, f"expected batch size 1 or a dynamic batch, got {shape[0]}")
        self._out_meta = [(o.name, o.type) for o in self._sess.get_outputs()]

    def _prepare(self, images: Sequence[NDArray[np.uint8]]) -> tuple[NDArray, list[tuple[float, float, float, float]]]:
        batch, tfs = [], []
        for im in images:
            r, tf = resize_rgb(im, self._w, self._h, getattr(self, "_letterbox", False))
            batch.append(r)
            tfs.append(tf)
        x = np.stack(batch)
        if self._dtype != np.uint8:
            x = x.astype(np.float32)
            if self.input_range == "unit":
                x /= 255.0
            elif self.input_range == "symmetric":
                x = x / 127.5 - 1.0
            x = x.astype(self._dtype)
        if self._nchw:
            x = np.ascontiguousarray(x.transpose(0, 3, 1, 2))
        return x, tfs

    def _run(self, x_hwc: NDArray[np.uint8]) -> list[NDArray]:
        x, _ = self._prepare(list(x_hwc))
        return self._sess.run(None, {self._input_name: x})

    def _layout_error(self, outs: list[NDArray], why: str) -> ModelFileError:
        got = ", ".join(f"{n} {tuple(o.shape)} {t}" for (n, t), o in zip(self._out_meta, outs))
        return ModelFileError(self.model_path, f"output layout not understood: {why}; the model gives [{got}]; "
                                               "expected YOLO (one output (B, 4+C, N) or (B, N, 5+C)) or SSD "
                                               "(boxes (B, N, 4) + scores (B, N) [+ classes (B, N)] or "
                                               "scores (B, N, C))")

    def _n_classes(self) -> int:
        return max(self._map) + 1

    def _check_map_covers(self, C: int) -> None:
        missing = [k for k in range(C) if k not in self._map]
        extra = [k for k in self._map if k >= C]
        if missing or extra:
            raise ModelFileError(self.map_path, f"the class mapping has {len(self._map)} entries (indices "
                                                f"{min(self._map)}..{max(self._map)}) but the model "
                                                f"{self.model_path.name} outputs {C} classes (indices 0..{C - 1})")

    def _resolve_layout(self, layout: str, outs: list[NDArray]) -> str:
        if layout == "auto":
            layout = "yolo" if len(outs) == 1 and outs[0].ndim == 3 else "ssd"
        if layout == "yolo":
            self._setup_yolo(outs)
        else:
            self._setup_ssd(outs)
        return layout

    def _setup_yolo(self, outs: list[NDArray]) -> None:
        if len(outs) != 1 or outs[0].ndim != 3:
            raise self._layout_error(outs, "YOLO needs exactly one output of rank 3")
        C = self._n_classes()
        a, b = outs[0].shape[1:]
        v8, v5 = a == 4 + C, b == 5 + C  # (B, 4+C, N) without objectness; (B, N, 5+C) with it
        if not (v8 or v5):
            raise ModelFileError(self.map_path, f"the class mapping gives C={C} classes but the YOLO output "
                                                f"{tuple(outs[0].shape)} of {self.model_path.name} is neither "
                                                f"(B, {4 + C}, N) nor (B, N, {5 + C})")
        if v8 and v5:  # both fit: the channel axis is the shorter one
            v8 = a <= b
        self._yolo_transpose, self._yolo_obj = v8, not v8
        self._check_map_covers(C)

    def _setup_ssd(self, outs: list[NDArray]) -> None:
        names = [n.lower() for n, _ in self._out_meta]
        boxes = [i for i, o in enumerate(outs) if o.ndim == 3 and o.shape[2] == 4]
        if len(boxes) != 1:
            raise self._layout_error(outs, f"SSD needs exactly one boxes output (B, N, 4), found {len(boxes)}")
        ib = boxes[0]
        N = outs[ib].shape[1]
        per_class = [i for i, o in enumerate(outs) if i != ib and o.ndim == 3 and o.shape[1] == N]
        flat = [i for i, o in enumerate(outs) if o.ndim == 2 and o.shape[1] == N]
        counts = [i for i, o in enumerate(outs)
                  if (o.ndim == 1 or (o.ndim == 2 and o.shape[1] == 1)) and i not in flat]
        self._ssd_boxes, self._ssd_num = ib, (counts[0] if len(counts) == 1 else None)
        if len(per_class) == 1 and not flat:
            self._ssd_scores, self._ssd_labels = per_class[0], None
            self._check_map_covers(outs[per_class[0]].shape[2])
            return
        if per_class or not 1 <= len(flat) <= 2:
            raise self._layout_error(outs, "SSD needs scores (B, N) with classes (B, N), or scores (B, N, C)")
        if len(flat) == 1:
            self._ssd_scores, self._ssd_labels = flat[0], None
            self._check_map_covers(1)
            return
        i, j = flat

        def is_labels(k: int) -> bool:
            return outs[k].dtype.kind in "iu" or "class" in names[k] or "label" in names[k]

        def is_scores(k: int) -> bool:
            return outs[k].dtype.kind == "f" and "score" in names[k]

        if (is_labels(i) and not is_labels(j)) or (is_scores(j) and not is_scores(i)):
            self._ssd_labels, self._ssd_scores = i, j
        elif (is_labels(j) and not is_labels(i)) or (is_scores(i) and not is_scores(j)):
            self._ssd_labels, self._ssd_scores = j, i
        else:
            raise self._layout_error(outs, "cannot tell the scores output from the classes output (name them "
                                           "'scores' and 'classes' or make the classes integer)")

    # ------------------------------------------------------------------ decoding
    def _label_of(self, k: int) -> str | None:
        if k not in self._map:
            raise ModelFileError(self.map_path, f"class index {k} output by {self.model_path.name} "
                                                "is not in the class mapping")
        return self._map[k]

    def _check_scores(self, s: NDArray) -> NDArray[np.float64]:
        s = np.asarray(s, dtype=np.float64)
        if self.logits:
            return _sigmoid(s)
        if s.size and (s.min() < -1e-3 or s.max() > 1.0 + 1e-3):
            raise ModelFileError(self.model_path, f"scores outside [0, 1] (min {s.min():.3g}, max {s.max():.3g}): "
                                                  "the model outputs logits? set logits=true")
        return np.clip(s, 0.0, 1.0)

    def _decode(self, outs: list[NDArray], b: int) -> tuple[NDArray, NDArray, NDArray]:
        """Boxes (K, 4) xyxy in network pixels, scores (K,), class indices (K,) of image b."""
        if self.layout == "yolo":
            o = np.asarray(outs[0][b], dtype=np.float64)
            if self._yolo_transpose:
                o = o.T
            cx, cy, w, h = o[:, 0], o[:, 1], o[:, 2], o[:, 3]
            if self._normalized:
                cx, w, cy, h = cx * self._w, w * self._w, cy * self._h, h * self._h
            cls = self._check_scores(o[:, 5:] if self._yolo_obj else o[:, 4:])
            if self._yolo_obj:
                cls = cls * self._check_scores(o[:, 4:5])
            k = np.argmax(cls, axis=1)
            scores = cls[np.arange(len(k)), k]
            boxes = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], -1)
            return boxes, scores, k
        boxes = np.asarray(outs[self._ssd_boxes][b], dtype=np.float64)
        sc = np.asarray(outs[self._ssd_scores][b])
        if sc.ndim == 2:
            cls = self._check_scores(sc)
            k = np.argmax(cls, axis=1)
            scores = cls[np.arange(len(k)), k]
        else:
            scores = self._check_scores(sc)
            k = (np.zeros(len(scores), np.int64) if self._ssd_labels is None
                 else np.rint(np.asarray(outs[self._ssd_labels][b], dtype=np.float64)).astype(np.int64))
        if self._ssd_num is not None:
            n = int(np.asarray(outs[self._ssd_num]).reshape(-1)[b])
            boxes, scores, k = boxes[:n], scores[:n], k[:n]
        if self.box_order == "yxyx":
            boxes = boxes[:, [1, 0, 3, 2]]
        if self._normalized:
            boxes = boxes * np.array([self._w, self._h, self._w, self._h])
        return boxes, scores, k

    def _postprocess(self, outs: list[NDArray], b: int, tf: tuple[float, float, float, float],
                     size: tuple[int, int]) -> list[ImageDetection]:
        boxes, scores, k = self._decode(outs, b)
        keep = scores >= self.score_threshold
        boxes, scores, k = boxes[keep], scores[keep], k[keep]
        labels = [self._label_of(int(i)) for i in k]
        sel = np.array([lab is not None for lab in labels], dtype=bool)
        boxes, scores = boxes[sel], scores[sel]
        labels = [lab for lab in labels if lab is not None]
        sx, sy, px, py = tf
        h, w = size
        boxes = (boxes - np.array([px, py, px, py])) / np.array([sx, sy, sx, sy])
        boxes = np.clip(boxes, 0.0, [w, h, w, h])
        valid = (boxes[:, 2] > boxes[:, 0]) & (boxes[:, 3] > boxes[:, 1])
        boxes, scores = boxes[valid], scores[valid]
        labels = [lab for lab, v in zip(labels, valid) if v]
        keep_idx = box_nms(boxes, scores, self.iou_threshold, labels)[: self.max_detections]
        return [ImageDetection(labels[i], float(scores[i]), boxes[i]) for i in keep_idx]  # type: ignore[arg-type]

    # ------------------------------------------------------------------ API
    def detect(self, image: NDArray[np.uint8]) -> list[ImageDetection]:
        """Detections in one ``(h, w, 3) uint8`` RGB image."""
        return self.detect_batch([image])[0]

    def detect_batch(self, images: Sequence[NDArray[np.uint8]]) -> list[list[ImageDetection]]:
        """Detections in several images (one session call when the model's batch is dynamic)."""
        imgs = [check_rgb_image(im, f"images[{i}]") for i, im in enumerate(images)]
        if not imgs:
            return []
        step = len(imgs) if self.batchable else 1
        out: list[list[ImageDetection]] = []
        for s in range(0, len(imgs), step):
            chunk = imgs[s:s + step]
            x, tfs = self._prepare(chunk)
            outs = self._sess.run(None, {self._input_name: x})
            for b, (im, tf) in enumerate(zip(chunk, tfs)):
                out.append(self._postprocess(outs, b, tf, im.shape[:2]))
        return out

    def __repr__(self) -> str:
        return f"OnnxDetector({str(self.model_path)!r}, layout={self.layout!r}, classes={self.classes})"


def from_spec(path: str | None, options: Mapping[str, object]) -> OnnxDetector:
    """Build an :class:`OnnxDetector` from a spec ``onnx:FILE?classes=MAP&score=0.3...``.

    Options: ``classes`` (file), ``layout``, ``score``, ``iou``, ``input_size``,
    ``resize``, ``input_range``, ``box_order``, ``normalized_boxes``,
    ``logits``, ``threads``, ``max_detections``.
    """
    if not path:
        raise ValueError("onnx detector: expected a model file, as in 'onnx:model.onnx'")
    o = Options(options, _OPTIONS, "onnx")
    classes = options.get("classes")
    if classes is not None and not isinstance(classes, (list, tuple, dict)):
        classes = o.get_path("classes")
    return OnnxDetector(
        path, classes,  # type: ignore[arg-type]
        layout=o.get_choice("layout", "auto", ("auto", "yolo", "ssd")) or "auto",
        score_threshold=o.get_float("score", 0.25), iou_threshold=o.get_float("iou", 0.45),
        input_size=o.get_int("input_size", None, lo=8),
        resize=o.get_choice("resize", None, ("letterbox", "stretch")),
        input_range=o.get_choice("input_range", "unit", ("unit", "symmetric", "byte")) or "unit",
        box_order=o.get_choice("box_order", "yxyx", ("yxyx", "xyxy")) or "yxyx",
        normalized_boxes=None if options.get("normalized_boxes") is None else o.get_bool("normalized_boxes", False),
        logits=o.get_bool("logits", False), num_threads=o.get_int("threads", 2) or 2,
        max_detections=o.get_int("max_detections", 100) or 100)
