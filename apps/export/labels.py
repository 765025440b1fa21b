"""labels.png: a colour-coded picture of a surface-label map (and, if asked, the raw ids).

Palette (:data:`apps.export.colors.LABEL_PALETTE`, shared/CONVENTIONS.md
"Surface labels"):

====  ===================  ===============
id    surface              colour (r, g, b)
====  ===================  ===============
0     unknown / clutter    (0, 0, 0) black
1     floor                (200, 140, 60)
2     ceiling              (230, 230, 230)
3     wall facing +-x      (60, 120, 220)
4     wall facing +-y      (60, 200, 120)
5     object (masked)      (220, 60, 60)
====  ===================  ===============

The raw id PNG is a single-channel 8-bit image whose pixel values are the ids
0..5 (it looks black in a viewer; read it back with PIL or OpenCV).

Convention: the label map has the pixel geometry of the INPUT panorama
(possibly at the working resolution), shape (H, W) with W == 2*H, so the
picture can be laid over the input.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from apps.atomic import write_image
from layout.labelmap import check_label_map

from .colors import LABEL_PALETTE

__all__ = ["LABEL_PALETTE", "colorize_labels", "write_labels"]


def colorize_labels(labels: ArrayLike) -> NDArray[np.uint8]:
    """Colour-code a label map with :data:`LABEL_PALETTE`.

    Parameters
    ----------
    labels : (H, W) integer, values 0..5, W == 2*H

    Returns
    -------
    (H, W, 3) uint8

    Examples
    --------
    >>> lab = np.zeros((2, 4), np.uint8); lab[1] = [1, 2, 3, 5]
    >>> colorize_labels(lab)[1].tolist()
    [[200, 140, 60], [230, 230, 230], [60, 120, 220], [220, 60, 60]]
    >>> colorize_labels(np.full((2, 4), 9))
    Traceback (most recent call last):
    ...
    ValueError: labels: expected surface labels 0..5, got values in [9, 9]
    """
    lab = check_label_map(labels)
    return LABEL_PALETTE[lab]


def write_labels(labels: ArrayLike, path: str | os.PathLike[str],
                 raw_path: str | os.PathLike[str] | None = None) -> tuple[Path, ...]:
    """Write the colour-coded label picture (and the raw ids when ``raw_path`` is given), atomically.

    Parameters
    ----------
    labels : (H, W) integer, values 0..5, W == 2*H
    path : str or PathLike
        The colour PNG, e.g. ``DIR/labels.png``.
    raw_path : str or PathLike, optional
        A single-channel PNG holding the ids themselves.

    Returns
    -------
    tuple of Path
        The files written, colour picture first.
    """
    lab = check_label_map(labels)
    for p in (path, raw_path):
        if p is not None and Path(p).suffix.lower() != ".png":
            raise ValueError(f"{p}: expected a .png file name (labels must not be compressed lossily)")
    written = [write_image(path, LABEL_PALETTE[lab])]
    if raw_path is not None:
        written.append(write_image(raw_path, np.ascontiguousarray(lab)))
    return tuple(written)
