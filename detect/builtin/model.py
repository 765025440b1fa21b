"""The builtin detector's network: a tiny anchor-free single-stage detector (CenterNet style).

A plain convolutional backbone (stride 2 to 32) with a top-down path back to
stride 4, and three heads on the stride-4 grid:

- ``heat`` ``(B, C, h, w)``: logits of a per-class centre heatmap (a peak at
  the box centre of every object, Gaussian around it);
- ``size`` ``(B, 2, h, w)``: ``log(width / stride), log(height / stride)``
  of the box whose centre falls in the cell;
- ``offset`` ``(B, 2, h, w)``: sub-cell position of that centre, in cells.

:func:`decode` turns the three maps into boxes; the training loss lives in
:mod:`detect.builtin.train`. The module imports torch lazily: building the
network or decoding needs ``pip install torch``.

Convention: images are RGB, boxes ``(u0, v0, u1, v1)`` in the continuous pixel
coordinates of the network input (pixel centres at integer + 0.5), as in
CONVENTIONS.md. Cell ``(i, j)`` of the output grid covers input pixels
``[stride*j, stride*(j+1)) x [stride*i, stride*(i+1))``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["NetConfig", "build_network", "decode", "STRIDE", "torch_module"]

#: Output stride of the heads (input pixels per heatmap cell).
STRIDE = 4


def torch_module() -> Any:
    """Import torch, with an install hint when it is missing."""
    try:
        import torch
    except ImportError as exc:
        raise ImportError("the builtin detector needs PyTorch: pip install torch") from exc
    return torch


@dataclass(frozen=True)
class NetConfig:
    """Shape of the network (stored with the weights).

    Attributes
    ----------
    classes : tuple of str
        Class names, index = heatmap channel.
    widths : tuple of int
        Channels of the backbone stages at strides 2, 4, 8, 16, 32.
    head : int
        Channels of the stride-4 feature map the heads read.
    input_size : int
        Side of the square input the network was trained on (pixels).

    Examples
    --------
    >>> NetConfig(("bed", "chair")).widths
    (12, 24, 32, 48, 64)
    """

    classes: tuple[str, ...]
    widths: tuple[int, ...] = (12, 24, 32, 48, 64)
    head: int = 32
    input_size: int = 160

    def __post_init__(self) -> None:
        if len(self.widths) != 5 or any(int(w) < 1 for w in self.widths):
            raise ValueError(f"widths: expected 5 positive channel counts, got {self.widths!r}")
        if not self.classes:
            raise ValueError("classes: expected at least one class name, got none")
        if self.input_size % 32:
            raise ValueError(f"input_size: expected a multiple of 32, got {self.input_size}")

    def to_json(self) -> dict[str, object]:
        """A JSON-able dict (inverse: ``NetConfig.from_json``)."""
        return {"classes": list(self.classes), "widths": list(self.widths), "head": self.head,
                "input_size": self.input_size}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> NetConfig:
        """Read :meth:`to_json`'s dict back."""
        return cls(tuple(d["classes"]), tuple(int(w) for w in d["widths"]), int(d["head"]),
                   int(d["input_size"]))


