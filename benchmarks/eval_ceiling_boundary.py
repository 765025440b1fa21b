"""The ceiling-wall boundary of the surface labels against the boundary network's, per room of synthetic sets.

Run::

    .venv/bin/python benchmarks/eval_ceiling_boundary.py out/tune7000 out/tune8000 [--weights PT]

For every room the panorama is labelled by
:func:`layout.surfaces.estimate_surfaces` (committed weights, the room's gt
boxes masked as objects, as ``benchmarks/eval_label_parts.py``). Its
ceiling-wall boundary (``SurfaceLabels.columns.ceiling_v``, the rows the
fusion chose from the geometric-context network) and the boundary network's
(:mod:`layout.surfaces.boundary_net`, ``--weights`` or the committed ones)
are compared with the empty room's true boundary (gt.json's polygon, ceiling
and camera height; :func:`layout.surfaces.train_boundary.room_boundary_targets`)
in every column, in pixels of the panorama's height. Printed per set: the
mean and median over rooms of each room's mean absolute error, the share of
columns more than 3 px off, the rooms where either is worse than 5 px, and
the network's floor-wall boundary error (behind furniture too) for reference.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def room_errors(room: Path, net) -> dict:
    """Mean absolute errors (px) and shares of columns more than 3 px off, labeller and network."""
    from PIL import Image

    from layout.likelihood import boxes_mask
    from layout.surfaces import estimate_surfaces
    from layout.surfaces.train_boundary import room_boundary_targets

    gt = json.loads((room / "gt.json").read_text())
    img = np.array(Image.open(room / "pano.png").convert("RGB"))
    h, w = img.shape[:2]
    s = w / float(gt["image"]["width"])
    boxes = np.array([o["bbox_pano"] for o in gt["objects"] if o.get("bbox_pano")], float).reshape(-1, 4) * s
    mask = boxes_mask(boxes, w) if len(boxes) else None
    true = room_boundary_targets(gt, w) * h
    lab = estimate_surfaces(img, object_mask=mask).columns.ceiling_v
    rows = net(img)
    ok = np.isfinite(lab)
    e_lab = np.abs(lab[ok] - true[0][ok])
    e_net = np.abs(rows[0] - true[0])
    return {"room": room.name, "labels": float(e_lab.mean()) if ok.any() else float("nan"),
            "labels_off": float(np.mean(e_lab > 3.0)) if ok.any() else float("nan"),
            "network": float(e_net.mean()), "network_off": float(np.mean(e_net > 3.0)),
            "network_floor": float(np.abs(rows[1] - true[1]).mean())}


def main(argv: list[str] | None = None) -> int:
    from layout.surfaces.boundary_net import load_boundary_net

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, nargs="+", help="synthetic sets (pano2cad synth output)")
    ap.add_argument("--weights", default=None, help="boundary_net.pt (default: the committed weights)")
    args = ap.parse_args(argv)
    net = load_boundary_net(args.weights)
    print(f"boundary network: {args.weights or 'committed weights'}; rows in pixels of the panorama's height")
    for data in args.data:
        rooms = sorted(p for p in data.iterdir() if (p / "gt.json").is_file())
        if not rooms:
            raise SystemExit(f"{data}: no room folders with gt.json")
        t0 = time.perf_counter()
        res = [room_errors(r, net) for r in rooms]
        h = int(json.loads((rooms[0] / "gt.json").read_text())["image"]["height"])
        print(f"\n{data}: {len(res)} rooms at height {h}, gt boxes masked ({time.perf_counter() - t0:.0f} s)\n")
        print("| ceiling-wall boundary | mean over rooms (px) | median room (px) | worst room (px) "
              "| columns > 3 px off | rooms > 5 px |\n|---|---:|---:|---:|---:|---:|")
        for key, name in (("labels", "surface labels (GC + OM fusion)"), ("network", "boundary network")):
            e = np.array([r[key] for r in res])
            off = np.array([r[key + "_off"] for r in res])
            print(f"| {name} | {np.nanmean(e):.2f} | {np.nanmedian(e):.2f} | {np.nanmax(e):.2f} "
                  f"| {np.nanmean(off):.3f} | {int(np.sum(e > 5))} |")
        fl = np.array([r["network_floor"] for r in res])
        print(f"\nboundary network, floor-wall boundary of the empty room (behind furniture too): mean {fl.mean():.2f} px, "
              f"median {np.median(fl):.2f} px")
        bad = [r for r in res if r["labels"] > 5 or r["network"] > 5]
        if bad:
            print("\n| room | labels (px) | network (px) |\n|---|---:|---:|")
            for r in bad:
                print(f"| {r['room']} | {r['labels']:.2f} | {r['network']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
