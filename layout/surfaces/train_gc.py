"""Train the geometric-context network (:mod:`layout.surfaces.gc_net`) on synthetic rooms.

The training data are folders written by the project's synthetic generator
(one ``room-NNNN/`` per room with ``pano.png`` and ``labels.png``, and an
``index.json`` naming the seed). Never train or tune on seed 0: it is the
evaluation set. The committed weights were made like this (the exact seeds,
rooms, epochs and accuracy are in ``layout/surfaces/weights/gc_net.json``;
the seed-1000 set stopped after 166 rooms, where the generator raised an
error, so three more seeds were added)::

    S=".venv/bin/pano2cad synth --size 512 --jobs 1"
    $S --seed 1000 --rooms 300 --out out/train/surfaces/train-1000
    for s in 1001 1002 1003; do $S --seed $s --rooms 50 --out out/train/surfaces/train-$s; done
    $S --seed 2000 --rooms 40 --out out/train/surfaces/val
    D=$(ls -d out/train/surfaces/train-100[0-3])
    .venv/bin/python -m layout.surfaces.train_gc --data $D --val out/train/surfaces/val \\
        --out out/train/surfaces/run1 --epochs 8
    .venv/bin/python -m layout.surfaces.train_gc --data $D --val out/train/surfaces/val \\
        --out layout/surfaces/weights --epochs 10 --lr 2e-3 --clutter-weight 1.5 \\
        --init out/train/surfaces/run1/gc_net.pt

``--data`` takes several folders. Training: Adam with a cosine learning
rate, batches of full panoramas at the working size (512x256), cross-entropy
over floor / ceiling / wall / clutter (synthetic objects, label 5, are
clutter), strong appearance augmentation (:func:`augment`: random roll and
mirror, white balance, brightness, contrast, saturation, channel swaps,
gamma, a smooth illumination field, blur, noise). After every epoch the
4-class pixel accuracy on the ``--val`` rooms is measured; the best epoch's
weights are written as fp16 to ``OUT/gc_net.pt`` with the record
``OUT/gc_net.json`` (re-measured with the stored fp16 weights).

One thread is the default: on a shared 2-core machine torch's second
thread mostly waits for a core (measured 2-3x slower than one thread).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from .gc_net import DEFAULT_CHANNELS, GC_CLASSES, GeometricContext, build_gc_net, gc_targets

__all__ = ["SynthSet", "load_synth_folder", "augment", "evaluate_gc", "train_gc", "main", "AUGMENTATION"]

#: Ranges of the appearance augmentation of :func:`augment` (also written into the record).
AUGMENTATION = {
    "roll": "uniform over the width",
    "mirror_p": 0.5,
    "white_balance": [0.8, 1.2],
    "brightness": [0.5, 1.5],
    "contrast": [0.6, 1.4],
    "saturation": [0.3, 1.6],
    "channel_swap_p": 0.2,
    "gamma_log": [-0.5, 0.5],
    "illumination_field": [0.0, 0.35],
    "blur_p": 0.3,
    "blur_sigma_px": [0.4, 1.5],
    "noise_sigma": [0.0, 0.05],
}


class SynthSet:
    """Panoramas and surface labels of synthetic rooms, at the working size, in memory.

    Attributes
    ----------
    images : (N, h, w, 3) uint8
    labels : (N, h, w) uint8
        Surface label ids (CONVENTIONS.md).
    sources : list of dict
        One ``{"path", "seeds", "rooms"}`` per folder read (seeds from the
        rooms' ``gt.json``, else ``index.json``).
    """

    def __init__(self, images: NDArray[np.uint8], labels: NDArray[np.uint8], sources: list[dict]) -> None:
        if images.ndim != 4 or images.shape[3] != 3 or labels.shape != images.shape[:3]:
            raise ValueError(f"expected images (N, h, w, 3) and labels (N, h, w), got {images.shape} and "
                             f"{labels.shape}")
        self.images, self.labels, self.sources = images, labels, sources

    def __len__(self) -> int:
        return int(len(self.images))

    @classmethod
    def concat(cls, sets: Sequence["SynthSet"]) -> "SynthSet":
        """All rooms of several sets."""
        return cls(np.concatenate([s.images for s in sets]), np.concatenate([s.labels for s in sets]),
                   [src for s in sets for src in s.sources])


def load_synth_folder(folder: str | Path, work_width: int = 512) -> SynthSet:
    """Read a synthetic-room folder (``room-*/pano.png`` + ``labels.png``) at the working size.

    Parameters
    ----------
    folder : str or Path
        Output of ``pano2cad synth``; rooms without both files are skipped.
    work_width : int
        Panoramas are resized (area) to ``work_width x work_width/2``,
        labels by nearest neighbour.

    Returns
    -------
    SynthSet

    Raises
    ------
    ValueError
        No room with a panorama and labels in the folder.
    """
    import cv2

    root = Path(folder)
    ww, wh = int(work_width), int(work_width) // 2
    imgs, labs, seeds = [], [], set()
    for room in sorted(root.glob("room-*")):
        pano_p, lab_p, gt_p = room / "pano.png", room / "labels.png", room / "gt.json"
        if not (pano_p.is_file() and lab_p.is_file()):
            continue
        if gt_p.is_file():
            gen = json.loads(gt_p.read_text()).get("generator") or {}
            if "seed" in gen:
                seeds.add(int(gen["seed"]))
        bgr = cv2.imread(str(pano_p), cv2.IMREAD_COLOR)
        lab = cv2.imread(str(lab_p), cv2.IMREAD_UNCHANGED)
        if bgr is None or lab is None or lab.ndim != 2 or lab.shape != bgr.shape[:2]:
            raise ValueError(f"{room}: expected a colour pano.png and a single-channel labels.png of the same size")
        if bgr.shape[1] != ww:
            bgr = cv2.resize(bgr, (ww, wh), interpolation=cv2.INTER_AREA)
            lab = cv2.resize(lab, (ww, wh), interpolation=cv2.INTER_NEAREST)
        imgs.append(bgr[..., ::-1])
        labs.append(lab)
    if not imgs:
        raise ValueError(f"{root}: expected room-*/pano.png and labels.png (pano2cad synth output), found none")
    index = root / "index.json"
    if not seeds and index.is_file() and json.loads(index.read_text()).get("seed") is not None:
        seeds.add(int(json.loads(index.read_text())["seed"]))
    return SynthSet(np.stack(imgs).astype(np.uint8), np.stack(labs).astype(np.uint8),
                    [{"path": str(root), "seeds": sorted(seeds), "rooms": len(imgs)}])


def _blur(x, sigma: float):
    """Separable Gaussian blur of (B, C, h, w), circular along the width."""
    import torch
    import torch.nn.functional as F

    r = max(1, int(math.ceil(2.5 * sigma)))
    t = torch.arange(-r, r + 1, dtype=x.dtype)
    k = torch.exp(-0.5 * (t / sigma) ** 2)
    k = k / k.sum()
    c = x.shape[1]
    x = F.pad(x, (r, r, 0, 0), mode="circular")
    x = F.conv2d(x, k.view(1, 1, 1, -1).repeat(c, 1, 1, 1), groups=c)
    x = F.pad(x, (0, 0, r, r), mode="replicate")
    return F.conv2d(x, k.view(1, 1, -1, 1).repeat(c, 1, 1, 1), groups=c)


def augment(images, targets, gen):
    """Random geometric and appearance changes of a batch (ranges in :data:`AUGMENTATION`).

    Parameters
    ----------
    images : (B, h, w, 3) uint8 torch tensor
    targets : (B, h, w) int64 torch tensor
        GC classes (-1 ignored); rolled and mirrored with the images.
    gen : torch.Generator
        All randomness comes from it.

    Returns
    -------
    x : (B, 3, h, w) float32 in [0, 1]
    y : (B, h, w) int64

    Examples
    --------
    >>> import torch
    >>> g = torch.Generator().manual_seed(0)
    >>> x, y = augment(torch.full((2, 16, 32, 3), 128, dtype=torch.uint8), torch.zeros(2, 16, 32, dtype=torch.long), g)
    >>> tuple(x.shape), float(x.min()) >= 0.0 and float(x.max()) <= 1.0
    ((2, 3, 16, 32), True)
    """
    import torch
    import torch.nn.functional as F

    A = AUGMENTATION
    b, h, w, _ = images.shape

    def uni(lo, hi, *shape):
        return lo + (hi - lo) * torch.rand(*shape, generator=gen)

    x = images.permute(0, 3, 1, 2).float().div(255.0)
    y = targets.clone()
    shifts = torch.randint(0, w, (b,), generator=gen).tolist()
    flips = (torch.rand(b, generator=gen) < A["mirror_p"]).tolist()
    xs, ys = [], []
    for i in range(b):
        xi, yi = torch.roll(x[i], shifts[i], dims=2), torch.roll(y[i], shifts[i], dims=1)
        if flips[i]:
            xi, yi = torch.flip(xi, dims=[2]), torch.flip(yi, dims=[1])
        xs.append(xi)
        ys.append(yi)
    x, y = torch.stack(xs), torch.stack(ys)
    # colour
    x = x * uni(*A["white_balance"], b, 3, 1, 1)
    x = x * uni(*A["brightness"], b, 1, 1, 1)
    mean = x.mean(dim=(1, 2, 3), keepdim=True)
    x = (x - mean) * uni(*A["contrast"], b, 1, 1, 1) + mean
    grey = x.mean(dim=1, keepdim=True)
    x = grey + (x - grey) * uni(*A["saturation"], b, 1, 1, 1)
    for i in range(b):
        if float(torch.rand(1, generator=gen)) < A["channel_swap_p"]:
            x[i] = x[i, torch.randperm(3, generator=gen)]
    x = x.clamp(0.0, 1.0) ** torch.exp(uni(*A["gamma_log"], b, 1, 1, 1))
    # smooth illumination field (low-frequency multiplicative shading)
    field = torch.randn(b, 1, 3, 6, generator=gen) * uni(*A["illumination_field"], b, 1, 1, 1)
    field = F.interpolate(F.pad(field, (1, 1, 0, 0), mode="circular"), size=(h, w + 2 * (w // 6)),
                          mode="bicubic", align_corners=False)[..., w // 6: w // 6 + w]
    x = x * torch.exp(field)
    for i in range(b):
        if float(torch.rand(1, generator=gen)) < A["blur_p"]:
            x[i:i + 1] = _blur(x[i:i + 1], float(uni(*A["blur_sigma_px"], 1)))
    x = x + torch.randn(x.shape, generator=gen) * uni(*A["noise_sigma"], b, 1, 1, 1)
    return x.clamp(0.0, 1.0).contiguous(), y.contiguous()


def evaluate_gc(model: GeometricContext, data: SynthSet) -> dict:
    """4-class pixel accuracy of a model on a set (pixels with a known label).

    Returns
    -------
    dict
        ``pixel_accuracy`` (float), ``class_accuracy`` (recall per class name)
        and ``pixels`` (count).
    """
    hits = np.zeros(len(GC_CLASSES))
    total = np.zeros(len(GC_CLASSES))
    for img, lab in zip(data.images, data.labels):
        t = gc_targets(lab)
        pred = np.argmax(model.probabilities_at_work_size(img), axis=2)
        for c in range(len(GC_CLASSES)):
            m = t == c
            total[c] += m.sum()
            hits[c] += (pred[m] == c).sum()
    return {"pixel_accuracy": float(hits.sum() / max(total.sum(), 1.0)),
            "class_accuracy": {n: float(hits[c] / max(total[c], 1.0)) for c, n in enumerate(GC_CLASSES)},
            "pixels": int(total.sum())}


def environment_record() -> dict:
    """When and with what a set of weights was made: date, torch / numpy / Python versions, torch threads."""
    import torch

    return {"date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"), "torch": torch.__version__,
            "numpy": np.__version__, "python": platform.python_version(), "threads": torch.get_num_threads()}


def write_record(path: str | Path, record: dict) -> None:
    """Write a weights record as JSON, atomically (a temporary file renamed over ``path``)."""
    js = Path(path)
    tmp = js.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(record, indent=1) + "\n")
    os.replace(tmp, js)


def _fp16_state(net) -> dict:
    return {k: (v.detach().half() if v.is_floating_point() else v.detach().clone())
            for k, v in net.state_dict().items()}


def train_gc(train: SynthSet, val: SynthSet, out_dir: str | Path, *, epochs: int = 20, batch: int = 8,
             lr: float = 4e-3, seed: int = 0, max_minutes: float | None = None,
             channels: tuple[int, int, int, int] = DEFAULT_CHANNELS, clutter_weight: float = 1.0,
             init: str | Path | None = None, log=print) -> dict:
    """Train, keep the best epoch on ``val``, write ``gc_net.pt`` and ``gc_net.json`` into ``out_dir``.

    Parameters
    ----------
    train, val : SynthSet
        Same working size (its width becomes the network's working width).
    out_dir : str or Path
    epochs, batch, lr, seed : training settings (cosine learning rate from ``lr``).
    max_minutes : float, optional
        Stop after the epoch that passes this wall-clock budget.
    channels : 4 ints
        Encoder channels (:func:`layout.surfaces.gc_net.build_gc_net`).
    clutter_weight : float
        Weight of the clutter class in the loss (the others weigh 1).
    init : str or Path, optional
        Start from these weights (a ``gc_net.pt`` with its record, which is
        kept in the new record under ``"init"``); ``channels`` are then the
        stored ones.
    log : callable
        Progress lines.

    Returns
    -------
    record : dict
        What was written to ``gc_net.json``.
    """
    import torch
    import torch.nn.functional as F

    if len(train) == 0 or len(val) == 0:
        raise ValueError(f"expected non-empty training and validation sets, got {len(train)} and {len(val)} rooms")
    work_width = int(train.images.shape[2])
    if val.images.shape[1:3] != train.images.shape[1:3] or work_width % 32:
        raise ValueError(f"expected train and val at one working size with a width divisible by 32, got "
                         f"{train.images.shape[1:3]} and {val.images.shape[1:3]}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(seed)
    gen = torch.Generator().manual_seed(seed)
    init_record = None
    if init is not None:
        from .gc_net import _load

        start = _load(str(Path(init).resolve()))
        if start.work_width != work_width:
            raise ValueError(f"init: expected weights for working width {work_width}, got {start.work_width}")
        net = build_gc_net(start.net.channels)
        net.load_state_dict(start.net.state_dict())
        init_record = dict(start.record, path=str(init))
    else:
        net = build_gc_net(channels)
    class_w = torch.tensor([1.0, 1.0, 1.0, float(clutter_weight)])
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=1e-5)
    steps_per_epoch = int(math.ceil(len(train) / batch))
    total_steps = epochs * steps_per_epoch
    warm = min(100, total_steps // 10)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: (s + 1) / max(warm, 1) if s < warm else
        0.02 + 0.98 * 0.5 * (1.0 + math.cos(math.pi * (s - warm) / max(total_steps - warm, 1))))
    images = torch.from_numpy(train.images)
    targets = torch.from_numpy(gc_targets(train.labels.reshape(-1, train.labels.shape[2])).reshape(train.labels.shape))
    best: dict = {"pixel_accuracy": -1.0}
    best_state = None
    t0 = time.time()
    done_epochs = 0
    history = []
    for epoch in range(epochs):
        net.train()
        order = torch.randperm(len(train), generator=gen)
        losses = []
        for k in range(steps_per_epoch):
            idx = order[k * batch:(k + 1) * batch]
            x, y = augment(images[idx], targets[idx], gen)
            loss = F.cross_entropy(net(x), y, weight=class_w, ignore_index=-1)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            losses.append(float(loss.detach()))
        net.eval()
        res = evaluate_gc(GeometricContext(net=net, work_width=work_width), val)
        done_epochs = epoch + 1
        minutes = (time.time() - t0) / 60.0
        history.append({"epoch": done_epochs, "loss": float(np.mean(losses)),
                        "val_pixel_accuracy": res["pixel_accuracy"], "minutes": round(minutes, 2)})
        log(f"epoch {done_epochs}/{epochs}: loss {np.mean(losses):.4f}, val accuracy {res['pixel_accuracy']:.4f}, "
            f"{minutes:.1f} min")
        if res["pixel_accuracy"] > best["pixel_accuracy"]:
            best, best_state = dict(res, epoch=done_epochs), _fp16_state(net)
        if max_minutes is not None and minutes > max_minutes:
            log(f"stopping: {minutes:.1f} min > --max-minutes {max_minutes}")
            break
    blob = {"state_dict": best_state, "channels": list(net.channels), "work_width": work_width}
    pt = out / "gc_net.pt"
    tmp = pt.with_suffix(".pt.tmp")
    torch.save(blob, tmp)
    os.replace(tmp, pt)
    # re-measure with exactly what was stored (fp16 weights)
    from .gc_net import _load

    _load.cache_clear()
    stored = _load(str(pt.resolve()))
    final = evaluate_gc(stored, val)
    record = {
        "schema": "pano2cad/gc-net@1",
        "classes": list(GC_CLASSES),
        "channels": list(net.channels),
        "work_width": work_width,
        "params": int(sum(p.numel() for p in net.parameters())),
        "weights_dtype": "float16",
        "train": {"sources": train.sources, "rooms": len(train)},
        "val": {"sources": val.sources, "rooms": len(val)},
        "epochs_planned": epochs,
        "epochs_done": done_epochs,
        "best_epoch": best["epoch"],
        "batch": batch,
        "optimizer": f"Adam lr {lr} weight_decay 1e-5, warm-up {warm} steps, cosine to 2% of lr",
        "loss": f"cross-entropy, unknown labels ignored, clutter weight {clutter_weight}",
        "init": init_record,
        "epochs_total": done_epochs + (int(init_record.get("epochs_total", init_record.get("epochs_done", 0)))
                                       if init_record else 0),
        "augmentation": AUGMENTATION,
        "seed": seed,
        "val_pixel_accuracy": final["pixel_accuracy"],
        "val_class_accuracy": final["class_accuracy"],
        "history": history,
        "train_minutes": round((time.time() - t0) / 60.0, 2),
        **environment_record(),
    }
    write_record(out / "gc_net.json", record)
    _load.cache_clear()
    return record


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m layout.surfaces.train_gc --data DIR [DIR ...] --val DIR --out DIR``."""
    ap = argparse.ArgumentParser(prog="python -m layout.surfaces.train_gc", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--data", nargs="+", required=True,
                    help="pano2cad synth output folders for training (never seed 0)")
    ap.add_argument("--val", nargs="+", required=True, help="synth folders for validation (a seed not trained on)")
    ap.add_argument("--out", required=True, help="folder for gc_net.pt and gc_net.json")
    ap.add_argument("--epochs", type=int, default=20)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--lr", type=float, default=4e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--work-width", type=int, default=512)
    ap.add_argument("--max-minutes", type=float, default=None, help="stop after the epoch that passes this budget")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--clutter-weight", type=float, default=1.0, help="loss weight of the clutter class")
    ap.add_argument("--init", default=None, help="start from these weights (gc_net.pt; its record is kept)")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(max(1, args.threads))
    try:
        train = SynthSet.concat([load_synth_folder(d, args.work_width) for d in args.data])
        val = SynthSet.concat([load_synth_folder(d, args.work_width) for d in args.val])
    except ValueError as err:
        print(f"train_gc: {err}", file=sys.stderr)
        return 2
    train_seeds = {x for s in train.sources for x in s["seeds"]}
    val_seeds = {x for s in val.sources for x in s["seeds"]}
    if 0 in train_seeds | val_seeds or train_seeds & val_seeds:
        print("train_gc: expected seeds other than 0 (the evaluation set) and validation seeds not used for "
              f"training, got train {sorted(train_seeds)}, val {sorted(val_seeds)}", file=sys.stderr)
        return 2
    print(f"train_gc: {len(train)} training rooms, {len(val)} validation rooms at {train.images.shape[2]}x"
          f"{train.images.shape[1]}", file=sys.stderr)
    rec = train_gc(train, val, args.out, epochs=args.epochs, batch=args.batch, lr=args.lr, seed=args.seed,
                   max_minutes=args.max_minutes, clutter_weight=args.clutter_weight, init=args.init,
                   log=lambda s: print(s, file=sys.stderr, flush=True))
    print(json.dumps({k: rec[k] for k in ("val_pixel_accuracy", "epochs_done", "best_epoch", "params")}))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
