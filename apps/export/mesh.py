"""scene.glb and scene.obj: the room as meshes plus the retrieved library models at their poses.

The file holds these nodes (names as a glTF viewer lists them):

- ``floor``, ``walls``, ``ceiling``: the room, one node each with its own
  material of the same name (:data:`~apps.export.colors.FLOOR_RGB`, ...).
  ``ceiling`` may be left out (``include_ceiling=False``); when kept it is a
  separate node so a viewer can hide it to look inside. Faces point into
  the room (floor up, ceiling down, walls inwards), so a viewer that culls
  back faces shows the inside from outside. With an unknown ceiling height
  the walls and ceiling are left out (their height is unknown).
- one node per object, named by its id (``bed-0``), whose children are the
  parts of its library model (``bed-0/frame``, ``bed-0/mattress``, ...; a
  part of several colours gets one child per colour, ``bed-0/duvet/0``,
  ``bed-0/duvet/1``), or a single child ``<id>/box`` (a box of the object's
  size in its class colour) when the model id is ``None`` or not in the
  library.

Every mesh has one named material (glTF ``material.name``, OBJ ``usemtl``
with a ``.mtl`` file): ``floor``, ``walls``, ``ceiling``, the class name for
a fallback box, and ``<part material>_<rrggbb>`` (``wood_b68a58``) for model
parts, so the colours show in viewers that ignore per-vertex colours.

Convention:
    The scene is in the world frame of shared/CONVENTIONS.md (metres, z up).
    glTF's frame is y up, +z towards the viewer: with ``y_up=True`` (the
    default, for both files, so they agree) every vertex is written as
    ``(x, z, -y)`` (:data:`posecrf.library.export.Z_UP_TO_Y_UP`); the metric
    scale is kept. A model is placed by :func:`object_transform`: scaled
    from its size to the object's size (``fit_size=True``), turned by the
    object's yaw about +z, and moved so that its base centre lies at
    ``(cx, cy, cz - h/2)``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from apps.atomic import write_bytes, write_text
from layout.scene import Scene, SceneObject

from .colors import CEILING_RGB, FLOOR_RGB, WALL_RGB, class_color

if TYPE_CHECKING:  # pragma: no cover - typing only
    import trimesh

    from posecrf.library import Model3D, ModelLibrary

__all__ = ["ROOM_NODES", "object_transform", "scene_to_trimesh", "export_glb", "export_obj"]

#: Node names of the room surfaces, in the order they are added.
ROOM_NODES: tuple[str, ...] = ("floor", "walls", "ceiling")


def object_transform(obj: SceneObject, model_size: Sequence[float] | NDArray[np.float64] | None = None
                     ) -> NDArray[np.float64]:
    """(4, 4) transform from a model's canonical frame to the object's pose in the world.

    Parameters
    ----------
    obj : SceneObject
    model_size : (3,) float, optional
        Size of the model along its x, y, z; when given the model is first
        scaled per axis to ``obj.size``.

    Returns
    -------
    (4, 4) float
        ``translate(cx, cy, cz - h/2) @ rot_z(yaw) @ scale``.

    Convention: canonical model frame base-centred, z up, front +x; object
    yaw counter-clockwise about +z from +x to its front (shared/CONVENTIONS.md).

    Examples
    --------
    >>> o = SceneObject("tv-0", "tv", [2.0, 1.0, 0.5], [0.2, 1.0, 0.6], np.pi / 2)
    >>> T = object_transform(o)
    >>> (T @ [1.0, 0.0, 0.0, 1.0]).round(12).tolist()   # the front direction +x ends up along +y
    [2.0, 2.0, 0.2, 1.0]
    >>> (object_transform(o, [0.4, 1.0, 0.6]) @ [0.2, 0.0, 0.0, 1.0]).round(12).tolist()
    [2.0, 1.1, 0.2, 1.0]
    """
    from panogeom.raycast import pose_matrix

    if not isinstance(obj, SceneObject):
        raise ValueError(f"obj: expected a SceneObject, got {type(obj).__name__}")
    c = obj.center
    T = pose_matrix(obj.yaw, (c[0], c[1], c[2] - 0.5 * obj.size[2]))
    if model_size is not None:
        ms = np.asarray(model_size, dtype=np.float64)
        if ms.shape != (3,) or not np.all(np.isfinite(ms)) or np.any(ms <= 0):
            raise ValueError(f"model_size: expected 3 sizes > 0 in metres, got {model_size!r}")
        T = T @ np.diag(np.append(obj.size / ms, 1.0))
    return T


def _material(name: str, rgba: Sequence[int]) -> "trimesh.visual.material.PBRMaterial":
    from trimesh.visual.material import PBRMaterial

    rgba = [int(c) for c in rgba] + [255] * (4 - len(rgba))
    return PBRMaterial(name=name, baseColorFactor=rgba, metallicFactor=0.0, roughnessFactor=0.9)


def _model_meshes(model: "Model3D", T: NDArray[np.float64], obj_id: str,
                  materials: dict[str, "trimesh.visual.material.PBRMaterial"]
                  ) -> list[tuple[str, "trimesh.Trimesh"]]:
    """The parts of a placed model as (node name, mesh) pairs, one material per colour.

    ``materials`` caches the materials by name, so equal colours share one
    material object across models (one ``newmtl`` each in the OBJ); the
    fallback boxes keep theirs there too, under the class name.
    """
    import trimesh

    v = model.vertices @ T[:3, :3].T + T[:3, 3]
    out = []
    for pid, pname in enumerate(model.part_names):
        sel = model.face_parts == pid
        faces, colors = model.faces[sel], model.face_colors[sel]
        uniq, inv = np.unique(colors, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        for j, rgba in enumerate(uniq):
            used, local = np.unique(faces[inv == j], return_inverse=True)
            mat_name = f"{model.part_materials[pid]}_{bytes(rgba[:3].tolist()).hex()}"
            if mat_name not in materials:
                materials[mat_name] = _material(mat_name, rgba)
            mesh = trimesh.Trimesh(vertices=v[used], faces=local.reshape(-1, 3), process=False)
            mesh.visual = trimesh.visual.TextureVisuals(material=materials[mat_name])
            out.append((f"{obj_id}/{pname}" if len(uniq) == 1 else f"{obj_id}/{pname}/{j}", mesh))
    return out


def _surface(vertices: NDArray[np.float64], faces: NDArray[np.int64], name: str,
             rgb: tuple[int, int, int]) -> "trimesh.Trimesh":
    import trimesh

    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    mesh.visual = trimesh.visual.TextureVisuals(material=_material(name, rgb))
    mesh.metadata["name"] = name
    return mesh


def _room_surfaces(scene: Scene, include_ceiling: bool, axes: NDArray[np.float64]) -> list["trimesh.Trimesh"]:
    """Floor, walls and ceiling as meshes in the output axes (faces pointing into the room).

    The floor and ceiling are triangulated with :func:`panogeom.raycast.triangulate_polygon`;
    walls are one quad per :attr:`Scene.walls` record. (:func:`panogeom.raycast.room_meshes`
    is not used because it requires exactly axis-aligned edges, while a scene may hold a
    floor whose edges are orthogonal but turned, or rounded in JSON.)
    """
    from panogeom.raycast import triangulate_polygon

    floor = scene.floor
    n = len(floor)
    tri = triangulate_polygon(floor)  # counter-clockwise seen from above: normal +z

    def lift(xy: NDArray[np.float64], z: float) -> NDArray[np.float64]:
        return np.column_stack([xy, np.full(len(xy), z)]) @ axes.T

    out = [_surface(lift(floor, scene.floor_z), tri, "floor", FLOOR_RGB)]
    if scene.ceiling_z is None:
        return out
    starts = np.array([w.start for w in scene.walls])
    ends = np.array([w.end for w in scene.walls])
    quads = np.concatenate([lift(starts, scene.floor_z), lift(ends, scene.floor_z),
                            lift(ends, scene.ceiling_z), lift(starts, scene.ceiling_z)])
    i = np.arange(n)
    a, b, c, d = i, i + n, i + 2 * n, i + 3 * n  # start-floor, end-floor, end-top, start-top
    wall_faces = np.stack([np.column_stack([a, c, b]), np.column_stack([a, d, c])], axis=1).reshape(-1, 3)
    out.append(_surface(quads, wall_faces, "walls", WALL_RGB))
    if include_ceiling:
        out.append(_surface(lift(floor, scene.ceiling_z), tri[:, ::-1], "ceiling", CEILING_RGB))
    return out


def _default_library() -> "ModelLibrary":
    from posecrf.library import builtin_library

    return builtin_library()


def scene_to_trimesh(scene: Scene, library: "ModelLibrary | None" = None, *, include_ceiling: bool = True,
                     y_up: bool = True, fit_size: bool = True) -> "trimesh.Scene":
    """The room and its placed models as a ``trimesh.Scene`` (the content of scene.glb / scene.obj).

    Parameters
    ----------
    scene : Scene
    library : ModelLibrary, optional
        Where ``model_id`` is looked up; default the built-in library.
    include_ceiling : bool
        Add the ``ceiling`` node (default True).
    y_up : bool
        Write glTF's y-up axes ``(x, z, -y)`` (default True); False keeps z up.
    fit_size : bool
        Scale each model per axis from its own size to the object's size, so
        the model fills the box of scene.json (default True).

    Returns
    -------
    trimesh.Scene
        Nodes as in the module docstring.

    Examples
    --------
    >>> s = Scene([[-2, -1.5], [2, -1.5], [2, 1.5], [-2, 1.5]], 2.6, 1.6,
    ...           (SceneObject("lamp-0", "lamp", [1.5, 1.0, 0.8], [0.3, 0.3, 1.6], 0.0),))
    >>> sc = scene_to_trimesh(s, library=None, include_ceiling=False)
    >>> sorted(sc.graph.nodes_geometry)
    ['floor', 'lamp-0/box', 'walls']
    >>> sc.bounds.round(6).tolist()    # y up: z = -y_world
    [[-2.0, 0.0, -1.5], [2.0, 2.6, 1.5]]
    """
    import trimesh

    from posecrf.library.export import Z_UP_TO_Y_UP

    if not isinstance(scene, Scene):
        raise ValueError(f"scene: expected a layout.scene.Scene, got {type(scene).__name__}")
    clash = sorted({o.id for o in scene.objects} & set(ROOM_NODES))
    if clash:
        raise ValueError(f"objects: expected ids other than the room node names {list(ROOM_NODES)}, got {clash}")
    axes4 = Z_UP_TO_Y_UP if y_up else np.eye(4)
    out = trimesh.Scene()
    for mesh in _room_surfaces(scene, include_ceiling, axes4[:3, :3]):
        name = mesh.metadata["name"]
        out.add_geometry(mesh, geom_name=name, node_name=name)
    materials: dict[str, trimesh.visual.material.PBRMaterial] = {}
    lib = None
    if any(o.model_id is not None for o in scene.objects):
        lib = _default_library() if library is None else library
    for obj in scene.objects:
        out.graph.update(frame_to=obj.id, frame_from=out.graph.base_frame, matrix=np.eye(4))
        model = None if (obj.model_id is None or lib is None) else lib.get(obj.model_id)
        if model is None:
            box = trimesh.creation.box(extents=obj.size)
            box.apply_transform(axes4 @ object_transform(obj) @ trimesh.transformations.translation_matrix(
                [0.0, 0.0, 0.5 * obj.size[2]]))
            if obj.cls not in materials:
                materials[obj.cls] = _material(obj.cls, class_color(obj.cls))
            box.visual = trimesh.visual.TextureVisuals(material=materials[obj.cls])
            out.add_geometry(box, geom_name=f"{obj.id}/box", node_name=f"{obj.id}/box", parent_node_name=obj.id)
            continue
        T = axes4 @ object_transform(obj, model.size if fit_size else None)
        for node, mesh in _model_meshes(model, T, obj.id, materials):
            out.add_geometry(mesh, geom_name=node, node_name=node, parent_node_name=obj.id)
    return out


def export_glb(scene: Scene, path: str | os.PathLike[str], library: "ModelLibrary | None" = None, *,
               include_ceiling: bool = True, y_up: bool = True, fit_size: bool = True) -> Path:
    """Write scene.glb (binary glTF 2.0) atomically; arguments as :func:`scene_to_trimesh`.

    Returns
    -------
    Path
        The written file.
    """
    p = Path(path)
    if p.suffix.lower() != ".glb":
        raise ValueError(f"{p}: expected a .glb file name")
    data = scene_to_trimesh(scene, library, include_ceiling=include_ceiling, y_up=y_up,
                            fit_size=fit_size).export(file_type="glb")
    return write_bytes(p, data)


def export_obj(scene: Scene, path: str | os.PathLike[str], library: "ModelLibrary | None" = None, *,
               include_ceiling: bool = True, y_up: bool = True, fit_size: bool = True) -> tuple[Path, Path]:
    """Write scene.obj and its material file (same name, ``.mtl``) atomically.

    One ``o`` object per mesh node of :func:`scene_to_trimesh`, each with
    its ``usemtl`` material from the ``.mtl`` file (``mtllib`` names it
    relative to the OBJ). The material file is written first, so a
    complete OBJ never points at a missing one.

    Returns
    -------
    (Path, Path)
        The OBJ and the MTL file.
    """
    from trimesh.exchange.obj import export_obj as trimesh_export_obj

    p = Path(path)
    if p.suffix.lower() != ".obj":
        raise ValueError(f"{p}: expected a .obj file name")
    mtl = p.with_suffix(".mtl")
    tm = scene_to_trimesh(scene, library, include_ceiling=include_ceiling, y_up=y_up, fit_size=fit_size)
    text, files = trimesh_export_obj(tm, include_normals=False, include_texture=True, return_texture=True,
                                     mtl_name=mtl.name)
    write_bytes(mtl, files[mtl.name])
    write_text(p, text)
    return p, mtl
