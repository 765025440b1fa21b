"""HOG descriptors of object crops, the paper's variant (Sec. 3.2).

Each crop is resized to a fixed square, gradients are taken with the
centred [-1, 0, 1] filter, their orientations folded to [0, pi) (unsigned),
and magnitude-weighted votes are split linearly between the two nearest of
``bins`` orientation bins. Votes are summed in a ``cells x cells`` grid
(4 x 4 in the paper) over the whole square; the cell histograms are
concatenated cell-row by cell-row and the vector is scaled to unit l2 norm.
The Euclidean distance between two such vectors is the paper's HOG distance
(used for k-NN retrieval of model renders and as the CRF edge weight).

Convention: images are ``(h, w)`` or ``(h, w, 3)`` arrays (RGB), uint8 in
[0, 255] or float in [0, 1]; colour is reduced to luminance
``0.299 R + 0.587 G + 0.114 B``. A mask is ``(h, w)`` bool (or 0/1), True on
the object; pixels outside it are replaced by the constant ``background``
before resizing, so the silhouette becomes an edge and clutter does not.
Descriptor layout: index ``(cy * cells + cx) * bins + b`` for cell row cy,
cell column cx (image x to the right, y down) and orientation bin b, whose
centre is ``(b + 0.5) * pi / bins`` measured from the +x image axis towards +y.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["hog_descriptors", "hog_distance", "descriptor_size"]


def descriptor_size(cells: int = 4, bins: int = 9) -> int:
    """Length D of a descriptor: ``cells * cells * bins`` (144 for the defaults)."""
    return int(cells) * int(cells) * int(bins)


def _gray(img: ArrayLike, k: int) -> NDArray[np.float32]:
    a = np.asarray(img)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3) or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"images[{k}]: expected an (h, w) or (h, w, 3) image, got shape {a.shape}")
    if a.dtype == np.uint8:
        f = a.astype(np.float32) / 255.0
    elif np.issubdtype(a.dtype, np.floating):
        f = a.astype(np.float32)
        if not np.all(np.isfinite(f)):
            raise ValueError(f"images[{k}]: expected finite values, got NaN or inf")
        if f.size and (f.min() < 0.0 or f.max() > 1.0):
            raise ValueError(f"images[{k}]: expected float values in [0, 1], got [{f.min():.3g}, {f.max():.3g}]")
    else:
        raise ValueError(f"images[{k}]: expected uint8 or float pixels, got dtype {a.dtype}")
    if f.ndim == 3:
        f = f[..., 0] * np.float32(0.299) + f[..., 1] * np.float32(0.587) + f[..., 2] * np.float32(0.114)
    return np.ascontiguousarray(f, dtype=np.float32)


def hog_descriptors(
    images: Sequence[ArrayLike] | NDArray[np.generic],
    masks: Sequence[ArrayLike | None] | None = None,
    *,
    size: int = 64,
    cells: int = 4,
    bins: int = 9,
    background: float = 1.0,
) -> NDArray[np.float32]:
    """HOG descriptors of a batch of crops (any sizes), one row each.

    Parameters
    ----------
    images : sequence of (h, w) or (h, w, 3) uint8 / float
        Crops of any size; a single ``(N, h, w)`` or ``(N, h, w, 3)`` array works too.
    masks : sequence of (h, w) bool or None, optional
        Object masks; outside the mask the image is set to ``background``.
        ``None`` entries (or ``masks=None``) keep the whole crop.
    size : int
        Side of the square the crop is resized to; a multiple of ``cells``.
    cells : int
        Cells per side (the paper: 4).
    bins : int
        Unsigned orientation bins over [0, pi).
    background : float
        Gray level in [0, 1] put outside masks (1.0: white, like renders on white).

    Returns
    -------
    descriptors : (N, cells*cells*bins) float32
        Unit l2 norm; an image without any gradient gives the zero vector.

    Convention: see the module docstring (layout, unsigned orientation, luminance).

    Examples
    --------
    >>> img = np.zeros((40, 60), np.uint8); img[:, 30:] = 255   # one vertical edge
    >>> d = hog_descriptors([img])
    >>> d.shape, d.dtype, round(float(np.linalg.norm(d)), 6)
    ((1, 144), dtype('float32'), 1.0)
    >>> int(np.argmax(d[0].reshape(16, 9).sum(axis=0)))  # gradient along +x: bin 0 or 8
    0
    """
    import cv2

    if isinstance(images, np.ndarray):
        if images.ndim not in (3, 4):
            raise ValueError(
                f"images: expected a sequence of images or an (N, h, w[, 3]) array, got shape {images.shape}"
            )
        imgs: list[ArrayLike] = list(images)
    else:
        try:
            imgs = list(images)
        except TypeError as exc:
            raise ValueError(f"images: expected a sequence of images, got {type(images).__name__}") from exc
    for name, val in (("size", size), ("cells", cells), ("bins", bins)):
        if isinstance(val, bool) or int(val) != val or val < 1:
            raise ValueError(f"{name}: expected a positive integer, got {val!r}")
    size, cells, bins = int(size), int(cells), int(bins)
    if size % cells or size < 2 * cells:
        raise ValueError(f"size: expected a multiple of cells={cells} with at least 2 pixels per cell, got {size}")
    bg = float(background)
    if not 0.0 <= bg <= 1.0:
        raise ValueError(f"background: expected a gray level in [0, 1], got {background!r}")
    if masks is not None:
        masks = list(masks)
        if len(masks) != len(imgs):
            raise ValueError(f"masks: expected one mask (or None) per image ({len(imgs)}), got {len(masks)}")
    n = len(imgs)
    d = descriptor_size(cells, bins)
    if n == 0:
        return np.zeros((0, d), dtype=np.float32)

    batch = np.empty((n, size, size), dtype=np.float32)
    for k, img in enumerate(imgs):
        g = _gray(img, k)
        if masks is not None and masks[k] is not None:
            m = np.asarray(masks[k])
            if m.shape != g.shape:
                raise ValueError(f"masks[{k}]: expected shape {g.shape} (the image's), got {m.shape}")
            if m.dtype != bool:
                if not np.all((m == 0) | (m == 1)):
                    raise ValueError(f"masks[{k}]: expected a boolean or 0/1 mask, got other values")
                m = m.astype(bool)
            g = np.where(m, g, np.float32(bg))
        interp = cv2.INTER_AREA if (g.shape[0] >= size and g.shape[1] >= size) else cv2.INTER_LINEAR
        batch[k] = cv2.resize(g, (size, size), interpolation=interp)

    gx = np.zeros_like(batch)
    gy = np.zeros_like(batch)
    gx[:, :, 1:-1] = batch[:, :, 2:] - batch[:, :, :-2]
    gy[:, 1:-1, :] = batch[:, 2:, :] - batch[:, :-2, :]
    mag = np.hypot(gx, gy)
    ang = np.mod(np.arctan2(gy, gx), np.pi)  # unsigned: [0, pi)
    t = ang * (bins / np.pi) - 0.5
    b0 = np.floor(t)
    frac = (t - b0).astype(np.float32)
    b0i = b0.astype(np.int64) % bins
    b1i = (b0i + 1) % bins
    cell_px = size // cells
    cy = (np.arange(size) // cell_px)[:, None]
    cxx = (np.arange(size) // cell_px)[None, :]
    cell = (cy * cells + cxx)[None, :, :]
    base = (np.arange(n)[:, None, None] * (cells * cells) + cell) * bins
    hist = np.bincount((base + b0i).ravel(), weights=(mag * (1.0 - frac)).ravel(), minlength=n * d)
    hist += np.bincount((base + b1i).ravel(), weights=(mag * frac).ravel(), minlength=n * d)
    out = hist.reshape(n, d)
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    out = np.divide(out, norm, out=np.zeros_like(out), where=norm > 1e-12)
    return out.astype(np.float32)


def hog_distance(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Pairwise Euclidean distances between descriptors.

    Parameters
    ----------
    a : (N, D) or (D,) float
    b : (M, D) or (D,) float

    Returns
    -------
    dist : (N, M) float64
        ``dist[i, j] = ||a_i - b_j||``; a 1-D input counts as one row.

    Examples
    --------
    >>> hog_distance([[0.0, 1.0], [1.0, 0.0]], [0.0, 1.0]).round(6).tolist()
    [[0.0], [1.414214]]
    """
    from scipy.spatial.distance import cdist

    aa = np.atleast_2d(np.asarray(a, dtype=np.float64))
    bb = np.atleast_2d(np.asarray(b, dtype=np.float64))
    if aa.ndim != 2 or bb.ndim != 2 or aa.shape[1] != bb.shape[1]:
        raise ValueError(f"expected descriptors (N, D) and (M, D) with the same D, got {np.shape(a)} and {np.shape(b)}")
    if not (np.all(np.isfinite(aa)) and np.all(np.isfinite(bb))):
        raise ValueError("descriptors: expected finite values, got NaN or inf")
    out: NDArray[np.float64] = cdist(aa, bb)
    return out
