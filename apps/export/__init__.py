"""The exports of ``pano2cad run``: 3D model, floor plan, overlay and label pictures.

:func:`export_all` writes into one folder (each file atomically, through
:mod:`apps.atomic`):

==================  ==========================================================
file                content
==================  ==========================================================
``scene.glb``       room (nodes ``floor``, ``walls``, ``ceiling``) and the
                    library models at their poses; glTF y-up (:mod:`.mesh`)
``scene.obj``       the same meshes, with ``scene.mtl`` for the materials
``floorplan.png``   top view: grid, scale bar, walls with lengths, objects
``floorplan.svg``   the same drawing as vector graphics (:mod:`.floorplan`)
``overlay.png``     layout, detection boxes and 3D boxes on the input
                    panorama (:mod:`.overlay`), when the image is given
``labels.png``      colour-coded surface labels (:mod:`.labels`), when a
                    label map is given; ``label_ids.png`` holds the raw ids
==================  ==========================================================

The submodules can be used on their own; heavy libraries (trimesh,
matplotlib, OpenCV) are imported only by the functions that need them.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from numpy.typing import ArrayLike

if TYPE_CHECKING:  # pragma: no cover - typing only
    from layout.scene import Scene
    from posecrf.library import ModelLibrary

__all__ = ["EXPORT_FILES", "export_all"]

#: File names written by :func:`export_all`, by key.
EXPORT_FILES: dict[str, str] = {
    "glb": "scene.glb",
    "obj": "scene.obj",
    "mtl": "scene.mtl",
    "floorplan_png": "floorplan.png",
    "floorplan_svg": "floorplan.svg",
    "overlay": "overlay.png",
    "labels": "labels.png",
    "label_ids": "label_ids.png",
}


def export_all(scene: "Scene", out_dir: str | os.PathLike[str], *, image: ArrayLike | None = None,
               labels: ArrayLike | None = None, library: "ModelLibrary | None" = None,
               include_ceiling: bool = True) -> dict[str, Path]:
    """Write every export of a scene into ``out_dir`` (which must exist).

    Parameters
    ----------
    scene : layout.scene.Scene
    out_dir : str or PathLike
    image : (H, W, 3) uint8, optional
        The input panorama; ``overlay.png`` is written only when given.
    labels : (H, W) uint8 with values 0..5, optional
        Surface labels in the input panorama's pixel geometry; ``labels.png``
        and ``label_ids.png`` are written only when given.
    library : ModelLibrary, optional
        Where the objects' model ids are looked up (default: built-in).
    include_ceiling : bool
        Keep the ``ceiling`` node in scene.glb / scene.obj.

    Returns
    -------
    dict of str -> Path
        The files written, keyed as in :data:`EXPORT_FILES`.
    """
    from .floorplan import write_floorplan
    from .labels import write_labels
    from .mesh import export_glb, export_obj
    from .overlay import write_overlay

    d = Path(out_dir)
    if not d.is_dir():
        raise ValueError(f"{d}: expected an existing output folder")
    f = {k: d / name for k, name in EXPORT_FILES.items()}
    out: dict[str, Path] = {}
    out["glb"] = export_glb(scene, f["glb"], library, include_ceiling=include_ceiling)
    out["obj"], out["mtl"] = export_obj(scene, f["obj"], library, include_ceiling=include_ceiling)
    out["floorplan_png"], out["floorplan_svg"] = write_floorplan(scene, f["floorplan_png"], f["floorplan_svg"])
    if image is not None:
        out["overlay"] = write_overlay(scene, image, f["overlay"])
    if labels is not None:
        out["labels"], out["label_ids"] = write_labels(labels, f["labels"], f["label_ids"])
    return out
