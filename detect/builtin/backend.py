"""The ``builtin`` detector backend: the project's own tiny network, run with PyTorch on the CPU.

:class:`BuiltinDetector` implements :class:`~detect.detection.BatchDetector`:
``(h, w, 3) uint8`` RGB perspective tiles in, :class:`~detect.detection.ImageDetection`
boxes in tile pixels out. A tile of any size is resized to the network input
(area averaging when it is larger, as during training) and the boxes are
scaled back; all tiles of a batch go through the network in one forward pass.

The network (:mod:`detect.builtin.model`) was trained on the project's
synthetic renders (:mod:`detect.builtin.train`); the weights and the record
of how they were made ship in ``detect/builtin/weights/`` (``builtin.pt``,
``builtin.json``).

Views: :func:`builtin_views` is the tile set the detector was tuned with: the
paper's 18 views (:func:`panogeom.perspective.detection_views`) rendered at
twice the network input size plus wide views for furniture larger than a 90 degree tile
(see the record). Pass it to :func:`detect.tiles.detect_panorama`::

    det = get_detector("builtin")
    dets = detect_panorama(pano, det, views=det.views())

Spec (:func:`detect.backends.get_detector`): ``builtin`` or
``builtin:WEIGHTS.pt``, options ``score`` (minimum score, default from the
record), ``max_detections`` (per tile), ``threads`` (torch intra-op threads).

Convention: CONVENTIONS.md; boxes ``(u0, v0, u1, v1)`` in tile pixels, pixel
centres at integer + 0.5.
"""

from __future__ import annotations

import json
import pickle
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from panogeom.perspective import PinholeView, detection_views, ring_views

from ..backends._common import ModelFileError, Options
from ..detection import ImageDetection, check_rgb_image
from ..nms import box_nms
from .model import NetConfig, build_network, decode, torch_module

__all__ = ["BuiltinDetector", "from_spec", "builtin_views", "WEIGHTS_DIR", "DEFAULT_WEIGHTS",
           "save_weights", "load_record"]

#: Folder of the committed weights and their record.
WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
#: The committed weights.
DEFAULT_WEIGHTS = WEIGHTS_DIR / "builtin.pt"

_OPTIONS = ("score", "max_detections", "threads")


def builtin_views(size: int = 320, wide: bool = True, wide_fov_deg: float = 130.0,
                  wide_pitch_deg: float = -25.0, n_wide: int = 6) -> list[PinholeView]:
    """The builtin detector's tile set.

    Parameters
    ----------
    size : int
        Tile side in pixels. Twice the network input is best: the detector
        reduces tiles by area averaging, as the training tiles were made.
    wide : bool
        Add ``n_wide`` views of ``wide_fov_deg`` FOV at ``wide_pitch_deg``
        pitch to the paper's 18, so that an object wider or taller than a
        90 degree tile (a bed beside the camera, a wardrobe) is seen whole
        in at least one tile; NMS on the sphere prefers that untruncated view.

    Returns
    -------
    list of PinholeView
        ``detection_views(size)`` followed by the wide views.

    Examples
    --------
    >>> len(builtin_views(64)), len(builtin_views(64, wide=False))
    (24, 18)
    """
    views = detection_views(int(size))
    if wide:
        views += ring_views(int(n_wide), float(np.deg2rad(wide_fov_deg)), int(size),
                            pitch=float(np.deg2rad(wide_pitch_deg)))
    return views


def load_record(weights: str | Path = DEFAULT_WEIGHTS) -> dict[str, Any]:
    """The JSON record next to a weights file (``builtin.pt`` -> ``builtin.json``); ``{}`` when there is none."""
    p = Path(weights).with_suffix(".json")
    if not p.is_file():
        return {}
    try:
        return dict(json.loads(p.read_text(encoding="utf-8")))
    except (OSError, json.JSONDecodeError) as exc:
        raise ModelFileError(p, f"cannot read the weights record ({exc})") from None


#: Format tag of the builtin detector's weights file.
DETECTOR_FORMAT = "pano2cad/builtin-detector@1"


def save_network(net: Any, fmt: str, config: dict[str, Any], path: str | Path) -> Path:
    """Write a network's weights (float32 state dict), its ``config`` and format tag ``fmt`` to ``path`` (a ``.pt``
    file), atomically: the builtin detector's and the box refiner's weights files."""
    torch = torch_module()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(".pt.tmp")
    state = {k: v.detach().cpu().float() if v.is_floating_point() else v.detach().cpu()
             for k, v in net.state_dict().items()}
    torch.save({"format": fmt, "config": config, "state_dict": state}, tmp)
    tmp.replace(p)
    return p


