"""overlay.png: the estimated room and objects drawn on the INPUT panorama.

Drawn with OpenCV, anti-aliased at sub-pixel precision:

- the layout: the floor-wall boundary (green), the ceiling-wall boundary
  (blue) and the vertical wall corners (yellow), each a 3D polyline
  projected with :func:`panogeom.project.world_polyline_to_pano`, which
  samples it along its great-circle arcs and splits it at the seam;
- the detection boxes ``bbox_pano`` in the class colour
  (:func:`apps.export.colors.class_color`) with the class name and score; a
  box that wraps the seam (``u0 > u1``) is drawn as two open parts;
- the objects' 3D boxes as wireframes (:func:`panogeom.project.world_box_to_pano`)
  in a lighter shade of the class colour, the front face drawn thicker.

Convention:
    ``scene.rotation`` maps input-camera directions into the world frame;
    the world geometry is projected back into the input panorama with it
    (``None``, as in ground truth, means the input is upright: identity).
    The camera centre is at ``(0, 0, floor_z + camera_height)``. Pixel
    coordinates are continuous (pixel centres at integer + 0.5,
    shared/CONVENTIONS.md); OpenCV's pixel ``i`` is centred at ``i``, so
    ``x_cv = u - 0.5``. ``bbox_pano`` is in pixels of the input panorama of
    ``scene.image_width``; it is rescaled when the image drawn on has
    another width.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from apps.atomic import write_image
from layout.scene import Scene, SceneObject

from .colors import class_color

__all__ = ["FLOOR_EDGE_RGB", "CEILING_EDGE_RGB", "CORNER_EDGE_RGB", "layout_polylines", "box_parts",
           "draw_overlay", "write_overlay"]

FLOOR_EDGE_RGB: tuple[int, int, int] = (70, 230, 70)
CEILING_EDGE_RGB: tuple[int, int, int] = (70, 150, 255)
CORNER_EDGE_RGB: tuple[int, int, int] = (255, 220, 40)

_SHIFT = 4  # cv2 fixed-point bits: coordinates in 1/16 pixel
_FRONT_EDGES = (0, 4, 8, 9)  # panogeom.project.BOX_EDGES rows of the front face (corners 0, 1, 4, 5)

Polylines = list[NDArray[np.float64]]


def _check_image(image: ArrayLike) -> NDArray[np.uint8]:
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3 or img.shape[1] != 2 * img.shape[0] \
            or img.shape[0] == 0:
        raise ValueError(f"image: expected an (H, W, 3) uint8 panorama with W == 2*H, got {img.dtype} {img.shape}")
    return img


def layout_polylines(scene: Scene, width: int, height: int, samples_per_segment: int | None = None
                     ) -> dict[str, Polylines]:
    """Pixel polylines of the room's edges in the input panorama.

    Parameters
    ----------
    scene : Scene
    width, height : int
        Panorama size, W == 2*H.
    samples_per_segment : int, optional
        Samples along each straight 3D edge (default ``max(32, W // 16)``).

    Returns
    -------
    dict
        ``"floor"``, ``"ceiling"`` and ``"corners"``: lists of (M, 2)
        continuous pixel polylines, split at the seam. ``"ceiling"`` and
        ``"corners"`` are empty when the ceiling height is unknown.

    Examples
    --------
    >>> s = Scene([[-2, -1.5], [2, -1.5], [2, 1.5], [-2, 1.5]], 2.6, 1.6)
    >>> pl = layout_polylines(s, 1024, 512)
    >>> len(pl["corners"]), bool(all(p[:, 1].max() < 512 for p in pl["floor"]))
    (4, True)
    """
    from panogeom.project import world_polyline_to_pano

    n = samples_per_segment if samples_per_segment is not None else max(32, int(width) // 16)
    cam_h = scene.floor_z + scene.camera_height
    R = scene.rotation
    floor = np.column_stack([scene.floor, np.full(len(scene.floor), scene.floor_z)])
    out: dict[str, Polylines] = {
        "floor": world_polyline_to_pano(floor, width, height, cam_h, R, n, closed=True),
        "ceiling": [],
        "corners": [],
    }
    if scene.ceiling_z is not None:
        ceiling = floor.copy()
        ceiling[:, 2] = scene.ceiling_z
        out["ceiling"] = world_polyline_to_pano(ceiling, width, height, cam_h, R, n, closed=True)
        for f, c in zip(floor, ceiling):
            out["corners"] += world_polyline_to_pano(np.stack([f, c]), width, height, cam_h, R, n)
    return out


def box_parts(bbox: ArrayLike, width: int) -> Polylines:
    """Outline of a panorama box ``(u0, v0, u1, v1)`` as pixel polylines, seam-aware.

    A box with ``u0 <= u1`` is one closed outline; one with ``u0 > u1``
    wraps the seam and becomes two open parts, ``[u0, W]`` and ``[0, u1]``,
    without a line along the seam.

    Examples
    --------
    >>> a, b = box_parts([900, 10, 100, 50], 1024)
    >>> a[:, 0].tolist(), b[:, 0].tolist()
    ([1024.0, 900.0, 900.0, 1024.0], [0.0, 100.0, 100.0, 0.0])
    """
    b = np.asarray(bbox, dtype=np.float64)
    if b.shape != (4,) or not np.all(np.isfinite(b)):
        raise ValueError(f"bbox: expected 4 finite numbers (u0, v0, u1, v1), got {bbox!r}")
    u0, v0, u1, v1 = b
    W = float(width)
    if u0 <= u1:
        return [np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1], [u0, v0]])]
    return [np.array([[W, v0], [u0, v0], [u0, v1], [W, v1]]), np.array([[0.0, v0], [u1, v0], [u1, v1], [0.0, v1]])]


def _draw(img: NDArray[np.uint8], polylines: Iterable[NDArray[np.float64]], rgb: tuple[int, int, int],
          thickness: int) -> None:
    import cv2

    pts = [np.round((p - 0.5) * (1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2) for p in polylines if len(p)]
    if pts:
        cv2.polylines(img, pts, isClosed=False, color=tuple(int(c) for c in rgb), thickness=thickness,
                      lineType=cv2.LINE_AA, shift=_SHIFT)


def _label(img: NDArray[np.uint8], text: str, u: float, v: float, rgb: tuple[int, int, int], scale: float,
           thickness: int, wraps: bool) -> None:
    """Text with a dark outline, its lower-left corner near (u, v), kept inside the image.

    A label that does not fit between ``u`` and the right edge goes to the
    left edge when the box wraps the seam (the box's other part starts
    there), else it is moved left until it fits.
    """
    import cv2

    font = cv2.FONT_HERSHEY_SIMPLEX
    (tw, th), base = cv2.getTextSize(text, font, scale, thickness)
    H, W = img.shape[:2]
    x = int(max(u, 0))
    if x + tw >= W:
        x = 0 if wraps else max(W - tw - 1, 0)
    y = int(np.clip(v - 3, th + 1, H - base - 1))
    cv2.putText(img, text, (x, y), font, scale, (0, 0, 0), thickness + 2, cv2.LINE_AA)
    cv2.putText(img, text, (x, y), font, scale, tuple(int(c) for c in rgb), thickness, cv2.LINE_AA)


def _lighter(rgb: tuple[int, int, int]) -> tuple[int, int, int]:
    return tuple(int(round(0.5 * c + 127.5)) for c in rgb)  # type: ignore[return-value]


def _wireframe(obj: SceneObject, width: int, height: int, scene: Scene, n: int) -> tuple[Polylines, Polylines]:
    """(front-face polylines, other polylines) of an object's projected 3D box."""
    from panogeom.project import world_box_to_pano

    bp = world_box_to_pano(obj.center, obj.size, obj.yaw, width, height, scene.floor_z + scene.camera_height,
                           scene.rotation, n)
    front = [pl for k in _FRONT_EDGES for pl in bp.edges[k]]
    rest = [pl for k, edge in enumerate(bp.edges) if k not in _FRONT_EDGES for pl in edge]
    return front, rest


def draw_overlay(image: ArrayLike, scene: Scene, *, layout: bool = True, boxes: bool = True,
                 wireframes: bool = True, thickness: int | None = None) -> NDArray[np.uint8]:
    """Draw the room layout, detection boxes and object wireframes on a copy of the input panorama.

    Parameters
    ----------
    image : (H, W, 3) uint8, W == 2*H
        The INPUT panorama (any resolution; geometry is projected at its size).
    scene : Scene
    layout, boxes, wireframes : bool
        What to draw (all by default).
    thickness : int, optional
        Line width in pixels (default ``max(1, W // 1024)``; front faces and
        the layout are drawn one pixel wider).

    Returns
    -------
    (H, W, 3) uint8
        A new image; ``image`` is not changed.

    Examples
    --------
    >>> s = Scene([[-2, -1.5], [2, -1.5], [2, 1.5], [-2, 1.5]], 2.6, 1.6)
    >>> out = draw_overlay(np.zeros((256, 512, 3), np.uint8), s)
    >>> out.shape, bool(out.any())
    ((256, 512, 3), True)
    """
    img = _check_image(image)
    if not isinstance(scene, Scene):
        raise ValueError(f"scene: expected a layout.scene.Scene, got {type(scene).__name__}")
    H, W = img.shape[:2]
    t = max(1, W // 1024) if thickness is None else int(thickness)
    if t < 1:
        raise ValueError(f"thickness: expected at least 1 pixel, got {thickness!r}")
    out = np.ascontiguousarray(img).copy()
    n = max(32, W // 16)
    if wireframes:
        for obj in scene.objects:
            front, rest = _wireframe(obj, W, H, scene, n)
            light = _lighter(class_color(obj.cls))
            _draw(out, rest, light, t)
            _draw(out, front, light, t + 1)
    if layout:
        lines = layout_polylines(scene, W, H, n)
        _draw(out, lines["corners"], CORNER_EDGE_RGB, t + 1)
        _draw(out, lines["ceiling"], CEILING_EDGE_RGB, t + 1)
        _draw(out, lines["floor"], FLOOR_EDGE_RGB, t + 1)
    if boxes:
        sx = 1.0 if scene.image_width is None else W / scene.image_width
        font_scale = max(0.35, 0.45 * H / 512)
        for obj in scene.objects:
            if obj.bbox_pano is None:
                continue
            b = obj.bbox_pano * sx
            color = class_color(obj.cls)
            _draw(out, box_parts(b, W), color, t)
            text = obj.cls if obj.score is None else f"{obj.cls} {obj.score:.2f}"
            _label(out, text, b[0], b[1], color, font_scale, t, wraps=bool(b[0] > b[2]))
    return out


def write_overlay(scene: Scene, image: ArrayLike, path: str | os.PathLike[str], **options: bool | int | None
                  ) -> Path:
    """Write overlay.png (:func:`draw_overlay` with ``options``) atomically and return its path."""
    if Path(path).suffix.lower() not in (".png", ".jpg", ".jpeg"):
        raise ValueError(f"{path}: expected a .png or .jpg file name")
    return write_image(path, draw_overlay(image, scene, **options))  # type: ignore[arg-type]
