"""Train the builtin detector on synthetic rooms (CPU is enough).

Usage::

    pano2cad synth --seed 3000 --rooms 1440 --size 1024 --out out/train/detect   # run 7; run 6: 720, 1-5: 240
    pano2cad synth --seed 3500 --rooms 90 --size 1024 --out out/train/detect_val  # run 7; runs 1-6: 30
    python -m detect.builtin.train --data out/train/detect --val out/train/detect_val \\
        --out detect/builtin/weights --minutes 25
    # optionally more stages, each starting from the last weights (run 7: --size 224 --lr 1e-3 --minutes 90):
    python -m detect.builtin.train ... --init detect/builtin/weights/builtin.pt --seed 1 --lr 2e-3

Every iteration draws a batch of random perspective tiles from the training
rooms (:class:`~detect.builtin.data.TileSampler`: random pointing, pitch and
FOV, half of them aimed at an object of a class drawn uniformly; labels from
the warped instance masks; photometric augmentation and flips), so no tile is
seen twice. The loss is CenterNet's: a penalty-reduced focal loss on the
class heatmaps plus L1 on log box size and centre offset. AdamW with a linear
warm-up and a cosine decay over the planned iterations (``--iterations``, or
as many as ``--minutes`` allows, re-estimated from the pace every 20 iterations).

Afterwards the weights are written (``builtin.pt``) and :func:`validate`
runs them through the panorama driver on the validation rooms to choose the
inference setting (network input size, with or without the wide views of
:func:`~detect.builtin.backend.builtin_views`, mirrored tiles or not) and the
default score threshold. The record ``builtin.json`` keeps the data seeds,
rooms, tiles, iterations, augmentation, earlier stages, the validation AP per
class and setting, torch version, parameter count and date. Never train or
tune on the evaluation set (seed 0): both refuse a set whose index.json says
seed 0.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..backends._common import KNOWN_CLASSES
from .backend import BuiltinDetector, builtin_views, save_weights
from .data import TileSampler, load_rooms, room_folders, synth_seed
from .evaluate import DIFFICULT_FRACTION, detect_rooms, evaluate, load_ground_truth, tune_score_threshold
from .model import STRIDE, NetConfig, build_network, torch_module

__all__ = ["detection_loss", "train", "validate", "main"]

AUGMENTATION = ("gamma 0.7-1.4, saturation x0.5-1.5, contrast x0.7-1.3, brightness +-0.12, per-channel gain "
                "x0.88-1.12, Gaussian blur sigma 0.4-1.2 (p=0.3), Gaussian noise sigma 0.005-0.04 (p=0.5), "
                "left-right flip (p=0.5); views: FOV 75-105 deg (p=0.5) else 55-130 deg, pitch -60..15 deg "
                "or aimed at an object (p=0.6), 5-degree steps, tiles rendered at 2x and area-reduced")


def detection_loss(outputs: tuple[Any, Any, Any], targets: dict[str, Any]) -> tuple[Any, dict[str, float]]:
    """CenterNet loss of a batch.

    Parameters
    ----------
    outputs : (heat, size, offset) torch tensors
        Network outputs, ``heat`` as logits ``(B, C, G, G)``.
    targets : dict of torch tensors
        ``heat``, ``heat_w`` ``(B, C, G, G)``, ``box`` ``(B, 4, G, G)``, ``box_w`` ``(B, G, G)``
        (:func:`detect.builtin.data.encode_targets`).

    Returns
    -------
    loss : scalar tensor
    parts : dict of float
        ``heat``, ``size``, ``offset`` terms.

    Examples
    --------
    >>> torch = torch_module()
    >>> t = {"heat": torch.zeros(1, 1, 4, 4), "heat_w": torch.ones(1, 1, 4, 4), "box": torch.zeros(1, 4, 4, 4),
    ...      "box_w": torch.zeros(1, 4, 4)}
    >>> t["heat"][0, 0, 1, 2] = 1.0; t["box_w"][0, 1, 2] = 1.0
    >>> loss, parts = detection_loss((torch.zeros(1, 1, 4, 4), torch.zeros(1, 2, 4, 4), torch.zeros(1, 2, 4, 4)), t)
    >>> sorted(parts), round(parts["heat"], 3)
    (['heat', 'offset', 'size'], 2.773)
    """
    torch = torch_module()
    F = torch.nn.functional
    heat, size, offset = outputs
    th, tw = targets["heat"], targets["heat_w"]
    pos = (th >= 1.0).float()
    logp, log1mp = F.logsigmoid(heat), F.logsigmoid(-heat)
    p = torch.sigmoid(heat)
    pos_loss = -logp * (1.0 - p) ** 2 * pos
    neg_loss = -log1mp * p ** 2 * (1.0 - th) ** 4 * (1.0 - pos)
    n_pos = pos.sum().clamp(min=1.0)
    l_heat = ((pos_loss + neg_loss) * tw).sum() / n_pos
    bw = targets["box_w"].unsqueeze(1)
    n_box = targets["box_w"].sum().clamp(min=1.0)
    l_size = ((size - targets["box"][:, :2]).abs() * bw).sum() / n_box
    l_off = ((offset - targets["box"][:, 2:]).abs() * bw).sum() / n_box
    loss = l_heat + l_size + l_off
    return loss, {"heat": l_heat.item(), "size": l_size.item(), "offset": l_off.item()}


def train(data: Path, val: Path, out: Path, *, iterations: int | None = None, minutes: float | None = None,
          batch: int = 16, size: int = 160, lr: float = 3e-3, seed: int = 0, threads: int = 2,
          widths: tuple[int, ...] = NetConfig.widths, head: int = NetConfig.head, val_rooms: int | None = None,
          init: Path | None = None, log=print) -> dict[str, Any]:
    """Train, save ``out/builtin.pt`` and ``out/builtin.json``; return the record.

    Exactly one of ``iterations`` and ``minutes`` is given. ``init``: start from
    these weights (and their record's network shape) instead of from scratch;
    the record then lists the earlier training stages under ``training.earlier``.
    """
    if (iterations is None) == (minutes is None):
        raise ValueError(f"expected exactly one of iterations and minutes, got {iterations!r} and {minutes!r}")
    if synth_seed(data) == 0 or synth_seed(val) == 0:
        raise ValueError("seed 0 is the evaluation set: expected training and validation rooms of other seeds")
    torch = torch_module()
    torch.set_num_threads(int(threads))
    torch.manual_seed(seed)
    t_start, c_start = time.perf_counter(), time.process_time()
    classes = KNOWN_CLASSES
    rooms = load_rooms(data)
    log(f"{len(rooms)} training rooms from {data}")
    sampler = TileSampler(rooms, size, seed=seed, classes=classes)
    earlier: list[dict[str, Any]] = []
    if init is not None:
        start = BuiltinDetector(init)
        config, net = start.config, start._net
        prev = start.record.get("training")
        if prev:
            earlier = [*prev.get("earlier", []), {k: v for k, v in prev.items() if k != "earlier"}]
        if tuple(config.classes) != tuple(classes):
            raise ValueError(f"init: expected weights for classes {list(classes)}, got classes "
                             f"{list(config.classes)}")
        if config.input_size != size:
            # the network is fully convolutional: only the tile size it learns on changes
            log(f"init: weights trained on {config.input_size}-px tiles, continuing on {size}-px tiles")
            config = dataclasses.replace(config, input_size=int(size))
        log(f"starting from {init}")
    else:
        config = NetConfig(tuple(classes), tuple(widths), int(head), int(size))
        net = build_network(config)
    n_params = int(sum(p.numel() for p in net.parameters()))
    log(f"network: {n_params} parameters, input {size}x{size}, stride {STRIDE}")
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    budget = None if minutes is None else float(minutes) * 60.0
    planned = int(iterations) if iterations is not None else None
    warm = 30
    it = 0
    mark, per = (0, time.perf_counter()), None
    running: dict[str, float] = {}
    net.train()
    while planned is None or it < planned:
        if budget is not None and it >= 20 and it % 20 == 0:
            # Re-plan from the recent pace (the machine is shared; the first iterations fill caches).
            now = time.perf_counter()
            recent = (now - mark[1]) / max(it - mark[0], 1)
            per = recent if per is None else 0.7 * per + 0.3 * recent
            mark = (it, now)
            planned = max(it + 1, it + int((budget - (now - t_start)) / per))
            if it % 200 == 0 or it == 20:
                log(f"{per:.2f} s per iteration: planning {planned} iterations")
        total = planned if planned is not None else 10 ** 9
        f = (it + 1) / warm if it < warm else 0.5 * (1.0 + math.cos(math.pi * min((it - warm) / max(total - warm, 1),
                                                                               1.0)))
        for g in opt.param_groups:
            g["lr"] = lr * max(f, 0.02)
        imgs, tg, _ = sampler.batch(batch)
        x = torch.from_numpy(imgs).permute(0, 3, 1, 2).float().div_(255.0)
        targets = {k: torch.from_numpy(v) for k, v in tg.items()}
        loss, parts = detection_loss(net(x), targets)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 10.0)
        opt.step()
        for k, v in parts.items():
            running[k] = 0.9 * running.get(k, v) + 0.1 * v
        it += 1
        if it % 25 == 0:
            el = time.perf_counter() - t_start
            log(f"it {it}/{planned} {el / 60:.1f} min  " + "  ".join(f"{k} {v:.3f}" for k, v in running.items()))
    net.eval()
    train_wall = time.perf_counter() - t_start
    train_cpu = time.process_time() - c_start
    out.mkdir(parents=True, exist_ok=True)
    wpath = save_weights(net, config, out / "builtin.pt")
    record = {
        "format": "pano2cad/builtin-detector-record@1",
        "weights": wpath.name,
        "weights_bytes": wpath.stat().st_size,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": " ".join(["python", "-m", "detect.builtin.train", *sys.argv[1:]]),
        "classes": list(classes),
        "network": {**config.to_json(), "stride": STRIDE, "parameters": n_params,
                    "kind": "CenterNet-style heatmap + log-size + offset, FPN to stride 4"},
        "data": {"train_dir": str(data), "train_seed": synth_seed(data), "train_rooms": len(rooms),
                 "pano_width": int(rooms[0].rgb.shape[1])},
        "training": {"command": " ".join(["python", "-m", "detect.builtin.train", *sys.argv[1:]]),
                     "iterations": it, "batch": batch, "tiles_seen": it * batch, "lr": lr, "optimizer": "AdamW",
                     "weight_decay": 1e-4, "schedule": f"linear warm-up {warm} it, cosine decay",
                     "seed": seed, "threads": threads, "wall_s": round(train_wall, 1), "cpu_s": round(train_cpu, 1),
                     "init": None if init is None else str(init), "earlier": earlier,
                     "augmentation": AUGMENTATION,
                     "tile_labels": "tight boxes of the instance mask warped into the tile (nearest); objects "
                                    "under 12 px, with a side under 3 px, or with under 35% of their box in "
                                    "the tile (unless a side reaches 45% of it) are ignored"},
        "environment": {"torch": torch.__version__, "numpy": np.__version__, "python": platform.python_version(),
                        "cpus": os.cpu_count()},
    }
    return validate(out, val, record, val_rooms=val_rooms, log=log)


#: The paper's object classes (its Table 2): settings are chosen by their mean AP on the validation rooms.
PAPER_CLASSES = ("bed", "chair", "tv", "plant")


def _paper_mean(res: Any) -> float:
    aps = [res.ap(c) for c in PAPER_CLASSES]
    aps = [a for a in aps if np.isfinite(a)]
    return float(np.mean(aps)) if aps else float(res.mean_ap)


def _setting(size: int, wide: bool, flip: bool) -> str:
    views = "18 + 6 wide views (130 deg, pitch -25)" if wide else "18 views (paper)"
    return f"input {size}, {views}" + (", flip" if flip else "")


def validate(out: Path, val: Path, record: dict[str, Any] | None = None, *, val_rooms: int | None = None,
             log=print) -> dict[str, Any]:
    """Choose the view set and score threshold on validation rooms; write ``out/builtin.json``; return it.

    The weights ``out/builtin.pt`` run through the panorama driver on the
    rooms of ``val`` with the paper's 18 views and with the wide views added
    (:func:`~detect.builtin.backend.builtin_views`), each at the training
    input size and 64 pixels more (tiles twice that, area-reduced); the
    setting with the highest mean AP over the paper's classes
    (:data:`PAPER_CLASSES`) is tried again with mirrored tiles averaged in
    (``flip``); the best is kept, and the score threshold with the best mean
    F1 (all classes) on it.
    ``record`` (default: the existing ``out/builtin.json``) gets the results.
    """
    if synth_seed(val) == 0:
        raise ValueError("seed 0 is the evaluation set: expected validation rooms of another seed")
    wpath = out / "builtin.pt"
    rpath = out / "builtin.json"
    if record is None:
        if not rpath.is_file():
            raise ValueError(f"{rpath}: expected the training record next to the weights, found none")
        record = json.loads(rpath.read_text(encoding="utf-8"))
    folders = room_folders(val)[:val_rooms]
    truths = [load_ground_truth(f) for f in folders]
    train_size = int(record["network"]["input_size"])
    results = {}

    def run(size: int, wide: bool, flip: bool) -> None:
        det = BuiltinDetector(wpath, score_threshold=0.05, input_size=size, flip=flip)
        dets = detect_rooms(det, folders, builtin_views(2 * size, wide=wide))
        res = evaluate(dets, truths, det.classes)
        thr = tune_score_threshold(dets, truths, det.classes)
        results[(size, wide, flip)] = (res, thr)
        log(f"validation ({_setting(size, wide, flip)}): mAP {res.mean_ap:.3f}  " +
            "  ".join(f"{c} {r.ap:.3f}" for c, r in res.classes.items()) + f"  best-F1 score {thr:.2f}")

    for size in sorted({train_size, train_size + 64}):
        for wide in (False, True):
            run(size, wide, False)
    def score(k: tuple[int, bool, bool]) -> float:
        return _paper_mean(results[k][0])

    size, wide, _ = max(results, key=score)
    run(size, wide, True)
    size, wide, flip = max(results, key=score)
    res, thr = results[(size, wide, flip)]
    record["data"] = {**record.get("data", {}), "val_dir": str(val), "val_seed": synth_seed(val),
                      "val_rooms": len(folders)}
    record["input_size"] = size
    record["flip"] = bool(flip)
    record["views"] = {"wide": bool(wide), "size": 2 * size}
    record["score_threshold"] = round(float(thr), 3)
    record["merge"] = ("detect.tiles.detect_panorama defaults: the group's medoid box (detect.nms.merge_sphere), "
                       "score by tile consensus 0.5 (detect.tiles.tile_consensus)")
    record["validation"] = {
        "iou": 0.5, "difficult_below_fraction": DIFFICULT_FRACTION, "detector_score_threshold": 0.05,
        "chosen": _setting(size, wide, flip), "border_snap": BuiltinDetector(wpath).border_snap,
        "ap": {c: round(r.ap, 4) for c, r in res.classes.items()},
        "mean_ap": round(res.mean_ap, 4),
        "selected_by": "mean AP of " + ", ".join(PAPER_CLASSES),
        "paper_classes_mean_ap_of_each_setting": {_setting(*k): round(_paper_mean(v[0]), 4)
                                                  for k, v in results.items()},
        "mean_ap_of_each_setting": {_setting(*k): round(v[0].mean_ap, 4) for k, v in results.items()},
    }
    tmp = rpath.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    tmp.replace(rpath)
    log(f"wrote {wpath} ({record.get('weights_bytes')} bytes) and {rpath}")
    return record


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m detect.builtin.train --data DIR --val DIR --out DIR``."""
    ap = argparse.ArgumentParser(prog="python -m detect.builtin.train", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--data", type=Path, help="training rooms (pano2cad synth output)")
    ap.add_argument("--val", type=Path, required=True, help="validation rooms (another seed)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "weights")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--iterations", type=int, default=None)
    g.add_argument("--minutes", type=float, default=None, help="time budget (default 20 when no --iterations)")
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--size", type=int, default=160, help="tile / network input side")
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--val-rooms", type=int, default=None, help="use only the first N validation rooms")
    ap.add_argument("--init", type=Path, default=None, help="continue from these weights (.pt)")
    ap.add_argument("--validate-only", action="store_true",
                    help="only redo the validation of OUT/builtin.pt (view set, score threshold) and its record")
    args = ap.parse_args(argv)
    log = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    minutes = args.minutes if args.minutes is not None or args.iterations is not None else 20.0
    try:
        if not args.validate_only and args.data is None:
            raise ValueError("--data: expected the training rooms (required unless --validate-only)")
        if args.validate_only:
            validate(args.out, args.val, val_rooms=args.val_rooms, log=log)
            return 0
        train(args.data, args.val, args.out, iterations=args.iterations, minutes=minutes, batch=args.batch,
              size=args.size, lr=args.lr, seed=args.seed, threads=args.threads, val_rooms=args.val_rooms,
              init=args.init,
              log=log)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