def load_network(path: Path, what: str, fmt: str, from_json: Callable[[dict[str, Any]], Any],
                 build: Callable[[Any], Any]) -> tuple[Any, Any]:
    """Read a weights file of :func:`save_network` with format tag ``fmt``: ``(config, network)``, the config
    parsed by ``from_json`` and the network made by ``build(config)``. A missing or foreign file (another tag
    included) raises ModelFileError naming ``what``."""
    torch = torch_module()
    if not path.is_file():
        raise ModelFileError(path, f"{what} weights not found")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
        if blob.get("format") != fmt:
            raise ValueError(f"format {blob.get('format')!r}, expected {fmt!r}")
        config = from_json(blob["config"])
        net = build(config)
        net.load_state_dict(blob["state_dict"])
    except (OSError, RuntimeError, KeyError, TypeError, ValueError, pickle.UnpicklingError) as exc:
        raise ModelFileError(path, f"not {what} weights ({type(exc).__name__}: {exc})") from None
    return config, net


def save_weights(net: Any, config: NetConfig, path: str | Path) -> Path:
    """Write the detector network's weights and config to ``path`` (a ``.pt`` file), atomically."""
    return save_network(net, DETECTOR_FORMAT, config.to_json(), path)


class BuiltinDetector:
    """The project's tiny CenterNet-style detector on perspective tiles.

    Parameters
    ----------
    weights : str or Path, optional
        A ``.pt`` file written by :func:`save_weights` (default: the committed
        ``weights/builtin.pt``).
    score_threshold : float, optional
        Minimum score (default: ``score_threshold`` of the weights' record,
        tuned on the validation rooms, else 0.3).
    max_detections : int
        Per tile.
    num_threads : int, optional
        torch intra-op threads (default: leave torch's setting).
    iou_threshold : float
        Per-class NMS inside one tile.
    input_size : int, optional
        Side the tiles are resized to before the network (a multiple of 32;
        default: ``input_size`` of the weights' record, tuned on the
        validation rooms, else the training size). The network is fully
        convolutional: a larger input enlarges what it sees.
    border_snap : float
        A box edge closer to the tile border than this fraction of the tile
        side is moved onto the border. Objects cut by the tile border were
        trained with boxes ending there; snapping makes the panorama driver
        see such boxes as truncated (``TileBox.truncated``), so that NMS on
        the sphere prefers a tile that sees the object whole.
    flip : bool, optional
        Also run every tile mirrored left-right and average the two outputs
        (test-time augmentation, twice the network time; default: ``flip``
        of the weights' record, chosen on the validation rooms, else False).

    Attributes
    ----------
    classes : tuple of str
    input_size : int
    record : dict
        The weights' record (``builtin.json``), empty if there is none.

    Examples
    --------
    >>> det = BuiltinDetector()
    >>> det.classes[:4], det.input_size == det.record["input_size"]
    (('bed', 'chair', 'tv', 'plant'), True)
    >>> det.detect(np.full((160, 160, 3), 128, np.uint8))
    []
    """

    def __init__(self, weights: str | Path | None = None, *, score_threshold: float | None = None,
                 max_detections: int = 50, num_threads: int | None = None, iou_threshold: float = 0.5,
                 input_size: int | None = None, border_snap: float = 0.03, flip: bool | None = None) -> None:
        torch = torch_module()
        self.weights = Path(weights) if weights is not None else DEFAULT_WEIGHTS
        config, net = load_network(self.weights, "builtin detector", DETECTOR_FORMAT, NetConfig.from_json,
                                   build_network)
        self.record = load_record(self.weights)
        if score_threshold is None:
            score_threshold = float(self.record.get("score_threshold", 0.3))
        if not 0.0 <= float(score_threshold) <= 1.0:
            raise ValueError(f"score_threshold: expected a number in [0, 1], got {score_threshold!r}")
        if int(max_detections) < 1:
            raise ValueError(f"max_detections: expected a positive integer, got {max_detections!r}")
        self.score_threshold = float(score_threshold)
        self.max_detections = int(max_detections)
        self.iou_threshold = float(iou_threshold)
        if not 0.0 <= float(border_snap) < 0.5:
            raise ValueError(f"border_snap: expected a fraction in [0, 0.5), got {border_snap!r}")
        self.border_snap = float(border_snap)
        self.flip = bool(self.record.get("flip", False)) if flip is None else bool(flip)
        self.config = config
        self.classes: tuple[str, ...] = tuple(config.classes)
        size = int(self.record.get("input_size", config.input_size)) if input_size is None else int(input_size)
        if size < 32 or size % 32:
            raise ValueError(f"input_size: expected a multiple of 32, got {input_size!r}")
        self.input_size = size
        if num_threads is not None:
            torch.set_num_threads(int(num_threads))
        self._net = net.eval()

    def views(self) -> list[PinholeView]:
        """The tile set chosen on the validation rooms: :func:`builtin_views` of twice the input size."""
        return builtin_views(2 * self.input_size, wide=bool(self.record.get("views", {}).get("wide", True)))

    def _prepare(self, images: Sequence[np.ndarray]) -> tuple[Any, list[tuple[float, float]]]:
        import cv2

        torch = torch_module()
        S = self.input_size
        batch = np.empty((len(images), S, S, 3), np.uint8)
        scales = []
        for k, im in enumerate(images):
            img = check_rgb_image(im, f"images[{k}]")
            h, w = img.shape[:2]
            if (h, w) != (S, S):
                interp = cv2.INTER_AREA if h > S and w > S else cv2.INTER_LINEAR
                img = cv2.resize(img, (S, S), interpolation=interp)
            batch[k] = img
            scales.append((w / S, h / S))
        x = torch.from_numpy(batch).permute(0, 3, 1, 2).float().div_(255.0)
        return x, scales

    def detect_batch(self, images: Sequence[np.ndarray]) -> list[list[ImageDetection]]:
        """Detections in each of ``images`` (``(h, w, 3) uint8`` RGB), one forward pass for all."""
        torch = torch_module()
        imgs = list(images)
        if not imgs:
            return []
        x, scales = self._prepare(imgs)
        with torch.inference_mode():
            if self.flip:
                # Mirrored tiles: cell j of the mirror is cell G-1-j here, and its centre offset dx is 1 - dx.
                n = len(imgs)
                heat2, size2, off2 = self._net(torch.cat([x, x.flip(3)]))
                heat = 0.5 * (heat2[:n] + heat2[n:].flip(3))
                size = 0.5 * (size2[:n] + size2[n:].flip(3))
                mirrored = off2[n:].flip(3)
                offset = 0.5 * (off2[:n] + torch.cat([1.0 - mirrored[:, :1], mirrored[:, 1:]], 1))
            else:
                heat, size, offset = self._net(x)
        raw = decode(heat, size, offset, self.score_threshold, self.max_detections)
        out: list[list[ImageDetection]] = []
        for (sx, sy), found, img in zip(scales, raw, imgs):
            h, w = img.shape[:2]
            dets = []
            mu, mv = self.border_snap * w, self.border_snap * h
            for c, s, b in found:
                u0, v0, u1, v1 = b[0] * sx, b[1] * sy, b[2] * sx, b[3] * sy
                u0, v0 = (0.0 if u0 < mu else u0), (0.0 if v0 < mv else v0)
                u1, v1 = (float(w) if u1 > w - mu else u1), (float(h) if v1 > h - mv else v1)
                if u0 < u1 and v0 < v1:
                    dets.append(ImageDetection(self.classes[c], min(max(s, 0.0), 1.0), [u0, v0, u1, v1]))
            if len(dets) > 1:
                keep = box_nms(np.stack([d.box for d in dets]), [d.score for d in dets], self.iou_threshold,
                               labels=[d.label for d in dets])
                dets = [dets[i] for i in keep]
            out.append(dets)
        return out

    def detect(self, image: np.ndarray) -> list[ImageDetection]:
        """Detections in one ``(h, w, 3) uint8`` RGB image."""
        return self.detect_batch([image])[0]


def from_spec(path: str | None, options: Mapping[str, object]) -> BuiltinDetector:
    """Registry factory: ``builtin`` or ``builtin:WEIGHTS.pt`` with options score, max_detections, threads."""
    o = Options(options, allowed=_OPTIONS, where="builtin")
    score = o.get_float("score", 0.0) if "score" in options else None
    return BuiltinDetector(path, score_threshold=score,
                           max_detections=o.get_int("max_detections", 50) or 50,
                           num_threads=o.get_int("threads", None))
