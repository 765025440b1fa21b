"""Which part of the estimated surface labels costs the layout: hybrids of estimated and ground-truth labels.

Run::

    .venv/bin/python benchmarks/eval_label_parts.py out/tune7000 [--snap-ceiling]

For every room of a synthetic set the panorama is labelled by
:func:`layout.surfaces.estimate_surfaces` (committed weights, the room's gt
boxes masked as objects), and :func:`layout.roomgeom.estimate_room_geometry`
runs at the room's true camera height with the gt boxes masked (as
``benchmarks/eval_layout_labels.py``) on six label maps:

- ``estimated``: the labeller's map;
- ``estimated, true orientation``: the labeller's map with the generator's
  wall orientation (3 / 4) wherever both maps say wall;
- ``true, estimated orientation``: the converse;
- ``true, estimated upper half``: the generator's map with the labeller's
  rows above the horizon (the ceiling-wall boundary);
- ``true, estimated lower half``: the same below the horizon (the floor-wall
  boundary);
- ``true``: the generator's map.

Maps whose upper half is the labeller's use the median ceiling estimate (what
the pipeline uses with objects masked), the others the lowest mode (the room
step's default, as ``eval_layout_labels.py``). The mean and median 3D IoU
against gt.json (:func:`layout.metrics.score_layout`) of each say how much of
the labels' cost lies in the wall orientation, in the ceiling boundary and in
the floor boundary. A room the room step cannot solve scores 0.

Then, per room, how far the estimated boundaries are from the generator's
(:func:`layout.labelmap.observe_boundaries` of both maps, gt boxes masked):
the share of the columns where both maps show a contact and the rows differ
by more than 3 (at the label resolution), for the ceiling-wall and the
floor-wall boundary, with the "estimated" row's 3D IoU and wall-height error;
rooms listed where the ceiling share exceeds 0.3 or the IoU is under 0.6.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    from PIL import Image

    from layout.labelmap import observe_boundaries
    from layout.likelihood import boxes_mask
    from layout.metrics import score_layout
    from layout.roomgeom import RoomGeometryError, estimate_room_geometry
    from layout.surfaces import estimate_surfaces

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="synthetic set (pano2cad synth output; never seed 0 for choices)")
    ap.add_argument("--snap-ceiling", action="store_true",
                    help="label with estimate_surfaces(snap_ceiling=True): the ceiling-wall boundary snapped to "
                         "the image's edges (layout.surfaces.boundary; off by default)")
    ap.add_argument("--ceiling-net", default=None, metavar="PT",
                    help="label with estimate_surfaces(ceiling_net=...): the ceiling-wall boundary of these boundary "
                         "network weights (layout.surfaces.boundary_net; 'default' for the committed ones)")
    args = ap.parse_args(argv)
    net = None
    if args.ceiling_net:
        from layout.surfaces.boundary_net import load_boundary_net

        net = load_boundary_net(None if args.ceiling_net == "default" else args.ceiling_net)
    rooms = sorted(p for p in args.data.iterdir() if (p / "gt.json").is_file())
    if not rooms:
        raise SystemExit(f"{args.data}: no room folders with gt.json")
    scores: dict[str, list[float]] = {}
    per_room: list[tuple[str, float, float, float, float]] = []
    for room in rooms:
        gt = json.loads((room / "gt.json").read_text())
        h = float(gt["camera_height_m"])
        img = np.array(Image.open(room / "pano.png").convert("RGB"))
        s = img.shape[1] / float(gt["image"]["width"])
        boxes = np.array([o["bbox_pano"] for o in gt["objects"] if o.get("bbox_pano")], float).reshape(-1, 4) * s
        mask = boxes_mask(boxes, img.shape[1]) if len(boxes) else None
        est = estimate_surfaces(img, object_mask=mask, snap_ceiling=args.snap_ceiling, ceiling_net=net).labels
        true = np.array(Image.open(room / "labels.png"))
        if true.shape != est.shape:
            true = np.array(Image.fromarray(true).resize(est.shape[::-1], Image.NEAREST))
        walls = np.isin(est, (3, 4)) & np.isin(true, (3, 4))
        half = est.shape[0] // 2
        variants = {"estimated": (est, "median")}
        m = est.copy(); m[walls] = true[walls]
        variants["estimated, true orientation"] = (m, "median")
        m = true.copy(); m[walls] = est[walls]
        variants["true, estimated orientation"] = (m, "lowest_mode")
        m = true.copy(); m[:half] = est[:half]
        variants["true, estimated upper half"] = (m, "median")
        m = true.copy(); m[half:] = est[half:]
        variants["true, estimated lower half"] = (m, "lowest_mode")
        variants["true"] = (true, "lowest_mode")
        for name, (lab, ceiling) in variants.items():
            try:
                g = estimate_room_geometry(lab, h, object_mask=mask, ceiling_estimate=ceiling)
                iou = score_layout(g.floor, float(g.ceiling_z), gt["room"]["floor"], float(gt["room"]["ceiling_z"]),
                                   camera_height=h, width=lab.shape[1]).iou_3d
                height_err = abs(float(g.ceiling_z) - float(gt["room"]["ceiling_z"]))
            except RoomGeometryError:
                iou, height_err = 0.0, float("nan")
            scores.setdefault(name, []).append(float(iou))
            if name == "estimated":
                est_iou, est_height_err = float(iou), height_err
        ob_e, ob_t = observe_boundaries(est, mask), observe_boundaries(true, mask)
        off = []
        for ce, ct, ve, vt in ((ob_e.ceil_contact, ob_t.ceil_contact, ob_e.ceil_v, ob_t.ceil_v),
                               (ob_e.floor_contact, ob_t.floor_contact, ob_e.floor_v, ob_t.floor_v)):
            seen = ce & ct
            off.append(float(np.mean(np.abs(ve[seen] - vt[seen]) > 3.0)) if seen.any() else float("nan"))
        per_room.append((room.name, off[0], off[1], est_iou, est_height_err))
    print(f"{len(rooms)} rooms of {args.data}, true camera height, gt boxes masked: room step on hybrid labels"
          + (" (ceiling boundary snapped to edges)" if args.snap_ceiling else "")
          + (f" (ceiling boundary of the boundary network {args.ceiling_net})" if net is not None else ""))
    print("| labels | mean 3D IoU | median | rooms under 0.6 |\n|---|---:|---:|---:|")
    for name, v in scores.items():
        a = np.array(v)
        print(f"| {name} | {a.mean():.3f} | {np.median(a):.3f} | {int((a < 0.6).sum())} |")
    ceil_off = np.array([r[1] for r in per_room])
    floor_off = np.array([r[2] for r in per_room])
    print(f"\nboundary rows more than 3 off where both maps show a contact, share of those columns: ceiling median "
          f"{np.nanmedian(ceil_off):.2f} (max {np.nanmax(ceil_off):.2f}), floor median {np.nanmedian(floor_off):.2f} "
          f"(max {np.nanmax(floor_off):.2f})")
    print("| room | ceiling rows off | floor rows off | 3D IoU (estimated) | wall-height error (m) |\n|---|---:|---:|---:|---:|")
    for name, c, f, iou, herr in per_room:
        if c > 0.3 or iou < 0.6:
            print(f"| {name} | {c:.2f} | {f:.2f} | {iou:.3f} | {herr:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
