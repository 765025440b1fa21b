"""Train the box-edge refiner (:mod:`detect.builtin.refine`) on the project's synthetic rooms.

Run (the committed weights; their record ``refine.json`` keeps the command)::

    pano2cad synth --rooms 1600 --seed 3000 --size 1024 --out out/train3000
    pano2cad synth --rooms 1600 --seed 5000 --size 1024 --out out/train5000
    pano2cad synth --rooms 30 --seed 7000 --size 1024 --out out/tune7000
    python -m detect.builtin.train_refine --data out/train3000 out/train5000 --val out/tune7000 \\
        --out out/refine --rooms 1600 --jitters 4 --views 8 --minutes 30

To go on training from weights already made (a lower rate, other jitters), add ``--init
detect/builtin/weights/refine.pt --lr 5e-4 --seed 1``; the new record keeps the old one under ``init``.

Samples: in each room, tiles aimed at objects (:func:`~detect.builtin.data.random_view`) and, one in four, tiles
of the builtin detector's set (:func:`~detect.builtin.backend.builtin_views`), 576 pixels; in each tile, every object the
detector is trained to find (:func:`~detect.builtin.data.tile_labels`) whose box does not touch the tile border.
Its true box is the tight box of its visible pixels in the tile. Each is given ``--jitters`` input boxes: every
edge moved by a normal error of ``sigma`` times the box's width / height, ``sigma`` log-uniform in
[0.01, 0.2] per box (the detector's edges are off by 0.5-1 degree, 1-15 % of a box's side, and more now and then). The window of the
input box (:func:`~detect.builtin.refine.box_window`) is augmented photometrically
(:func:`~detect.builtin.data.augment`) and mirrored half the time while training.

Loss: binary cross-entropy between the network's inside probabilities of the window's columns and rows and their
true shares inside the box (:func:`~detect.builtin.refine.inout_targets`). AdamW, cosine decay,
for ``--minutes`` of wall time. The validation rooms give the edge error in degrees (at the tile's focal
length) before and after one pass. The best state on them is kept, of those every 500 iterations, the last one
and, with ``--init``, the given weights (so training further never returns worse ones; the record's
``kept_iteration`` says which, 0 for the given weights). Writes ``refine.pt`` and
``refine.json`` (the record: command, data, training, validation) into ``--out``; copy both to
``detect/builtin/weights/`` to make them the default.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..detection import TileBox
from .backend import builtin_views
from .data import KNOWN_CLASSES, augment, load_room, random_view, room_folders, synth_seed, tile_labels
from .model import torch_module
from .refine import BoxRefiner, RefineConfig, box_window, build_refiner, inout_targets, network_moves, save_refiner

TILE = 576
SIGMA = (0.01, 0.2)


def room_samples(folder: Path, seed: int, config: RefineConfig, views_per_room: int = 8, jitters: int = 3,
                 aug: bool = True) -> dict[str, NDArray]:
    """Training samples of one room: windows (N, S, S, 3) uint8, class ids (N,), true moves (N, 4),
    input boxes (N, 4) and the tile's focal length (N,) in pixels."""
    rng = np.random.default_rng(seed)
    room = load_room(folder, width=1024)
    fixed = builtin_views(TILE)
    wins, cls, moves, boxes, focal = [], [], [], [], []
    for k in range(views_per_room):
        view = fixed[int(rng.integers(len(fixed)))] if k % 4 == 0 else random_view(rng, room, TILE, aim=1.0)
        lab = tile_labels(room, view, TILE)
        for b, c in zip(lab.boxes, lab.classes):
            if b[0] <= 2 or b[1] <= 2 or b[2] >= TILE - 2 or b[3] >= TILE - 2:
                continue
            w, h = b[2] - b[0], b[3] - b[1]
            for _ in range(jitters):
                sigma = math.exp(rng.uniform(math.log(SIGMA[0]), math.log(SIGMA[1])))
                noisy = b + np.clip(rng.normal(0.0, sigma, 4), -0.35, 0.35) * np.array([w, h, w, h])
                if not (noisy[2] - noisy[0] > 2 and noisy[3] - noisy[1] > 2):
                    continue
                nw, nh = noisy[2] - noisy[0], noisy[3] - noisy[1]
                win = box_window(room.rgb, TileBox(view, noisy), config.size, config.margin)
                wins.append(augment(win, rng) if aug else win)
                cls.append(int(c))
                moves.append((b - noisy) / np.array([nw, nh, nw, nh]))
                boxes.append(noisy)
                focal.append(view.focal)
    n = len(wins)
    S = config.size
    return {"windows": np.array(wins, np.uint8).reshape(n, S, S, 3), "classes": np.array(cls, np.int64),
            "moves": np.array(moves, np.float32).reshape(n, 4), "boxes": np.array(boxes).reshape(n, 4),
            "focal": np.array(focal, np.float64)}


def _job(args: tuple) -> dict[str, NDArray]:
    return room_samples(*args)


