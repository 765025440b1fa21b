"""One object detected twice: same-class objects whose initial footprints cover each other.

Two pieces of furniture never share floor (the generator's rooms allow 1 cm^2 of overlap, and a real room none).
When two detections of the same class are placed by their boxes and models onto nearly the same footprint, they are
one object the detector reported twice (two tile boxes of one plant that the panorama merge kept apart). The sampler
would otherwise push the two apart, and both end away from the object (seed-0 room-0001: a plant found twice ended 29
cm off; docs/EVALUATION.md, session 43).

:func:`same_class_duplicates` returns the detections to drop: of each pair of the same class whose footprints share
at least ``min_share`` of the smaller one's area, the one with the lower detection score (greedily, from the most
shared pair down, so that three copies leave one). Objects of different classes are never merged: a chair pushed
under a table by a wrong box is not the table.

Not in the paper; :func:`layout.sampler.map_estimate` applies it to the initial hypothesis in the improved scheme
(``SamplerConfig.duplicate_share``).

Convention:
    Positions ``(N, 2)`` in metres on the floor, yaws ``(N,)`` radians counter-clockwise from +x to the front, sizes
    ``(N, 2)`` (length along the front, width), as :func:`layout.context.pair_overlap_areas`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .context import pair_overlap_areas

__all__ = ["Duplicate", "same_class_duplicates"]


@dataclass(frozen=True)
class Duplicate:
    """One detection dropped as a copy of another.

    Attributes
    ----------
    dropped : int
        Index of the dropped object.
    kept : int
        Index of the object it copies (higher score).
    share : float
        Footprint intersection over the smaller footprint's area, in [0, 1].
    """

    dropped: int
    kept: int
    share: float


def same_class_duplicates(classes: Sequence[str], scores: Sequence[float | None], centers: ArrayLike, yaws: ArrayLike,
                          sizes: ArrayLike, min_share: float = 0.5) -> tuple[Duplicate, ...]:
    """Detections that copy a better-scored one of the same class (module docstring).

    Parameters
    ----------
    classes : sequence of N str
    scores : sequence of N float or None
        Detection scores (None counts as 0; on a tie the earlier object is kept).
    centers : (N, 2) float
    yaws : (N,) float
    sizes : (N, 2) float
        Footprints as :func:`layout.context.pair_overlap_areas`.
    min_share : float
        Smallest intersection over the smaller footprint that makes a pair one object, in (0, 1].

    Returns
    -------
    tuple of Duplicate
        Ordered by ``dropped``; empty when nothing is dropped.

    Examples
    --------
    >>> d = same_class_duplicates(["plant", "plant", "chair"], [0.5, 0.6, 0.9],
    ...                           [[0.0, 2.0], [0.05, 2.0], [0.0, 2.1]], [0.0, 0.0, 0.0], [[0.5, 0.5]] * 3)
    >>> [(x.dropped, x.kept, round(x.share, 2)) for x in d]
    [(0, 1, 0.9)]
    """
    if not 0.0 < float(min_share) <= 1.0:
        raise ValueError(f"min_share: expected a value in (0, 1], got {min_share!r}")
    c = np.asarray(centers, dtype=np.float64)
    n = len(classes)
    if len(scores) != n or c.shape != (n, 2):
        raise ValueError(f"expected {n} scores and centers of shape ({n}, 2), got {len(scores)} and {c.shape}")
    if n < 2:
        return ()
    s = np.asarray(sizes, dtype=np.float64)
    area = pair_overlap_areas(c, np.asarray(yaws, dtype=np.float64), s)
    smaller = np.minimum.outer(s.prod(axis=1), s.prod(axis=1))
    share = area / np.maximum(smaller, 1e-12)
    score = np.array([-np.inf if v is None else float(v) for v in scores])
    i, j = np.triu_indices(n, k=1)
    same = np.array([classes[a] == classes[b] for a, b in zip(i, j)], dtype=bool)
    pick = same & (share[i, j] >= min_share)
    out: dict[int, Duplicate] = {}
    for k in np.argsort(-share[i, j], kind="stable"):
        if not pick[k]:
            continue
        a, b = int(i[k]), int(j[k])
        if a in out or b in out:
            continue  # one of them already dropped: the pair is settled by the copy it made of the other
        drop, keep = (a, b) if score[a] < score[b] else (b, a)
        out[drop] = Duplicate(drop, keep, float(share[a, b]))
    return tuple(out[k] for k in sorted(out))
