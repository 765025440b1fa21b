"""Detector backend that reads known panorama boxes from a file (evaluation, hand labelling).

It is a :class:`~detect.detection.PanoramaDetector`: the boxes are already in
panorama pixels, so :func:`detect.tiles.detect_panorama` uses them as they
are (no tiles, no NMS). Boxes are scaled to the size of the panorama they are
asked for, so annotations made on the full-size image serve a working-size copy.

Formats (JSON):

pano2cad (``scene.json``, ``gt.json`` or a file written by hand)
    ``{"image": {"width": W, "height": H}, "objects": [{"class": "chair",
    "bbox_pano": [u0, v0, u1, v1], "score": 0.9}, ...]}``. ``score`` is
    optional (1.0); objects whose ``bbox_pano`` is null or absent are
    skipped and counted in ``skipped``. ``u0 > u1`` wraps the seam.

COCO
    ``{"images": [...], "annotations": [...], "categories": [...]}`` with
    ``bbox = [x, y, w, h]`` in pixels of the image; a box with ``x + w > W``
    wraps the seam. ``score`` is read when present (result files). When the
    file holds several images, ``image`` picks one by file name or id.

Class names go through :func:`~detect.backends._common.canonical_label`
(``couch`` -> ``sofa``). Any problem raises one
:class:`~detect.backends._common.ModelFileError` naming the file.

Convention: panorama pixels of CONVENTIONS.md (u right, v down, W == 2*H).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..detection import Detection, check_rgb_image
from ._common import ModelFileError, Options, canonical_label

__all__ = ["AnnotationDetector", "from_spec"]

_Box = tuple[str, float, list[float]]


class AnnotationDetector:
    """Panorama boxes read from a pano2cad or COCO JSON file.

    Parameters
    ----------
    path : str or Path
    image : str or int, optional
        COCO only: file name (or its base name) or id of the image to use
        when the file holds several.

    Attributes
    ----------
    width, height : int
        Size of the annotated panorama.
    skipped : int
        Objects without a box.
    classes : tuple of str

    Examples
    --------
    >>> import tempfile, os
    >>> f = os.path.join(tempfile.mkdtemp(), "boxes.json")
    >>> _ = open(f, "w").write('{"image": {"width": 1024, "height": 512}, '
    ...                        '"objects": [{"class": "Couch", "bbox_pano": [1000, 300, 30, 400]}]}')
    >>> d = AnnotationDetector(f).detections(2048, 1024)[0]
    >>> d.label, d.box.tolist(), d.wraps
    ('sofa', [2000.0, 600.0, 60.0, 800.0], True)
    """

    def __init__(self, path: str | Path, image: str | int | None = None) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise ModelFileError(self.path, "annotation file not found")
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ModelFileError(self.path, f"cannot read the annotation file as JSON ({exc})") from None
        self.skipped = 0
        if isinstance(data, dict) and "annotations" in data and "images" in data:
            self.width, self.height, self._boxes = self._coco(data, image)
        elif isinstance(data, dict) and "objects" in data:
            if image is not None:
                raise ValueError(f"image: only COCO files hold several images, {self.path} is a pano2cad file")
            self.width, self.height, self._boxes = self._pano2cad(data)
        else:
            raise ModelFileError(self.path, "expected a pano2cad file (with 'image' and 'objects') or a COCO file "
                                            "(with 'images', 'annotations', 'categories')")
        self.classes = tuple(sorted({b[0] for b in self._boxes}))

    # ------------------------------------------------------------------ parsing
    def _size(self, img: object) -> tuple[int, int]:
        if not isinstance(img, Mapping):
            raise ModelFileError(self.path, f"expected an image record with width and height, got {img!r}")
        try:
            w, h = int(img["width"]), int(img["height"])
        except (KeyError, TypeError, ValueError):
            raise ModelFileError(self.path, f"expected integer image width and height, got {dict(img)!r}") from None
        if w <= 0 or w != 2 * h:
            raise ModelFileError(self.path, f"expected an equirectangular image size with W == 2*H, got {w}x{h}")
        return w, h

    def _label(self, name: object, where: str) -> str:
        try:
            lab = canonical_label(name)  # type: ignore[arg-type]
        except ValueError:
            lab = None
        if lab is None:
            raise ModelFileError(self.path, f"{where}: expected a class name like 'chair', got {name!r}")
        return lab

    def _score(self, obj: Mapping[str, object], where: str) -> float:
        s = obj.get("score", 1.0)
        try:
            f = float(s)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            f = -1.0
        if not 0.0 <= f <= 1.0:
            raise ModelFileError(self.path, f"{where}: expected a score in [0, 1], got {s!r}")
        return f

    def _check_box(self, b: object, W: int, H: int, where: str) -> list[float]:
        try:
            box = [float(x) for x in b]  # type: ignore[union-attr]
        except (TypeError, ValueError):
            box = []
        ok = (len(box) == 4 and all(np.isfinite(box)) and 0 <= box[0] < W and 0 < box[2] <= W
              and box[0] != box[2] and 0 <= box[1] < box[3] <= H)
        if not ok:
            raise ModelFileError(self.path, f"{where}: expected a box (u0, v0, u1, v1) inside the {W}x{H} panorama "
                                            f"with v0 < v1 and u0 != u1, got {b!r}")
        return box

    def _pano2cad(self, data: Mapping[str, object]) -> tuple[int, int, list[_Box]]:
        W, H = self._size(data.get("image"))
        objs = data["objects"]
        if not isinstance(objs, list):
            raise ModelFileError(self.path, f"expected 'objects' to be a list, got {type(objs).__name__}")
        out = []
        for i, o in enumerate(objs):
            where = f"objects[{i}]"
            if not isinstance(o, Mapping):
                raise ModelFileError(self.path, f"{where}: expected an object record, got {o!r}")
            if o.get("bbox_pano") is None:
                self.skipped += 1
                continue
            out.append((self._label(o.get("class"), where), self._score(o, where),
                        self._check_box(o["bbox_pano"], W, H, where)))
        return W, H, out

    def _coco(self, data: Mapping[str, object], image: str | int | None) -> tuple[int, int, list[_Box]]:
        images, anns, cats = data.get("images"), data.get("annotations"), data.get("categories", [])
        if not isinstance(images, list) or not isinstance(anns, list) or not isinstance(cats, list) or not images:
            raise ModelFileError(self.path, "expected COCO lists 'images' (non-empty), 'annotations', 'categories'")
        if image is None:
            if len(images) != 1:
                names = [im.get("file_name") for im in images if isinstance(im, Mapping)][:10]
                raise ModelFileError(self.path, f"holds {len(images)} images; choose one with image=NAME, e.g. {names}")
            img = images[0]
        else:
            def match(im: object) -> bool:
                if not isinstance(im, Mapping):
                    return False
                fn = str(im.get("file_name", ""))
                return str(image) in (str(im.get("id")), fn, Path(fn).name)
            found = [im for im in images if match(im)]
            if len(found) != 1:
                raise ModelFileError(self.path, f"expected one image named or numbered {image!r}, found {len(found)}")
            img = found[0]
        W, H = self._size(img)
        names = {}
        for c in cats:
            if isinstance(c, Mapping) and "id" in c:
                names[c["id"]] = c.get("name")
        out = []
        for i, a in enumerate(anns):
            where = f"annotations[{i}]"
            if not isinstance(a, Mapping):
                raise ModelFileError(self.path, f"{where}: expected an annotation record, got {a!r}")
            if a.get("image_id") != img.get("id"):  # type: ignore[union-attr]
                continue
            if a.get("category_id") not in names:
                raise ModelFileError(self.path, f"{where}: category_id {a.get('category_id')!r} is not in 'categories'")
            bb = a.get("bbox")
            try:
                x, y, w, h = (float(t) for t in bb)  # type: ignore[union-attr]
            except (TypeError, ValueError):
                raise ModelFileError(self.path, f"{where}: expected bbox [x, y, w, h], got {bb!r}") from None
            if not (w > 0 and h > 0 and w <= W):
                raise ModelFileError(self.path, f"{where}: expected bbox [x, y, w, h] with 0 < w <= W and h > 0, "
                                                f"got {bb!r}")
            if w >= W:
                box = [0.0, y, float(W), y + h]
            else:
                u1 = x + w
                box = [x, y, u1 - W if u1 > W else u1, y + h]
            out.append((self._label(names[a["category_id"]], where), self._score(a, where),
                        self._check_box(box, W, H, where)))
        return W, H, out

    # ------------------------------------------------------------------ API
    def detections(self, width: int, height: int) -> list[Detection]:
        """The boxes as detections in a ``width`` x ``height`` panorama (scaled from the annotated size)."""
        if int(width) != 2 * int(height) or int(height) <= 0:
            raise ValueError(f"panorama size: expected W == 2*H > 0, got W={width}, H={height}")
        s = int(width) / self.width
        out = []
        for label, score, b in self._boxes:
            box = np.array(b) * s
            if box[2] > width or box[0] >= width:  # rounding at the right edge
                box[[0, 2]] = np.minimum(box[[0, 2]], [np.nextafter(width, 0), width])
            out.append(Detection(label, score, box, int(width), int(height)))
        return out

    def detect_panorama(self, pano: NDArray[np.uint8]) -> list[Detection]:
        """The boxes in pixels of ``pano`` ((H, W, 3) uint8, W == 2*H)."""
        img = check_rgb_image(pano, "pano")
        return self.detections(img.shape[1], img.shape[0])

    def __repr__(self) -> str:
        return f"AnnotationDetector({str(self.path)!r}, {len(self._boxes)} boxes, classes={self.classes})"


def from_spec(path: str | None, options: Mapping[str, object]) -> AnnotationDetector:
    """Build an :class:`AnnotationDetector` from ``annotations:FILE`` (option ``image`` for COCO)."""
    if not path:
        raise ValueError("annotations detector: expected a file, as in 'annotations:boxes.json'")
    Options(options, ("image",), "annotations")
    img = options.get("image")
    return AnnotationDetector(path, None if img is None else str(img))  # type: ignore[arg-type]