def make_samples(roots: list[Path], rooms: int, seed: int, config: RefineConfig, views_per_room: int, jitters: int,
                 aug: bool, workers: int) -> dict[str, NDArray]:
    """Samples of the first ``rooms`` rooms under each of ``roots`` (see :func:`room_samples`), concatenated."""
    folders = [f for root in roots for f in room_folders(root)[:rooms]]
    jobs = [(f, seed * 100003 + i, config, views_per_room, jitters, aug) for i, f in enumerate(folders)]
    t0 = time.time()
    parts = []
    if workers > 1:
        from multiprocessing import get_context

        with get_context("fork").Pool(workers) as pool:
            for i, p in enumerate(pool.imap(_job, jobs, chunksize=4)):
                parts.append(p)
                if (i + 1) % 100 == 0:
                    print(f"  samples: {i + 1}/{len(jobs)} rooms, {time.time() - t0:.0f} s", file=sys.stderr)
    else:
        parts = [_job(j) for j in jobs]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def edge_errors_deg(samples: dict[str, NDArray], moves: NDArray) -> NDArray[np.float64]:
    """Signed edge errors (N, 4) in degrees at the tile's focal length: the box moved by ``moves`` minus the
    true box (``moves`` zero: the input boxes' errors)."""
    b = samples["boxes"]
    w, h = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
    side = np.stack([w, h, w, h], 1)
    err_px = (moves - samples["moves"]) * side
    return np.rad2deg(np.arctan(err_px / samples["focal"][:, None]))


def _predict(net: Any, samples: dict[str, NDArray], config: RefineConfig, batch: int = 512) -> NDArray[np.float64]:
    """Edge moves (N, 4) the network reads on the samples' windows (one pass)."""
    eye = np.eye(len(config.classes), dtype=np.float32)
    net.eval()
    out = [network_moves(net, config, samples["windows"][i:i + batch], eye[samples["classes"][i:i + batch]])
           for i in range(0, len(samples["classes"]), batch)]
    net.train()
    return np.concatenate(out)


def _summary(err: NDArray[np.float64]) -> dict[str, Any]:
    a = np.abs(err)
    return {"median_abs_deg": np.median(a, 0).round(3).tolist(), "mean_abs_deg": a.mean(0).round(3).tolist(),
            "within_0.5": (a <= 0.5).mean(0).round(3).tolist(), "over_2": (a > 2.0).mean(0).round(3).tolist()}


