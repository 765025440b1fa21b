"""Train the boundary network (:mod:`layout.surfaces.boundary_net`) on synthetic rooms.

The training data are folders written by the project's synthetic generator
(``room-NNNN/pano.png`` and ``gt.json``). The targets are the empty room's
ceiling-wall and floor-wall boundary in every column, computed exactly from
gt.json's floor polygon, ceiling height and camera height
(:func:`layout.labelmap.room_boundaries`); furniture is ignored, so the
network learns the boundary behind it. Never train or tune on seed 0: it is
the evaluation set, and seeds 7000 / 8000 are the tuning sets. The committed
weights were made like this (the exact seeds, rooms, epochs and errors are
in ``layout/surfaces/weights/boundary_net.json``)::

    S=".venv/bin/pano2cad synth --size 512 --quiet"
    $S --seed 1000 --rooms 300 --out out/train/surfaces/train-1000
    for s in 1001 1002 1003; do $S --seed $s --rooms 50 --out out/train/surfaces/train-$s; done
    for s in 1004 1005 1006 1007; do $S --seed $s --rooms 150 --out out/train/surfaces/train-$s; done
    $S --seed 2000 --rooms 40 --out out/train/surfaces/val
    .venv/bin/python -m layout.surfaces.train_boundary --data out/train/surfaces/train-100[0-7] \\
        --val out/train/surfaces/val --out out/train/boundary1 --epochs 24
    # second stage (session 20), from those weights on twice the rooms:
    for s in $(seq 1008 1014); do $S --seed $s --rooms 150 --out out/train/surfaces/train-$s; done
    .venv/bin/python -m layout.surfaces.train_boundary --data out/train/surfaces/train-10[0-1][0-9] \\
        --val out/train/surfaces/val --out layout/surfaces/weights --epochs 16 --lr 1e-3 \\
        --init out/train/boundary1/boundary_net.pt
    # third and fourth stages (session 33), from those weights, adding the orientation network's rooms (seeds
    # 3000 and 5000, rendered at 1024x512 and resized to the working size) and 1500 new ones:
    for s in 3000 5000; do .venv/bin/pano2cad synth --rooms 1600 --seed $s --size 1024 --out out/train$s; done
    for s in $(seq 1015 1024); do $S --seed $s --rooms 150 --out out/s33/train/train-$s; done
    $S --seed 2000 --rooms 40 --out out/s33/train/val
    .venv/bin/python -m layout.surfaces.train_boundary --data out/train3000 out/s33/train/train-10[1-2][0-9] \\
        --val out/s33/train/val --out out/s33/train/bnet --epochs 8 --lr 5e-4 --threads 2 \\
        --init layout/surfaces/weights/boundary_net.pt
    .venv/bin/python -m layout.surfaces.train_boundary --data out/train3000 out/train5000 \\
        out/s33/train/train-10[1-2][0-9] --val out/s33/train/val --out out/s33/train/bnet2 --epochs 8 \\
        --lr 3e-4 --threads 2 --init out/s33/train/bnet/boundary_net.pt
    cp out/s33/train/bnet2/boundary_net.* layout/surfaces/weights/

Training: Adam with a cosine learning rate, batches of full panoramas at the
working size (512x256), L1 loss on both boundaries (rows / height), the GC
network's augmentation (:func:`layout.surfaces.train_gc.augment`: random
roll and mirror, which move the targets with the image, and the appearance
changes). After every epoch the mean absolute row error of the ceiling
boundary on the ``--val`` rooms is measured (pixels at the working height);
the best epoch's weights are written as fp16 with the record.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from .boundary_net import BoundaryNet, build_boundary_net
from .train_gc import AUGMENTATION, SynthSet, _fp16_state, augment, environment_record, load_synth_folder, write_record

__all__ = ["room_boundary_targets", "load_boundary_folder", "evaluate_boundaries", "train_boundary", "main"]


def room_boundary_targets(gt: dict, width: int) -> NDArray[np.float32]:
    """The empty room's boundaries of a gt.json, as the network's targets.

    Parameters
    ----------
    gt : dict
        A parsed ``gt.json`` (schema pano2cad/gt@1: ``room.floor``,
        ``room.ceiling_z``, ``camera_height_m``; camera at the origin).
    width : int
        Working width w (height w / 2).

    Returns
    -------
    (2, w) float32
        Ceiling-wall and floor-wall boundary rows divided by the height.

    Examples
    --------
    >>> gt = {"room": {"floor": [[-2, -2], [2, -2], [2, 2], [-2, 2]], "ceiling_z": 2.6}, "camera_height_m": 1.6}
    >>> t = room_boundary_targets(gt, 64)
    >>> t.shape, bool((t[0] < 0.5).all() and (t[1] > 0.5).all())
    ((2, 64), True)
    """
    from layout.labelmap import room_boundaries

    b = room_boundaries(np.asarray(gt["room"]["floor"], dtype=np.float64), float(gt["room"]["ceiling_z"]),
                        [0.0, 0.0], float(gt["camera_height_m"]), int(width))
    if not bool(b.valid):
        raise ValueError("gt.json: the camera is not inside the room's floor polygon")
    return (np.stack([b.ceil_v, b.floor_v]) / b.height).astype(np.float32)


def load_boundary_folder(folder: str | Path, work_width: int = 512) -> tuple[SynthSet, NDArray[np.float32]]:
    """Panoramas (:func:`layout.surfaces.train_gc.load_synth_folder`) and their boundary targets.

    Returns
    -------
    data : SynthSet
    targets : (N, 2, work_width) float32
        :func:`room_boundary_targets` of each room, in the set's order.
    """
    data = load_synth_folder(folder, work_width)
    rooms = [r for r in sorted(Path(folder).glob("room-*"))
             if (r / "pano.png").is_file() and (r / "labels.png").is_file()]
    if len(rooms) != len(data):
        raise ValueError(f"{folder}: expected one gt.json per room read, got {len(rooms)} rooms for {len(data)}")
    targets = []
    for r in rooms:
        gt_p = r / "gt.json"
        if not gt_p.is_file():
            raise ValueError(f"{r}: expected a gt.json next to pano.png")
        targets.append(room_boundary_targets(json.loads(gt_p.read_text()), work_width))
    return data, np.stack(targets)


def evaluate_boundaries(model: BoundaryNet, data: SynthSet, targets: NDArray[np.float32]) -> dict:
    """Mean and 90th-percentile absolute row errors at the working height, ceiling and floor."""
    h = data.images.shape[1]
    err = np.stack([np.abs(model.rows_at_work_size(img) - t) * h for img, t in zip(data.images, targets)])
    return {"ceiling_mae_px": float(err[:, 0].mean()), "floor_mae_px": float(err[:, 1].mean()),
            "ceiling_p90_px": float(np.percentile(err[:, 0], 90)), "floor_p90_px": float(np.percentile(err[:, 1], 90)),
            "rooms": int(len(err))}


def train_boundary(train: SynthSet, train_targets: NDArray[np.float32], val: SynthSet,
                   val_targets: NDArray[np.float32], out_dir: str | Path, *, epochs: int = 14, batch: int = 8,
                   lr: float = 2e-3, seed: int = 0, max_minutes: float | None = None,
                   init: str | Path | None = None, log=print) -> dict:
    """Train, keep the best epoch on ``val``, write ``boundary_net.pt`` and ``boundary_net.json``.

    Parameters
    ----------
    train, val : SynthSet
        One working size (width a multiple of 64, height = width / 2).
    train_targets, val_targets : (N, 2, w) float32
        :func:`room_boundary_targets` of the rooms.
    out_dir : str or Path
    epochs, batch, lr, seed : training settings (cosine learning rate from ``lr``).
    max_minutes : float, optional
        Stop after the epoch that passes this wall-clock budget.
    init : str or Path, optional
        Start from these weights (a ``boundary_net.pt`` with its record,
        which is kept in the new record under ``"init"``; the network's
        shape is then the stored one).
    log : callable
        Progress lines.

    Returns
    -------
    record : dict
        What was written to ``boundary_net.json``.
    """
    import torch

    if len(train) == 0 or len(val) == 0:
        raise ValueError(f"expected non-empty training and validation sets, got {len(train)} and {len(val)} rooms")
    h, w = train.images.shape[1:3]
    if w % 64 or w != 2 * h or val.images.shape[1:3] != (h, w):
        raise ValueError(f"expected train and val at one working size w x w/2 with w a multiple of 64, got "
                         f"{train.images.shape[1:3]} and {val.images.shape[1:3]}")
    if train_targets.shape != (len(train), 2, w) or val_targets.shape != (len(val), 2, w):
        raise ValueError(f"targets: expected (N, 2, {w}), got {train_targets.shape} and {val_targets.shape}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(seed)
    gen = torch.Generator().manual_seed(seed)
    init_record = None
    if init is not None:
        from .boundary_net import _load

        start = _load(str(Path(init).resolve()))
        if start.work_width != w:
            raise ValueError(f"init: expected weights for working width {w}, got {start.work_width}")
        net = build_boundary_net(h, start.net.channels, start.net.hidden)
        net.load_state_dict(start.net.state_dict())
        init_record = dict(start.record, path=str(init))
    else:
        net = build_boundary_net(h)
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=1e-5)
    steps_per_epoch = int(math.ceil(len(train) / batch))
    total_steps = epochs * steps_per_epoch
    warm = min(100, total_steps // 10)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: (s + 1) / max(warm, 1) if s < warm else
        0.02 + 0.98 * 0.5 * (1.0 + math.cos(math.pi * (s - warm) / max(total_steps - warm, 1))))
    images = torch.from_numpy(train.images)
    targets = torch.from_numpy(train_targets)
    best: dict = {"ceiling_mae_px": math.inf}
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
            loss = (net(x) - y).abs().mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            losses.append(float(loss.detach()))
        net.eval()
        res = evaluate_boundaries(BoundaryNet(net=net, work_width=w), val, val_targets)
        done_epochs = epoch + 1
        minutes = (time.time() - t0) / 60.0
        history.append({"epoch": done_epochs, "loss": float(np.mean(losses)), **{k: round(v, 3) for k, v in
                        res.items() if k.endswith("_px")}, "minutes": round(minutes, 2)})
        log(f"epoch {done_epochs}/{epochs}: loss {np.mean(losses):.5f}, val ceiling {res['ceiling_mae_px']:.2f} px "
            f"(p90 {res['ceiling_p90_px']:.2f}), floor {res['floor_mae_px']:.2f} px, {minutes:.1f} min")
        if res["ceiling_mae_px"] < best["ceiling_mae_px"]:
            best, best_state = dict(res, epoch=done_epochs), _fp16_state(net)
        if max_minutes is not None and minutes > max_minutes:
            log(f"stopping: {minutes:.1f} min > --max-minutes {max_minutes}")
            break
    blob = {"state_dict": best_state, "channels": list(net.channels), "hidden": net.hidden, "work_width": w}
    pt = out / "boundary_net.pt"
    tmp = pt.with_suffix(".pt.tmp")
    torch.save(blob, tmp)
    os.replace(tmp, pt)
    from .boundary_net import _load

    _load.cache_clear()
    final = evaluate_boundaries(_load(str(pt.resolve())), val, val_targets)  # what was stored (fp16)
    record = {
        "schema": "pano2cad/boundary-net@1",
        "outputs": ["ceiling-wall row / H", "floor-wall row / H"],
        "channels": list(net.channels),
        "hidden": net.hidden,
        "work_width": w,
        "params": int(sum(p.numel() for p in net.parameters())),
        "weights_dtype": "float16",
        "train": {"sources": train.sources, "rooms": len(train)},
        "epochs_planned": epochs,
        "epochs_done": done_epochs,
        "best_epoch": best["epoch"],
        "init": init_record,
        "epochs_total": done_epochs + (int(init_record.get("epochs_total", init_record.get("epochs_done", 0)))
                                       if init_record else 0),
        "batch": batch,
        "optimizer": f"Adam lr {lr} weight_decay 1e-5, warm-up {warm} steps, cosine to 2% of lr",
        "loss": "L1 on both boundaries (rows / height)",
        "augmentation": AUGMENTATION,
        "seed": seed,
        "val": {"sources": val.sources, "rooms": len(val), **final},
        "history": history,
        "train_minutes": round((time.time() - t0) / 60.0, 2),
        **environment_record(),
    }
    write_record(out / "boundary_net.json", record)
    _load.cache_clear()
    return record


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m layout.surfaces.train_boundary --data DIR [DIR ...] --val DIR --out DIR``."""
    ap = argparse.ArgumentParser(prog="python -m layout.surfaces.train_boundary",
                                 description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--data", nargs="+", required=True, help="pano2cad synth output folders for training")
    ap.add_argument("--val", nargs="+", required=True, help="synth folders for validation (a seed not trained on)")
    ap.add_argument("--out", required=True, help="folder for boundary_net.pt and boundary_net.json")
    ap.add_argument("--epochs", type=int, default=14)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--work-width", type=int, default=512)
    ap.add_argument("--max-minutes", type=float, default=None, help="stop after the epoch that passes this budget")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--init", default=None, help="start from these weights (boundary_net.pt; its record is kept)")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(max(1, args.threads))
    try:
        tr = [load_boundary_folder(d, args.work_width) for d in args.data]
        va = [load_boundary_folder(d, args.work_width) for d in args.val]
    except ValueError as err:
        print(f"train_boundary: {err}", file=sys.stderr)
        return 2
    train, val = SynthSet.concat([d for d, _ in tr]), SynthSet.concat([d for d, _ in va])
    train_t, val_t = np.concatenate([t for _, t in tr]), np.concatenate([t for _, t in va])
    train_seeds = {x for s in train.sources for x in s["seeds"]}
    val_seeds = {x for s in val.sources for x in s["seeds"]}
    reserved = {0, 7000, 8000}
    if (train_seeds | val_seeds) & reserved or train_seeds & val_seeds:
        print("train_boundary: expected seeds other than 0 (evaluation) and 7000 / 8000 (tuning), and validation "
              f"seeds not used for training, got train {sorted(train_seeds)}, val {sorted(val_seeds)}",
              file=sys.stderr)
        return 2
    print(f"train_boundary: {len(train)} training rooms, {len(val)} validation rooms at {train.images.shape[2]}x"
          f"{train.images.shape[1]}", file=sys.stderr)
    rec = train_boundary(train, train_t, val, val_t, args.out, epochs=args.epochs, batch=args.batch, lr=args.lr,
                         seed=args.seed, max_minutes=args.max_minutes, init=args.init,
                         log=lambda s: print(s, file=sys.stderr, flush=True))
    print(json.dumps({"val": {k: rec["val"][k] for k in ("ceiling_mae_px", "floor_mae_px")},
                      "epochs_done": rec["epochs_done"], "best_epoch": rec["best_epoch"], "params": rec["params"]}))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