def build_network(config: NetConfig) -> Any:
    """The detector as a ``torch.nn.Module``: ``(B, 3, S, S)`` float in [0, 1] -> ``(heat, size, offset)``.

    Parameters
    ----------
    config : NetConfig

    Returns
    -------
    torch.nn.Module
        ``forward(x)`` returns ``heat (B, C, S/4, S/4)`` logits, ``size
        (B, 2, S/4, S/4)`` and ``offset (B, 2, S/4, S/4)``.

    Examples
    --------
    >>> net = build_network(NetConfig(("bed", "chair"), input_size=64))
    >>> torch = torch_module()
    >>> [tuple(t.shape) for t in net(torch.zeros(1, 3, 64, 64))]
    [(1, 2, 16, 16), (1, 2, 16, 16), (1, 2, 16, 16)]
    """
    torch = torch_module()
    nn = torch.nn
    F = torch.nn.functional

    def cbr(cin: int, cout: int, stride: int = 1, k: int = 3) -> Any:
        return nn.Sequential(nn.Conv2d(cin, cout, k, stride, k // 2, bias=False), nn.BatchNorm2d(cout),
                             nn.ReLU(inplace=True))

    class TinyCenterNet(nn.Module):
        def __init__(self, cfg: NetConfig) -> None:
            super().__init__()
            w = [int(x) for x in cfg.widths]
            h = int(cfg.head)
            self.register_buffer("mean", torch.tensor([0.45, 0.45, 0.45]).view(1, 3, 1, 1))
            self.register_buffer("std", torch.tensor([0.25, 0.25, 0.25]).view(1, 3, 1, 1))
            self.s2 = cbr(3, w[0], 2)
            self.s4 = nn.Sequential(cbr(w[0], w[1], 2), cbr(w[1], w[1]))
            self.s8 = nn.Sequential(cbr(w[1], w[2], 2), cbr(w[2], w[2]))
            self.s16 = nn.Sequential(cbr(w[2], w[3], 2), cbr(w[3], w[3]))
            self.s32 = nn.Sequential(cbr(w[3], w[4], 2), cbr(w[4], w[4]), cbr(w[4], w[4]))
            self.lat16 = nn.Conv2d(w[3], w[4], 1)
            self.up16 = cbr(w[4], w[3])
            self.lat8 = nn.Conv2d(w[2], w[3], 1)
            self.up8 = cbr(w[3], h)
            self.lat4 = nn.Conv2d(w[1], h, 1)
            self.up4 = cbr(h, h)
            self.heat = nn.Sequential(cbr(h, h), nn.Conv2d(h, len(cfg.classes), 1))
            self.box = nn.Sequential(cbr(h, h), nn.Conv2d(h, 4, 1))
            # CenterNet's prior: a low initial heatmap probability keeps the focal loss stable.
            nn.init.constant_(self.heat[-1].bias, -4.6)

        def forward(self, x: Any) -> tuple[Any, Any, Any]:
            x = (x - self.mean) / self.std
            c4 = self.s4(self.s2(x))
            c8 = self.s8(c4)
            c16 = self.s16(c8)
            c32 = self.s32(c16)
            p16 = self.up16(self.lat16(c16) + F.interpolate(c32, scale_factor=2.0, mode="nearest"))
            p8 = self.up8(self.lat8(c8) + F.interpolate(p16, scale_factor=2.0, mode="nearest"))
            p4 = self.up4(self.lat4(c4) + F.interpolate(p8, scale_factor=2.0, mode="nearest"))
            box = self.box(p4)
            return self.heat(p4), box[:, :2], box[:, 2:]

    return TinyCenterNet(config)


def decode(heat: Any, size: Any, offset: Any, score_threshold: float, max_detections: int = 50,
           stride: int = STRIDE) -> list[list[tuple[int, float, tuple[float, float, float, float]]]]:
    """Peaks of the centre heatmaps -> boxes, per image.

    Parameters
    ----------
    heat : (B, C, h, w) torch tensor
        Heatmap *logits*.
    size, offset : (B, 2, h, w) torch tensors
        Network outputs (see the module docstring).
    score_threshold : float
        Minimum peak probability.
    max_detections : int
        Highest peaks kept per image.
    stride : int

    Returns
    -------
    list (one per image) of ``(class_index, score, (u0, v0, u1, v1))``
        Boxes in input pixels, by decreasing score.

    Examples
    --------
    >>> torch = torch_module()
    >>> heat = torch.full((1, 1, 8, 8), -9.0); heat[0, 0, 2, 5] = 3.0
    >>> size = torch.zeros(1, 2, 8, 8); size[0, :, 2, 5] = torch.log(torch.tensor([2.0, 1.0]))
    >>> offset = torch.full((1, 2, 8, 8), 0.5)
    >>> [(c, round(s, 2), b) for c, s, b in decode(heat, size, offset, 0.5)[0]]
    [(0, 0.95, (18.0, 8.0, 26.0, 12.0))]
    """
    torch = torch_module()
    F = torch.nn.functional
    with torch.no_grad():
        p = torch.sigmoid(heat)
        peaks = (F.max_pool2d(p, 3, 1, 1) == p) & (p >= score_threshold)
        p = torch.where(peaks, p, torch.zeros_like(p))
        B, C, h, w = p.shape
        k = min(int(max_detections), C * h * w)
        scores, idx = p.reshape(B, -1).topk(k, dim=1)
        out = []
        for b in range(B):
            keep = scores[b] > 0
            sc, ix = scores[b][keep], idx[b][keep]
            cls = ix // (h * w)
            cell = ix % (h * w)
            i, j = cell // w, cell % w
            off = offset[b, :, i, j]
            wh = torch.exp(size[b, :, i, j].clamp(-6.0, 6.0)) * stride
            cx = (j.to(off.dtype) + off[0]) * stride
            cy = (i.to(off.dtype) + off[1]) * stride
            boxes = torch.stack([cx - wh[0] / 2, cy - wh[1] / 2, cx + wh[0] / 2, cy + wh[1] / 2], 1)
            out.append([(int(c), float(s), tuple(float(v) for v in bx))
                        for c, s, bx in zip(cls.tolist(), sc.tolist(), boxes.tolist())])
        return out
