"""Box-edge refinement: a small network that moves a tile detection's box edges onto the object's outline.

Not in the paper. The builtin detector regresses box sizes on a stride-4 grid
of its 288-pixel input, about 1.25 degrees per cell on a 90 degree tile, and
its edges are off by most of a degree (docs/EVALUATION.md, "Detector box
edges"); the box fits that fix the room's scale and the objects' depths read
those edges. The refiner looks again at each tile box, at a finer scale:

1. the box is grown by ``margin`` of its width and height on each side and
   that window of the tile's image plane is rendered from the panorama at
   ``size`` x ``size`` pixels (:func:`box_window`; rendered at twice the size
   and reduced by area, as the detector's tiles);
2. a small convolutional network (:func:`build_refiner`) reads the window and
   the detection's class and tells, for each column and each row of the
   window, whether it lies inside the object's box (LocNet's in-out
   probabilities); each edge is read off them (:func:`decode_moves`) as a
   move of the box's edge, a fraction of its width or height
   (:func:`apply_moves`);
3. this is repeated ``passes`` times on the moved box (a cascade; the
   training boxes cover the small errors of a second pass too).

Edges at the tile border (:meth:`~detect.detection.TileBox.border_edges`) are
not moved: there the object may go on beyond the tile. Every tile box of a
detection is refined (``Detection.tile`` and ``Detection.views``); its
panorama box is left as it was.

Trained by :mod:`detect.builtin.train_refine` on the project's synthetic
rooms (the target is the tight box of the object's visible pixels in the
tile, as the detector's; the input boxes are those targets with random edge
errors). The committed weights are ``detect/builtin/weights/refine.pt`` with
the record ``refine.json``. Torch is imported lazily.

Convention: panoramas ``(H, W, 3) uint8`` RGB; tile boxes ``(u0, v0, u1, v1)``
in the tile's pixels (CONVENTIONS.md; pixel centres at integer + 0.5).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import ray_to_pixel
from panogeom.sampling import sample_equirect

from ..detection import Detection, TileBox, check_rgb_image
from .backend import load_network, save_network
from .model import torch_module

__all__ = ["RefineConfig", "box_window", "window_box", "apply_moves", "inout_targets", "decode_moves",
           "build_refiner", "network_moves", "BoxRefiner", "default_refiner", "DEFAULT_REFINE_WEIGHTS",
           "save_refiner"]

#: Format tag of the refiner's weights file.
REFINER_FORMAT = "pano2cad/box-refiner@1"
#: The committed refiner weights.
DEFAULT_REFINE_WEIGHTS = Path(__file__).resolve().parent / "weights" / "refine.pt"


@dataclass(frozen=True)
class RefineConfig:
    """Shape and input of the refinement network (stored with the weights).

    Attributes
    ----------
    classes : tuple of str
        Class names, index = the class input's one-hot position.
    size : int
        Side of the square window the network reads, pixels.
    margin : float
        Fraction of the box's width / height the window adds on each side.
    widths : tuple of int
        Channels of the convolution stages (the first at full resolution, then each at half the last).
    hidden : int
        Channels of the two 1D branches (columns, rows).
    """

    classes: tuple[str, ...]
    size: int = 64
    margin: float = 0.25
    widths: tuple[int, ...] = (16, 32, 48, 64)
    hidden: int = 64

    def to_json(self) -> dict[str, Any]:
        return {"classes": list(self.classes), "size": self.size, "margin": self.margin,
                "widths": list(self.widths), "hidden": self.hidden}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RefineConfig:
        return cls(tuple(d["classes"]), int(d["size"]), float(d["margin"]), tuple(int(w) for w in d["widths"]),
                   int(d["hidden"]))


def window_box(box: ArrayLike, margin: float) -> NDArray[np.float64]:
    """The window a box is refined in: the box grown by ``margin`` of its width / height per side. (4,) float."""
    b = np.asarray(box, np.float64)
    w, h = b[2] - b[0], b[3] - b[1]
    return b + float(margin) * np.array([-w, -h, w, h])


def box_window(pano: ArrayLike, tile: TileBox, size: int = 64, margin: float = 0.25,
               supersample: int = 2) -> NDArray[np.uint8]:
    """Render the window of a tile's image plane around a box (:func:`window_box`): ``(size, size, 3) uint8``.

    The window is stretched to a square; it is sampled on the tile's image plane (a pinhole view, not the
    panorama), rendered at ``supersample * size`` and reduced by area.

    Examples
    --------
    >>> from panogeom.perspective import PinholeView
    >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=100, height=100)
    >>> pano = np.zeros((64, 128, 3), np.uint8); pano[:, 60:68] = 255   # a white band ahead of the camera
    >>> win = box_window(pano, TileBox(view, [40, 40, 60, 60]), size=16)
    >>> win.shape, int(win[8, 8, 0]) > 200, int(win[8, 0, 0])
    ((16, 16, 3), True, 0)
    """
    import cv2

    img = check_rgb_image(pano, "pano")
    H, W = img.shape[:2]
    s = int(size) * max(1, int(supersample))
    x0, y0, x1, y1 = window_box(tile.box, margin)
    u = x0 + (np.arange(s) + 0.5) * (x1 - x0) / s
    v = y0 + (np.arange(s) + 0.5) * (y1 - y0) / s
    uu, vv = np.meshgrid(u, v)
    rays = tile.view.pixel_to_ray(np.stack([uu, vv], -1))
    out = sample_equirect(img, ray_to_pixel(rays, W, H), "linear")
    if s != size:
        out = cv2.resize(out, (int(size), int(size)), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(out)


def apply_moves(box: ArrayLike, moves: ArrayLike) -> NDArray[np.float64]:
    """Move a box's edges by ``moves`` = (left, top, right, bottom) fractions of its width / height. (4,) float.

    The network's output and the training target: ``target = (true - box) / (w, h, w, h)``.

    Examples
    --------
    >>> apply_moves([10, 20, 30, 60], [0.1, -0.25, 0.0, 0.5]).tolist()
    [12.0, 10.0, 30.0, 80.0]
    """
    b = np.asarray(box, np.float64)
    w, h = b[2] - b[0], b[3] - b[1]
    return b + np.asarray(moves, np.float64) * np.array([w, h, w, h])


def inout_targets(moves: ArrayLike, size: int, margin: float) -> NDArray[np.float32]:
    """What the network learns: for each column and each row of a window, the share of it inside the true box.

    Parameters
    ----------
    moves : (N, 4) float
        The true box as moves of the window's box (:func:`apply_moves`).
    size : int
    margin : float

    Returns
    -------
    (N, 2, size) float32
        Columns (left to right), then rows (top to bottom), in [0, 1].

    Examples
    --------
    >>> inout_targets([[0.0, 0.0, 0.0, 0.0]], 6, 0.25)[0, 0].round(2).tolist()   # the box is columns 1 to 5
    [0.0, 1.0, 1.0, 1.0, 1.0, 0.0]
    """
    m = np.asarray(moves, np.float64).reshape(-1, 4)
    f = float(margin)
    lo = (f + m[:, [0, 1]]) / (1.0 + 2.0 * f) * size          # (N, 2): left, top in window pixels
    hi = (1.0 + f + m[:, [2, 3]]) / (1.0 + 2.0 * f) * size    # right, bottom
    px = np.arange(size, dtype=np.float64)
    share = np.clip(np.minimum(px + 1.0, hi[..., None]) - np.maximum(px, lo[..., None]), 0.0, 1.0)
    return share.astype(np.float32)


def decode_moves(inside: ArrayLike, margin: float) -> NDArray[np.float64]:
    """Edge moves (N, 4) from the network's inside probabilities (N, 2, S) of a window's columns and rows.

    Each edge lies where the outside mass on its half of the window ends: the left edge at the sum of
    ``1 - p`` over the left half's columns, the right edge at ``S`` minus that sum over the right half (sub-pixel,
    and robust to a stray column); so for rows.

    Examples
    --------
    >>> t = inout_targets([[0.1, -0.05, 0.02, 0.2]], 64, 0.25)
    >>> decode_moves(t, 0.25).round(3).tolist()
    [[0.1, -0.05, 0.02, 0.2]]
    """
    p = np.asarray(inside, np.float64)
    S = p.shape[-1]
    h = S // 2
    out = 1.0 - p
    lo = out[..., :h].sum(-1)
    hi = S - out[..., h:].sum(-1)
    f = float(margin)
    return np.stack([lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]], 1) / S * (1.0 + 2.0 * f) - np.array([f, f, 1 + f, 1 + f])


def build_refiner(config: RefineConfig) -> Any:
    """The network: ``forward(images (B, 3, S, S) float in [0, 1], classes (B, C) one-hot)`` -> logits
    ``(B, 2, S)`` that each column / row of the window lies inside the object's box (:func:`inout_targets`).

    A small convolutional trunk; its map is pooled over the rows (mean and max) for the columns' branch and over
    the columns for the rows' branch; each branch is a 1D network with the class as extra channels, upsampled to
    the window's pixels (as LocNet's in-out probabilities, Gidaris and Komodakis, CVPR 2016).
    """
    torch = torch_module()
    nn = torch.nn
    F = torch.nn.functional

    def block(cin: int, cout: int, stride: int) -> Any:
        return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(True),
                             nn.Conv2d(cout, cout, 3, 1, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(True))

    def branch(cin: int, hidden: int) -> Any:
        return nn.Sequential(nn.Conv1d(cin, hidden, 3, 1, 1), nn.ReLU(True), nn.Conv1d(hidden, hidden, 5, 1, 2),
                             nn.ReLU(True), nn.Conv1d(hidden, hidden, 5, 1, 2), nn.ReLU(True))

    class Refiner(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            w = config.widths
            self.trunk = nn.Sequential(block(3, w[0], 1), *(block(w[i], w[i + 1], 2) for i in range(len(w) - 1)))
            n = 2 * w[-1] + len(config.classes)
            self.cols, self.rows = branch(n, config.hidden), branch(n, config.hidden)
            self.out_cols = nn.Conv1d(config.hidden + w[0], 1, 3, 1, 1)
            self.out_rows = nn.Conv1d(config.hidden + w[0], 1, 3, 1, 1)

        def forward(self, images: Any, classes: Any) -> Any:
            x = (images - 0.5) / 0.25
            first = self.trunk[0](x)
            f = self.trunk[1:](first)
            S = images.shape[-1]
            c = classes[:, :, None]

            def axis(dim: int, net: Any, head: Any) -> Any:
                pooled = torch.cat([f.mean(dim), f.amax(dim), c.expand(-1, -1, f.shape[-1])], 1)
                coarse = F.interpolate(net(pooled), size=S, mode="linear", align_corners=False)
                fine = first.mean(dim)          # full-resolution edges of the first stage
                return head(torch.cat([coarse, fine], 1))[:, 0]

            return torch.stack([axis(2, self.cols, self.out_cols), axis(3, self.rows, self.out_rows)], 1)

    return Refiner()


def network_moves(net: Any, config: RefineConfig, windows: NDArray[np.uint8], onehot: NDArray[np.float32]
                  ) -> NDArray[np.float64]:
    """Edge moves (N, 4) a refiner network (in eval mode) reads on windows ``(N, S, S, 3) uint8`` of boxes of the
    classes ``onehot`` (N, C): its inside probabilities decoded by :func:`decode_moves`."""
    torch = torch_module()
    if len(windows) == 0:
        return np.zeros((0, 4))
    x = torch.from_numpy(np.ascontiguousarray(windows, np.float32) / 255.0).permute(0, 3, 1, 2)
    with torch.inference_mode():
        inside = torch.sigmoid(net(x, torch.from_numpy(np.asarray(onehot, np.float32)))).numpy()
    return decode_moves(inside, config.margin)


def save_refiner(net: Any, config: RefineConfig, path: str | Path) -> Path:
    """Write the refiner's weights and config to ``path`` (a ``.pt`` file), atomically."""
    return save_network(net, REFINER_FORMAT, config.to_json(), path)


