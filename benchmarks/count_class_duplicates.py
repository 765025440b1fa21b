"""One object detected as two classes: pairs of a run's detections of different classes on nearly the same box.

Run::

    .venv/bin/python benchmarks/count_class_duplicates.py out/s7/wallp_tune7000,out/s7/wallp_tune8000 [--iou 0.7]

Reads each room's ``detections.json`` of ``pano2cad eval`` / ``pano2cad run`` output folders (those marked
``used``: the detections the scene was built from) and counts the pairs of different classes whose panorama
boxes overlap by more than ``--iou`` (:func:`detect.nms.pano_box_iou`: the files keep the lon/lat extent, not the
tile boxes, so this is the IoU of the extents). Runs made with :func:`detect.nms.suppress_across_classes` in the
pipeline (session 7 on) have few left; runs made before show how often the class-aware merge produced them.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np

from detect.nms import pano_box_iou


def duplicate_pairs(run: Path, iou_threshold: float) -> list[tuple[str, str, str, float]]:
    """(room, class a, class b, IoU) for every pair of different classes above the threshold."""
    out = []
    for f in sorted(run.glob("*/detections.json")):
        d = json.loads(f.read_text())
        dets = [x for x in d["detections"] if x.get("used", True)]
        if len(dets) < 2:
            continue
        boxes = np.array([x["bbox_pano"] for x in dets], dtype=np.float64)
        iou = pano_box_iou(boxes, boxes, int(d["width"]), int(d["height"]))
        for i in range(len(dets)):
            for j in range(i + 1, len(dets)):
                if dets[i]["class"] != dets[j]["class"] and iou[i, j] > iou_threshold:
                    a, b = sorted((dets[i]["class"], dets[j]["class"]))
                    out.append((f.parent.name, a, b, float(iou[i, j])))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", help="run folders, comma-separated")
    ap.add_argument("--iou", type=float, default=0.7)
    args = ap.parse_args(argv)
    for run in (Path(p) for p in args.runs.split(",")):
        pairs = duplicate_pairs(run, args.iou)
        rooms = len({p[0] for p in pairs})
        kinds = Counter(f"{a} / {b}" for _, a, b, _ in pairs)
        print(f"{run}: {len(pairs)} pairs in {rooms} of {len(list(run.glob('*/detections.json')))} rooms"
              + (": " + ", ".join(f"{k} {n}" for k, n in kinds.most_common()) if pairs else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
