"""Training tiles for the builtin detector, cut from the project's synthetic rooms.

A synthetic room folder (``pano2cad synth``) holds ``pano.png`` (RGB),
``instances.png`` (16-bit: 0 room, ``k`` = object ``k - 1`` of gt.json's
``objects``, 65535 no hit) and ``gt.json``. A training tile is a pinhole view
of the panorama (panogeom :class:`~panogeom.perspective.PinholeView`) with the
boxes of the objects it shows:

- the instance image is warped into the tile with *nearest* interpolation and
  each object's box is the tight box of its pixels there (the visible part,
  like gt.json's ``bbox_pano``; more accurate than mapping the panorama box,
  whose lon/lat rectangle is not a box in the tile);
- the same view with a 3x wider canvas (same focal direction, lower
  resolution) gives each object's box beyond the tile border, so the part of
  it the tile shows is known;
- an object is a *positive* when it covers at least ``min_pixels`` tile
  pixels, both box sides reach ``min_side`` pixels and the tile shows at least
  ``min_fraction`` of its box area (or a box side of ``big_side`` of the
  tile: a bed or wardrobe larger than the tile is still a bed);
- any other object seen in the tile (a sliver at the border, a few pixels
  behind a table) is *ignored*: the loss neither rewards nor punishes a
  detection of it.

Tiles are rendered at ``supersample`` times the network input and reduced by
area averaging, as :class:`~detect.builtin.backend.BuiltinDetector` reduces
what the panorama driver gives it.

Convention: CONVENTIONS.md. Views point by ``(yaw, pitch)`` as in panogeom
(a view at yaw ``a`` looks at ``lon = -a``); boxes are ``(u0, v0, u1, v1)`` in
tile pixels, pixel centres at integer + 0.5.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from panogeom.coords import pixel_to_lonlat, ray_to_pixel
from panogeom.perspective import PinholeView
from panogeom.sampling import EquirectSampler, Interp

from ..backends._common import KNOWN_CLASSES

__all__ = [
    "SynthRoom",
    "TileLabels",
    "LabelRules",
    "load_room",
    "load_rooms",
    "room_folders",
    "tile_labels",
    "render_tile",
    "warp",
    "random_view",
    "augment",
    "encode_targets",
    "TileSampler",
]

Array = NDArray[np.float64]
NO_HIT = 65535


@dataclass(frozen=True, eq=False)
class SynthRoom:
    """One synthetic room in memory.

    Attributes
    ----------
    name : str
        Folder name (``room-0007``).
    rgb : (H, W, 3) uint8
    instances : (H, W) uint16
        0 room, ``k`` object ``k - 1`` of ``labels``, 65535 no hit.
    labels : tuple of str
        Class of each object (gt.json order).
    boxes : (N, 4) float
        gt.json ``bbox_pano`` of each object (NaN where it is not visible).
    """

    name: str
    rgb: NDArray[np.uint8]
    instances: NDArray[np.uint16]
    labels: tuple[str, ...]
    boxes: Array


@dataclass(frozen=True, eq=False)
class TileLabels:
    """Boxes of one tile.

    Attributes
    ----------
    boxes : (N, 4) float
        Positive boxes ``(u0, v0, u1, v1)`` in tile pixels.
    classes : (N,) int
        Class index of each positive box.
    ignore_boxes : (M, 4) float
        Objects seen but too small or too cut to learn from.
    ignore_classes : (M,) int
    """

    boxes: Array
    classes: NDArray[np.int64]
    ignore_boxes: Array
    ignore_classes: NDArray[np.int64]

    def flipped(self, width: int) -> TileLabels:
        """Labels of the tile mirrored left-right (``width`` = tile width)."""
        def f(b: Array) -> Array:
            return np.stack([width - b[:, 2], b[:, 1], width - b[:, 0], b[:, 3]], 1) if len(b) else b
        return TileLabels(f(self.boxes), self.classes, f(self.ignore_boxes), self.ignore_classes)


@dataclass(frozen=True)
class LabelRules:
    """When an object seen in a tile is a positive (see the module docstring).

    Sizes are in pixels of the output tile; ``big_side`` is a fraction of its side.
    """

    min_pixels: int = 12
    min_side: float = 3.0
    min_fraction: float = 0.35
    big_side: float = 0.45


def synth_seed(root: str | Path) -> int | None:
    """The generator seed of a synthetic set (``index.json`` of ``pano2cad synth``); None if it does not say.

    The training scripts refuse seed 0, the evaluation set.
    """
    idx = Path(root) / "index.json"
    if idx.is_file():
        try:
            return int(json.loads(idx.read_text(encoding="utf-8"))["seed"])
        except (OSError, ValueError, KeyError, TypeError, json.JSONDecodeError):
            return None
    return None


def room_folders(root: str | Path) -> list[Path]:
    """Room folders (those holding a gt.json) under ``root``, sorted.

    Raises
    ------
    ValueError
        If ``root`` holds no room folder.
    """
    r = Path(root)
    found = sorted(p.parent for p in r.glob("*/gt.json"))
    if not found:
        raise ValueError(f"{r}: expected synthetic room folders (*/gt.json, from `pano2cad synth`), found none")
    return found


def load_room(folder: str | Path, width: int | None = None) -> SynthRoom:
    """Read a synthetic room folder.

    Parameters
    ----------
    folder : str or Path
    width : int, optional
        Resize the panorama (area) and instances (nearest) to this width.
    """
    import cv2

    d = Path(folder)
    gt = json.loads((d / "gt.json").read_text(encoding="utf-8"))
    bgr = cv2.imread(str(d / "pano.png"), cv2.IMREAD_COLOR)
    inst = cv2.imread(str(d / "instances.png"), cv2.IMREAD_UNCHANGED)
    if bgr is None or inst is None or inst.dtype != np.uint16 or inst.shape != bgr.shape[:2]:
        raise ValueError(f"{d}: expected pano.png (RGB) and instances.png (16-bit) of one size")
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    W0 = rgb.shape[1]
    if width is not None and int(width) != W0:
        w = int(width)
        rgb = cv2.resize(rgb, (w, w // 2), interpolation=cv2.INTER_AREA)
        inst = cv2.resize(inst, (w, w // 2), interpolation=cv2.INTER_NEAREST)
    s = rgb.shape[1] / W0
    objs = gt["objects"]
    boxes = np.array([[np.nan] * 4 if o["bbox_pano"] is None else [x * s for x in o["bbox_pano"]]
                      for o in objs], dtype=np.float64).reshape(-1, 4)
    return SynthRoom(d.name, rgb, inst, tuple(o["class"] for o in objs), boxes)


def load_rooms(root: str | Path, width: int | None = None, limit: int | None = None) -> list[SynthRoom]:
    """All rooms under ``root`` (first ``limit`` of them), see :func:`load_room`."""
    folders = room_folders(root)
    return [load_room(f, width) for f in folders[:limit]]


@lru_cache(maxsize=1100)
def _sampler(view: PinholeView, width: int, height: int, interpolation: Interp) -> EquirectSampler:
    return EquirectSampler.from_uv(ray_to_pixel(view.grid_rays(), width, height), width, height, interpolation)


def _turn(image: np.ndarray, view: PinholeView) -> tuple[np.ndarray, PinholeView]:
    """Fold a yaw of a whole number of columns into the panorama (rolled) and the view (yaw 0)."""
    W = image.shape[1]
    n = view.yaw * W / (2.0 * np.pi)
    if abs(n - round(n)) < 1e-6:
        return np.roll(image, int(round(n)) % W, axis=1), replace(view, yaw=0.0)
    return image, view


def warp(image: np.ndarray, view: PinholeView, interpolation: Interp = "linear") -> np.ndarray:
    """Render ``view`` of a panorama ``image`` (RGB, labels or ids), sampling maps cached per view.

    A yaw that is a whole number of panorama columns is done by rolling the
    panorama (the sphere turned about z), so random views that differ only in
    yaw (:func:`random_view` draws them so) share one set of maps.

    Examples
    --------
    >>> pano = np.random.default_rng(0).integers(0, 255, (32, 64, 3)).astype(np.uint8)
    >>> view = PinholeView(yaw=2 * np.pi * 5 / 64, pitch=0.1, roll=0.0, fov=1.5, width=16, height=16)
    >>> from panogeom.perspective import equirect_to_perspective
    >>> int(np.abs(warp(pano, view).astype(int) - equirect_to_perspective(pano, view)).max()) <= 1
    True
    """
    H, W = image.shape[:2]
    img, v = _turn(image, view)
    return _sampler(v, W, H, interpolation)(img)


def _boxes_by_id(ids: NDArray[np.uint16], n_objects: int) -> dict[int, tuple[Array, int]]:
    """Object index -> (tight box, pixel count) of the ids in a label image."""
    flat = ids.ravel()
    idx = np.flatnonzero((flat > 0) & (flat <= n_objects))
    out: dict[int, tuple[Array, int]] = {}
    if not len(idx):
        return out
    vals = flat[idx]
    order = np.argsort(vals, kind="stable")
    vals, idx = vals[order], idx[order]
    ys, xs = np.divmod(idx, ids.shape[1])
    starts = np.flatnonzero(np.r_[True, vals[1:] != vals[:-1]])
    ends = np.r_[starts[1:], len(vals)]
    for a, b in zip(starts, ends):
        box = [xs[a:b].min(), ys[a:b].min(), xs[a:b].max() + 1, ys[a:b].max() + 1]
        out[int(vals[a]) - 1] = (np.array(box, np.float64), int(b - a))
    return out


def tile_labels(room: SynthRoom, view: PinholeView, size: int, classes: Sequence[str] = KNOWN_CLASSES,
                rules: LabelRules = LabelRules()) -> TileLabels:
    """Positive and ignored boxes of the objects a view shows.

    Parameters
    ----------
    room : SynthRoom
    view : PinholeView
        The tile's camera (any pixel size: boxes are scaled to ``size``).
    size : int
        Side of the output tile in pixels (``view`` must be square).
    classes : sequence of str
        Class names, index = class id. Objects of other classes are ignored.
    rules : LabelRules

    Returns
    -------
    TileLabels
    """
    if view.width != view.height:
        raise ValueError(f"view: expected a square view, got {view.width}x{view.height}")
    H, W = room.instances.shape
    n = len(room.labels)
    inst, view0 = _turn(room.instances, view)
    seen = _boxes_by_id(_sampler(view0, W, H, "nearest")(inst), n)
    # The same view on a canvas with 3x the half-width tangent, at half the focal: boxes beyond the border.
    t = np.tan(0.5 * view.fov)
    fov_ext = min(2.0 * np.arctan(3.0 * t), np.deg2rad(170.0))
    ext_w = max(8, int(round(0.5 * view.width * np.tan(0.5 * fov_ext) / t)))
    ext = PinholeView(view0.yaw, view.pitch, view.roll, float(fov_ext), ext_w, ext_w)
    full = _boxes_by_id(_sampler(ext, W, H, "nearest")(inst), n)
    scale = size / view.width
    k_ext = view.focal / ext.focal
    cls_index = {c: i for i, c in enumerate(classes)}
    pos, pos_c, ign, ign_c = [], [], [], []
    for k, (box, npx) in seen.items():
        label = room.labels[k]
        if label not in cls_index:
            continue
        b = box * scale
        px = npx * scale * scale
        w, h = b[2] - b[0], b[3] - b[1]
        if k in full:
            fb = (full[k][0] - 0.5 * ext_w) * k_ext + 0.5 * view.width
            fb *= scale
            frac = (w * h) / max((fb[2] - fb[0]) * (fb[3] - fb[1]), 1e-9)
        else:
            frac = 1.0
        good = px >= rules.min_pixels and min(w, h) >= rules.min_side and (
            frac >= rules.min_fraction or max(w, h) >= rules.big_side * size)
        (pos if good else ign).append(b)
        (pos_c if good else ign_c).append(cls_index[label])
    return TileLabels(np.array(pos, np.float64).reshape(-1, 4), np.array(pos_c, np.int64),
                      np.array(ign, np.float64).reshape(-1, 4), np.array(ign_c, np.int64))


def render_tile(pano: NDArray[np.uint8], view: PinholeView, size: int, supersample: int = 2) -> NDArray[np.uint8]:
    """A ``(size, size, 3) uint8`` tile of a panorama: rendered at ``supersample * size``, reduced by area.

    The view's own pixel size is ignored (only its pointing and FOV count).

    Examples
    --------
    >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=1, height=1)
    >>> render_tile(np.zeros((64, 128, 3), np.uint8), view, 32).shape
    (32, 32, 3)
    """
    import cv2

    s = int(size) * max(1, int(supersample))
    img = warp(pano, replace(view, width=s, height=s), "linear")
    if s != size:
        img = cv2.resize(img, (int(size), int(size)), interpolation=cv2.INTER_AREA)
    return img


def random_view(rng: np.random.Generator, room: SynthRoom, size: int, aim: float = 0.6,
                fov_deg: tuple[float, float] = (55.0, 130.0), step_deg: float = 5.0,
                classes: Sequence[str] = KNOWN_CLASSES) -> PinholeView:
    """A random square view of a room for training.

    With probability ``aim`` it looks near a visible object of a class drawn
    uniformly among those present (class balance); otherwise anywhere with
    pitch in [-60, 15] degrees. The FOV is 90 degrees +- 15 half the time,
    uniform in ``fov_deg`` otherwise. Pitch and FOV are rounded to
    ``step_deg`` and yaw to whole panorama columns, so that :func:`warp`
    reuses a bounded set of sampling maps.

    Examples
    --------
    >>> room = SynthRoom("r", np.zeros((64, 128, 3), np.uint8), np.zeros((64, 128), np.uint16), (), np.zeros((0, 4)))
    >>> v = random_view(np.random.default_rng(0), room, 96)
    >>> (v.width, v.height), round(float(np.rad2deg(v.fov))) % 5, round(float(v.yaw * 128 / (2 * np.pi)), 6) % 1
    ((96, 96), 0, 0.0)
    """
    fov = rng.uniform(75.0, 105.0) if rng.random() < 0.5 else rng.uniform(*fov_deg)
    visible = [i for i, lab in enumerate(room.labels) if np.isfinite(room.boxes[i, 0]) and lab in classes]
    H, W = room.instances.shape
    if visible and rng.random() < aim:
        present = sorted({room.labels[i] for i in visible})
        cls = present[int(rng.integers(len(present)))]
        members = [j for j in visible if room.labels[j] == cls]
        i = members[int(rng.integers(len(members)))]
        u0, v0, u1, v1 = room.boxes[i]
        du = (u1 - u0) % W if u1 != u0 else W
        lon, lat = pixel_to_lonlat(np.array([u0 + 0.5 * du, 0.5 * (v0 + v1)]), W, H)
        lon += np.deg2rad(rng.uniform(-0.35, 0.35) * fov)
        pitch = float(np.clip(np.rad2deg(lat) + rng.uniform(-0.3, 0.3) * fov, -70.0, 30.0))
    else:
        lon = rng.uniform(-np.pi, np.pi)
        pitch = float(rng.uniform(-60.0, 15.0))
    q = float(step_deg)
    col = int(np.round(-lon * W / (2.0 * np.pi))) % W
    return PinholeView(yaw=float(2.0 * np.pi * col / W), pitch=float(np.deg2rad(q * round(pitch / q))), roll=0.0,
                       fov=float(np.deg2rad(q * round(fov / q))), width=int(size), height=int(size))


def augment(image: NDArray[np.uint8], rng: np.random.Generator) -> NDArray[np.uint8]:
    """Photometric augmentation: saturation, gamma, contrast, brightness, colour cast, blur, noise.

    Examples
    --------
    >>> img = np.full((8, 8, 3), 128, np.uint8)
    >>> out = augment(img, np.random.default_rng(0))
    >>> out.shape, out.dtype
    ((8, 8, 3), dtype('uint8'))
    """
    import cv2

    grey = cv2.cvtColor(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)
    sat = float(rng.uniform(0.5, 1.5))
    x = cv2.addWeighted(image, sat, grey, 1.0 - sat, 0.0)
    # gamma, contrast, brightness and a per-channel gain: one lookup table per channel
    v = np.arange(256, dtype=np.float64) / 255.0
    v = v ** rng.uniform(0.7, 1.4)
    v = (v - 0.5) * rng.uniform(0.7, 1.3) + 0.5 + rng.uniform(-0.12, 0.12)
    lut = np.clip(v[:, None] * rng.uniform(0.88, 1.12, 3)[None, :] * 255.0 + 0.5, 0, 255).astype(np.uint8)
    x = cv2.LUT(x, lut.reshape(256, 1, 3))
    if rng.random() < 0.3:
        x = cv2.GaussianBlur(x, (0, 0), float(rng.uniform(0.4, 1.2)))
    if rng.random() < 0.5:
        noise = rng.normal(0.0, 255.0 * rng.uniform(0.005, 0.04), x.shape).astype(np.float32)
        x = np.clip(x.astype(np.float32) + noise + 0.5, 0, 255).astype(np.uint8)
    return x


def encode_targets(labels: TileLabels, size: int, n_classes: int, stride: int = 4,
                   alpha: float = 0.54) -> dict[str, NDArray[np.float32]]:
    """Network targets of one tile (CenterNet style, elliptical Gaussians as in TTFNet).

    Parameters
    ----------
    labels : TileLabels
        Boxes in pixels of a ``size`` x ``size`` tile.
    size, n_classes, stride : int
    alpha : float
        Gaussian sigma = ``alpha * box side / 6`` (in cells).

    Returns
    -------
    dict of float32 arrays, ``G = size // stride``:
        ``heat (C, G, G)`` target heatmap (1 at box centres), ``heat_w (C, G, G)``
        loss weight (0 inside ignored boxes), ``box (4, G, G)`` size and offset
        targets (``log(w/stride), log(h/stride), dx, dy``) and ``box_w (G, G)``
        their weight (the Gaussian in the 3x3 cells around each centre).

    Examples
    --------
    >>> lab = TileLabels(np.array([[8.0, 8.0, 24.0, 16.0]]), np.array([1]), np.zeros((0, 4)), np.zeros(0, np.int64))
    >>> t = encode_targets(lab, 32, 2)
    >>> t["heat"].shape, float(t["heat"][1, 3, 4]), [round(float(x), 3) for x in t["box"][:, 3, 4]]
    ((2, 8, 8), 1.0, [1.386, 0.693, 0.0, 0.0])
    """
    G = size // stride
    heat = np.zeros((n_classes, G, G), np.float32)
    heat_w = np.ones((n_classes, G, G), np.float32)
    box = np.zeros((4, G, G), np.float32)
    box_w = np.zeros((G, G), np.float32)
    gy, gx = np.mgrid[0:G, 0:G].astype(np.float32)
    for b, c in zip(labels.ignore_boxes, labels.ignore_classes):
        j0, i0 = int(max(np.floor(b[0] / stride), 0)), int(max(np.floor(b[1] / stride), 0))
        j1, i1 = int(min(np.ceil(b[2] / stride), G)), int(min(np.ceil(b[3] / stride), G))
        heat_w[c, i0:i1, j0:j1] = 0.0
    order = np.argsort(-(labels.boxes[:, 2] - labels.boxes[:, 0]) * (labels.boxes[:, 3] - labels.boxes[:, 1]))
    for n in order:  # large boxes first: a small box's regression target wins where they meet
        b, c = labels.boxes[n], labels.classes[n]
        cx, cy = 0.5 * (b[0] + b[2]) / stride, 0.5 * (b[1] + b[3]) / stride
        w, h = (b[2] - b[0]) / stride, (b[3] - b[1]) / stride
        ci, cj = int(np.clip(np.floor(cy), 0, G - 1)), int(np.clip(np.floor(cx), 0, G - 1))
        sx, sy = max(alpha * w / 6.0, 0.4), max(alpha * h / 6.0, 0.4)
        g = np.exp(-0.5 * (((gx + 0.5 - cx) / sx) ** 2 + ((gy + 0.5 - cy) / sy) ** 2)).astype(np.float32)
        g[ci, cj] = 1.0
        np.maximum(heat[c], g, out=heat[c])
        heat_w[c][g > 0.01] = 1.0
        for i in range(max(ci - 1, 0), min(ci + 2, G)):
            for j in range(max(cj - 1, 0), min(cj + 2, G)):
                if g[i, j] >= box_w[i, j] and g[i, j] > 0.05:
                    box_w[i, j] = g[i, j]
                    box[:, i, j] = (np.log(max(w, 0.25)), np.log(max(h, 0.25)), cx - j, cy - i)
    return {"heat": heat, "heat_w": heat_w, "box": box, "box_w": box_w}


class TileSampler:
    """Random training tiles (with labels and targets) from a set of rooms.

    Parameters
    ----------
    rooms : sequence of SynthRoom
    size : int
        Tile side in pixels (the network input).
    seed : int
    classes : sequence of str
    augment_images : bool
        Photometric augmentation and left-right flips.
    rules : LabelRules
    """

    def __init__(self, rooms: Sequence[SynthRoom], size: int, seed: int = 0,
                 classes: Sequence[str] = KNOWN_CLASSES, augment_images: bool = True,
                 rules: LabelRules = LabelRules()) -> None:
        if not rooms:
            raise ValueError("rooms: expected at least one room, got none")
        self.rooms = list(rooms)
        self.size = int(size)
        self.classes = tuple(classes)
        self.augment_images = bool(augment_images)
        self.rules = rules
        self.rng = np.random.default_rng(seed)

    def sample(self) -> tuple[NDArray[np.uint8], TileLabels]:
        """One random tile ``(size, size, 3) uint8`` and its labels."""
        room = self.rooms[int(self.rng.integers(len(self.rooms)))]
        view = random_view(self.rng, room, self.size, classes=self.classes)
        img = render_tile(room.rgb, view, self.size)
        big = replace(view, width=2 * self.size, height=2 * self.size)
        lab = tile_labels(room, big, self.size, self.classes, self.rules)
        if self.augment_images:
            img = augment(img, self.rng)
            if self.rng.random() < 0.5:
                img = np.ascontiguousarray(img[:, ::-1])
                lab = lab.flipped(self.size)
        return img, lab

    def batch(self, n: int) -> tuple[NDArray[np.uint8], dict[str, NDArray[np.float32]], list[TileLabels]]:
        """``n`` tiles ``(n, size, size, 3) uint8``, stacked targets (see :func:`encode_targets`), labels."""
        imgs, labs = zip(*(self.sample() for _ in range(int(n))))
        targets = [encode_targets(lab, self.size, len(self.classes)) for lab in labs]
        stacked = {k: np.stack([t[k] for t in targets]) for k in targets[0]}
        return np.stack(imgs), stacked, list(labs)
