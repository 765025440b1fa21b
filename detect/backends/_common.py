"""Shared pieces of the detector backends: errors, class names, options, image preparation.

Class names (CONVENTIONS.md, "Objects and models") are lowercase words. A
backend's own names (Open Images "Computer monitor", COCO "dining table",
"couch", "potted plant", ...) are mapped to the toolkit's classes by
:data:`ALIASES`; a name without an alias keeps its own name, lowercased,
with spaces and dashes turned into ``_`` ("Computer mouse" -> ``computer_mouse``).
Placeholders for "no class" (``???``, ``background``, ``-``, ``n/a``, empty)
map to ``None`` and their detections are dropped.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..detection import check_label

__all__ = [
    "ModelFileError",
    "KNOWN_CLASSES",
    "ALIASES",
    "canonical_label",
    "load_class_map",
    "Options",
    "resize_rgb",
]

#: The toolkit's object classes (CONVENTIONS.md).
KNOWN_CLASSES: tuple[str, ...] = ("bed", "chair", "tv", "plant", "sofa", "table", "nightstand", "wardrobe")

#: Names used by common detection datasets (lowercased, single spaces) -> toolkit class.
ALIASES: dict[str, str] = {
    "bed": "bed", "beds": "bed", "infant bed": "bed",
    "chair": "chair", "chairs": "chair", "office chair": "chair", "armchair": "chair", "stool": "chair",
    "tv": "tv", "television": "tv", "tvmonitor": "tv", "tv monitor": "tv", "monitor": "tv",
    "computer monitor": "tv",
    "plant": "plant", "houseplant": "plant", "potted plant": "plant", "pottedplant": "plant",
    "flowerpot": "plant",
    "sofa": "sofa", "couch": "sofa", "sofa bed": "sofa", "studio couch": "sofa",
    "table": "table", "desk": "table", "dining table": "table", "diningtable": "table", "coffee table": "table",
    "kitchen & dining room table": "table",
    "nightstand": "nightstand", "night stand": "nightstand", "bedside table": "nightstand",
    "wardrobe": "wardrobe", "closet": "wardrobe", "cupboard": "wardrobe",
}

_DROP = {"", "???", "-", "background", "__background__", "n/a", "none"}


class ModelFileError(ValueError):
    """A model, class-mapping or annotation file is missing, unreadable or does not fit.

    The message names the file; ``path`` holds it.
    """

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        super().__init__(f"{path}: {problem}")


def canonical_label(name: str) -> str | None:
    """A backend's class name -> the toolkit's class name (None for "no class").

    Examples
    --------
    >>> canonical_label("Computer monitor"), canonical_label("Coffee cup"), canonical_label("???")
    ('tv', 'coffee_cup', None)
    """
    if not isinstance(name, str):
        raise ValueError(f"class name: expected a string, got {name!r}")
    key = " ".join(name.strip().lower().split())
    if key in _DROP:
        return None
    if key in ALIASES:
        return ALIASES[key]
    word = re.sub(r"[\s\-]+", "_", key)
    return check_label(word)


def _parse_map_entries(entries: Sequence[object] | Mapping[object, object], path: Path) -> dict[int, str | None]:
    out: dict[int, str | None] = {}
    items = entries.items() if isinstance(entries, Mapping) else enumerate(entries)
    for k, v in items:
        try:
            idx = int(k)  # type: ignore[call-overload]
        except (TypeError, ValueError):
            raise ModelFileError(path, f"expected integer class indices as keys, got {k!r}") from None
        if idx < 0:
            raise ModelFileError(path, f"expected non-negative class indices, got {idx}")
        if v is None:
            out[idx] = None
            continue
        try:
            out[idx] = canonical_label(v)  # type: ignore[arg-type]
        except ValueError:
            raise ModelFileError(path, f"class {idx}: expected a class name (a word like 'chair'), got {v!r}") from None
    return out


def load_class_map(path: str | Path) -> dict[int, str | None]:
    """Read a class-mapping file: model class index -> toolkit class name (None: ignore that class).

    Formats
    -------
    - ``.json``: a list of names (index = position) or an object
      ``{"0": "chair", "56": "couch", ...}``; ``null`` ignores a class.
    - any other suffix (``.txt``, ``.names``): one name per line, line k is
      class k; ``-`` or ``???`` ignores a class.

    Names go through :func:`canonical_label` (``couch`` -> ``sofa``).

    Raises
    ------
    ModelFileError
        Missing or unreadable file, or an entry that is not a class name.
    """
    p = Path(path)
    if not p.is_file():
        raise ModelFileError(p, "class-mapping file not found")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(p, f"cannot read the class-mapping file ({exc})") from None
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ModelFileError(p, f"invalid JSON in the class-mapping file ({exc})") from None
        if not isinstance(data, (list, dict)):
            raise ModelFileError(p, f"expected a JSON list or object of class names, got {type(data).__name__}")
        out = _parse_map_entries(data, p)
    else:
        lines = text.splitlines()
        while lines and not lines[-1].strip():
            lines.pop()
        out = _parse_map_entries([ln.strip() for ln in lines], p)
    if not any(v is not None for v in out.values()):
        raise ModelFileError(p, "expected at least one class name in the class-mapping file, got none")
    return out


class Options:
    """Backend options from a spec string (all str) or keyword arguments (typed), checked by name.

    Examples
    --------
    >>> o = Options({"score": "0.3"}, allowed=("score", "threads"), where="onnx")
    >>> o.get_float("score", 0.25), o.get_int("threads", 2)
    (0.3, 2)
    """

    def __init__(self, options: Mapping[str, object], allowed: Sequence[str], where: str) -> None:
        unknown = sorted(set(options) - set(allowed))
        if unknown:
            raise ValueError(f"{where} detector: unknown option(s) {unknown}; expected some of {sorted(allowed)}")
        self._o = dict(options)
        self._where = where

    def _get(self, key: str) -> object:
        return self._o.get(key)

    def get_float(self, key: str, default: float, lo: float = 0.0, hi: float = 1.0) -> float:
        v = self._get(key)
        if v is None:
            return default
        try:
            f = float(v)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise ValueError(f"{self._where} detector: option {key}: expected a number, got {v!r}") from None
        if not lo <= f <= hi:
            raise ValueError(f"{self._where} detector: option {key}: expected a number in [{lo}, {hi}], got {v!r}")
        return f

    def get_int(self, key: str, default: int | None, lo: int = 1) -> int | None:
        v = self._get(key)
        if v is None:
            return default
        try:
            i = int(v)  # type: ignore[call-overload]
        except (TypeError, ValueError):
            raise ValueError(f"{self._where} detector: option {key}: expected an integer, got {v!r}") from None
        if i < lo:
            raise ValueError(f"{self._where} detector: option {key}: expected an integer >= {lo}, got {v!r}")
        return i

    def get_bool(self, key: str, default: bool) -> bool:
        v = self._get(key)
        if v is None:
            return default
        if isinstance(v, bool):
            return v
        s = str(v).lower()
        if s in ("1", "true", "yes", "on"):
            return True
        if s in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"{self._where} detector: option {key}: expected true or false, got {v!r}")

    def get_choice(self, key: str, default: str | None, choices: Sequence[str]) -> str | None:
        v = self._get(key)
        if v is None:
            return default
        if v not in choices:
            raise ValueError(f"{self._where} detector: option {key}: expected one of {list(choices)}, got {v!r}")
        return str(v)

    def get_path(self, key: str) -> Path | None:
        v = self._get(key)
        return None if v is None else Path(str(v))


def resize_rgb(image: NDArray[np.uint8], width: int, height: int, letterbox: bool,
               fill: int = 114) -> tuple[NDArray[np.uint8], tuple[float, float, float, float]]:
    """Resize an image for a network input.

    Returns
    -------
    out : (height, width, 3) uint8
    transform : (sx, sy, px, py)
        Network pixel = image pixel * (sx, sy) + (px, py).
    """
    import cv2

    h, w = image.shape[:2]
    if not letterbox:
        out = cv2.resize(image, (width, height), interpolation=cv2.INTER_LINEAR)
        return out, (width / w, height / h, 0.0, 0.0)
    r = min(width / w, height / h)
    nw, nh = max(1, int(round(w * r))), max(1, int(round(h * r)))
    px, py = (width - nw) // 2, (height - nh) // 2
    out = np.full((height, width, 3), fill, np.uint8)
    out[py:py + nh, px:px + nw] = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_LINEAR)
    return out, (nw / w, nh / h, float(px), float(py))
