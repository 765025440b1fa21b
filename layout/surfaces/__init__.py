"""Surface labels of upright panoramas: orientation map + geometric context, fused (paper Sec. 3.1).

- :mod:`layout.surfaces.orientation_map`: Lee et al.'s orientation map from
  line sweeps, computed on the sphere (:func:`orientation_map`).
- :mod:`layout.surfaces.gc_net`: the geometric-context network (floor /
  ceiling / wall / clutter probabilities; :func:`gc_probabilities`), with
  committed weights trained by :mod:`layout.surfaces.train_gc`.
- :mod:`layout.surfaces.fusion`: GC decides floor / ceiling / wall, the OM
  (with the shape of the floor and ceiling boundaries) decides the wall
  orientation, per column; unknown where both are unsure; objects masked
  (:func:`estimate_surfaces`).
- :mod:`layout.surfaces.boundary`: the ceiling-wall boundary moved onto the
  strongest smooth image edge near it, a Viterbi path across the columns
  (:func:`ceiling_edge_path`, :func:`move_ceiling_boundary`; optional
  step 6 of :func:`estimate_surfaces`, ``snap_ceiling=True``).
- :mod:`layout.surfaces.overlay`: colour-coded labels blended on the
  panorama (:func:`label_overlay`, :func:`surfaces_figure`).

Convention: label ids of CONVENTIONS.md ("Surface labels"): 0 unknown /
clutter, 1 floor, 2 ceiling, 3 wall facing +-x, 4 wall facing +-y, 5 object;
axes of the rectified (Manhattan-aligned) frame; the pixel geometry of the
panorama the labels are computed on.
"""

from .boundary import ceiling_edge_path, edge_strength, move_ceiling_boundary
from .fusion import ColumnLayout, SurfaceLabels, boxes_to_mask, estimate_surfaces, fuse_surfaces
from .gc_net import GC_CLASSES, GeometricContext, gc_probabilities, load_gc_net
from .orientation_map import OrientationMap, orientation_map
from .overlay import LABEL_COLORS, gc_overlay, label_overlay, surfaces_figure

__all__ = [
    "ColumnLayout",
    "GC_CLASSES",
    "GeometricContext",
    "LABEL_COLORS",
    "OrientationMap",
    "SurfaceLabels",
    "boxes_to_mask",
    "ceiling_edge_path",
    "edge_strength",
    "estimate_surfaces",
    "fuse_surfaces",
    "gc_overlay",
    "gc_probabilities",
    "label_overlay",
    "load_gc_net",
    "move_ceiling_boundary",
    "orientation_map",
    "surfaces_figure",
]
