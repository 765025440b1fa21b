"""Colours shared by every export, so a class looks the same in the GLB, the floor plan and the overlay.

- :data:`LABEL_PALETTE`: the surface-label colours of labels.png
  (shared/CONVENTIONS.md, "Surface labels").
- :func:`class_color`: one colour per object class; the classes of the
  conventions have fixed colours, any other class name gets a stable colour
  derived from its name (the same in every run and process).
- :data:`FLOOR_RGB`, :data:`WALL_RGB`, :data:`CEILING_RGB`: the room
  surfaces in scene.glb / scene.obj.

All colours are ``(r, g, b)`` uint8 in sRGB.
"""

from __future__ import annotations

import colorsys
import zlib
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "LABEL_NAMES",
    "LABEL_PALETTE",
    "CLASS_COLORS",
    "FLOOR_RGB",
    "WALL_RGB",
    "CEILING_RGB",
    "class_color",
]

#: Names of the surface labels 0..5 (shared/CONVENTIONS.md).
LABEL_NAMES: tuple[str, ...] = ("unknown", "floor", "ceiling", "wall x", "wall y", "object")

#: (6, 3) uint8: colour of surface label k in labels.png. 0 unknown/clutter
#: black, 1 floor ochre, 2 ceiling light grey, 3 wall facing +-x blue,
#: 4 wall facing +-y green, 5 object red.
LABEL_PALETTE: NDArray[np.uint8] = np.array([[0, 0, 0], [200, 140, 60], [230, 230, 230],
                                             [60, 120, 220], [60, 200, 120], [220, 60, 60]], dtype=np.uint8)
LABEL_PALETTE.setflags(write=False)

#: Fixed colours of the classes named in shared/CONVENTIONS.md (Tango palette).
CLASS_COLORS = MappingProxyType({
    "bed": (52, 101, 164),
    "chair": (245, 121, 0),
    "tv": (117, 80, 123),
    "plant": (78, 154, 6),
    "sofa": (204, 0, 0),
    "table": (143, 89, 2),
    "nightstand": (6, 152, 154),
    "wardrobe": (193, 55, 141),
})

FLOOR_RGB: tuple[int, int, int] = (150, 108, 70)
WALL_RGB: tuple[int, int, int] = (222, 218, 206)
CEILING_RGB: tuple[int, int, int] = (240, 240, 236)


def class_color(cls: str) -> tuple[int, int, int]:
    """The ``(r, g, b)`` uint8 colour of an object class.

    Classes of the conventions have fixed colours (:data:`CLASS_COLORS`);
    another name gets a saturated colour whose hue comes from the CRC-32 of
    the name, so it is the same in every process.

    Examples
    --------
    >>> class_color("bed")
    (52, 101, 164)
    >>> class_color("lamp") == class_color("lamp"), len(class_color("lamp"))
    (True, 3)
    """
    if not isinstance(cls, str) or not cls:
        raise ValueError(f"cls: expected a class name, got {cls!r}")
    if cls in CLASS_COLORS:
        return CLASS_COLORS[cls]
    hue = (zlib.crc32(cls.encode("utf-8")) % 360) / 360.0
    r, g, b = colorsys.hsv_to_rgb(hue, 0.75, 0.85)
    return (round(255 * r), round(255 * g), round(255 * b))
