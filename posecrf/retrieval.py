"""k-nearest-neighbour search among library renders in HOG space, model retrieval and E_o.

The paper (Sec. 3.2) compares the HOG descriptor of an object crop with the
descriptors of renders of every 3D model of the detected class at every pose:
the K = 6 nearest renders vote for poses (the pose CRF's unary term,
:mod:`posecrf.pose`), the nearest render names the retrieved model, and the
object-orientation cost E_o of a candidate pose is the Euclidean distance
between the crop's descriptor and the descriptor of that render.

Search is brute force with batched matrix products (``|a - b|^2 = |a|^2 +
|b|^2 - 2 a.b``): a class holds at most a few thousand renders, so this is
exact and fast; no scikit-learn is needed.

Convention: crops are square images prepared by :func:`prepare_crops` the
same way as the renders (:func:`posecrf.render.crop_square`); pose labels are
in C order over the grid's ``(n_yaw, n_pitch)``; a render's row in a
:class:`RenderIndex` is ``model_index * L + label``.

Examples
--------
>>> import tempfile
>>> from posecrf.library import builtin_library
>>> from posecrf.cache import library_renders
>>> from posecrf.render import PoseGrid, RenderSettings, render_poses
>>> grid, st = PoseGrid(8, 1, 0.0), RenderSettings(size=32, viewport=64)
>>> lib = builtin_library().subset(["tv"])
>>> renders = library_renders(lib, grid=grid, settings=st, use_cache=False, workers=1)
>>> index = RenderIndex.from_renders(renders, "tv")
>>> crop = render_poses(lib["tv-02"], PoseGrid(8, 1, 0.0), st)
>>> q = render_descriptors(crop.images[2:3], crop.masks[2:3])
>>> nb = index.knn(q, k=3)
>>> index.model_ids[nb.model[0, 0]], int(nb.label[0, 0]), float(nb.distance[0, 0]) < 1e-3
('tv-02', 2, True)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .render import PoseGrid, RenderSettings, crop_square

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .cache import LibraryRenders

__all__ = [
    "Neighbours",
    "RenderIndex",
    "render_descriptors",
    "prepare_crops",
    "crop_descriptors",
]


def render_descriptors(images: ArrayLike, masks: ArrayLike | None = None) -> NDArray[np.float32]:
    """HOG descriptors of square crops (renders or prepared object crops).

    Parameters
    ----------
    images : (N, S, S, 3) uint8
    masks : (N, S, S) bool, optional

    Returns
    -------
    (N, D) float32
        :func:`posecrf.hog.hog_descriptors` (4 x 4 cells, unsigned gradients,
        l2-normalised).
    """
    from .hog import hog_descriptors

    imgs = np.asarray(images)
    if imgs.ndim != 4 or imgs.shape[3] != 3 or imgs.dtype != np.uint8:
        raise ValueError(f"images: expected (N, S, S, 3) uint8, got shape {imgs.shape} dtype {imgs.dtype}")
    return np.ascontiguousarray(hog_descriptors(imgs, masks), dtype=np.float32)


def prepare_crops(
    crops: Sequence[ArrayLike],
    masks: Sequence[ArrayLike | None] | None = None,
    settings: RenderSettings | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_] | None]:
    """Object crops resized into the library renders' square format.

    With a mask, a crop is cut again to the mask's bounding box (plus the
    settings' margin) and the background is painted the renders' neutral
    colour; without one, the whole crop is resized as it is.

    Parameters
    ----------
    crops : sequence of (H_i, W_i, 3) uint8
        One perspective crop per object (the detection box).
    masks : sequence of (H_i, W_i) bool or None, optional
        Object segmentation per crop (e.g. grab-cut), None where there is none.
    settings : RenderSettings, optional
        Uses ``size``, ``margin`` and ``background``.

    Returns
    -------
    images : (N, S, S, 3) uint8
    masks : (N, S, S) bool or None
        None when no crop had a mask.
    """
    s = settings if settings is not None else RenderSettings()
    n = len(crops)
    if n == 0:
        raise ValueError("crops: expected at least one crop, got 0")
    ms: list[ArrayLike | None] = [None] * n if masks is None else list(masks)
    if len(ms) != n:
        raise ValueError(f"masks: expected one mask (or None) per crop, {n} crops, got {len(ms)} masks")
    out = np.empty((n, s.size, s.size, 3), dtype=np.uint8)
    out_m = np.ones((n, s.size, s.size), dtype=bool)
    for i, (c, m) in enumerate(zip(crops, ms)):
        img = np.asarray(c)
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise ValueError(f"crops[{i}]: expected an (H, W, 3) uint8 image, got shape {img.shape} dtype {img.dtype}")
        if m is None:
            out[i], out_m[i] = crop_square(img, None, s.size, 0.0)
        else:
            out[i], out_m[i] = crop_square(img, m, s.size, s.margin, background=s.background)
    return out, (out_m if any(m is not None for m in ms) else None)


def crop_descriptors(
    crops: Sequence[ArrayLike],
    masks: Sequence[ArrayLike | None] | None = None,
    settings: RenderSettings | None = None,
) -> NDArray[np.float32]:
    """(N, D) float32 HOG descriptors of object crops, prepared like the renders (:func:`prepare_crops`)."""
    images, ms = prepare_crops(crops, masks, settings)
    return render_descriptors(images, ms)


@dataclass(frozen=True, eq=False)
class Neighbours:
    """The K nearest renders of each query.

    Attributes
    ----------
    distance : (Q, K) float
        Euclidean descriptor distances, ascending per row.
    row : (Q, K) int
        Render rows in the index.
    model : (Q, K) int
        Model index (into ``RenderIndex.model_ids``).
    label : (Q, K) int
        Pose label of the render.
    """

    distance: NDArray[np.float64]
    row: NDArray[np.int64]
    model: NDArray[np.int64]
    label: NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class RenderIndex:
    """All renders of one class, ready for k-NN queries.

    Build with :meth:`from_renders`. Rows are ``model_index * L + label``.

    Attributes
    ----------
    cls : str
    grid : PoseGrid
    model_ids : tuple of str
    symmetries : tuple of str
        Per model: "none", "two" or "full".
    descriptors : (M * L, D) float32
    """

    cls: str
    grid: PoseGrid
    model_ids: tuple[str, ...]
    symmetries: tuple[str, ...]
    descriptors: NDArray[np.float32] = field(repr=False)
    _sq: NDArray[np.float64] = field(repr=False, init=False)

    def __post_init__(self) -> None:
        d = np.asarray(self.descriptors, dtype=np.float32)
        n_models = len(self.model_ids)
        if n_models == 0:
            raise ValueError(f"class {self.cls!r}: expected at least one rendered model, got none")
        if d.ndim != 2 or d.shape[0] != n_models * self.grid.size:
            raise ValueError(
                f"descriptors: expected ({n_models} * {self.grid.size}, D) rows, got shape {d.shape}"
            )
        if len(self.symmetries) != n_models:
            raise ValueError(f"symmetries: expected {n_models} entries, got {len(self.symmetries)}")
        object.__setattr__(self, "descriptors", d)
        object.__setattr__(self, "_sq", np.einsum("ij,ij->i", d, d, dtype=np.float64))

    @classmethod
    def from_renders(cls, renders: "LibraryRenders", class_name: str) -> "RenderIndex":
        """The index of every rendered model of class `class_name`.

        Raises
        ------
        ValueError
            No model of that class was rendered.
        """
        ms = renders.by_class(class_name)
        if not ms:
            raise ValueError(f"class_name: expected a class with rendered models {list(renders.classes)}, got {class_name!r}")
        d = np.concatenate([m.descriptors for m in ms], axis=0)
        return cls(class_name, renders.grid, tuple(m.model_id for m in ms), tuple(m.symmetry for m in ms), d)

    @property
    def n_models(self) -> int:
        """Number of models M."""
        return len(self.model_ids)

    @property
    def n_renders(self) -> int:
        """Number of renders M * L."""
        return int(self.descriptors.shape[0])

    def _query(self, query: ArrayLike) -> NDArray[np.float64]:
        q = np.asarray(query, dtype=np.float64)
        if q.ndim == 1:
            q = q[None]
        if q.ndim != 2 or q.shape[1] != self.descriptors.shape[1] or not np.all(np.isfinite(q)):
            raise ValueError(f"query: expected finite (Q, {self.descriptors.shape[1]}) descriptors, got shape {q.shape}")
        return q

    def distances(self, query: ArrayLike) -> NDArray[np.float64]:
        """Euclidean distances from each query to every render: ``(Q, M * L) float``."""
        q = self._query(query)
        d2 = np.einsum("ij,ij->i", q, q)[:, None] + self._sq[None, :] - 2.0 * (q @ self.descriptors.T.astype(np.float64))
        return np.sqrt(np.maximum(d2, 0.0))

    def knn(self, query: ArrayLike, k: int = 6) -> Neighbours:
        """The `k` nearest renders of each query (ties broken by row order).

        Parameters
        ----------
        query : (Q, D) or (D,) float
        k : int
            1 <= k <= M * L.
        """
        if int(k) != k or not (1 <= k <= self.n_renders):
            raise ValueError(f"k: expected an integer in [1, {self.n_renders}], got {k!r}")
        d = self.distances(query)
        k = int(k)
        part = np.argpartition(d, k - 1, axis=1)[:, :k] if k < d.shape[1] else np.tile(np.arange(d.shape[1]), (len(d), 1))
        pd = np.take_along_axis(d, part, axis=1)
        order = np.lexsort((part, pd), axis=1)
        rows = np.take_along_axis(part, order, axis=1).astype(np.int64)
        L = self.grid.size
        return Neighbours(np.take_along_axis(d, rows, axis=1), rows, rows // L, rows % L)

    def nearest_model(self, query: ArrayLike) -> NDArray[np.int64]:
        """(Q,) int: model index of each query's nearest render (the paper's model retrieval)."""
        return self.knn(query, 1).model[:, 0]

    def e_o(self, query: ArrayLike) -> NDArray[np.float64]:
        """E_o of every candidate (model, pose): ``(Q, M, n_yaw, n_pitch) float``.

        The Euclidean distance between each query descriptor and the
        descriptor of the render of model m at pose (i_yaw, i_pitch).
        """
        d = self.distances(query)
        return d.reshape(d.shape[0], self.n_models, *self.grid.shape)
