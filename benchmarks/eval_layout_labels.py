"""Where the layout error comes from: the room step on ground-truth labels against the pipeline's labels.

Run::

    pano2cad eval --data out/eval88 --out out/s4_gtscale --detector gt-boxes --gt-scale --samples 3000
    .venv/bin/python benchmarks/eval_layout_labels.py out/eval88 out/s4_gtscale

For every room of a synthetic set, :func:`layout.roomgeom.estimate_room_geometry`
runs at the room's true camera height with its gt boxes masked on two label
maps: the generator's ground-truth ``labels.png`` (lowest-mode ceiling, the
room step's default) and the pipeline's ``label_ids.png`` of the run
(median ceiling, what the pipeline uses when objects are masked). The 3D IoU
of both against gt.json (:func:`layout.metrics.score_layout`; a room the room
step cannot solve scores 0 and is listed) separates the labeller's share of
the layout error from the room step's. The run's label
maps are in its rectified frame, which for the upright synthetic panoramas is
the input's to a fraction of a degree.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    from PIL import Image

    from layout.likelihood import boxes_mask
    from layout.metrics import score_layout
    from layout.roomgeom import RoomGeometryError, estimate_room_geometry

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="synthetic set (pano2cad synth output)")
    ap.add_argument("run", type=Path, help="pano2cad eval output on it (label_ids.png per room)")
    ap.add_argument("--worst", type=int, default=8, help="list the rooms the labels cost most")
    args = ap.parse_args(argv)
    rows, unsolved = [], []
    for room in sorted(p for p in args.data.iterdir() if (p / "gt.json").is_file()):
        pred = args.run / room.name / "label_ids.png"
        if not pred.is_file():
            continue
        gt = json.loads((room / "gt.json").read_text())
        h = float(gt["camera_height_m"])
        boxes = np.array([o["bbox_pano"] for o in gt["objects"] if o.get("bbox_pano")], float).reshape(-1, 4)
        ious = []
        for path, ceiling in ((room / "labels.png", "lowest_mode"), (pred, "median")):
            lab = np.array(Image.open(path))
            s = lab.shape[1] / float(gt["image"]["width"])
            mask = boxes_mask(boxes * s, lab.shape[1]) if len(boxes) else None
            try:
                g = estimate_room_geometry(lab, h, object_mask=mask, ceiling_estimate=ceiling)
            except RoomGeometryError:  # the room step cannot solve these labels: the room scores 0
                ious.append(0.0)
                unsolved.append(f"{room.name} ({path.name})")
                continue
            sc = score_layout(g.floor, float(g.ceiling_z), gt["room"]["floor"], float(gt["room"]["ceiling_z"]),
                              camera_height=h, width=lab.shape[1])
            ious.append(sc.iou_3d)
        rows.append((room.name, *ious))
    if not rows:
        raise SystemExit(f"{args.run}: no label_ids.png of the rooms of {args.data}")
    a = np.array([r[1:] for r in rows], float)
    print(f"{len(rows)} rooms, true camera height, gt boxes masked: mean 3D IoU on ground-truth labels "
          f"{a[:, 0].mean():.3f} (median {np.median(a[:, 0]):.3f}), on the run's labels {a[:, 1].mean():.3f} "
          f"(median {np.median(a[:, 1]):.3f})")
    gap = sorted(rows, key=lambda r: r[2] - r[1])[: args.worst]
    if unsolved:
        print(f"not solved by the room step (scored 0): {', '.join(unsolved)}")
    print("largest losses to the labels: " + "; ".join(f"{n} {g:.2f} -> {p:.2f}" for n, g, p in gap))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
