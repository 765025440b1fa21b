"""Colour-coded surface labels blended on the panorama, for people to look at.

Colours (RGB) of the label ids of CONVENTIONS.md: unknown / clutter grey,
floor green, ceiling yellow, wall facing +-x red, wall facing +-y blue,
object magenta (:data:`LABEL_COLORS`). Geometric-context probabilities are
shown as the probability-weighted mix of floor green, ceiling yellow, wall
white and clutter magenta (:data:`GC_COLORS`).

Convention: images are (H, W, 3) uint8 RGB; label maps have the pixel
geometry of the panorama they are drawn on.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import rgb_pano

if TYPE_CHECKING:  # pragma: no cover
    from .fusion import SurfaceLabels

__all__ = ["LABEL_COLORS", "LABEL_NAMES", "GC_COLORS", "label_overlay", "gc_overlay", "surfaces_figure"]

#: RGB colour of each surface label id 0..5.
LABEL_COLORS = np.array([[128, 128, 128], [40, 180, 60], [235, 205, 40], [220, 50, 50], [50, 100, 230],
                         [220, 40, 220]], dtype=np.uint8)
#: Names of the surface label ids 0..5 (legend text).
LABEL_NAMES = ("unknown", "floor", "ceiling", "wall x", "wall y", "object")
#: RGB colour of each geometric-context class (floor, ceiling, wall, clutter).
GC_COLORS = np.array([[40, 180, 60], [235, 205, 40], [240, 240, 240], [220, 40, 220]], dtype=np.uint8)


def _label_image(labels: ArrayLike, shape: tuple[int, int]) -> NDArray[np.uint8]:
    lab = np.asarray(labels)
    if lab.shape != shape or lab.dtype.kind not in "ui":
        raise ValueError(f"labels: expected an integer label map of shape {shape}, got shape {lab.shape} "
                         f"dtype {lab.dtype}")
    if lab.size and (lab.min() < 0 or lab.max() >= len(LABEL_COLORS)):
        raise ValueError(f"labels: expected label ids 0..{len(LABEL_COLORS) - 1}, got "
                         f"{int(lab.min())}..{int(lab.max())}")
    return lab.astype(np.uint8, copy=False)


def label_overlay(pano: ArrayLike, labels: ArrayLike, alpha: float = 0.5, *, edges: bool = True,
                  colors: ArrayLike = LABEL_COLORS) -> NDArray[np.uint8]:
    """Blend label colours on a panorama.

    Parameters
    ----------
    pano : (H, W, 3) uint8, W == 2*H
    labels : (H, W) int
        Surface label ids 0..5.
    alpha : float
        Weight of the label colour (0: the panorama alone, 1: colours alone).
    edges : bool
        Draw the borders between labels in white (wrapping the seam).
    colors : (6, 3) uint8

    Returns
    -------
    overlay : (H, W, 3) uint8

    Examples
    --------
    >>> img = np.zeros((2, 4, 3), np.uint8)
    >>> label_overlay(img, np.full((2, 4), 1), alpha=1.0, edges=False)[0, 0].tolist()
    [40, 180, 60]
    """
    img = rgb_pano(pano)
    lab = _label_image(labels, img.shape[:2])
    if not (0.0 <= alpha <= 1.0):
        raise ValueError(f"alpha: expected a value in [0, 1], got {alpha!r}")
    pal = np.asarray(colors, dtype=np.float32)
    if pal.shape != (len(LABEL_COLORS), 3):
        raise ValueError(f"colors: expected shape ({len(LABEL_COLORS)}, 3), got {pal.shape}")
    out = (1.0 - alpha) * img.astype(np.float32) + alpha * pal[lab]
    if edges:
        diff = (lab != np.roll(lab, 1, axis=1)) | (lab != np.roll(lab, -1, axis=1))
        diff[1:] |= lab[1:] != lab[:-1]
        diff[:-1] |= lab[:-1] != lab[1:]
        out[diff] = 255.0
    return np.clip(out + 0.5, 0, 255).astype(np.uint8)


def gc_overlay(pano: ArrayLike, gc_probs: ArrayLike, alpha: float = 0.6) -> NDArray[np.uint8]:
    """Blend the geometric-context probabilities (as a colour mix) on a panorama.

    Parameters
    ----------
    pano : (H, W, 3) uint8
    gc_probs : (H, W, 4) float
        Floor, ceiling, wall, clutter probabilities.
    alpha : float

    Returns
    -------
    overlay : (H, W, 3) uint8

    Examples
    --------
    >>> p = np.zeros((2, 4, 4), np.float32); p[..., 2] = 1.0
    >>> gc_overlay(np.zeros((2, 4, 3), np.uint8), p, alpha=1.0)[0, 0].tolist()
    [240, 240, 240]
    """
    img = rgb_pano(pano)
    P = np.asarray(gc_probs, dtype=np.float32)
    if P.shape != img.shape[:2] + (4,):
        raise ValueError(f"gc_probs: expected shape {img.shape[:2] + (4,)}, got {P.shape}")
    if not (0.0 <= alpha <= 1.0):
        raise ValueError(f"alpha: expected a value in [0, 1], got {alpha!r}")
    mix = P @ GC_COLORS.astype(np.float32)
    return np.clip((1.0 - alpha) * img + alpha * mix + 0.5, 0, 255).astype(np.uint8)


def _caption(img: NDArray[np.uint8], text: str) -> None:
    import cv2

    scale = max(0.35, img.shape[0] / 700.0)
    thick = max(1, int(round(scale * 2)))
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    cv2.rectangle(img, (0, 0), (tw + 10, th + base + 8), (0, 0, 0), -1)
    cv2.putText(img, text, (5, th + 4), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), thick, cv2.LINE_AA)


def _legend(width: int, height: int) -> NDArray[np.uint8]:
    import cv2

    bar = np.full((height, width, 3), 255, np.uint8)
    n = len(LABEL_NAMES)
    scale = max(0.35, height / 45.0)
    for k, name in enumerate(LABEL_NAMES):
        x0 = int(k * width / n)
        cv2.rectangle(bar, (x0 + 4, 4), (x0 + height - 4, height - 4), tuple(int(c) for c in LABEL_COLORS[k]), -1)
        cv2.putText(bar, name, (x0 + height + 2, int(height * 0.7)), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0),
                    1, cv2.LINE_AA)
    return bar


def surfaces_figure(pano: ArrayLike, surfaces: "SurfaceLabels", truth: ArrayLike | None = None) -> NDArray[np.uint8]:
    """A stacked figure: fused labels, geometric context, orientation map, clutter-free layout (and the truth).

    Parameters
    ----------
    pano : (H, W, 3) uint8
        The panorama the labels were computed on.
    surfaces : SurfaceLabels
        Result of :func:`layout.surfaces.estimate_surfaces`.
    truth : (H, W) int, optional
        Reference labels, shown in a last panel.

    Returns
    -------
    figure : (k*H + legend, W, 3) uint8
        Captioned panels and a colour legend.
    """
    img = rgb_pano(pano)
    panels = [(label_overlay(img, surfaces.labels), "fused labels (GC + OM)"),
              (gc_overlay(img, surfaces.gc_probs), "geometric context: floor / ceiling / wall / clutter"),
              (label_overlay(img, surfaces.om, edges=False), "orientation map (line sweeps)"),
              (label_overlay(img, surfaces.layout), "clutter-free layout labels")]
    if truth is not None:
        panels.append((label_overlay(img, _label_image(truth, img.shape[:2])), "reference labels"))
    out = []
    for pic, text in panels:
        pic = np.ascontiguousarray(pic)
        _caption(pic, text)
        out.append(pic)
    out.append(_legend(img.shape[1], max(16, img.shape[0] // 16)))
    return np.concatenate(out, axis=0)
