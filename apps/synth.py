"""The synthetic data engine: rooms with furniture rendered into panoramas with ground truth.

Composition only (ARCHITECTURE.md): the room template and the paper's
perturbation (:mod:`layout.rooms`), object placement under the context prior
(:mod:`layout.placement`), the furniture (:mod:`posecrf.library`) and the ray
caster and shader (:mod:`panogeom.raycast`, :mod:`panogeom.texture`).

Each room is fully determined by ``(seed, index)``: room ``i`` of a set made
with seed ``s`` is the same whether the set has 1 or 88 rooms.

Per room, :func:`write_room` writes ``pano.png`` (RGB), ``labels.png``
(surface label ids of CONVENTIONS.md), ``instances.png`` (16-bit, 0 = room,
k = object k of gt.json's list + 1), ``depth.png`` (16-bit, millimetres along
the ray, 0 = no hit) and ``gt.json`` (schema pano2cad/gt@1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SCHEMA_GT = "pano2cad/gt@1"

# Library material names -> the shader's material ids (panogeom.texture.Material).
_MATERIAL_MAP = {
    "wood": "WOOD", "fabric": "FABRIC", "metal": "METAL", "plastic": "PLASTIC", "leaf": "LEAF",
    "screen": "SCREEN", "ceramic": "PLASTIC", "soil": "CARPET", "glass": "SCREEN",
}


@dataclass(frozen=True)
class SynthRoom:
    """One generated room.

    Attributes
    ----------
    name : str
        Folder name, ``room-0007``.
    rgb : (H, W, 3) uint8
    labels : (H, W) uint8
        Surface labels (1 floor, 2 ceiling, 3/4 walls, 5 object).
    instances : (H, W) uint16
        0 room, k > 0 object k - 1 of ``gt["objects"]``, 65535 no hit.
    depth_mm : (H, W) uint16
        Distance along the ray in millimetres (0 where nothing was hit).
    gt : dict
        The pano2cad/gt@1 record.
    """

    name: str
    rgb: np.ndarray
    labels: np.ndarray
    instances: np.ndarray
    depth_mm: np.ndarray
    gt: dict


def _model_mesh(model, instance_id: int):
    """A library model as a panogeom RenderMesh in its canonical frame."""
    from panogeom.raycast import RenderMesh
    from panogeom.texture import Material

    mats = np.array([int(Material[_MATERIAL_MAP.get(m, "PLASTIC")]) for m in model.part_materials], dtype=np.int32)
    return RenderMesh(
        vertices=np.asarray(model.vertices, dtype=np.float64),
        faces=np.asarray(model.faces, dtype=np.int64),
        labels=np.full(len(model.faces), 5, np.uint8),
        instance_ids=np.full(len(model.faces), instance_id, np.int32),
        material_ids=mats[np.asarray(model.face_parts)],
        colors=np.asarray(model.face_colors)[:, :3].astype(np.float32) / 255.0,
    )


def _choose_specs(rng: np.random.Generator, library):
    from layout.placement import ObjectSpec, sample_class_counts

    counts = sample_class_counts(rng)
    specs = []
    for cls in sorted(counts):
        models = sorted(library.by_class(cls), key=lambda m: m.id)
        if not models:
            continue
        for _ in range(counts[cls]):
            m = models[int(rng.integers(len(models)))]
            specs.append(ObjectSpec(class_name=cls, size=tuple(float(s) for s in m.size), model_id=m.id,
                                    symmetric=m.symmetry == "full"))
    return specs


def make_room(index: int, seed: int = 0, width: int = 1024, library=None) -> SynthRoom:
    """Generate, place, render and annotate room ``index`` of the set made with ``seed``.

    Parameters
    ----------
    index : int
        Room number in the set (>= 0).
    seed : int
        Seed of the set.
    width : int
        Panorama width (even); height is width / 2.
    library : posecrf.library.ModelLibrary, optional
        Furniture to draw from (default: the built-in procedural library).
    """
    from layout.corners import polygon_to_corners_px
    from layout.placement import place_objects
    from layout.rooms import generate_room
    from panogeom.boxes import mask_to_pano_box
    from panogeom.raycast import pose_matrix, raycast_equirect, room_meshes, transform_mesh
    from panogeom.texture import sample_post, sample_styles, shade
    from posecrf.library import builtin_library

    if width < 16 or width % 2:
        raise ValueError(f"width: expected an even panorama width >= 16, got {width}")
    lib = library if library is not None else builtin_library()
    rng = np.random.default_rng([int(seed), int(index)])
    room = generate_room(rng)
    placement = place_objects(room, _choose_specs(rng, lib), rng).centered_on_camera()
    room = placement.room
    cam_h = float(placement.camera_height)

    meshes = [room_meshes(room.floor, room.ceiling_z)]
    for k, obj in enumerate(placement.objects):
        base = (obj.center[0], obj.center[1], obj.center[2] - obj.size[2] / 2.0)
        meshes.append(transform_mesh(_model_mesh(lib[obj.model_id], k + 1), pose_matrix(obj.yaw, base)))
    result = raycast_equirect(meshes, width, camera_position=(0.0, 0.0, cam_h))
    rgb = shade(result, meshes, materials=sample_styles(rng), rng=rng, post=sample_post(rng))

    H, W = result.labels.shape
    inst = result.instance_ids
    instances = np.where(inst < 0, 65535, inst).astype(np.uint16)
    depth = np.where(np.isfinite(result.depth), np.round(result.depth * 1000.0), 0.0)
    depth_mm = np.clip(depth, 0, 65535).astype(np.uint16)

    objects = []
    counters: dict[str, int] = {}
    for k, obj in enumerate(placement.objects):
        n = counters.get(obj.class_name, 0)
        counters[obj.class_name] = n + 1
        visible = inst == k + 1
        model = lib[obj.model_id]
        objects.append({
            "id": f"{obj.class_name}-{n}",
            "class": obj.class_name,
            "center": [round(float(c), 6) for c in obj.center],
            "size": [round(float(s), 6) for s in obj.size],
            "yaw_deg": round(math.degrees(obj.yaw) % 360.0, 6),
            "model": obj.model_id,
            "symmetry": model.symmetry,
            "bbox_pano": [round(float(b), 3) for b in mask_to_pano_box(visible)] if visible.any() else None,
            "visible_px": int(visible.sum()),
        })
    corners = polygon_to_corners_px(room.floor, room.ceiling_z, cam_h, width=W, height=H)
    gt = {
        "schema": SCHEMA_GT,
        "image": {"file": "pano.png", "width": int(W), "height": int(H)},
        "camera_height_m": round(cam_h, 6),
        "scale_known": True,
        "room": {"floor": [[round(float(x), 6), round(float(y), 6)] for x, y in room.floor],
                 "floor_z": 0.0, "ceiling_z": round(float(room.ceiling_z), 6)},
        "corners_px": [[round(float(c), 3) for c in row] for row in corners],
        "manhattan": True,
        "n_corners": int(len(room.floor)),
        "template": room.template,
        "objects": objects,
        "generator": {"seed": int(seed), "index": int(index), "renderer": result.backend},
    }
    return SynthRoom(name=f"room-{index:04d}", rgb=rgb, labels=result.labels.astype(np.uint8),
                     instances=instances, depth_mm=depth_mm, gt=gt)


def write_room(room: SynthRoom, out_dir: str | Path) -> Path:
    """Write a room's files into ``out_dir / room.name`` (each file atomically); return the folder."""
    from .atomic import write_image, write_json

    d = Path(out_dir) / room.name
    d.mkdir(parents=True, exist_ok=True)
    write_image(d / "pano.png", room.rgb)
    write_image(d / "labels.png", room.labels)
    write_image(d / "instances.png", room.instances)
    write_image(d / "depth.png", room.depth_mm)
    # gt.json last: a room folder with gt.json is complete.
    write_json(d / "gt.json", room.gt)
    return d


def room_is_complete(folder: str | Path) -> bool:
    """True when a room folder holds all its files (gt.json is written last)."""
    d = Path(folder)
    return all((d / f).is_file() for f in ("pano.png", "labels.png", "instances.png", "depth.png", "gt.json"))
