"""Detector backends, chosen by name or file: :func:`get_detector`.

A *spec* string names a backend and, where it needs one, a file, with
optional ``?key=value&...`` options::

    tflite                                   Objectron SSD (Open Images), fetched by `make models`
    tflite:/path/model.tflite?labels=L.txt   another file with the same output layout
    onnx:/path/yolov8n.onnx?classes=coco.names&score=0.3
    annotations:/path/boxes.json             known panorama boxes (pano2cad or COCO JSON)
    /path/model.onnx                         a bare file: backend from the suffix
                                             (.onnx, .tflite, .json)

Keyword arguments of :func:`get_detector` add to (and override) the spec's
options; spec options are strings, keyword options may be typed values.

Registry: each backend is an entry ``name -> "module:function"`` imported
only when asked for, so optional dependencies (onnxruntime, ai-edge-litert)
are needed only by the backend that uses them. The function is called as
``function(path_or_None, options_dict)`` and returns a
:class:`~detect.detection.Detector` or
:class:`~detect.detection.PanoramaDetector`. A new backend - the built-in
network trained on the project's synthetic renders among them - plugs in with
one :func:`register_backend` call (or one line in ``_ENTRIES``), e.g.
``register_backend("builtin", "detect.builtin:from_spec")``.

Errors: an unknown backend or option raises ``ValueError``; a missing or
unusable file raises :class:`ModelFileError` (a ``ValueError``) naming it;
a missing optional dependency raises ``ImportError`` with the pip command.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Union
from urllib.parse import parse_qsl

from ..detection import Detector, PanoramaDetector
from ._common import ALIASES, KNOWN_CLASSES, ModelFileError, canonical_label, load_class_map

__all__ = [
    "get_detector",
    "parse_spec",
    "DetectorSpec",
    "register_backend",
    "available_backends",
    "ModelFileError",
    "KNOWN_CLASSES",
    "ALIASES",
    "canonical_label",
    "load_class_map",
]

AnyDetector = Union[Detector, PanoramaDetector]
Factory = Callable[[Union[str, None], Mapping[str, object]], AnyDetector]

_ENTRIES: dict[str, str | Factory] = {
    "onnx": "detect.backends.onnx_backend:from_spec",
    "tflite": "detect.backends.tflite_backend:from_spec",
    "annotations": "detect.backends.annotations_backend:from_spec",
    "builtin": "detect.builtin.backend:from_spec",
}
_NEEDS_PATH = {"onnx", "annotations"}
_SUFFIXES = {".onnx": "onnx", ".tflite": "tflite", ".json": "annotations"}


def register_backend(name: str, factory: str | Factory, needs_path: bool = False) -> None:
    """Add (or replace) a backend.

    Parameters
    ----------
    name : str
        Spec prefix, a lowercase word.
    factory : str or callable
        ``"module:function"`` (imported on first use) or the function itself,
        called as ``factory(path_or_None, options)``.
    needs_path : bool
        The spec must name a file (``name:FILE``).
    """
    if not isinstance(name, str) or not name.isidentifier() or name != name.lower():
        raise ValueError(f"name: expected a lowercase identifier, got {name!r}")
    if isinstance(factory, str) and factory.count(":") != 1:
        raise ValueError(f"factory: expected 'module:function' or a callable, got {factory!r}")
    if not isinstance(factory, str) and not callable(factory):
        raise ValueError(f"factory: expected 'module:function' or a callable, got {type(factory).__name__}")
    _ENTRIES[name] = factory
    if needs_path:
        _NEEDS_PATH.add(name)
    else:
        _NEEDS_PATH.discard(name)


def available_backends() -> tuple[str, ...]:
    """Names of the registered backends (their optional dependencies may still be missing).

    Examples
    --------
    >>> available_backends()
    ('annotations', 'builtin', 'onnx', 'tflite')
    """
    return tuple(sorted(_ENTRIES))


@dataclass(frozen=True)
class DetectorSpec:
    """A parsed detector spec: backend name, optional file, options (strings)."""

    kind: str
    path: str | None
    options: dict[str, str] = field(default_factory=dict)


def parse_spec(spec: str) -> DetectorSpec:
    """Split a spec string into backend, file and options (see the module docstring).

    Examples
    --------
    >>> parse_spec("onnx:models/y.onnx?classes=coco.names&score=0.3")
    DetectorSpec(kind='onnx', path='models/y.onnx', options={'classes': 'coco.names', 'score': '0.3'})
    >>> parse_spec("room.json").kind
    'annotations'
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"detector spec: expected a string like 'tflite' or 'onnx:FILE', got {spec!r}")
    s = spec.strip()
    options: dict[str, str] = {}
    if "?" in s:
        head, query = s.rsplit("?", 1)
        if "=" in query:
            try:
                pairs = parse_qsl(query, keep_blank_values=False, strict_parsing=True)
            except ValueError:
                raise ValueError(f"detector spec {spec!r}: expected options as ?key=value&key=value") from None
            options = dict(pairs)
            s = head
    kind, sep, rest = s.partition(":")
    if sep and kind in _ENTRIES:
        path: str | None = rest or None
    elif not sep and s in _ENTRIES:
        kind, path = s, None
    else:
        suffix = Path(s).suffix.lower()
        if suffix not in _SUFFIXES:
            raise ValueError(f"detector spec {spec!r}: expected one of {', '.join(available_backends())} "
                             f"(as NAME or NAME:FILE) or a file ending in {', '.join(sorted(_SUFFIXES))}")
        kind, path = _SUFFIXES[suffix], s
    if kind in _NEEDS_PATH and not path:
        raise ValueError(f"detector spec {spec!r}: the {kind} backend needs a file, as in '{kind}:FILE'")
    return DetectorSpec(kind, path, options)


def _factory(kind: str) -> Factory:
    entry = _ENTRIES[kind]
    if callable(entry):
        return entry
    module, func = entry.split(":")
    return getattr(importlib.import_module(module), func)  # type: ignore[no-any-return]


def get_detector(spec: str, **options: object) -> AnyDetector:
    """Build a detector from a spec string.

    Parameters
    ----------
    spec : str
        ``"tflite"``, ``"onnx:FILE"``, ``"annotations:FILE"``, a bare file, with
        optional ``?key=value`` options (see the module docstring).
    **options
        More options for the backend (override the spec's).

    Returns
    -------
    Detector or PanoramaDetector

    Raises
    ------
    ValueError
        Unknown backend or option.
    ModelFileError
        A missing or unusable file (the message names it).
    ImportError
        The backend's optional dependency is not installed.

    Examples
    --------
    >>> get_detector("no-such-backend")
    Traceback (most recent call last):
    ...
    ValueError: detector spec 'no-such-backend': expected one of annotations, builtin, onnx, tflite (as NAME or NAME:FILE) or a file ending in .json, .onnx, .tflite
    """
    parsed = parse_spec(spec)
    merged: dict[str, object] = {**parsed.options, **options}
    return _factory(parsed.kind)(parsed.path, merged)