def train(data: list[Path], val: Path, out: Path, *, rooms: int, val_rooms: int, minutes: float, seed: int,
          iterations: int | None = None, batch: int = 128, lr: float = 2e-3, workers: int = 2,
          views_per_room: int = 8, jitters: int = 3, init: Path | None = None) -> dict[str, Any]:
    """Train for ``minutes`` of wall time (or ``iterations``, whichever ends first); save ``out/refine.pt`` and
    ``out/refine.json``; return the record. ``init``: a refiner's ``.pt`` file (:func:`save_refiner`) to go on
    training from instead of random weights; its record is kept as the ``init`` entry of the new one."""
    if any(synth_seed(d) == 0 for d in data) or synth_seed(val) == 0:
        raise ValueError("seed 0 is the evaluation set: expected training and validation rooms of other seeds")
    if not all(room_folders(d) for d in data) or not room_folders(val):
        raise ValueError(f"expected synthetic rooms (folders with gt.json) under {', '.join(map(str, data))} and {val}")
    torch = torch_module()
    torch.manual_seed(seed)
    config = RefineConfig(tuple(KNOWN_CLASSES))
    start = BoxRefiner(init) if init is not None else None  # read before the minutes of sampling: fail early
    if start is not None and start.config != config:
        raise ValueError(f"{init}: a refiner of another shape or class list than this script trains")
    t0 = time.time()
    tr = make_samples(data, rooms, seed, config, views_per_room, jitters, True, workers)
    va = make_samples([val], val_rooms, seed + 1, config, views_per_room, 1, False, workers)
    gen_s = time.time() - t0
    print(f"samples: {len(tr['classes'])} training, {len(va['classes'])} validation ({gen_s:.0f} s)", file=sys.stderr)
    if len(tr["classes"]) == 0 or len(va["classes"]) == 0:
        raise ValueError("no objects to learn from: the rooms show no object of the detector's classes whole")
    net = build_refiner(config) if start is None else start.network.train()
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    n = len(tr["classes"])
    rng = np.random.default_rng(seed)
    nc = len(config.classes)
    before = _summary(edge_errors_deg(va, np.zeros_like(va["moves"], np.float64)))
    print(f"validation before: {before}", file=sys.stderr)
    budget = float(minutes) * 60.0
    t1, it, best, best_state, best_it, history = time.time(), 0, math.inf, None, None, []

    def validate() -> None:  # the state of iteration ``it`` on the validation samples; kept when the best so far
        nonlocal best, best_state, best_it
        score = float(np.abs(edge_errors_deg(va, _predict(net, va, config))).mean())
        history.append({"iteration": it, "loss": round(loss.item(), 5) if it else None,
                        "val_mean_abs_deg": round(score, 4)})
        print(f"it {it}" + (f" loss {loss.item():.4f}" if it else "") + f" val mean |edge error| {score:.3f} deg "
              f"({time.time() - t1:.0f} s)", file=sys.stderr)
        if score < best:
            best, best_state, best_it = score, {k: v.detach().clone() for k, v in net.state_dict().items()}, it

    loss = None
    if start is not None:  # the given weights are a candidate too: training further never returns worse ones
        validate()
    cpu0 = time.process_time()
    while time.time() - t1 < budget and (iterations is None or it < iterations):
        frac = max((time.time() - t1) / budget, it / iterations if iterations else 0.0)
        for g in opt.param_groups:
            g["lr"] = lr * 0.5 * (1.0 + math.cos(math.pi * min(frac, 1.0)))
        idx = rng.integers(0, n, batch)
        x = tr["windows"][idx].astype(np.float32) / 255.0
        y = tr["moves"][idx].copy()
        flip = rng.random(batch) < 0.5
        x[flip] = x[flip, :, ::-1]
        y[flip] = np.stack([-y[flip, 2], y[flip, 1], -y[flip, 0], y[flip, 3]], 1)
        xt = torch.from_numpy(np.ascontiguousarray(x)).permute(0, 3, 1, 2)
        ct = torch.nn.functional.one_hot(torch.from_numpy(tr["classes"][idx]), nc).float()
        target = torch.from_numpy(inout_targets(y, config.size, config.margin))
        loss = torch.nn.functional.binary_cross_entropy_with_logits(net(xt, ct), target)
        opt.zero_grad()
        loss.backward()
        opt.step()
        it += 1
        if it % 500 == 0:
            validate()
    if it % 500 != 0:  # the last state, where no check point fell on it
        validate()
    if best_state is not None:
        net.load_state_dict(best_state)
    out.mkdir(parents=True, exist_ok=True)
    path = save_refiner(net, config, out / "refine.pt")
    after1 = _summary(edge_errors_deg(va, _predict(net, va, config)))
    record = {
        "format": "pano2cad/box-refiner-record@1",
        "weights": "refine.pt",
        "weights_bytes": path.stat().st_size,
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "command": "python -m detect.builtin.train_refine " + " ".join(sys.argv[1:]),
        "network": {**config.to_json(), "parameters": int(sum(p.numel() for p in net.parameters()))},
        "data": {"train_dirs": [str(d) for d in data], "train_seeds": [synth_seed(d) for d in data],
                 "train_rooms": rooms, "train_samples": n, "val_dir": str(val), "val_seed": synth_seed(val),
                 "val_rooms": val_rooms, "val_samples": int(len(va["classes"])), "views_per_room": views_per_room,
                 "jitters": jitters, "sigma": list(SIGMA), "tile": TILE, "sample_seconds": round(gen_s, 1)},
        "training": {"iterations": it, "batch": batch, "lr": lr, "optimizer": "AdamW", "weight_decay": 1e-4,
                     "schedule": "cosine decay over the wall-time budget",
                     "loss": "binary cross-entropy of the columns' and rows' inside shares",
                     "seed": seed, "threads": torch.get_num_threads(), "wall_s": round(time.time() - t1, 1),
                     "cpu_s": round(time.process_time() - cpu0, 1), "kept_iteration": best_it,
                     "history": history},
        "validation": {"input boxes": before, "one pass": after1},
    }
    if start is not None:
        record["init"] = {"weights": str(init), "record": start.record}
    (out / "refine.json").write_text(json.dumps(record, indent=1), encoding="utf-8")
    return record


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m detect.builtin.train_refine", description=__doc__.split("\n")[0])
    p.add_argument("--data", type=Path, nargs="+", required=True, help="synthetic rooms to train on (one or more sets)")
    p.add_argument("--val", type=Path, required=True, help="synthetic rooms to validate on (another seed)")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--rooms", type=int, default=1200, help="rooms of each training set")
    p.add_argument("--val-rooms", type=int, default=30)
    p.add_argument("--minutes", type=float, default=25.0, help="wall-time budget")
    p.add_argument("--iterations", type=int, default=None, help="stop after this many iterations (if sooner)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--batch", type=int, default=128)
    p.add_argument("--lr", type=float, default=2e-3)
    p.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    p.add_argument("--views", type=int, default=8, help="tiles per room")
    p.add_argument("--jitters", type=int, default=3, help="input boxes per object and tile")
    p.add_argument("--init", type=Path, default=None,
                   help="go on training from these refiner weights (a refine.pt) instead of random ones")
    a = p.parse_args(argv)
    try:
        rec = train(a.data, a.val, a.out, rooms=a.rooms, val_rooms=a.val_rooms, minutes=a.minutes, seed=a.seed,
                    iterations=a.iterations, batch=a.batch, lr=a.lr, workers=a.workers, views_per_room=a.views,
                    jitters=a.jitters, init=a.init)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(rec["validation"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
