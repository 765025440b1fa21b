"""The room's ceiling-wall and floor-wall boundary per column, regressed by a small network.

The geometric-context network (:mod:`layout.surfaces.gc_net`) labels pixels
one neighbourhood at a time. In dark, evenly lit rooms its ceiling-wall
boundary drifts: the ceiling label creeps down a shadowed wall or the wall
label climbs a dark ceiling (docs/EVALUATION.md, "Sessions 13-15 on the
tuning sets"). The room step reads each wall's distance from that boundary
first. This network instead regresses the two boundaries of the empty room
(the layout, furniture ignored) for every column at once, in the manner of
HorizonNet (Sun et al. 2019): an encoder whose features are collapsed along
the height into one vector per column group, and a bidirectional GRU
running around the panorama, so that a column whose junction the image does
not show takes it from the rest of the room (the ceiling boundary of a
Manhattan room is its floor boundary scaled by one ratio per room).

Network (:func:`build_boundary_net`): four stride-2 levels (16-96
channels, circular padding along the width, as the GC network), the two
lowest levels flattened over the height into one feature per 8 columns, a
1x1 projection to 128, a bidirectional GRU (hidden 96) over the 64 column
groups with 8 groups of wrap-around context on each side, and a linear head
giving both boundaries for the 8 columns of each group. Input: the upright
panorama at the fixed working size 512x256 plus a latitude channel. Output:
rows divided by the height (``v / H``, continuous pixel coordinates).

Weights live in ``layout/surfaces/weights/boundary_net.pt`` with the record
of how they were made in ``boundary_net.json``; they are trained by
:mod:`layout.surfaces.train_boundary` on the project's synthetic rooms.
torch is imported inside the functions that need it.

Convention: panorama pixels as in :mod:`panogeom.coords` (W == 2*H, rows from
the top, pixel centres at integer + 0.5); the panorama must be upright.
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
from .gc_net import resize_wrapped

__all__ = [
    "BOUNDARY_WEIGHTS",
    "build_boundary_net",
    "BoundaryNet",
    "load_boundary_net",
    "predict_boundaries",
]

#: The committed weights (the JSON record of how they were made sits next to them).
BOUNDARY_WEIGHTS = Path(__file__).resolve().parent / "weights" / "boundary_net.pt"

#: Encoder channels of :func:`build_boundary_net`, its GRU's hidden size and columns per GRU step.
DEFAULT_CHANNELS = (16, 32, 64, 96)
DEFAULT_HIDDEN = 96
STEP = 8
#: GRU steps of wrap-around context on each side of the panorama.
WRAP_STEPS = 8


def _torch():
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("the boundary network needs PyTorch: pip install torch") from exc
    return torch


@lru_cache(maxsize=1)
def _modules() -> dict[str, Any]:
    """The torch module class, defined on first use (torch is imported lazily)."""
    torch = _torch()
    nn = torch.nn
    F = torch.nn.functional
    from .gc_net import _modules as _gc_modules

    PanoConv = _gc_modules()["PanoConv"]

    class BoundaryNetModule(nn.Module):
        """(B, 3, h, w) RGB in [0, 1] -> (B, 2, w) rows / h of the ceiling and floor boundary.

        ``h`` is fixed at construction (the features are flattened over the
        height); ``w`` must be a multiple of 16 * 8 / 2 = 64.
        """

        def __init__(self, height: int, channels=DEFAULT_CHANNELS, hidden: int = DEFAULT_HIDDEN) -> None:
            super().__init__()
            c0, c1, c2, c3 = (int(c) for c in channels)
            if height % 32:
                raise ValueError(f"height: expected a multiple of 32, got {height}")
            self.height, self.channels, self.hidden = int(height), (c0, c1, c2, c3), int(hidden)
            self.enc0 = nn.Sequential(PanoConv(4, c0, 2), PanoConv(c0, c0))
            self.enc1 = nn.Sequential(PanoConv(c0, c1, 2), PanoConv(c1, c1))
            self.enc2 = nn.Sequential(PanoConv(c1, c2, 2), PanoConv(c2, c2))
            self.enc3 = nn.Sequential(PanoConv(c2, c3, 2), PanoConv(c3, c3, dilation=2))
            self.squeeze2 = PanoConv(c2, c2 // 2, stride=(2, 1))
            feat = c3 * (height // 16) + (c2 // 2) * (height // 16)
            self.project = nn.Conv1d(feat, 128, 1)
            self.rnn = nn.GRU(128, hidden, batch_first=True, bidirectional=True)
            self.head = nn.Linear(2 * hidden, 2 * STEP)
            with torch.no_grad():
                self.head.weight.mul_(0.1)
                self.head.bias.view(2, STEP)[0].fill_(0.35)
                self.head.bias.view(2, STEP)[1].fill_(0.65)

        def forward(self, rgb):  # noqa: D401 - torch API
            b, _, h, w = rgb.shape
            lat = (1.0 - (2.0 * torch.arange(h, dtype=rgb.dtype, device=rgb.device) + 1.0) / h)
            x = torch.cat([rgb - 0.5, lat.view(1, 1, h, 1).expand(b, 1, h, w)], dim=1)
            e2 = self.enc2(self.enc1(self.enc0(x)))            # (B, c2, h/8, w/8)
            e3 = self.enc3(e2)                                 # (B, c3, h/16, w/16)
            f3 = e3.flatten(1, 2)                              # (B, c3*h/16, w/16)
            f3 = torch.repeat_interleave(f3, 2, dim=2)         # (B, ., w/8)
            f2 = self.squeeze2(e2).flatten(1, 2)               # (B, c2/2*h/16, w/8)
            f = F.relu(self.project(torch.cat([f3, f2], dim=1)))  # (B, 128, n) with n = w/8 column groups
            n = f.shape[2]
            k = min(WRAP_STEPS, n)
            seq = torch.cat([f[..., -k:], f, f[..., :k]], dim=2).transpose(1, 2)  # (B, n + 2k, 128)
            out, _ = self.rnn(seq)
            y = self.head(out[:, k:k + n])                     # (B, n, 2 * STEP)
            return y.view(b, n, 2, STEP).permute(0, 2, 1, 3).reshape(b, 2, n * STEP)

    return {"BoundaryNetModule": BoundaryNetModule}


def build_boundary_net(height: int = 256, channels=DEFAULT_CHANNELS, hidden: int = DEFAULT_HIDDEN):
    """A new, untrained boundary network (a ``torch.nn.Module``).

    Parameters
    ----------
    height : int
        Working height h (multiple of 32); the width must be ``2 * h`` or
        any multiple of 64.
    channels : 4 ints
        Encoder channels (strides 2, 4, 8, 16).
    hidden : int
        Hidden size of each direction of the GRU.

    Returns
    -------
    torch.nn.Module
        ``(B, 3, h, w)`` RGB in [0, 1] -> ``(B, 2, w)``: the ceiling-wall
        (index 0) and floor-wall (index 1) boundary of each column as
        ``v / h``.

    Examples
    --------
    >>> import torch
    >>> net = build_boundary_net(64).eval()
    >>> tuple(net(torch.zeros(1, 3, 64, 128)).shape)
    (1, 2, 128)
    """
    return _modules()["BoundaryNetModule"](int(height), tuple(int(c) for c in channels), int(hidden))


@dataclass(frozen=True, eq=False)
class BoundaryNet:
    """A loaded boundary network, callable on panoramas.

    Attributes
    ----------
    net : torch.nn.Module
        In eval mode, float32, on the CPU.
    work_width : int
        Panoramas are resized to ``work_width x work_width/2``.
    record : dict
        The JSON record of the weights, empty for an untrained network.

    Call it with an ``(H, W, 3) uint8`` upright panorama to get ``(2, W)``
    float rows (continuous pixel coordinates of that panorama): the
    ceiling-wall boundary (row 0) and the floor-wall boundary (row 1) of the
    empty room in every column.
    """

    net: Any
    work_width: int = 512
    record: dict = field(default_factory=dict)

    def rows_at_work_size(self, pano: ArrayLike) -> NDArray[np.float32]:
        """``(2, work_width)`` boundaries as ``v / h`` at the working size."""
        import cv2

        torch = _torch()
        img = rgb_pano(pano)
        ww, wh = int(self.work_width), int(self.work_width) // 2
        interp = cv2.INTER_AREA if img.shape[1] > ww else cv2.INTER_LINEAR
        small = img if img.shape[1] == ww else cv2.resize(img, (ww, wh), interpolation=interp)
        x = torch.from_numpy(np.ascontiguousarray(small.transpose(2, 0, 1))).float().div_(255.0)[None]
        with torch.inference_mode():
            y = self.net(x)[0]
        return np.ascontiguousarray(y.numpy(), dtype=np.float32)

    def __call__(self, pano: ArrayLike) -> NDArray[np.float64]:
        img = rgb_pano(pano)
        h, w = img.shape[:2]
        rel = self.rows_at_work_size(img)
        if rel.shape[1] != w:  # columns resampled across the seam (pixel centres at integer + 0.5)
            rel = resize_wrapped(rel, w, 2)
        rel = rel.astype(np.float64)
        top = np.clip(rel[0] * h, 1.0, h / 2.0 - 1.0)
        bottom = np.clip(rel[1] * h, h / 2.0 + 1.0, h - 1.0)
        return np.stack([top, bottom])


def load_boundary_net(path: str | Path | None = None) -> BoundaryNet:
    """Load boundary-network weights (default: the committed :data:`BOUNDARY_WEIGHTS`).

    Parameters
    ----------
    path : str or Path, optional
        A ``.pt`` file written by :mod:`layout.surfaces.train_boundary`; its
        JSON record (same name, ``.json``) is read when present.

    Returns
    -------
    BoundaryNet
        Cached per path.

    Raises
    ------
    FileNotFoundError
        No weights at ``path``.
    """
    p = Path(BOUNDARY_WEIGHTS if path is None else path).resolve()
    return _load(str(p))


@lru_cache(maxsize=4)
def _load(path: str) -> BoundaryNet:
    torch = _torch()
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"boundary-network weights: expected a .pt file at {p}, found none "
                                f"(train them with python -m layout.surfaces.train_boundary)")
    blob = torch.load(p, map_location="cpu", weights_only=True)
    if not isinstance(blob, dict) or not {"state_dict", "channels", "hidden", "work_width"} <= set(blob):
        raise ValueError(f"{p}: expected a dict with 'state_dict', 'channels', 'hidden' and 'work_width' "
                         f"(written by layout.surfaces.train_boundary), got {type(blob).__name__}")
    ww = int(blob["work_width"])
    net = build_boundary_net(ww // 2, tuple(blob["channels"]), int(blob["hidden"]))
    net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in blob["state_dict"].items()})
    net.eval()
    rec_path = p.with_suffix(".json")
    record = json.loads(rec_path.read_text()) if rec_path.is_file() else {}
    return BoundaryNet(net=net, work_width=ww, record=record)


def predict_boundaries(pano: ArrayLike, model: BoundaryNet | None = None) -> NDArray[np.float64]:
    """Ceiling-wall and floor-wall boundary rows of the empty room, per column.

    Parameters
    ----------
    pano : (H, W, 3) uint8, W == 2*H
        Upright (rectified) RGB panorama.
    model : BoundaryNet, optional
        Default: :func:`load_boundary_net` (the committed weights).

    Returns
    -------
    (2, W) float
        Row 0: the ceiling-wall boundary in ``[1, H/2 - 1]``; row 1: the
        floor-wall boundary in ``[H/2 + 1, H - 1]`` (continuous rows; the
        boundary between pixel rows k - 1 and k is at k).
    """
    return (load_boundary_net() if model is None else model)(pano)
