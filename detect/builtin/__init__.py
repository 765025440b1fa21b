"""The ``builtin`` detector: a tiny network trained by the project on its own synthetic renders.

- :mod:`detect.builtin.model`: the network (CenterNet style: class heatmaps,
  box size and offset at stride 4) and the decoding of its outputs.
- :mod:`detect.builtin.backend`: :class:`BuiltinDetector`, a
  :class:`~detect.detection.BatchDetector` on perspective tiles, its tile set
  :func:`builtin_views`, and :func:`from_spec` for
  :func:`detect.backends.get_detector` (spec ``builtin`` or ``builtin:WEIGHTS.pt``).
- :mod:`detect.builtin.data`: training tiles cut from synthetic rooms, with
  boxes from the warped instance masks.
- :mod:`detect.builtin.train`: ``python -m detect.builtin.train --data DIR --val DIR --out DIR``.
- :mod:`detect.builtin.evaluate`: panorama-level AP per class (VOC style).

The committed weights and the record of how they were made are
``detect/builtin/weights/builtin.pt`` and ``builtin.json``. PyTorch is needed
to run or train the network (imported lazily).

Classes: ``bed``, ``chair``, ``tv``, ``plant``, ``sofa``, ``table``,
``nightstand``, ``wardrobe`` (CONVENTIONS.md).
"""

from .backend import DEFAULT_WEIGHTS, BuiltinDetector, builtin_views, from_spec, load_record, save_weights
from .model import NetConfig, build_network, decode

__all__ = [
    "BuiltinDetector",
    "builtin_views",
    "from_spec",
    "load_record",
    "save_weights",
    "DEFAULT_WEIGHTS",
    "NetConfig",
    "build_network",
    "decode",
]
