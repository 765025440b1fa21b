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
the layout error from the room step's. The ceiling-wall and floor-wall contact
rows of the run's labels are compared with the generator's column by column
(:func:`contact_row_errors`): a mean or median off zero is a bias of the
labeller (session 36 found the ceiling half a row low, a rasterisation of the
boundary network's rows).

On the generator's labels, the rooms the room step gets worst are listed
(``--worst``) with their corner counts and the columns where floor that the
labels show (unmasked floor pixels) lies beyond the polygon's wall, more
than 2 rows above its floor boundary (:func:`floor_beyond`): where there is none, the polygon
agrees with every floor pixel and what it misses no floor pixel shows. With ``--hidden`` the generator's figures
are also split by whether the room's view shows its corner count (``_hidden_walls.py``: a polygon with fewer
corners, an unseen run of walls replaced, explains every pixel as well where it does not). The run's label
maps are in its rectified frame, which for the upright synthetic panoramas is
the input's to a fraction of a degree.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def floor_beyond(labels: np.ndarray, mask: np.ndarray | None, floor: np.ndarray, ceiling_z: float,
                 camera_height: float, rows: float = 2.0) -> int:
    """Columns of ``labels`` (H, W) with an unmasked floor pixel more than ``rows`` rows above the floor-wall
    boundary of the room ``floor`` (K, 2), ``ceiling_z`` (:func:`layout.labelmap.room_boundaries`, camera at the
    origin): floor the labels show beyond the polygon's wall."""
    from layout.labelmap import room_boundaries

    seen = (labels == 1) if mask is None else (labels == 1) & ~mask
    top = np.argmax(seen, axis=0) + 0.5  # (W,) centre of the highest floor pixel: the farthest floor seen
    wall_v = room_boundaries(floor, ceiling_z, [0.0, 0.0], camera_height, labels.shape[1]).floor_v
    return int(np.count_nonzero(seen.any(axis=0) & (top < wall_v - rows)))


def contact_row_errors(truth: np.ndarray, labels: np.ndarray, skip: int = 2) -> dict[str, np.ndarray]:
    """Ceiling-wall and floor-wall contact rows of ``labels`` minus those of ``truth`` (both (H, W) label maps,
    read by :func:`layout.labelmap.observe_boundaries`), in the columns where both show the contact and the true row
    does not jump within ``skip`` columns (a wall's end). Positive: the contact lies lower in the image. Returns
    ``{"ceiling": (n_c,), "floor": (n_f,)}`` in rows."""
    from layout.labelmap import observe_boundaries

    ot, ol = observe_boundaries(truth), observe_boundaries(labels)
    out = {}
    for kind in ("ceiling", "floor"):
        name = "ceil" if kind == "ceiling" else "floor"
        tv, lv = getattr(ot, name + "_v"), getattr(ol, name + "_v")
        ok = getattr(ot, name + "_contact") & getattr(ol, name + "_contact")
        jump = np.abs(np.diff(tv, append=tv[:1])) > 1.5
        near = jump.copy()
        for k in range(1, skip + 1):
            near |= np.roll(jump, k) | np.roll(jump, -k)
        ok &= ~near
        out[kind] = lv[ok] - tv[ok]
    return out


