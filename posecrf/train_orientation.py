"""Train the orientation network (:mod:`posecrf.orientnet`) on the project's synthetic rooms.

    pano2cad synth --rooms 1600 --seed 3000 --size 1024 --out out/train3000
    pano2cad synth --rooms 1600 --seed 5000 --size 1024 --out out/train5000
    python -m posecrf.train_orientation --rooms out/train5000 out/train3000 --out posecrf/weights/orientnet.pt \
        --epochs 24 --jitter 8 --val-fraction 0.05

(the committed weights, session 31: 3040 training rooms, the last 160 of train3000 held out, 43 minutes on 2 CPU
cores; the record ``posecrf/weights/orientnet.json`` holds the command and the held-out figures). ``--init``
starts from given weights instead of a fresh network (fine-tuning); session 34 fine-tuned the committed weights for
8 epochs on 1600 more rooms (seed 6000), held-out chairs within 45 deg 95.1 -> 96.3 %, but the pipeline on the tuning
sets was no better and they were not kept (docs/EVALUATION.md, "Session 34").

Data: room folders written by ``pano2cad synth`` (``pano.png`` and
``gt.json``). Every object of a class in :data:`~posecrf.orientnet.ORIENT_CLASSES`
with at least ``--min-pixels`` visible pixels gives ``--jitter`` crops
(:func:`posecrf.crops.extract_crop` of its gt box, each edge moved by up to
``--box-jitter`` of the box size, as a detector's box would be), labelled
with the crop-relative yaw of the object (:func:`posecrf.crops.relative_yaw`
along the crop's central ray). A crop mirrored left-right shows the object
at minus that yaw (the furniture is left-right symmetric), which doubles the
data at training time. The last ``--val-fraction`` of the rooms is held out
(with several ``--rooms`` folders, the rooms are taken folder by folder in
the order given, so the held-out rooms are the last folder's last ones)
and scored at the end (median angular error of the most likely bin and the
share within 45 degrees, per class).

Loss: cross-entropy against a soft target ``~ exp(kappa cos(bin - yaw))``
(kappa 16: about 15 degrees wide), Adam, cosine learning-rate decay.
A JSON record (command, data, figures) is written next to the weights.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from .crops import extract_crop, relative_yaw
from panogeom.boxes import box_width
from panogeom.rotation import angle_difference

from .orientnet import ORIENT_CLASSES, bin_yaws, build_network, head_probabilities, prepare_crops, save_weights

__all__ = ["crops_from_rooms", "train", "score", "read_rgb", "main"]


def read_rgb(path: Path) -> np.ndarray:
    """An image file as (H, W, 3) uint8 RGB; ValueError naming an unreadable file."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"{path}: not a readable image")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def crops_from_rooms(rooms: list[Path], jitter: int, box_jitter: float, min_pixels: int,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Network inputs, class indices and yaw labels of the objects of ``rooms``.

    Returns
    -------
    x : (N, 3, 64, 64) float32
    cls : (N,) int
        Index into ORIENT_CLASSES.
    yaw : (N,) float
        Crop-relative yaw, radians.
    """
    xs, cs, ys = [], [], []
    for room in rooms:
        gt = json.loads((room / "gt.json").read_text())
        pano = read_rgb(room / "pano.png")
        H, W = pano.shape[:2]
        for obj in gt["objects"]:
            if obj["class"] not in ORIENT_CLASSES or obj.get("visible_px", 0) < min_pixels:
                continue
            if obj.get("symmetry", "none") != "none":
                continue
            u0, v0, u1, v1 = (float(t) for t in obj["bbox_pano"])
            bw, bh = box_width(obj["bbox_pano"], W), v1 - v0
            crops = []
            for j in range(jitter):
                d = np.zeros(4) if j == 0 else rng.uniform(-box_jitter, box_jitter, 4) * [bw, bh, bw, bh]
                box = [u0 + d[0], max(0.0, v0 + d[1]), u1 + d[2], min(float(H), v1 + d[3])]
                box[0] %= W
                box[2] %= W
                if box[3] - box[1] < 4:
                    continue
                try:
                    crop, view = extract_crop(pano, box)
                except ValueError:
                    continue
                crops.append(crop)
                ys.append(float(relative_yaw(math.radians(obj["yaw_deg"]), view.direction)))
                cs.append(ORIENT_CLASSES.index(obj["class"]))
            if crops:
                xs.append(prepare_crops(crops))
    if not xs:
        return np.zeros((0, 3, 64, 64), np.float32), np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(xs), np.array(cs, np.int64), np.array(ys)


def _soft_targets(yaw: np.ndarray, kappa: float) -> np.ndarray:
    logit = kappa * np.cos(bin_yaws()[None, :] - yaw[:, None])
    t = np.exp(logit - logit.max(axis=1, keepdims=True))
    return (t / t.sum(axis=1, keepdims=True)).astype(np.float32)


def score(probs: np.ndarray, yaw: np.ndarray, cls: np.ndarray) -> dict:
    """Per class: crops, median angular error of the most likely bin (deg) and the share within 45 deg."""
    best = bin_yaws(probs.shape[1])[probs.argmax(axis=1)]
    err = np.degrees(angle_difference(best, yaw))
    out = {}
    for k, name in enumerate(ORIENT_CLASSES):
        m = cls == k
        if m.any():
            out[name] = {"crops": int(m.sum()), "median_error_deg": round(float(np.median(err[m])), 1),
                         "within_45_deg": round(float(np.mean(err[m] <= 45.0)), 3)}
    return out


def train(x: np.ndarray, cls: np.ndarray, yaw: np.ndarray, epochs: int, batch: int, lr: float,
          kappa: float, seed: int, log=print, init: str | Path | None = None):
    """Train a network, fresh or from the weights at ``init``; returns the torch module (eval mode)."""
    import torch

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = build_network()
    if init is not None:
        from .orientnet import load_orientation_net

        start = load_orientation_net(init)
        if tuple(start.classes) != tuple(ORIENT_CLASSES):
            raise ValueError(f"init: expected a network of the classes {list(ORIENT_CLASSES)}, got "
                             f"{list(start.classes)}")
        net.load_state_dict(start.module.state_dict())
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=1e-4)
    steps = epochs * max(1, math.ceil(len(x) / batch))
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=steps, pct_start=0.15)
    X = torch.from_numpy(x)
    for ep in range(epochs):
        net.train()
        order = rng.permutation(len(x))
        total, t0 = 0.0, time.time()
        for s in range(0, len(order), batch):
            b = order[s:s + batch]
            flip = rng.random(len(b)) < 0.5
            xb = X[b].clone()
            xb[torch.from_numpy(flip)] = torch.flip(xb[torch.from_numpy(flip)], dims=[3])
            yb = np.where(flip, -yaw[b], yaw[b])
            gain = torch.from_numpy(rng.uniform(0.7, 1.3, (len(b), 1, 1, 1)).astype(np.float32))
            xb = (xb + 0.5) * gain - 0.5
            target = torch.from_numpy(_soft_targets(yb, kappa))
            logits = net(xb)[torch.arange(len(b)), torch.from_numpy(cls[b])]
            loss = -(target * torch.log_softmax(logits, dim=1)).sum(dim=1).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss.detach()) * len(b)
        log(f"epoch {ep + 1}/{epochs}: loss {total / len(x):.3f} ({time.time() - t0:.0f} s)")
    net.eval()
    return net


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m posecrf.train_orientation", description=__doc__.split("\n")[0])
    ap.add_argument("--rooms", required=True, nargs="+", metavar="DIR",
                    help="folders of pano2cad synth rooms (room-*/pano.png, gt.json), taken in the order given")
    ap.add_argument("--out", required=True, help="weights file to write (.pt); a .json record beside it")
    ap.add_argument("--val-fraction", type=float, default=0.1)
    ap.add_argument("--jitter", type=int, default=4, help="crops per object (the first with the exact box)")
    ap.add_argument("--box-jitter", type=float, default=0.08)
    ap.add_argument("--min-pixels", type=int, default=300)
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--kappa", type=float, default=16.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--init", default=None, metavar="PT", help="start from these weights (a fine-tuning run)")
    a = ap.parse_args(argv)
    import torch

    torch.set_num_threads(max(1, torch.get_num_threads()))
    rooms = [p for d in a.rooms for p in sorted(Path(d).glob("room-*")) if (p / "gt.json").is_file()]
    if len(rooms) < 2:
        print(f"error: no synthetic rooms under {' '.join(a.rooms)}", file=sys.stderr)
        return 2
    n_val = max(1, int(round(len(rooms) * a.val_fraction)))
    rng = np.random.default_rng(a.seed)
    t0 = time.time()
    x, c, y = crops_from_rooms(rooms[:-n_val], a.jitter, a.box_jitter, a.min_pixels, rng)
    xv, cv, yv = crops_from_rooms(rooms[-n_val:], 1, 0.0, a.min_pixels, rng)
    print(f"{len(x)} training crops from {len(rooms) - n_val} rooms, {len(xv)} validation crops from {n_val} "
          f"rooms ({time.time() - t0:.0f} s)", flush=True)
    try:
        net = train(x, c, y, a.epochs, a.batch, a.lr, a.kappa, a.seed, log=lambda s: print(s, flush=True),
                    init=a.init)
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    val = score(head_probabilities(net, xv, cv), yv, cv)
    print(json.dumps(val, indent=1))
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_weights(net, ORIENT_CLASSES, out)
    record = {
        "format": "pano2cad/orientation-net-record@1",
        "weights": out.name,
        "weights_bytes": out.stat().st_size,
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "command": "python -m posecrf.train_orientation " + " ".join(sys.argv[1:] if argv is None else argv),
        "rooms": {"folders": list(a.rooms), "train": len(rooms) - n_val, "val": n_val},
        "crops": {"train": int(len(x)), "val": int(len(xv))},
        "seconds": round(time.time() - t0, 1),
        "init": a.init,
        "validation": val,
    }
    out.with_suffix(".json").write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {out} and {out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