class BoxRefiner:
    """Refine the box edges of tile detections (see the module docstring).

    Parameters
    ----------
    weights : path, optional
        A ``.pt`` file of :func:`save_refiner` (default: the committed weights).
    passes : int
        How many times each box is refined (each pass reads the window of the last one's box).
    max_move : float
        Largest move of one edge per pass, as a fraction of the box's side (a guard against a window that shows
        something else).

    Examples
    --------
    >>> r = BoxRefiner()                       # the committed weights; then r.refine(pano, detection)
    >>> r.config.size, r.passes, r.config.classes[:2]
    (64, 2, ('bed', 'chair'))
    """

    def __init__(self, weights: str | Path | None = None, *, passes: int = 2, max_move: float = 0.3) -> None:
        if int(passes) < 1:
            raise ValueError(f"passes: expected a positive integer, got {passes!r}")
        if not float(max_move) > 0.0:
            raise ValueError(f"max_move: expected a fraction > 0, got {max_move!r}")
        self.weights = Path(weights) if weights is not None else DEFAULT_REFINE_WEIGHTS
        self.config, net = load_network(self.weights, "box refiner", REFINER_FORMAT, RefineConfig.from_json,
                                        build_refiner)
        self.passes = int(passes)
        self.max_move = float(max_move)
        self._net = net.eval()

    @property
    def network(self) -> Any:
        """The torch module that reads the windows (eval mode); :mod:`detect.builtin.train_refine` goes on
        training it with ``--init``."""
        return self._net

    @property
    def record(self) -> dict[str, Any]:
        """The JSON record next to the weights (``refine.pt`` -> ``refine.json``); ``{}`` when there is none."""
        p = self.weights.with_suffix(".json")
        return dict(json.loads(p.read_text(encoding="utf-8"))) if p.is_file() else {}

    def moves(self, windows: NDArray[np.uint8], labels: Sequence[str]) -> NDArray[np.float64]:
        """The network's edge moves for windows ``(N, S, S, 3) uint8`` of boxes of classes ``labels``: (N, 4).
        A class the network was not trained on reads with an all-zero class input."""
        onehot = np.zeros((len(labels), len(self.config.classes)), np.float32)
        for i, c in enumerate(labels):
            if c in self.config.classes:
                onehot[i, self.config.classes.index(c)] = 1.0
        return network_moves(self._net, self.config, windows, onehot)

    def refine_tiles(self, pano: ArrayLike, tiles: Sequence[TileBox], labels: Sequence[str]) -> list[TileBox]:
        """Refined copies of tile boxes (one class per box); edges at the tile border stay."""
        img = check_rgb_image(pano, "pano")
        boxes = [np.asarray(t.box, np.float64) for t in tiles]
        keep = [t.border_edges() for t in tiles]
        for _ in range(self.passes):
            wins = np.stack([box_window(img, replace(t, box=b), self.config.size, self.config.margin)
                             for t, b in zip(tiles, boxes)]) if tiles else np.zeros((0, 1, 1, 3), np.uint8)
            for i, m in enumerate(np.clip(self.moves(wins, labels), -self.max_move, self.max_move)):
                nb = np.where(keep[i], boxes[i], apply_moves(boxes[i], m))
                nb = np.clip(nb, 0.0, [tiles[i].view.width, tiles[i].view.height] * 2)
                if nb[0] < nb[2] and nb[1] < nb[3]:
                    boxes[i] = nb
        return [replace(t, box=b) for t, b in zip(tiles, boxes)]

    def refine(self, pano: ArrayLike, det: Detection) -> Detection:
        """A detection with its tile boxes (``tile`` and ``views``) refined; one without a tile is returned as is."""
        return self.refine_detections(pano, [det])[0]

    def refine_detections(self, pano: ArrayLike, dets: Sequence[Detection]) -> list[Detection]:
        """:meth:`refine` of every detection, their tile boxes in one batch per pass."""
        # ``views`` starts with ``tile`` when not empty
        tiles = [list(d.views) or [d.tile] if d.tile is not None else [] for d in dets]
        flat = self.refine_tiles(pano, [t for ts in tiles for t in ts],
                                 [d.label for d, ts in zip(dets, tiles) for _ in ts])
        out, k = [], 0
        for d, ts in zip(dets, tiles):
            new, k = flat[k:k + len(ts)], k + len(ts)
            out.append(d if not ts else replace(d, tile=new[0], views=tuple(new) if d.views else ()))
        return out


@lru_cache(maxsize=2)
def default_refiner(passes: int = 2) -> BoxRefiner:
    """The refiner on the committed weights, loaded once per process (what ``pano2cad run`` uses)."""
    return BoxRefiner(passes=passes)
