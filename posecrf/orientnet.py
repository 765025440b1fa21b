"""A learned view-relative yaw prior: a small CNN that tells an object's front from its back in its crop.

Not in the paper. The paper's orientation evidence is the HOG distance E_o
between the crop and a model's renders (:mod:`posecrf.pose`); at the
detector's crop sizes it often cannot tell a chair's front from its back,
or a bed's foot from its head, and the context prior cannot either where
both alignments are usual (a desk chair faces the wall, a chair in the room
faces away from it). This module adds a per-crop distribution over the
crop-relative yaw, learned from the project's synthetic rooms
(:mod:`posecrf.train_orientation`), as an extra cost on the E_o tables:

    E_o'(model, yaw_rel, pitch) = E_o(model, yaw_rel, pitch) - w * log(N_BINS * p(yaw_rel | crop))

(:func:`orientation_costs`; the weight ``w`` is the caller's). Several crops of one object (the pipeline: one per
tile that sees it whole) add their costs, each read at its own relative yaw of the same world yaw.

Network: five 3x3 conv blocks (stride 2 from the second on) on a 64 x 64
RGB crop, global average pooling, one linear layer giving ``N_BINS`` logits
per class (:data:`ORIENT_CLASSES`); the class of the detection picks its
head. ``p`` over the bins is interpolated linearly (on the circle) between
bin centres. At test time :meth:`OrientationNet.probabilities` averages each
crop's distribution with its left-right mirror's, the mirror's yaws mapped
back (:func:`mirror_average`, ``mirror=True`` by default): the training
mirrors crops at random, and the average is right more often on the whole
(gt boxes, ``benchmarks/eval_orientnet.py held-out``: chairs within 45 deg,
crop alone -> averaged, on tuning seeds 7000 / 8000 93 / 86 % -> 95 / 93 %
with the session-24 weights, docs/EVALUATION.md, "Session 24"; with the
session-30 weights 98 / 92 % -> 93 / 94 %, the first worse, and 91 % -> 92 %
on 160 rooms none of them was trained on; with the committed weights, trained
on 3040 rooms in session 31, 100 / 97 % -> 100 / 99 % and 95 % -> 96 %, while
the wardrobes of those 160 rooms go 96 % -> 94 %).

Convention: crop-relative yaw of :mod:`posecrf.crops` (direction object ->
camera in the object's frame, counter-clockwise from its front, radians);
bin ``k`` is centred on ``2*pi*k / N_BINS``. Crops are RGB uint8 of any
size (those of :func:`posecrf.crops.extract_crop`). The module imports torch
lazily.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "ORIENT_CLASSES",
    "N_BINS",
    "INPUT_SIZE",
    "DEFAULT_WEIGHTS",
    "mirror_average",
    "OrientationNet",
    "prepare_crops",
    "build_network",
    "load_orientation_net",
    "orientation_costs",
    "save_weights",
    "bin_yaws",
    "head_probabilities",
]

#: Classes with a head (every asymmetric class of the builtin library).
ORIENT_CLASSES: tuple[str, ...] = ("bed", "chair", "tv", "sofa", "nightstand", "wardrobe")
#: Yaw bins over [0, 2*pi).
N_BINS = 24
#: Side of the square network input, pixels.
INPUT_SIZE = 64
#: The committed weights (made by :mod:`posecrf.train_orientation`; record in ``orientnet.json`` beside it).
DEFAULT_WEIGHTS = Path(__file__).resolve().parent / "weights" / "orientnet.pt"

_WIDTHS = (16, 32, 48, 64, 96)


def bin_yaws(n_bins: int = N_BINS) -> NDArray[np.float64]:
    """Centres of the yaw bins, radians: ``2*pi*k / n_bins`` for k = 0 .. n_bins - 1."""
    return np.arange(n_bins) * (2.0 * math.pi / n_bins)


def _torch() -> Any:
    try:
        import torch
    except ImportError as exc:
        raise ImportError("the orientation network needs PyTorch: pip install torch") from exc
    return torch


def prepare_crops(crops: Sequence[ArrayLike]) -> NDArray[np.float32]:
    """Network input of RGB crops: each padded to a square (grey, centred) and resized by area averaging.

    Parameters
    ----------
    crops : sequence of (h, w, 3) uint8

    Returns
    -------
    (N, 3, INPUT_SIZE, INPUT_SIZE) float32 in [-0.5, 0.5]
    """
    import cv2

    out = np.empty((len(crops), 3, INPUT_SIZE, INPUT_SIZE), np.float32)
    for i, c in enumerate(crops):
        a = np.asarray(c)
        if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8 or min(a.shape[:2]) < 1:
            raise ValueError(f"crops[{i}]: expected an (h, w, 3) uint8 RGB image, got {a.dtype} {a.shape}")
        h, w = a.shape[:2]
        s = max(h, w)
        sq = np.full((s, s, 3), 128, np.uint8)
        y0, x0 = (s - h) // 2, (s - w) // 2
        sq[y0:y0 + h, x0:x0 + w] = a
        interp = cv2.INTER_AREA if s >= INPUT_SIZE else cv2.INTER_LINEAR
        r = cv2.resize(sq, (INPUT_SIZE, INPUT_SIZE), interpolation=interp)
        out[i] = r.transpose(2, 0, 1).astype(np.float32) / 255.0 - 0.5
    return out


def build_network(n_classes: int = len(ORIENT_CLASSES), n_bins: int = N_BINS) -> Any:
    """The untrained network: ``(B, 3, 64, 64) -> (B, n_classes, n_bins)`` logits."""
    torch = _torch()
    nn = torch.nn

    class _Net(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            layers: list = []
            c_in = 3
            for k, c in enumerate(_WIDTHS):
                layers += [nn.Conv2d(c_in, c, 3, stride=1 if k == 0 else 2, padding=1, bias=False),
                           nn.BatchNorm2d(c), nn.ReLU(inplace=True)]
                c_in = c
            self.features = nn.Sequential(*layers)
            self.head = nn.Linear(c_in, n_classes * n_bins)
            self.n_classes, self.n_bins = n_classes, n_bins

        def forward(self, x):  # noqa: D401 - torch API
            f = self.features(x).mean(dim=(2, 3))
            return self.head(f).view(-1, self.n_classes, self.n_bins)

    return _Net()


@dataclass(frozen=True, eq=False)
class OrientationNet:
    """A trained orientation network (:func:`load_orientation_net`).

    Attributes
    ----------
    module : torch.nn.Module
        In eval mode, on the CPU.
    classes : tuple of str
        Head order.
    n_bins : int
    path : str
        The weights file.
    """

    module: Any
    classes: tuple[str, ...]
    n_bins: int
    path: str

    def probabilities(self, crops: Sequence[ArrayLike], classes: Sequence[str],
                      mirror: bool = True) -> NDArray[np.float64]:
        """p(yaw bin | crop) of each crop under its class's head: (N, n_bins), rows sum to 1.

        With ``mirror`` (test-time augmentation), the mean of the crop's distribution and its left-right mirror's
        with the yaws mirrored back (:func:`mirror_average`). Raises ValueError for a class without a head.
        """
        if len(crops) != len(classes):
            raise ValueError(f"classes: expected one per crop ({len(crops)}), got {len(classes)}")
        unknown = sorted({c for c in classes if c not in self.classes})
        if unknown:
            raise ValueError(f"classes: no orientation head for {unknown}; known: {list(self.classes)}")
        if not crops:
            return np.zeros((0, self.n_bins))
        return head_probabilities(self.module, prepare_crops(crops), [self.classes.index(c) for c in classes],
                                  mirror=mirror)


def head_probabilities(module: Any, x: NDArray[np.float32], heads: ArrayLike,
                       batch: int = 512, mirror: bool = False) -> NDArray[np.float64]:
    """Softmax of each prepared crop's logits under head ``heads[i]``: (N, n_bins), rows sum to 1.

    ``module``: the network (:func:`build_network`, or :attr:`OrientationNet.module`); ``x``: (N, 3, S, S) float32
    from :func:`prepare_crops`; ``heads``: (N,) int head indices. Evaluated without gradients, ``batch`` at a time.
    With ``mirror``, averaged with the distributions of the crops mirrored left-right (:func:`mirror_average`).
    """
    torch = _torch()
    h = np.asarray(heads, dtype=np.int64).reshape(-1)
    if len(h) != len(x):
        raise ValueError(f"heads: expected one per crop ({len(x)}), got {len(h)}")
    n = len(x)
    if mirror:  # the crops and their mirrors in the same forward passes
        x, h = np.concatenate([x, x[..., ::-1]]), np.concatenate([h, h])
    out = []
    with torch.no_grad():
        for s in range(0, len(x), batch):
            logits = module(torch.from_numpy(np.ascontiguousarray(x[s:s + batch])))
            sel = logits[torch.arange(len(logits)), torch.from_numpy(h[s:s + batch])]
            out.append(torch.softmax(sel.double(), dim=1).numpy())
    p = np.concatenate(out) if out else np.zeros((0, N_BINS))
    return mirror_average(p[:n], p[n:]) if mirror else p


def mirror_average(probs: ArrayLike, mirrored: ArrayLike) -> NDArray[np.float64]:
    """Mean of yaw-bin distributions of crops and of their left-right mirrors, the mirrors' yaws mapped back.

    A crop mirrored left-right shows the object at the crop-relative yaw ``-yaw`` (the training's augmentation,
    :mod:`posecrf.train_orientation`), so bin ``k`` of a mirror's distribution is bin ``-k mod n_bins`` of the
    crop's.

    Parameters
    ----------
    probs, mirrored : (N, n_bins) float
        Rows of p(yaw bin | crop) and p(yaw bin | mirrored crop), bins centred at ``2*pi*k / n_bins``.

    Returns
    -------
    (N, n_bins) float, rows summing to 1 where both inputs' rows do.

    >>> p = np.eye(4)[[1]]                      # the crop: yaw 90 deg
    >>> mirror_average(p, np.eye(4)[[3]])[0]    # its mirror seen at 270 deg = -90: agreement
    array([0., 1., 0., 0.])
    """
    p = np.asarray(probs, dtype=np.float64)
    m = np.asarray(mirrored, dtype=np.float64)
    if p.ndim != 2 or m.shape != p.shape:
        raise ValueError(f"expected two (N, n_bins) arrays of one shape, got {p.shape} and {m.shape}")
    back = (-np.arange(p.shape[1])) % p.shape[1]
    return 0.5 * (p + m[:, back])


@lru_cache(maxsize=4)
def _load(path: str) -> OrientationNet:
    torch = _torch()
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"orientation network weights not found: {p}")
    try:
        blob = torch.load(p, map_location="cpu", weights_only=True)
        classes = tuple(json.loads(blob["classes"].numpy().tobytes().decode()))
        n_bins = int(blob["n_bins"])
        net = build_network(len(classes), n_bins)
        net.load_state_dict({k[len("net."):]: v for k, v in blob.items() if k.startswith("net.")})
    except Exception as exc:  # torch raises many types for a file that is not its own (pickle, zip, key errors)
        raise ValueError(f"{p}: not an orientation network weights file ({exc})") from exc
    net.eval()
    return OrientationNet(net, classes, n_bins, str(p))


def load_orientation_net(path: str | Path | None = None) -> OrientationNet:
    """The network at ``path`` (default :data:`DEFAULT_WEIGHTS`), loaded once per path.

    Raises FileNotFoundError naming a missing file, ValueError naming a file that is not such weights.
    """
    return _load(str(Path(path) if path is not None else DEFAULT_WEIGHTS))


def save_weights(module: Any, classes: Sequence[str], path: str | Path) -> None:
    """Write a trained network (state dict, classes and bin count in one torch file)."""
    torch = _torch()
    blob = {f"net.{k}": v for k, v in module.state_dict().items()}
    blob["classes"] = torch.frombuffer(bytearray(json.dumps(list(classes)).encode()), dtype=torch.uint8)
    blob["n_bins"] = torch.tensor(module.n_bins)
    torch.save(blob, Path(path))


def orientation_costs(probs: ArrayLike, yaw_rel: ArrayLike, symmetry: str = "none",
                      floor: float = 1e-3, shifts: ArrayLike | None = None) -> NDArray[np.float64]:
    """-log(n_bins p(yaw_rel | crop)) at crop-relative yaws, p interpolated between bin centres on the circle.

    Several crops of one object (say, the tiles that each see it whole) are taken as independent evidence: their
    costs add (the product of their densities), crop ``j``'s read at ``yaw_rel + shifts[j]``, its crop-relative
    yaw of the same world yaw. Crops centred on rays of azimuths ``alpha_j`` (:func:`posecrf.crops.view_azimuth`)
    have ``shifts[j] = alpha_j - alpha_0`` (:func:`posecrf.crops.relative_yaw`), and ``yaw_rel`` is then crop 0's.
    (A mean of the densities, or of the costs, is less sure than the one crop wherever one view disagrees, and
    lost on the tuning sets: docs/EVALUATION.md, "Session 38".)

    Parameters
    ----------
    probs : (n_bins,) or (V, n_bins) float
        One crop's row of :meth:`OrientationNet.probabilities`, or the rows of V crops of one object.
    yaw_rel : (...) float
        Radians.
    symmetry : {"none", "two", "full"}
        A 2-fold symmetric model looks the same at ``yaw`` and ``yaw + pi``: the two are added; a fully
        symmetric one gets cost 0 everywhere.
    floor : float
        Smallest density counted, relative to a uniform one (the cost is capped at ``-log(floor)``).
    shifts : (V,) float, optional
        Radians, with a (V, n_bins) ``probs`` (default: zeros, crops of one view).

    Returns
    -------
    (...) float
        ``-log(n_bins * p)``: the density relative to a uniform one, so a uniform ``p`` costs 0 everywhere, a
        likelier yaw less than 0 and an unlikely one up to ``-log(floor)``; with V crops the sum of their costs.

    Examples
    --------
    >>> p = np.zeros(N_BINS); p[0] = 1.0
    >>> [round(float(c), 3) for c in orientation_costs(p, [0.0, math.pi])]
    [-3.178, 6.908]

    Two crops that agree on the world yaw though their views differ by 90 degrees of azimuth: twice the evidence.

    >>> q = np.zeros(N_BINS); q[N_BINS // 4] = 1.0
    >>> [round(float(c), 3) for c in orientation_costs([p, q], [0.0, math.pi], shifts=[0.0, math.pi / 2])]
    [-6.356, 13.816]
    """
    p = np.asarray(probs, dtype=np.float64)
    p = p.reshape(1, -1) if p.ndim == 1 else p
    n = p.shape[-1] if p.ndim else 0
    if p.ndim != 2 or len(p) == 0 or n < 2 or not np.all(np.isfinite(p)) or np.any(p < 0):
        raise ValueError(f"probs: expected finite non-negative (n_bins,) or (V, n_bins) rows, got shape {p.shape}")
    s = np.zeros(len(p)) if shifts is None else np.asarray(shifts, dtype=np.float64).reshape(-1)
    if s.shape != (len(p),) or not np.all(np.isfinite(s)):
        raise ValueError(f"shifts: expected {len(p)} finite radians (one per row of probs), got shape {s.shape}")
    y = np.asarray(yaw_rel, dtype=np.float64)
    if symmetry == "full":
        return np.zeros_like(y)
    if symmetry not in ("none", "two"):
        raise ValueError(f"symmetry: expected 'none', 'two' or 'full', got {symmetry!r}")

    def dens(a: NDArray[np.float64], row: NDArray[np.float64]) -> NDArray[np.float64]:
        f = (a % (2.0 * math.pi)) / (2.0 * math.pi) * n
        k0 = np.floor(f).astype(np.int64) % n
        t = f - np.floor(f)
        return n * ((1.0 - t) * row[k0] + t * row[(k0 + 1) % n])

    cost = np.zeros_like(y)
    for row, shift in zip(p, s):
        d = dens(y + shift, row)
        if symmetry == "two":
            d = 0.5 * (d + dens(y + math.pi + shift, row))
        cost += -np.log(np.maximum(d, floor))
    return cost
