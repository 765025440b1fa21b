"""What the wall snap adds to the room step: the layout from the labels, with the walls snapped, and with the height.

Run::

    pano2cad eval --data out/tune7000 --out out/runs/t7000 --detector builtin --samples 3000
    .venv/bin/python benchmarks/eval_wallsnap.py out/tune7000 out/runs/t7000

For every room of a synthetic set, :func:`layout.roomgeom.estimate_room_geometry`
runs on the run's ``label_ids.png`` at the room's true camera height with the
run's detections masked (``--mask run``, the boxes of ``detections.json``
marked used: the pipeline's mask) or the gt boxes (``--mask gt``, as
``benchmarks/eval_layout_labels.py``), median ceiling estimate (as the
pipeline with objects). Then :func:`layout.wallsnap.snap_walls`
moves the walls onto the panorama's ceiling-wall edges and
:func:`layout.wallsnap.snap_ceiling_height` scales the room onto its
floor-wall edges (the same mask; both by :func:`layout.wallsnap.snap_room`, as
the pipeline). Printed: the mean and median 3D IoU
against gt.json (:func:`layout.metrics.score_layout`) and the mean
wall-height error after each step, the rooms each step makes better or
worse by more than 0.005, how many walls moved and rooms were scaled, the
median time of the two snaps, and the rooms that changed most.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    from PIL import Image

    from layout.likelihood import boxes_mask
    from layout.metrics import score_layout
    from layout.roomgeom import RoomGeometryError, estimate_room_geometry
    from layout.wallsnap import snap_room

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="synthetic set (pano2cad synth output; never seed 0 for choices)")
    ap.add_argument("run", type=Path, help="pano2cad eval output on it (label_ids.png per room)")
    ap.add_argument("--mask", choices=["run", "gt"], default="run",
                    help="objects masked: the run's detections (the pipeline's mask) or the gt boxes")
    ap.add_argument("--worst", type=int, default=6, help="rooms listed whose 3D IoU changed most")
    args = ap.parse_args(argv)

    rows, names, unsolved, moved, scaled, secs = [], [], [], 0, 0, []
    for room in sorted(p for p in args.data.iterdir() if (p / "gt.json").is_file()):
        lab_p = args.run / room.name / "label_ids.png"
        if not lab_p.is_file():
            continue
        gt = json.loads((room / "gt.json").read_text())
        h = float(gt["camera_height_m"])
        lab = np.array(Image.open(lab_p))
        if args.mask == "gt":
            objs, width = gt["objects"], float(gt["image"]["width"])
        else:
            det_p = args.run / room.name / "detections.json"
            if not det_p.is_file():
                raise SystemExit(f"{det_p}: missing (a pano2cad eval output has one per room); or use --mask gt")
            dets = json.loads(det_p.read_text())
            objs, width = [d for d in dets["detections"] if d.get("used")], float(dets["width"])
        boxes = np.array([o["bbox_pano"] for o in objs if o.get("bbox_pano")], float).reshape(-1, 4)
        mask = boxes_mask(boxes * lab.shape[1] / width, lab.shape[1]) if len(boxes) else None
        try:
            g = estimate_room_geometry(lab, h, object_mask=mask, ceiling_estimate="median")
        except RoomGeometryError:
            unsolved.append(room.name)
            continue
        img = np.array(Image.open(room / gt.get("image", {}).get("file", "pano.png")).convert("RGB"))
        t0 = time.perf_counter()
        snap = snap_room(img, g.floor, g.ceiling_z, h, object_mask=mask)
        secs.append(time.perf_counter() - t0)
        walls, height = snap.walls, snap.height
        moved += int(walls.moved.sum())
        scaled += int(height.moved)
        gf, gc = gt["room"]["floor"], float(gt["room"]["ceiling_z"])
        row = []
        for floor, cz in ((g.floor, g.ceiling_z), (walls.floor, walls.ceiling_z), (height.floor, height.ceiling_z)):
            s = score_layout(floor, float(cz), gf, gc, camera_height=h, width=lab.shape[1])
            row += [s.iou_3d, abs(float(cz) - gc)]
        rows.append(row)
        names.append(room.name)
    if not rows:
        raise SystemExit(f"{args.run}: no label_ids.png of the rooms of {args.data}")
    a = np.array(rows)
    print(f"{args.data}: {len(a)} rooms, true camera height, {'gt boxes' if args.mask == 'gt' else 'detections'} "
          "masked, the run's labels"
          + (f" ({len(unsolved)} the room step cannot solve: {', '.join(unsolved)})" if unsolved else ""))
    print()
    print("| step | mean 3D IoU | median 3D IoU | wall height error cm (mean) | rooms better | rooms worse |")
    print("|---|---:|---:|---:|---:|---:|")
    steps = ("room step (labels)", "+ walls and ceiling on the creases", "+ room scaled onto the floor creases")
    for k, name in enumerate(steps):
        iou, err = a[:, 2 * k], a[:, 2 * k + 1]
        better = int(np.sum(iou > a[:, 0] + 0.005)) if k else 0
        worse = int(np.sum(iou < a[:, 0] - 0.005)) if k else 0
        print(f"| {name} | {iou.mean():.4f} | {np.median(iou):.4f} | {100 * err.mean():.2f} | {better} | {worse} |")
    print()
    print(f"walls moved: {moved}; rooms scaled: {scaled} of {len(a)}; both snaps {1000 * np.median(secs):.0f} ms "
          "median per room")
    change = a[:, 4] - a[:, 0]
    order = np.argsort(-np.abs(change))[: args.worst]
    print("largest changes: " + "; ".join(f"{names[i]} {a[i, 0]:.3f} -> {a[i, 4]:.3f}" for i in order))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
