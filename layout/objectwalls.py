"""Walls the objects say stand too near: an estimated wall moved out to the objects that stand beyond it.

The room step places a far wall from where the labels' ceiling boundary runs; a boundary a few rows off at 5 m puts
the wall half a metre short. The objects' initial positions come from their detection boxes and models
(:func:`layout.sampler.fit_boxes`), independently of the walls. Where several objects' footprints cross the same
estimated wall by about the same depth, they agree on where the wall really is, and the wall moves out by the least
of those depths. One object beyond a wall, or several that disagree, is more often an object placed too far (a
wrong model size or box) than a wall placed too near: those leave the wall where it is (session 41 of
docs/EVALUATION.md measured both on the tuning sets).

Not in the paper, whose layout is fixed before the objects are placed; :func:`layout.sampler.map_estimate` applies it
to the initial hypothesis in the improved scheme (``SamplerConfig.wall_move_objects``).

Convention:
    Floor polygons ``(K, 2)``, Manhattan, either orientation (the pipeline's are counter-clockwise), no repeated
    closing vertex; wall ``i`` runs from vertex ``i`` to ``i + 1``. Footprints ``(N, 4, 2)`` in the same units (e.g. from
    :func:`layout.polygon.oriented_rectangles`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .polygon import as_polygon, closest_segment, points_in_polygon, polygon_problems, wall_segments

__all__ = ["WallMove", "ObjectWalls", "move_walls_to_objects"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class WallMove:
    """One wall moved out.

    Attributes
    ----------
    wall : int
        Index of the wall in the input polygon.
    distance : float
        How far it moved, outward along its normal (polygon units).
    objects : tuple of int
        The objects whose footprints placed it (indices into the footprints).
    """

    wall: int
    distance: float
    objects: tuple[int, ...]


@dataclass(frozen=True)
class ObjectWalls:
    """Result of :func:`move_walls_to_objects`.

    Attributes
    ----------
    floor : (K, 2) float
        The polygon with the walls moved (the input's values where nothing moved; same vertex count).
    moves : tuple of WallMove
    """

    floor: FloatArray
    moves: tuple[WallMove, ...]


def move_walls_to_objects(floor: ArrayLike, footprints: ArrayLike, *, min_objects: int = 2, min_depth: float = 0.1,
                          agree: float = 0.1) -> ObjectWalls:
    """Move each wall that ``min_objects`` or more footprints cross by about the same depth out to the nearest.

    Parameters
    ----------
    floor : (K, 2) float
        Manhattan floor polygon, either orientation, no zero-length wall.
    footprints : (N, 4, 2) float
        Object rectangles seen from above, same units.
    min_objects : int
        How many objects must agree.
    min_depth : float
        An object counts for a wall when its corner farthest outside the polygon lies at least this far beyond it
        (the wall nearest that corner).
    agree : float
        The objects' depths behind one wall must lie within this of each other (the largest such group counts);
        the wall moves by the least of them, so that the nearest of those objects just touches it.

    Returns
    -------
    ObjectWalls
        A move that would make the polygon invalid (self-intersecting, not Manhattan) is not made.

    Examples
    --------
    A 4 m x 3 m room whose right wall was placed 0.5 m short; two objects stand against the true one:

    >>> room = [[0, 0], [4, 0], [4, 3], [0, 3]]
    >>> feet = [[[4.0, 0.5], [4.5, 0.5], [4.5, 1.0], [4.0, 1.0]], [[3.9, 2.0], [4.48, 2.0], [4.48, 2.4], [3.9, 2.4]]]
    >>> res = move_walls_to_objects(room, feet)
    >>> res.floor.tolist(), [(m.wall, round(m.distance, 2), m.objects) for m in res.moves]
    ([[0.0, 0.0], [4.48, 0.0], [4.48, 3.0], [0.0, 3.0]], [(1, 0.48, (0, 1))])
    """
    poly = as_polygon(floor)
    if poly.ndim != 2:
        raise ValueError(f"floor: expected one polygon (K, 2), got shape {poly.shape}")
    feet = np.asarray(footprints, dtype=np.float64)
    if feet.size == 0:
        return ObjectWalls(floor=poly.copy(), moves=())
    if feet.ndim != 3 or feet.shape[1:] != (4, 2):
        raise ValueError(f"footprints: expected shape (N, 4, 2), got {feet.shape}")
    if int(min_objects) < 1 or not (min_depth >= 0.0) or not (agree >= 0.0):
        raise ValueError(f"expected min_objects >= 1, min_depth >= 0 and agree >= 0, got {min_objects}, "
                         f"{min_depth}, {agree}")
    behind: dict[int, list[tuple[float, int]]] = {}
    outside = ~points_in_polygon(feet, poly)  # (N, 4)
    for j in np.flatnonzero(outside.any(axis=1)):
        wall, depth, _ = closest_segment(feet[j][outside[j]], poly)
        k = int(np.argmax(depth))
        if depth[k] >= min_depth:
            behind.setdefault(int(wall[k]), []).append((float(depth[k]), int(j)))
    outward = -wall_segments(poly).normal  # (K, 2); a Manhattan shift keeps every wall's direction
    out, moves = poly.copy(), []
    for wall, items in sorted(behind.items()):
        items.sort()
        d = np.array([v for v, _ in items])
        ends = np.searchsorted(d, d + agree, side="right")  # group i: items i .. ends[i] - 1
        i = int(np.argmax(ends - np.arange(len(d))))
        if ends[i] - i < int(min_objects):
            continue
        shift = float(d[i]) * outward[wall]
        cand = out.copy()
        cand[wall] += shift
        cand[(wall + 1) % len(out)] += shift
        if not polygon_problems(cand, ccw=False):  # either orientation; simple and Manhattan
            out = cand
            moves.append(WallMove(wall=wall, distance=float(d[i]),
                                  objects=tuple(sorted(j for _, j in items[i:ends[i]]))))
    return ObjectWalls(floor=out, moves=tuple(moves))
