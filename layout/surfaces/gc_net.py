"""Geometric context (Hedau et al. 2009, paper Sec. 3.1): a small fully convolutional network.

Predicts, for every pixel of an upright panorama, the probabilities of four
geometric classes: floor, ceiling, wall and clutter (anything in front of the
room's walls: furniture, objects). It is the "GC" half of the surface labels;
the wall's orientation comes from the orientation map
(:mod:`layout.surfaces.orientation_map`) and the fusion
(:mod:`layout.surfaces.fusion`).

Network: an encoder-decoder (4 stride-2 levels, 16-64 channels, dilated
convolutions and a per-row global context at the lowest level, skip
connections, about 0.2 M parameters) whose convolutions pad circularly along
the width (a panorama wraps) and by replication along the height. Its input
is the panorama resized to a fixed working size (default 512x256) plus a
latitude channel (the floor is below the horizon); logits are predicted at
half the working size and upsampled bilinearly, then probabilities are
resized to the panorama's size with the seam wrapped.

Weights live in ``layout/surfaces/weights/gc_net.pt`` with the record of how
they were made in ``gc_net.json`` next to it (data seeds, rooms, epochs,
augmentation, validation accuracy, torch version); they are trained by
:mod:`layout.surfaces.train_gc` on the project's synthetic rooms.

Convention: panorama pixels as in :mod:`panogeom.coords` (W == 2*H, rows from
the top, latitude ``pi/2 - pi*v/H``); the panorama must be upright (gravity
along the image columns), as the output of :mod:`panogeom.rectify`. torch is
imported inside the functions that need it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import rgb_pano

__all__ = [
    "GC_CLASSES",
    "GC_FLOOR",
    "GC_CEILING",
    "GC_WALL",
    "GC_CLUTTER",
    "DEFAULT_WEIGHTS",
    "DEFAULT_CHANNELS",
    "gc_targets",
    "build_gc_net",
    "GeometricContext",
    "load_gc_net",
    "gc_probabilities",
    "resize_wrapped",
]

#: Names of the network's output channels, in order.
GC_CLASSES = ("floor", "ceiling", "wall", "clutter")
GC_FLOOR, GC_CEILING, GC_WALL, GC_CLUTTER = 0, 1, 2, 3

#: The committed weights (the JSON record of how they were made sits next to them).
DEFAULT_WEIGHTS = Path(__file__).resolve().parent / "weights" / "gc_net.pt"

#: Channels of the four encoder levels of :func:`build_gc_net`.
DEFAULT_CHANNELS = (16, 32, 48, 64)

# surface label id (CONVENTIONS.md) -> GC class; 0 (unknown) is ignored (-1)
_LABEL_TO_GC = np.array([-1, GC_FLOOR, GC_CEILING, GC_WALL, GC_WALL, GC_CLUTTER], dtype=np.int64)


def _torch():
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("the geometric-context network needs PyTorch: pip install torch") from exc
    return torch


def gc_targets(labels: ArrayLike) -> NDArray[np.int64]:
    """Surface label ids to geometric-context classes (training targets).

    Parameters
    ----------
    labels : (H, W) uint8
        Surface labels (CONVENTIONS.md): 0 unknown, 1 floor, 2 ceiling,
        3 / 4 walls, 5 object.

    Returns
    -------
    targets : (H, W) int64
        0 floor, 1 ceiling, 2 wall (both orientations), 3 clutter (objects),
        -1 where the label is unknown.

    Examples
    --------
    >>> gc_targets(np.array([[0, 1, 2, 3, 4, 5]], np.uint8)).tolist()
    [[-1, 0, 1, 2, 2, 3]]
    """
    lab = np.asarray(labels)
    if lab.ndim != 2 or lab.dtype.kind not in "ui":
        raise ValueError(f"labels: expected an (H, W) integer label image, got shape {lab.shape} dtype {lab.dtype}")
    if lab.size and (lab.min() < 0 or lab.max() > 5):
        raise ValueError(f"labels: expected surface label ids in 0..5, got values {int(lab.min())}..{int(lab.max())}")
    return _LABEL_TO_GC[lab]


@lru_cache(maxsize=1)
def _modules() -> dict[str, Any]:
    """The torch module classes, defined on first use (torch is imported lazily)."""
    torch = _torch()
    nn = torch.nn
    F = torch.nn.functional

    def _up2(x):
        """Bilinear 2x upsampling that wraps around the width (the panorama's seam)."""
        x = F.pad(x, (1, 1, 0, 0), mode="circular")
        x = F.interpolate(x, scale_factor=2.0, mode="bilinear", align_corners=False)
        return x[..., 2:-2]

    class PanoConv(nn.Module):
        """3x3 convolution (no bias), batch norm, ReLU; circular padding along the width."""

        def __init__(self, cin: int, cout: int, stride: int = 1, dilation: int = 1) -> None:
            super().__init__()
            self.pad = dilation
            self.conv = nn.Conv2d(cin, cout, 3, stride=stride, padding=0, dilation=dilation, bias=False)
            self.bn = nn.BatchNorm2d(cout)

        def forward(self, x):  # noqa: D401 - torch API
            p = self.pad
            x = F.pad(x, (p, p, 0, 0), mode="circular")
            x = F.pad(x, (0, 0, p, p), mode="replicate")
            return F.relu(self.bn(self.conv(x)))

    class GCNet(nn.Module):
        """Encoder-decoder on (B, 3, h, w) RGB in [0, 1] -> (B, 4, h, w) logits (h, w divisible by 16)."""

        def __init__(self, channels: tuple[int, int, int, int] = DEFAULT_CHANNELS) -> None:
            super().__init__()
            c0, c1, c2, c3 = (int(c) for c in channels)
            self.channels = (c0, c1, c2, c3)
            self.enc0 = nn.Sequential(PanoConv(4, c0, 2), PanoConv(c0, c0))
            self.enc1 = nn.Sequential(PanoConv(c0, c1, 2), PanoConv(c1, c1))
            self.enc2 = nn.Sequential(PanoConv(c1, c2, 2), PanoConv(c2, c2))
            self.enc3 = nn.Sequential(PanoConv(c2, c3, 2), PanoConv(c3, c3, dilation=2), PanoConv(c3, c3, dilation=4))
            self.row_context = nn.Conv2d(c3, c3, 1)
            self.dec2 = PanoConv(c3 + c2, c2)
            self.dec1 = PanoConv(c2 + c1, c1)
            self.dec0 = PanoConv(c1 + c0, c0)
            self.head = nn.Conv2d(c0, len(GC_CLASSES), 1)

        def forward(self, rgb):  # noqa: D401 - torch API
            b, _, h, w = rgb.shape
            lat = (1.0 - (2.0 * torch.arange(h, dtype=rgb.dtype, device=rgb.device) + 1.0) / h)
            x = torch.cat([rgb - 0.5, lat.view(1, 1, h, 1).expand(b, 1, h, w)], dim=1)
            e0 = self.enc0(x)
            e1 = self.enc1(e0)
            e2 = self.enc2(e1)
            e3 = self.enc3(e2)
            e3 = e3 + self.row_context(e3.mean(dim=3, keepdim=True))  # what each latitude looks like all around

            d2 = self.dec2(torch.cat([_up2(e3), e2], dim=1))
            d1 = self.dec1(torch.cat([_up2(d2), e1], dim=1))
            d0 = self.dec0(torch.cat([_up2(d1), e0], dim=1))
            return _up2(self.head(d0))

    return {"GCNet": GCNet, "PanoConv": PanoConv}


def build_gc_net(channels: tuple[int, int, int, int] = DEFAULT_CHANNELS):
    """A new, untrained geometric-context network (a ``torch.nn.Module``).

    Parameters
    ----------
    channels : 4 ints
        Channels of the encoder levels (strides 2, 4, 8, 16).

    Returns
    -------
    torch.nn.Module
        Maps ``(B, 3, h, w)`` RGB in [0, 1] (h, w divisible by 16; the
        latitude channel is added inside, rows spanning +pi/2..-pi/2) to
        ``(B, 4, h, w)`` logits in the order of :data:`GC_CLASSES`.

    Examples
    --------
    >>> import torch
    >>> net = build_gc_net().eval()
    >>> sum(p.numel() for p in net.parameters()) < 300_000
    True
    >>> tuple(net(torch.zeros(1, 3, 32, 64)).shape)
    (1, 4, 32, 64)
    """
    ch = tuple(int(c) for c in channels)
    if len(ch) != 4 or min(ch) < 1:
        raise ValueError(f"channels: expected 4 positive integers, got {channels!r}")
    return _modules()["GCNet"](ch)  # type: ignore[arg-type]


def resize_wrapped(image: ArrayLike, width: int, height: int) -> NDArray[np.float32]:
    """Bilinear resize of an equirectangular float image, wrapping the seam.

    Parameters
    ----------
    image : (h, w[, C]) float
    width, height : int
        Output size.

    Returns
    -------
    out : (height, width[, C]) float32
        Pixel centres stay at integer + 0.5 (OpenCV's convention for
        ``resize``); columns near the left and right edges are interpolated
        across the seam.

    Examples
    --------
    >>> img = np.zeros((2, 4), np.float32); img[:, 0] = 1.0
    >>> resize_wrapped(img, 8, 4)[0].round(3).tolist()
    [0.75, 0.75, 0.25, 0.0, 0.0, 0.0, 0.0, 0.25]
    """
    import cv2

    img = np.asarray(image, dtype=np.float32)
    if img.ndim not in (2, 3) or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"image: expected (h, w) or (h, w, C), got shape {img.shape}")
    w_out, h_out = int(width), int(height)
    if w_out < 1 or h_out < 1:
        raise ValueError(f"width, height: expected positive sizes, got {width!r}, {height!r}")
    h, w = img.shape[:2]
    if (h, w) == (h_out, w_out):
        return img.copy()
    pad = 2
    padded = np.ascontiguousarray(np.concatenate([img[:, -pad:], img, img[:, :pad]], axis=1))
    # output centre j + 0.5 sits at input coordinate (j + 0.5) * w / w_out; OpenCV indexes centres at integers
    mx = ((np.arange(w_out) + 0.5) * (w / w_out) - 0.5 + pad).astype(np.float32)
    my = ((np.arange(h_out) + 0.5) * (h / h_out) - 0.5).astype(np.float32)
    map_x = np.ascontiguousarray(np.broadcast_to(mx[None, :], (h_out, w_out)))
    map_y = np.ascontiguousarray(np.broadcast_to(my[:, None], (h_out, w_out)))
    return cv2.remap(padded, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


@dataclass(frozen=True, eq=False)
class GeometricContext:
    """A loaded geometric-context network, callable on panoramas.

    Attributes
    ----------
    net : torch.nn.Module
        In eval mode, float32, on the CPU.
    work_width : int
        Panoramas are resized to ``work_width x work_width/2`` (a multiple of 32).
    record : dict
        The JSON record of the weights (how they were made), empty for an
        untrained network.

    Call it with an ``(H, W, 3) uint8`` upright panorama to get ``(H, W, 4)``
    float32 class probabilities (:data:`GC_CLASSES`).
    """

    net: Any
    work_width: int = 512
    record: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if int(self.work_width) != self.work_width or self.work_width < 32 or self.work_width % 32:
            raise ValueError(f"work_width: expected a positive multiple of 32, got {self.work_width!r}")

    def probabilities_at_work_size(self, pano: ArrayLike) -> NDArray[np.float32]:
        """Class probabilities at the working size: (work_width/2, work_width, 4) float32."""
        import cv2

        torch = _torch()
        img = rgb_pano(pano)
        ww, wh = int(self.work_width), int(self.work_width) // 2
        interp = cv2.INTER_AREA if img.shape[1] > ww else cv2.INTER_LINEAR
        small = img if img.shape[1] == ww else cv2.resize(img, (ww, wh), interpolation=interp)
        x = torch.from_numpy(np.ascontiguousarray(small.transpose(2, 0, 1))).float().div_(255.0)[None]
        with torch.inference_mode():
            prob = torch.softmax(self.net(x), dim=1)[0]
        return np.ascontiguousarray(prob.numpy().transpose(1, 2, 0), dtype=np.float32)

    def __call__(self, pano: ArrayLike) -> NDArray[np.float32]:
        img = rgb_pano(pano)
        prob = self.probabilities_at_work_size(img)
        h, w = img.shape[:2]
        if prob.shape[:2] != (h, w):
            prob = resize_wrapped(prob, w, h)
            prob /= np.maximum(prob.sum(axis=2, keepdims=True), 1e-12)
        return prob


def load_gc_net(path: str | Path | None = None) -> GeometricContext:
    """Load geometric-context weights (default: the committed :data:`DEFAULT_WEIGHTS`).

    Parameters
    ----------
    path : str or Path, optional
        A ``.pt`` file written by :mod:`layout.surfaces.train_gc`; its JSON
        record (same name, ``.json``) is read when present.

    Returns
    -------
    GeometricContext
        Cached per path: repeated calls return the same object.

    Raises
    ------
    FileNotFoundError
        No weights at ``path``.

    Examples
    --------
    >>> gc = load_gc_net()
    >>> gc.work_width, gc.record["classes"]
    (512, ['floor', 'ceiling', 'wall', 'clutter'])
    """
    p = Path(DEFAULT_WEIGHTS if path is None else path).resolve()
    return _load(str(p))


@lru_cache(maxsize=4)
def _load(path: str) -> GeometricContext:
    torch = _torch()
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"geometric-context weights: expected a .pt file at {p}, found none "
                                f"(train them with python -m layout.surfaces.train_gc)")
    blob = torch.load(p, map_location="cpu", weights_only=True)
    if not isinstance(blob, dict) or "state_dict" not in blob or "channels" not in blob:
        raise ValueError(f"{p}: expected a dict with 'state_dict', 'channels' and 'work_width' "
                         f"(written by layout.surfaces.train_gc), got {type(blob).__name__}")
    net = build_gc_net(tuple(int(c) for c in blob["channels"]))
    net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in blob["state_dict"].items()})
    net.eval()
    rec_path = p.with_suffix(".json")
    record = json.loads(rec_path.read_text()) if rec_path.is_file() else {}
    return GeometricContext(net=net, work_width=int(blob.get("work_width", 512)), record=record)


def gc_probabilities(pano: ArrayLike, model: GeometricContext | None = None) -> NDArray[np.float32]:
    """Per-pixel floor / ceiling / wall / clutter probabilities of an upright panorama.

    Parameters
    ----------
    pano : (H, W, 3) uint8, W == 2*H
        Upright (rectified) RGB panorama.
    model : GeometricContext, optional
        Default: :func:`load_gc_net` (the committed weights).

    Returns
    -------
    probs : (H, W, 4) float32
        Channels in the order of :data:`GC_CLASSES`; they sum to 1.

    Examples
    --------
    >>> p = gc_probabilities(np.full((128, 256, 3), 128, np.uint8))
    >>> p.shape, bool(np.allclose(p.sum(axis=2), 1.0, atol=1e-4))
    ((128, 256, 4), True)
    """
    return (load_gc_net() if model is None else model)(pano)