def main(argv: list[str] | None = None) -> int:
    from PIL import Image

    from layout.likelihood import boxes_mask
    from layout.metrics import score_layout
    from layout.roomgeom import RoomGeometryError, estimate_room_geometry

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="synthetic set (pano2cad synth output)")
    ap.add_argument("run", type=Path, help="pano2cad eval output on it (label_ids.png per room)")
    ap.add_argument("--worst", type=int, default=8,
                    help="list the rooms the labels cost most, and the rooms worst on the generator's labels")
    ap.add_argument("--hidden", action="store_true",
                    help="split the generator's figures by whether the view shows the room's corner count "
                         "(needs depth.png; some 0.4 s per room)")
    args = ap.parse_args(argv)
    if args.hidden:
        from _hidden_walls import fewer_corner_explanations, lift_view

        from layout.metrics import iou_2d
    rows, unsolved, shown = [], [], {}
    contact: dict[str, list[np.ndarray]] = {"ceiling": [], "floor": []}
    for room in sorted(p for p in args.data.iterdir() if (p / "gt.json").is_file()):
        pred = args.run / room.name / "label_ids.png"
        if not pred.is_file():
            continue
        gt = json.loads((room / "gt.json").read_text())
        h = float(gt["camera_height_m"])
        boxes = np.array([o["bbox_pano"] for o in gt["objects"] if o.get("bbox_pano")], float).reshape(-1, 4)
        ious, extra = [], ()
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
            if path.name == "labels.png":
                truth = lab
                beyond = floor_beyond(lab, mask, np.asarray(g.floor), float(g.ceiling_z), h)
                extra = (len(g.floor), len(gt["room"]["floor"]), beyond)
                if args.hidden:
                    view = lift_view(lab, np.array(Image.open(room / "depth.png")))
                    truth_poly = np.asarray(gt["room"]["floor"], float)
                    others = fewer_corner_explanations(truth_poly, view)
                    # None: the view shows the count; else the 2D IoU of the closest other explanation
                    shown[room.name] = max(iou_2d(q, truth_poly) for q in others) if others else None
        rows.append((room.name, *ious, *extra))
        if extra:
            for kind, d in contact_row_errors(truth, lab).items():
                contact[kind].append(d)
    if not rows:
        raise SystemExit(f"{args.run}: no label_ids.png of the rooms of {args.data}")
    a = np.array([r[1:3] for r in rows], float)
    print(f"{len(rows)} rooms, true camera height, gt boxes masked: mean 3D IoU on ground-truth labels "
          f"{a[:, 0].mean():.3f} (median {np.median(a[:, 0]):.3f}), on the run's labels {a[:, 1].mean():.3f} "
          f"(median {np.median(a[:, 1]):.3f})")
    parts = []
    for kind, ds in contact.items():
        d = np.concatenate(ds) if ds else np.zeros(0)
        if d.size:
            parts.append(f"{kind} mean {d.mean():+.2f} median {np.median(d):+.2f}, {100 * np.mean(np.abs(d) > 2):.1f} % "
                         f"more than 2 rows off ({d.size} columns)")
    if parts:
        print("contact rows of the run's labels minus the generator's (columns where both show one, away from wall "
              "ends; + lower in the image): " + "; ".join(parts))
    gap = sorted(rows, key=lambda r: r[2] - r[1])[: args.worst]
    if unsolved:
        print(f"not solved by the room step (scored 0): {', '.join(unsolved)}")
    print("largest losses to the labels: " + "; ".join(f"{r[0]} {r[1]:.2f} -> {r[2]:.2f}" for r in gap))
    solved = [r for r in rows if len(r) > 3]
    beyond = [r for r in solved if r[5] > 0]
    print(f"generator's labels: {len(beyond)} of {len(solved)} rooms leave floor the labels show outside the polygon; "
          "worst rooms (3D IoU, corners ours / gt, columns of floor beyond): " + "; ".join(
              f"{r[0]} {r[1]:.2f} {r[3]}/{r[4]} {r[5]}" for r in sorted(solved, key=lambda r: r[1])[: args.worst]))
    if args.hidden:
        print(hidden_split(solved, shown))
    return 0


def hidden_split(solved: list[tuple], shown: dict[str, float | None]) -> str:
    """The generator's-label figures (rows ``(room, iou_gt, iou_run, corners, gt corners, beyond)``) split by
    whether the room's view shows its corner count: ``shown[room]`` None where it does, else the 2D IoU with the
    truth of the closest polygon with fewer corners that explains the view as well."""
    yes = [r for r in solved if shown.get(r[0]) is None]
    no = [r for r in solved if shown.get(r[0]) is not None]

    def figs(rs: list[tuple]) -> str:
        if not rs:
            return "none"
        return (f"3D IoU {np.mean([r[1] for r in rs]):.3f}, exact corner count "
                f"{100 * np.mean([r[3] == r[4] for r in rs]):.1f} %")

    return (f"the view shows the corner count in {len(yes)} of {len(solved)} rooms (at least {len(no)} leave it "
            f"open: {', '.join(r[0] for r in no) or 'none'}); generator's labels where shown: {figs(yes)}; where "
            f"not: {figs(no)} (the closest fewer-corner polygon that explains the view: 2D IoU "
            f"{np.mean([shown[r[0]] for r in no]) if no else float('nan'):.3f} with the truth); exact corner count "
            f"possible without guessing unseen walls: at most {100 * len(yes) / max(len(solved), 1):.1f} %")


if __name__ == "__main__":
    raise SystemExit(main())
